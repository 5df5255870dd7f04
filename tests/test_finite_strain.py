"""Finite-strain element, variable step, wall and the Taylor bar (serial and mpirun -n 2),
the force driven by hand (tests/finite_body.py) and the runs through Simulation.

Round-off bounds count roundings, whole runs compare within the spread of a one-ulp
change of the initial velocity, ledgers within roundoff.ledger (tests/roundoff.py)."""
import math

import numpy as np
import pytest
from mpi4py import MPI

from finite_body import bar_simulation, finite_body
from impact_fenics.quad_meshes import quad_bar
from impact_fenics.materials.finite_j2 import FiniteJ2
from impact_fenics.materials.neo_hookean import NeoHookean
from roundoff import LIBM, assert_runs_agree, assert_within_spread, ledger, one_ulp, rounding

RUBBERY = NeoHookean(E=1e9, nu=0.3, density=1000.0)


def set_field(run, fn):
    """u or v on the owned dofs from fn(R, Z) -> (a_r, a_z); u_r = 0 kept on the axis.
    ``run``: a finite_body or a Simulation."""
    model = getattr(run, "model", run)
    free = run.integrator.free
    xy = model.node_xy[: model.n_owned // 2]
    a_r, a_z = fn(xy[:, 0], xy[:, 1])
    out = np.zeros(model.n_owned)
    out[0::2], out[1::2] = a_r, a_z
    out[~free] = 0.0
    return out


def force_at(run, u_owned):
    run.u_owned[:] = u_owned
    run.u_fn.x.scatter_forward()
    return run.force.compute(1e-8).copy()


def test_rigid_translation_and_homogeneous_stretch(comm):
    """A z translation of 3.7 m gives f_int = 0 to round-off (F = I + sum_a Grad N_a u, with
    sum_a Grad N_a = 0 to eps: |F - I| ~ eps u / h, forces ~ eps u mu 2 pi R; the sum
    over the cell's 4 nodes and the stress from it: 10 roundings). A homogeneous stretch
    u = ((l_r - 1) R, (l_z - 1) Z) of tens of percent gives, with the virtual fields
    w = (R, 0) and (0, Z), f.w = (P_rr + P_tt) V_0 and P_zz V_0 (the closed-form
    neo-Hookean Piola stress, V_0 = pi R^2 L): 2x2 Gauss integrates them exactly, to
    round-off (a point's stress, about 40 roundings and a log, in both; f.w sums the 48
    dofs' terms, all of one sign here)."""
    R, L = 0.01, 0.03
    run = finite_body(quad_bar(comm, R, L, 3, 5), RUBBERY)
    f = force_at(run, set_field(run, lambda r, z: (0 * r, 0 * r + 3.7)))
    bound = rounding(10, 3.7 * RUBBERY.mu * 2 * math.pi * R)
    assert comm.allreduce(np.abs(f).max(), op=MPI.MAX) < bound
    m = RUBBERY
    for lr, lz in ((1.0, 1.4), (1.3, 1.0), (0.8, 1.25)):
        f = force_at(run, set_field(run, lambda r, z: ((lr - 1) * r, (lz - 1) * z)))
        w_r, w_z = set_field(run, lambda r, z: (r, 0 * r)), set_field(run, lambda r, z: (0 * r, z))
        # u_r is fixed on the axis, where w_r = R = 0 too: no reaction is missed
        got = np.array([comm.allreduce(float(f @ w_r)), comm.allreduce(float(f @ w_z))])
        lnj = math.log(lr * lr * lz)
        P = [m.mu * (x - 1 / x) + m.lmbda * lnj / x for x in (lr, lr, lz)]
        V0 = math.pi * R * R * L
        expected = np.array([(P[0] + P[1]) * V0, P[2] * V0])
        assert np.allclose(got, expected, atol=0, rtol=rounding(2 * (40 + LIBM) + 48))


def modified_euler_reference(run, u0, v0, dt, n):
    """Today's scheme written out: v += dt M^-1 (-f(u)), u += dt v."""
    u, v = u0.copy(), v0.copy()
    for _ in range(n):
        f = force_at(run, u)
        v += np.where(run.free, dt * (-f) / run.mass, 0.0)
        u += dt * v
    return u, v


def test_constant_step_is_modified_euler_and_kinetic_identity(comm):
    """With a fixed dt the half-step scheme is the modified Euler scheme of the Integrator
    (to round-off: only the order of two products differs, at every one of the 120 steps,
    so within 120 x the spread of the reference under a one-ulp change of v0); with the
    adaptive step the kinetic identity K + W_int = K_0 holds to the round-off of a ledger."""
    R, L = 0.01, 0.03
    mesh = quad_bar(comm, R, L, 3, 6)
    vel = lambda r, z: (300 * r / R * z / L, -150 * np.sin(math.pi * z / L))  # noqa: E731
    dt, n = 5e-8, 120
    sim = bar_simulation(mesh, RUBBERY, n * dt, dt=dt)
    v0 = set_field(sim, vel)
    sim.integrator.v_owned[:] = v0
    s = sim.run()
    assert s["n_steps"] == n
    ref = finite_body(mesh, RUBBERY)
    u_ref, v_ref = modified_euler_reference(ref, np.zeros(ref.n_owned), v0, dt, n)
    u_ulp, _ = modified_euler_reference(ref, np.zeros(ref.n_owned), np.nextafter(v0, np.inf),
                                        dt, n)
    gather = lambda x: np.concatenate(comm.allgather(x))  # noqa: E731
    assert_within_spread(gather(sim.integrator.u_owned), gather(u_ref), gather(u_ulp), n, "u")
    # adaptive: the step varies (the bar deforms), the identity still closes
    sim = bar_simulation(mesh, RUBBERY, n * dt, interval=3, energy_every=1)
    sim.integrator.v_owned[:] = v0
    s = sim.run()
    assert s["dt_range"][1] > s["dt_range"][0]
    bound = ledger(s["n_steps"], s["n_dofs"])
    assert abs(s["energy_balance_error_rel"]) <= bound
    assert np.abs(sim.energy.data()["balance_error"]).max() <= bound * s["energy_initial"]


@pytest.mark.parametrize("material", [RUBBERY, FiniteJ2(E=1e9, nu=0.3, density=1000.0,
                                                          yield_stress=5e6, hardening=1e8)],
                         ids=["neo_hookean", "finite_j2"])
def test_stored_energy_plus_dissipation_equals_internal_work(comm, material):
    """The trapezoidal internal work sum 1/2 (f^n + f^{n+1}) . du equals the stored energy
    (plus the plastic work) up to the time discretisation: the trapezoid of a
    non-quadratic energy errs by O(dt^2) a step; halving dt divides the gap by about 4
    (3 allowed). J2 yields: a step that crosses the yield surface books its plastic work
    by the exact integral of sigma_y but the force by the trapezoid, a local O(dt) error
    at the onset: measured ratio 2.9, 2.5 allowed."""
    R, L = 0.01, 0.03
    mesh = quad_bar(comm, R, L, 3, 6)
    vel = lambda r, z: (200 * r / R, -300 * z / L)  # noqa: E731
    gaps = []
    for dt in (1e-7, 5e-8):
        sim = bar_simulation(mesh, material, 8e-6, dt=dt)
        sim.integrator.v_owned[:] = set_field(sim, vel)
        s = sim.run(extra=summary_energies)
        gaps.append(abs(s["energy"]["work_gap"]) / (s["stored_elastic"] + s["plastic_work"]))
        assert abs(s["energy_balance_error_rel"]) <= ledger(s["n_steps"], s["n_dofs"])
    if material is not RUBBERY:
        assert s["plastic_work"] > 0.25 * s["stored_elastic"]  # a third of the work dissipated
    print("relative work gaps at dt, dt/2:", gaps)
    assert gaps[1] < gaps[0] / (3 if material is RUBBERY else 2.5)
    assert gaps[1] < 1e-4


def test_fixed_step_stops_when_the_limit_falls(comm):
    """A fixed dt just below the initial limit: the bar flattens on the wall, the limit
    falls below dt and the run stops with the diagnosis (UnstableRunError, exit 3)."""
    from impact_fenics.errors import UnstableRunError

    mesh = quad_bar(comm, 3.2e-3, 32.4e-3, 2, 20)
    dt = 0.9 * finite_body(mesh, FiniteJ2()).force.stable_dt()
    sim = bar_simulation(mesh, FiniteJ2(), 80e-6, (0.0, -227.0), "film", dt=dt)
    with pytest.raises(UnstableRunError, match="above the current stable limit"):
        sim.run()
    assert sim.status == "diverged"


def test_stable_step_estimate_is_below_the_converged_limit():
    """The step rule safety x min(A / max diagonal) / c with safety 0.5 stays below the
    converged 2 / omega_max of the linearised element operator (power iteration on
    M^-1 K with K x from central differences of f_int; axis cells, where the hoop
    stiffness adds, included). On one rank per process (COMM_SELF)."""
    comm = MPI.COMM_SELF
    for n_r, n_z in ((4, 8), (3, 12)):
        mesh = quad_bar(comm, 0.01, 0.03, n_r, n_z)
        run = finite_body(mesh, NeoHookean(E=117e9, nu=0.35, density=8930.0))
        rng = np.random.default_rng(1)
        x = rng.standard_normal(run.n_owned) * run.free
        eps = 1e-9
        lam = 0.0
        for _ in range(3000):
            x /= np.linalg.norm(x)
            Kx = (force_at(run, eps * x) - force_at(run, -eps * x)) / (2 * eps)
            y = np.where(run.free, Kx / run.mass, 0.0)
            lam_new = float(x @ y)
            x = y
            if abs(lam_new - lam) < 1e-10 * lam_new:
                break
            lam = lam_new
        dt_true = 2.0 / math.sqrt(lam_new)
        assert 0.5 * run.force.stable_dt() < dt_true
        assert 0.5 * run.force.stable_dt() > 0.3 * dt_true  # and not needlessly small


def summary_energies(sim) -> dict:
    """The finite body's stored energy and plastic work at u^N (J) for the summary."""
    shares = np.array([sum(f.stored_energy_local() for f in sim.integrator.finite),
                       sum(f.plastic_work_local for f in sim.integrator.finite)])
    sim.comm.Allreduce(MPI.IN_PLACE, shares)
    return {"stored_elastic": float(shares[0]), "plastic_work": float(shares[1])}


def taylor(comm, n_r, t_end=80e-6, method="film", v0=227.0):
    """The Taylor bar's summary, with its energy's last row's terms at the top level."""
    from impact_fenics import scenes
    from impact_fenics.simulation import Settings

    sim = scenes.taylor_bar(Settings(quiet=True, plots=False, fields=False, history_every=50),
                            FiniteJ2(E=117e9, nu=0.35, density=8930.0, yield_stress=400e6,
                                     hardening=100e6),
                            n_r=n_r, v0=v0, method=method, t_end=t_end, comm=comm)
    s = sim.run(extra=sim.scene_figures)
    return {**s, "kinetic": s["energy"]["kinetic"],
            "activation_loss": s["energy"]["activation_loss"]}


def test_taylor_bar_coarse(comm):
    """The Taylor bar on a 2 x 20 mesh: initial kinetic energy = 1/2 rho pi R^2 L v0^2
    (239.8 J, to the round-off of the lumped mass: each node's about 30 roundings, the
    sums one a node), the kinetic identity to the round-off of a ledger,
    the ledger (kinetic + stored + plastic + wall losses = 239.8 J) to the time
    discretisation (0.5 %), and the shape within the coarse mesh's error of the
    converged Q1/P0 results (21.42-21.48 mm, 7.22-7.23 mm): the convergence table of
    docs/taylor_bar.md measures 2-4 % at h = R/2, less on finer meshes."""
    s = taylor(comm, 2)
    K0 = 0.5 * 8930.0 * math.pi * 3.2e-3 ** 2 * 32.4e-3 * 227.0 ** 2
    assert s["energy_initial"] == pytest.approx(K0, rel=rounding(40 + 2 * 3 * 21))
    assert K0 == pytest.approx(239.8, abs=0.05)
    assert abs(s["energy_balance_error_rel"]) <= ledger(s["n_steps"], s["n_dofs"])
    total = s["kinetic"] + s["stored_elastic"] + s["plastic_work"] + s["activation_loss"]
    assert total == pytest.approx(K0, rel=5e-3)
    assert s["plastic_work"] > 0.9 * K0
    assert s["final_length"] * 1e3 == pytest.approx(21.45, rel=0.03)
    assert s["final_face_radius"] * 1e3 == pytest.approx(7.225, rel=0.06)


def test_taylor_bar_partitions(comm):
    """The same numbers on any number of ranks: this rank alone against all ranks, within
    the steps x the spread of the serial run under a one-ulp change of v0."""
    if comm.size == 1:
        pytest.skip("needs mpirun -n 2 (the MPI pass runs it)")
    a = taylor(comm, 2, t_end=15e-6)
    b = taylor(MPI.COMM_SELF, 2, t_end=15e-6)
    ulp = taylor(MPI.COMM_SELF, 2, t_end=15e-6, v0=one_ulp(227.0))
    assert a["n_steps"] == b["n_steps"]
    for k in ("final_length", "final_face_radius", "eps_p_max", "plastic_work", "kinetic",
              "activation_loss"):
        assert_runs_agree(a[k], b[k], ulp[k], b["n_steps"], k)


def test_johnson_cook_bar_heats_by_its_plastic_work(comm):
    """A Johnson-Cook copper bar onto the wall (coarse, 10 us): the heat in the bar,
    sum_q w_q rho c_p (T_q - T_room), equals chi times the plastic work of the ledger to
    round-off (both book the step's trapezoid of sigma_y); the temperature reaches the
    cell output. Round-off: a point's temperature is a running sum, rounded each step on
    its size T (not on T - T_room), twice with the increment's own roundings."""
    from impact_fenics.materials.johnson_cook import JohnsonCook

    jc = JohnsonCook()
    mesh = quad_bar(comm, 3.2e-3, 32.4e-3, 2, 20)
    sim = bar_simulation(mesh, jc, 10e-6, (0.0, -227.0), "dme")
    s = sim.run(extra=summary_energies)
    force = sim.integrator.finite[0]
    g = force.geometry
    temp = force.state[..., 5]
    heat = comm.allreduce(float((g.w * jc.density * jc.c_p * (temp - jc.t_room)).sum()))
    capacity = comm.allreduce(float((g.w * jc.density * jc.c_p).sum()))  # J/K
    t_max = comm.allreduce(float(temp.max(initial=0.0)), op=MPI.MAX)
    assert s["plastic_work"] > 10.0
    assert heat == pytest.approx(jc.chi * s["plastic_work"], rel=0,
                                 abs=rounding(2 * s["n_steps"], capacity * t_max))
    _, eps, temp = force.cell_values()
    hot = comm.allreduce(float(temp.max(initial=0.0)), op=MPI.MAX)
    assert hot > jc.t_room + 20.0  # tens of kelvin at the impact face
    assert np.all((temp >= jc.t_room - 1e-9) | (eps == 0))


def test_inverted_element_is_diagnosed(comm):
    """A displacement that folds cells (u_z = -2 Z: F_zz = -1, J < 0) stops the force with
    UnstableRunError naming J and a cell position, on every rank alike."""
    from impact_fenics.errors import UnstableRunError

    run = finite_body(quad_bar(comm, 0.01, 0.03, 2, 4), RUBBERY)
    with pytest.raises(UnstableRunError, match=r"inverted: J = det F = .* <= 0 \(cell at R"):
        force_at(run, set_field(run, lambda r, z: (0 * r, -2.0 * z)))


def _ring_volumes(x: np.ndarray) -> np.ndarray:
    """2 pi r_c A of quadrilaterals with vertices x (n, 4, 2) in dolfinx's order (0,0), (1,0),
    (0,1), (1,1) (m^3, Pappus: the ring volume of a plane figure is its area times the
    path of its centroid); the shoelace formula on the cycle 0, 1, 3, 2, about the first
    vertex (coordinates of the cell's size: no cancellation of the bar's)."""
    origin = x[:, :1, :]
    p = (x - origin)[:, [0, 1, 3, 2], :]
    q = np.roll(p, -1, axis=1)
    cross = p[..., 0] * q[..., 1] - q[..., 0] * p[..., 1]
    area = 0.5 * cross.sum(axis=1)
    r_c = origin[:, 0, 0] + ((p[..., 0] + q[..., 0]) * cross).sum(axis=1) / (6.0 * area)
    return np.abs(2.0 * math.pi * r_c * area)


def test_cell_stress_is_the_mean_of_the_point_stresses(comm):
    """What a finite-strain run outputs per cell: the Cauchy stress sum_q w_q tau_q /
    (J_bar V_0), the mean of the material's point Cauchy stresses tau_q / J_bar (with
    mean dilatation the point update sees F_bar_q, det F_bar_q = J_bar) weighted by the
    points' current volumes w_q J_bar. Oracle for J_bar: the current ring volume of the
    cell over the reference one, by Pappus (2x2 Gauss integrates 2 pi r dA exactly on a
    bilinear cell); round-off bound 64 eps of the largest stress: some 30 rounded
    operations on each side (Gauss sums, shoelace, the means), the cell's coordinates
    taken about its first vertex. And the yield condition on the output: J_bar times its von Mises is
    within the points' largest Kirchhoff yield stress sigma_y0 + H eps_bar_p (the finite J2
    yields in the Kirchhoff stress), to 64 eps of its largest stress component (the
    return's logarithms and principal axes, the mean and the von Mises)."""
    sy0, H = 400e6, 100e6
    mesh = quad_bar(comm, 3.2e-3, 32.4e-3, 4, 40)
    sim = bar_simulation(mesh, FiniteJ2(E=117e9, nu=0.35, density=8930.0, yield_stress=sy0,
                                        hardening=H), 10e-6, (0.0, -227.0), "film")
    sim.run()  # ends with the force at the final u: tau and the state are of that u
    f = sim.integrator.finite[0]
    g = f.geometry
    sig, _, _ = f.cell_values()  # (rr, tt, zz, rz), Pa: the cell output
    X = sim.model.node_xy[g.dofs]
    u = sim.integrator.u_function.x.array.reshape(-1, 2)[g.dofs]
    j_bar = _ring_volumes(X + u) / _ring_volumes(X)
    mean_tau = np.einsum("nq,nqi->ni", g.w, f.tau) / g.volume[:, None]
    assert np.abs(sig * j_bar[:, None] - mean_tau).max() <= \
        64 * np.finfo(float).eps * np.abs(mean_tau).max()
    kirchhoff = sig * j_bar[:, None]  # the output, back to the points' measure
    d = kirchhoff[:, :3] - kirchhoff[:, :3].mean(axis=1, keepdims=True)
    vm_kirchhoff = np.sqrt(1.5 * ((d * d).sum(axis=1) + 2.0 * kirchhoff[:, 3] ** 2))
    sy = sy0 + H * f.state[..., 0].max(axis=1)
    slack = 64 * np.finfo(float).eps * np.abs(f.tau).max(axis=(1, 2))
    assert np.all(vm_kirchhoff <= sy + slack)
    yielded = comm.allreduce(int((f.state[..., 0].max(axis=1) > 0).sum()))
    assert yielded > comm.allreduce(g.dofs.shape[0]) // 10  # the impact end yields


def test_final_length_after_a_rebound_is_the_length_of_the_bar(comm):
    """An elastic (neo-Hookean) bar at 10 m/s onto the wall leaves it after 2 L / c0 and flies
    off: final_length is the axis length, z of the top axis node minus z of the bottom
    one (both read here from the nodes), not the top's height above the wall. Oracle:
    after the rebound the bar vibrates with a strain of at most v0 / c0 (the impact's
    plane-wave strain), so its length is L (1 +- v0 / c0), while the top has risen by
    the flight (several millimetres here)."""
    R, L, v0 = 0.01, 0.03, 10.0
    c0 = math.sqrt(RUBBERY.E / RUBBERY.density)
    from impact_fenics.scenes import track_bar

    sim = bar_simulation(quad_bar(comm, R, L, 2, 6), RUBBERY, 600e-6, (0.0, -v0), "film")
    figures = track_bar(sim, R, L)
    s = sim.run(extra=figures)
    x0 = sim.model.node_xy[: sim.model.n_owned // 2]
    z = x0[:, 1] + sim.integrator.u_owned[1::2]
    axis = np.abs(x0[:, 0]) < 1e-12
    top = comm.allreduce(float(z[axis & (x0[:, 1] > L * (1 - 1e-12))].max(initial=-np.inf)),
                         op=MPI.MAX)
    bottom = comm.allreduce(float(z[axis & (x0[:, 1] < 1e-12 * L)].min(initial=np.inf)),
                            op=MPI.MIN)
    assert bottom > 10 * v0 / c0 * L  # off the wall, far beyond a vibration of the length
    assert s["final_length"] == top - bottom
    assert abs(s["final_length"] / L - 1) <= v0 / c0
    e = s["energy"]
    assert e["activation_loss"] >= 0 and e["kinetic"] > 0.5 * s["energy_initial"]
