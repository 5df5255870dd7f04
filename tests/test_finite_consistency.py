"""Independent checks of the finite-strain element, the J2 return and the rigid wall
(serial and mpirun -n 2): the oracles are written here, not taken from the code.

* The F-bar element's internal force is the derivative of its stored energy
  W(u) = sum_q w_q psi(F_bar_q), with J_bar the 2 pi R-weighted cell mean of
  J = det F (hoop stretch included) and F_bar = (J_bar / J)^(1/3) F: W is
  recomputed here in numpy from the node coordinates (own shape functions,
  quadrature and closed-form energies) on a distorted mesh under a large,
  non-homogeneous deformation.
* The Hencky J2 return (exponential map) in uniaxial compression to a log strain
  of -1.5, in axes rotated in the (r, z) plane: the closed form of linear
  hardening in log strain, tau = -(sigma_y + H |eps|) E / (E + H).
* The wall (a fixed plane: a contact set with a fixed rigid part): a penetrating node
  is put back on the wall with v = (z_wall - z^n) / dt, its tangential velocity
  untouched; an open node (or one pulled off the wall) is left alone with zero force;
  an arriving node's loss is the kinetic energy of the normal velocity it loses.

Round-off bounds count roundings (tests/roundoff.py); the partitions of the held-face
run compare within the spread of a one-ulp change of the impact velocity.
"""
import math

import numpy as np
import pytest
from mpi4py import MPI

from impact_fenics import compat
from finite_body import finite_body
from impact_fenics.quad_meshes import quad_bar
from wall_oracle import standalone_plane
from impact_fenics.materials.finite_j2 import FiniteJ2, update as j2_update
from impact_fenics.materials.neo_hookean import NeoHookean
from roundoff import LIBM, assert_runs_agree, ledger, one_ulp, rounding

NEO = NeoHookean(E=1e9, nu=0.45, density=1000.0)
HENCKY = FiniteJ2(E=1e9, nu=0.45, density=1000.0, yield_stress=1e15, hardening=0.0)  # elastic


def psi_neo_hookean(m, F3):
    """mu/2 (tr C - 3 - 2 ln J) + lambda/2 (ln J)^2 (J/m^3) of 3x3 gradients (..., 3, 3)."""
    lnj = np.log(np.linalg.det(F3))
    return 0.5 * m.mu * (np.einsum("...ij,...ij", F3, F3) - 3 - 2 * lnj) + 0.5 * m.lmbda * lnj ** 2


def psi_hencky(m, F3):
    """mu |dev e|^2 + K/2 (tr e)^2 (J/m^3), e = 1/2 ln(F F') by eigenvalues."""
    e = 0.5 * np.log(np.linalg.eigvalsh(F3 @ np.swapaxes(F3, -1, -2)))
    tr = e.sum(axis=-1)
    dev = e - tr[..., None] / 3
    return m.mu * (dev * dev).sum(axis=-1) + 0.5 * (m.lmbda + 2 * m.mu / 3) * tr ** 2


def fbar_energy(run, psi, u):
    """sum over this rank's owned cells of sum_q w_q psi(F_bar_q) (J). Reference map of
    dolfinx's quadrilateral: vertices (0,0), (1,0), (0,1), (1,1); 2x2 Gauss on [0, 1]^2."""
    n_cells = run.mesh.topology.index_map(2).size_local
    cells = compat.cell_dofs(run.V)[:n_cells]
    X = run.node_xy[cells]  # (n, 4, 2) reference coordinates (m)
    U = np.stack([u[2 * cells], u[2 * cells + 1]], axis=-1)  # (n, 4, 2)
    g = 0.5 / math.sqrt(3.0)
    W = 0.0
    F3s, Js, ws = [], [], []
    for xi, eta in [(0.5 - g, 0.5 - g), (0.5 + g, 0.5 - g), (0.5 - g, 0.5 + g), (0.5 + g, 0.5 + g)]:
        N = np.array([(1 - xi) * (1 - eta), xi * (1 - eta), (1 - xi) * eta, xi * eta])
        dN = np.array([[-(1 - eta), -(1 - xi)], [1 - eta, -xi], [-eta, 1 - xi], [eta, xi]])
        jac = np.einsum("nia,ib->nab", X, dN)
        grad = np.einsum("ib,nba->nia", dN, np.linalg.inv(jac))  # dN_i/dX_a
        Rq = X[:, :, 0] @ N
        H = np.einsum("nia,nib->nab", U, grad)  # du_a / dX_b, (r, z)
        F3 = np.zeros((len(X), 3, 3))
        F3[:, :2, :2] = np.eye(2) + H
        F3[:, 2, 2] = 1 + (U[:, :, 0] @ N) / Rq
        F3s.append(F3)
        Js.append(np.linalg.det(F3))
        ws.append(0.25 * np.abs(np.linalg.det(jac)) * 2 * math.pi * Rq)
    V0 = sum(ws)
    jbar = sum(w * J for w, J in zip(ws, Js)) / V0  # current / reference cell volume
    for F3, J, w in zip(F3s, Js, ws):
        W += float(np.sum(w * psi(F3 * np.cbrt(jbar / J)[:, None, None])))
    return W


@pytest.mark.parametrize("material,psi", [(NEO, psi_neo_hookean), (HENCKY, psi_hencky)],
                         ids=["neo_hookean", "hencky"])
def test_fbar_force_is_the_gradient_of_the_stored_energy(comm, material, psi):
    """On a distorted 3 x 4 mesh (axis cells included) under a deformation of tens of
    percent (J from 0.78 to 1.31 at the points): (1) the numpy W equals the code's
    stored energy to round-off; (2) the directional derivative of the numpy W, by
    central differences with step 1e-4 of the displacement, equals f_int . d: the
    quotient errs by (step^2 / 6) W''' ~ 1e-8 relative (6e-8 measured), 1e-6 allowed.
    An energy whose J_bar lacks the 2 pi R weight is off by 1.7e-3 in (1) and 2e-2
    in (2) here."""
    R, L = 0.01, 0.02
    mesh = quad_bar(comm, R, L, 3, 4)
    x = mesh.geometry.x
    h = R / 3
    r, z = x[:, 0].copy(), x[:, 1].copy()
    x[:, 0] = r + 0.2 * h * np.sin(math.pi * r / R) * np.sin(2 * math.pi * z / L)
    x[:, 1] = z + 0.2 * h * np.sin(math.pi * r / R) * np.sin(3 * math.pi * z / L)
    run = finite_body(mesh, material)

    def field(fr, fz):
        xy = run.node_xy
        out = np.zeros(2 * len(xy))
        out[0::2], out[1::2] = fr(xy[:, 0], xy[:, 1]), fz(xy[:, 0], xy[:, 1])
        out[0::2][np.abs(xy[:, 0]) < 1e-12] = 0.0  # u_r = 0 on the axis
        return out  # owned + ghost entries, the same function on every rank

    u = field(lambda r, z: 0.25 * r * np.sin(40 * z) + 0.1 * r * r / R,
              lambda r, z: -0.3 * z + 0.15 * r * r / R + 0.05 * z * z / L)
    d = field(lambda r, z: r / R * np.cos(90 * z), lambda r, z: np.sin(120 * r + 50 * z))
    run.u[:] = u
    f = run.force.compute(1e-9).copy()
    assert 0.7 < run.force.j_min < 0.9  # a large deformation, not a small-strain check
    stored = comm.allreduce(run.force.stored_energy_local())
    psi_m = lambda F3: psi(material, F3)  # noqa: E731
    energy = lambda w: comm.allreduce(fbar_energy(run, psi_m, w))  # noqa: E731
    # each path: a point's energy from F (the gradient, det F, J_bar's weighted mean, the
    # cube root, the energy's terms: about 60 roundings and 3 LIBM calls), summed over
    # the 12 cells x 4 points (energies >= 0: no cancellation in the sum)
    assert energy(u) == pytest.approx(stored, rel=rounding(2 * (60 + 3 * LIBM) + 48))
    step = 1e-4 * comm.allreduce(float(np.abs(u).max()), op=MPI.MAX)  # one step on every rank
    dW = (energy(u + step * d) - energy(u - step * d)) / (2 * step)
    f_d = comm.allreduce(float(f @ d[: run.n_owned]))
    assert f_d == pytest.approx(dW, rel=1e-6)


@pytest.mark.parametrize("angle", [0.0, 0.7])
@pytest.mark.parametrize("n_steps", [1, 20])
def test_hencky_j2_uniaxial_compression_closed_form(angle, n_steps):
    """Uniaxial stress to eps_zz = ln(lambda_z) = -1.5 (lateral stretch solved for
    tau_rr = tau_tt = 0), the loading axes rotated by ``angle`` in the (r, z) plane. With
    log strains, Hencky elasticity and linear hardening the exponential-map return is
    exact on this coaxial path for any step size: tau_zz = -(sigma_y + H |eps|) E / (E + H),
    eps_bar_p = |eps| - |tau_zz| / E, to the lateral solve's accuracy: brentq returns a
    stretch within 2 (xtol + rtol lr) of the root, and a relative change of the lateral
    stretch (two directions) moves the stresses by up to 2 (lambda + 2 mu) times it; the
    point's own round-off (128 roundings with its exp and log) on top."""
    from scipy.optimize import brentq

    m = FiniteJ2(E=117e9, nu=0.35, density=8930.0, yield_stress=400e6, hardening=100e6)
    params, work = m.params(), np.zeros(16)
    c, s = math.cos(angle), math.sin(angle)
    Q = np.array([[c, -s], [s, c]])
    state = m.initial_state().copy()

    def point(lr, lz):
        Fm = Q @ np.diag([lr, lz])
        st, tau = state.copy(), np.zeros(4)
        F = np.array([Fm[0, 0], Fm[0, 1], Fm[1, 0], Fm[1, 1], lr])
        j2_update(F, st, params, 0.0, tau, work)
        T = Q.T @ np.array([[tau[0], tau[3]], [tau[3], tau[2]]]) @ Q  # in the loading axes
        return T, tau[1], st

    eps = -1.5
    for k in range(1, n_steps + 1):
        lz = math.exp(eps * k / n_steps)
        g = 1 / math.sqrt(lz)
        lr = brentq(lambda x: point(x, lz)[0][0, 0], 0.7 * g, 1.4 * g, xtol=1e-16, rtol=1e-15)
        T, t_hoop, st = point(lr, lz)
        state[:] = st
    exact = -(m.yield_stress + m.hardening * abs(eps)) * m.E / (m.E + m.hardening)
    root = 2 * (1e-16 + 1e-15 * lr) / lr * 2 * (m.lmbda + 2 * m.mu) / abs(exact)
    tol = root + rounding(128)
    assert T[1, 1] == pytest.approx(exact, rel=tol)
    assert abs(t_hoop) < tol * abs(exact) and abs(T[0, 1]) < tol * abs(exact)
    assert state[0] == pytest.approx(abs(eps) - abs(exact) / m.E, rel=tol)


def test_wall_projects_releases_and_leaves_the_tangent_alone():
    """Four nodes above the plane z = 0 (Z = 0), mass 2 kg, dt = 1e-6 s, no internal force,
    through the fixed plane (contact/plane.py): a node predicted 1e-6 m below the plane is
    put on it, v_z = (0 - z^n) / dt, v_r kept, (DME: v_z = 0), the reaction >= 0; a node
    on the plane whose prediction leaves it (pulled off) and a node in the air are left
    alone with zero force; the loss booked is the kinetic energy of the normal velocity
    lost, 1/2 m (v~_z^2 - v_z^2)."""
    Z = np.zeros(4)
    mass = np.full(4, 2.0)
    dt = 1e-6
    z_n = np.array([2e-6, 0.0, 0.0, 5e-6])  # positions before the step
    # predicted velocities: arriving, pressing on the wall, leaving it, in the air
    vz = np.array([-3.0, -1.0, 0.5, -1.0])
    vr = np.array([7.0, -2.0, 3.0, 1.0])
    for method in ("film", "dme"):
        u = np.zeros(8)
        v = np.zeros(8)
        wall = standalone_plane(Z, mass, u, v, method)
        v[0::2], v[1::2] = vr, vz
        u[0::2] = 1e-3
        u[1::2] = z_n + dt * vz  # predicted
        w_fix = wall.step(u, v, dt, dt, np.zeros(8))
        assert w_fix == 0.0
        np.testing.assert_array_equal(v[0::2], vr)  # frictionless: tangential untouched
        np.testing.assert_array_equal(u[0::2], 1e-3)
        on = [0, 1]  # the two whose predictions penetrate
        v_new = np.zeros(2) if method == "dme" else (0.0 - z_n[on]) / dt
        # FILM: g~ = z_n + dt v~ (2 roundings), d = dt dt (1/m) (3), 1/d (1), f = -g~ / d
        # (1), dv = f (dt / m) (2), v~ + dv (1): 10 roundings of |v~| + |z_n| / dt; the
        # position u~ + dt dv (2 more) of |u~| + |z_n|. DME: u = -(Z - z_wall) = 0 exactly.
        v_round = rounding(10, np.abs(vz[on]) + np.abs(z_n[on]) / dt)
        u_round = rounding(12, np.abs(u[1::2][on]) + np.abs(z_n[on])) if method == "film" else 0
        assert np.all(np.abs(u[1::2][on]) <= u_round)  # z_wall - Z = 0 - 0
        assert np.all(np.abs(v[1::2][on] - v_new) <= v_round)
        np.testing.assert_array_equal(u[1::2][2:], z_n[2:] + dt * vz[2:])  # left alone
        np.testing.assert_array_equal(v[1::2][2:], vz[2:])
        force = wall.set.force
        assert np.all(force[on] > 0) and np.all(force[2:] == 0)
        # m (v - v~) / dt: the velocity's roundings and 3 more, times m / dt
        assert np.all(np.abs(force[on] - mass[on] * (v_new - vz[on]) / dt)
                      <= (v_round + rounding(3, np.abs(vz[on]))) * mass[on] / dt)
        # no internal force: v^- = v~; the loss is 1/2 m (v~^2 - v^2), the kinetic energy lost:
        # by other expressions (12 roundings of the energies), and the velocities' roundings
        loss = float(np.sum(0.5 * mass[on] * (vz[on] ** 2 - v_new ** 2)))
        gross = float(np.sum(0.5 * mass[on] * (vz[on] ** 2 + v_new ** 2)))
        v_err = float(np.sum(mass[on] * np.abs(v_new) * v_round))
        assert wall.contact_loss_local == pytest.approx(loss, rel=0,
                                                        abs=rounding(12, gross) + v_err)
        assert wall.n_active_local == 2


def test_held_face_taylor_bar(comm):
    """The Taylor bar with the impact face held (demo --face held), 2 x 20, 15 us: the
    face's stop at t = 0 is 1/2 m_face v0^2, so run's initial kinetic energy plus it is
    the closed form 1/2 rho pi R^2 L v0^2 (the lumped masses sum to rho V exactly: each
    node's mass about 30 roundings, the sums one a node); the held face slides out (its
    rim's r grows by more than 20 %); the same numbers on this rank alone as on all ranks
    (within the spread of a one-ulp change of v0, tests/roundoff.py)."""
    from conftest import load_demo

    demo = load_demo("taylor_bar")
    demo.T_END = 15e-6
    s = demo.run(2, comm=comm, face="held")
    n_nodes = 3 * 21
    assert s["energy_initial"] + s["impact_face_loss"] == pytest.approx(
        s["initial_kinetic_closed_form"], rel=rounding(40 + 2 * n_nodes))
    assert s["impact_face_loss"] > 0
    assert s["final_face_radius"] > 1.2 * demo.RADIUS
    assert abs(s["energy_balance_error_rel"]) <= ledger(s["n_steps"], s["n_dofs"])
    if comm.size > 1:
        b = demo.run(2, comm=MPI.COMM_SELF, face="held")
        demo.V0 = one_ulp(demo.V0)
        ulp = demo.run(2, comm=MPI.COMM_SELF, face="held")
        for k in ("final_length", "final_face_radius", "eps_p_max", "plastic_work"):
            assert_runs_agree(s[k], b[k], ulp[k], b["n_steps"], k)
        assert_runs_agree(s["energy"]["kinetic"], b["energy"]["kinetic"],
                          ulp["energy"]["kinetic"], b["n_steps"], "kinetic")
