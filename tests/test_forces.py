"""The internal forces behind one protocol (set_step, velocity_increment, stable_dt, book).

Oracles:

* Bit for bit against the previous code path, which this test keeps while the protocol
  lands: the small-strain step as the Integrator made it before (A = -dt M^-1 K built and
  multiplied here, the quadrature force's own increment with coef = -dt / m computed
  here), on a linear and a J2 body sharing one mesh, triangles and Q1; the finite-strain
  step as the former finite-strain driver made it (the force's compute at the step just
  taken, then the trapezoid and the velocity passes: its kernels, moved unchanged,
  called here in its order), with a step that changes. u, v and
  every booked work are compared with array_equal / ==.
* A step change through set_step gives the force a fresh run at that step would have,
  bit for bit (A, coef).
* Each force's stable_dt() against its element bound, 2 / omega with omega^2 the
  largest eigenvalue of K_e v = omega^2 M_e v over its cells, K_e and M_e built by hand
  here: on triangles the textbook axisymmetric constant-strain element (eps_tt = u_r / r,
  the three interior points (1/6, 1/6), (2/3, 1/6), (1/6, 2/3) of the degree-2 rule, the
  row-sum lumped mass rho 2 pi A (2 r_a + r_b + r_c) / 12); on Q1 the B-bar element of
  docs/materials.md (eps_bar_q = eps_q + (theta_bar - tr eps_q) / 3 (1, 1, 1, 0),
  K = sum_q w_q B_bar_q' D B_bar_q, lumped mass rho sum_q w_q N_a, 2 x 2 Gauss); the
  finite-strain force's min L / c with L = A / (largest diagonal), c = sqrt((lambda +
  2 mu) / rho) (docs/materials.md), at the start and on cells flattened by a
  homogeneous compression.
"""
import math

import numpy as np
import pytest
from dolfinx import fem
from mpi4py import MPI
from petsc4py import PETSc

from impact_fenics import compat
from impact_fenics.bodies import Body, DeformableModel
from finite_body import finite_body
from impact_fenics.quad_meshes import quad_bar
from impact_fenics.integrator import Integrator
from impact_fenics.internal_force import QuadratureForce
from impact_fenics.internal_force.finite import trapezoid_work, velocity_update
from impact_fenics.materials import LinearElastic
from impact_fenics.materials.finite_j2 import FiniteJ2
from impact_fenics.materials.j2 import J2
from impact_fenics.operators import assemble_stiffness
from roundoff import rounding
from two_halves import EIG, two_halves

COMM = MPI.COMM_WORLD
E, NU, RHO = 200e9, 0.3, 7850.0
E_UPPER = 2.25 * E
# off the axis (no fixed dof: each element problem takes all its dofs); dyadic coordinates
R0, R1, Z1, N_R, N_Z = 1.0, 1.5, 1.0, 4, 8
H = (R1 - R0) / N_R  # 1/8 m: square cells


def _two_bodies(quadrilateral: bool) -> DeformableModel:
    """The rectangle R0..R1 x 0..Z1: 'elastic' (E) below z = 1/2, 'plastic' (J2, E_UPPER,
    a low yield stress) above."""
    tm = two_halves(COMM, (R0, 0.0), (R1, Z1), N_R, N_Z, quadrilateral, ("elastic", "plastic"))
    return DeformableModel(tm, [
        Body("elastic", LinearElastic(E=E, nu=NU, density=RHO)),
        Body("plastic", J2(E=E_UPPER, nu=NU, density=RHO, yield_stress=20e6, hardening=1e9))])


# ---------------------------------------------------------------- bit for bit, small strain
# PETSc adds the entries other ranks send to a row of K in the order they arrive. On 1 or
# 2 ranks a row receives from one rank at most, in one message: every assembly gives the
# same bits. From 3 ranks on, a row can receive from two, and its last bit may change
# from one assembly to the next (seen on 3 ranks here): two paths that assemble K each on
# their own then agree to round-off only, and the test runs both on one assembly.
REPRODUCIBLE_ASSEMBLY = COMM.size <= 2


def previous_A(model: DeformableModel, integ: Integrator, dt: float, fixed: np.ndarray):
    """A = -dt M^-1 K over the linear bodies as the Integrator built it before (zero rows
    on ``fixed``), assembled here; from 3 ranks a copy of ``integ``'s own (see
    REPRODUCIBLE_ASSEMBLY)."""
    if not REPRODUCIBLE_ASSEMBLY:
        return integ.A.copy()
    A = assemble_stiffness(model, "aij", [p for p in model.parts if p[0].linear])
    scale = A.createVecRight()
    scale.array[:] = -dt / integ.mass
    A.diagonalScale(L=scale)
    A.zeroRows(model.to_global(fixed).astype(PETSc.IntType), diag=0.0)
    return A


def previous_path(model: DeformableModel, integ: Integrator, dt: float, fixed: np.ndarray,
                  v0: np.ndarray):
    """The previous small-strain step's pieces, at rest in u and at ``v0`` (m/s) in v:
    (A of :func:`previous_A`, u's Function, u, v, the 'plastic' body's quadrature force
    with its own coef = -dt / m on the free dofs)."""
    free = np.ones(model.n_owned, dtype=bool)
    free[fixed] = False
    A = previous_A(model, integ, dt, fixed)
    u_fn = fem.Function(model.V)
    u = compat.petsc_vec(u_fn)
    v = u.duplicate()
    u.set(0.0)
    v.array[:] = v0
    force = QuadratureForce(model, "plastic", u_fn, dt, np.where(free, -dt / integ.mass, 0.0))
    return A, u_fn, u, v, force


@pytest.mark.parametrize("quadrilateral", [False, True], ids=["triangles", "quadrilaterals"])
def test_small_strain_step_is_the_previous_path_bit_for_bit(quadrilateral):
    model = _two_bodies(quadrilateral)
    fixed = model.axis_dofs()
    dt = 4e-6  # s: far below a cell's transit time H / c = 0.125 / 8.9e3 s
    integ = Integrator(model, dt, fixed)
    n = model.n_owned
    x = model.node_xy[: n // 2]
    v0 = np.zeros(n)
    v0[0::2], v0[1::2] = 30.0 * (x[:, 0] - R0), 80.0 * x[:, 1] ** 2  # shear and stretch
    integ.set_initial(None, v0)

    # the previous path, kept here: A built as the Integrator built it, one MatMultAdd,
    # the quadrature force's own increment with coef = -dt / m, then u += dt v
    A, u_fn, u, v, old = previous_path(model, integ, dt, fixed, v0)
    new = integ.nonlinear[0]
    for _ in range(40):
        A.multAdd(u, v, v)
        u_fn.x.scatter_forward()
        old.add_velocity_increment(u_fn.x.array[:n], v.array)
        u.axpy(dt, v)
        integ.predict()
        integ.advance()
        assert np.array_equal(integ.u_owned, u_fn.x.array[:n])
        assert np.array_equal(integ.v_owned, v.array)
    assert new.deformation_work_local == old.deformation_work_local
    assert new.plastic_work_local == old.plastic_work_local
    assert np.array_equal(new.qs.sigma, old.qs.sigma)
    yielded = COMM.allreduce(int((new.qs.state[..., 0] > 0.0).sum()))
    assert yielded > 0  # the plastic path ran
    # book() reports what the force booked
    b = new.book()
    assert (b.work, b.dissipated) == (new.deformation_work_local, new.plastic_work_local)
    assert b.stored == new.elastic_energy_local()
    lin = integ.linear.book()
    Ku = integ.K.createVecLeft()
    integ.K.mult(integ.u_vec, Ku)
    assert lin.stored == 0.5 * float(np.dot(integ.u_owned, Ku.array)) and lin.work is None

    # a new step through set_step: the A and coef a run started at that step would have
    dt2 = 0.75 * dt
    fresh = Integrator(model, dt2, fixed)
    integ.linear.set_step(dt2, dt2)
    for f in integ.nonlinear:
        f.set_step(dt2, dt2)
    w = u.duplicate()
    w.array[:] = np.linspace(-1.0, 1.0, n)
    y1, y2 = w.duplicate(), w.duplicate()
    integ.A.mult(w, y1)
    fresh.A.mult(w, y2)
    if REPRODUCIBLE_ASSEMBLY:  # (two assemblies)
        assert np.array_equal(y1.array, y2.array)
    assert np.array_equal(integ.nonlinear[0].coef, fresh.nonlinear[0].coef)
    assert integ.nonlinear[0].dt == dt  # the points' step: the one just taken


# ---------------------------------------------------------------- bit for bit, finite strain
def test_finite_strain_step_is_the_previous_path_bit_for_bit():
    """The finite-strain driver's step before the protocol (kept here) and the force's set_step, evaluate
    and add_increment, over steps that change (the points' step is the one just taken)."""
    def bar():
        mesh = quad_bar(COMM, 2.0 ** -8, 10 * 2.0 ** -8, 2, 20)
        run = finite_body(mesh, FiniteJ2(E=117e9, nu=0.35, density=8930.0,
                                         yield_stress=40e6, hardening=100e6))
        z = run.node_xy[: run.n_owned_nodes, 1]
        run.v[1::2] = -5000.0 * z / (10 * 2.0 ** -8)  # a compression that yields
        return run
    old, new = bar(), bar()
    lim = old.force.stable_dt()
    steps = [0.5 * lim] * 3 + [0.3 * lim] * 2 + [0.45 * lim, 0.2 * lim]
    f_prev, u_prev = np.zeros(old.n_owned), np.zeros(old.n_owned)
    w_old = trap_old = 0.0
    dt_prev = None
    for dt in steps:
        dt_avg = dt if dt_prev is None else 0.5 * (dt_prev + dt)
        old.u_fn.x.scatter_forward()
        f = old.force.compute(dt_prev if dt_prev is not None else dt)
        trap_old += trapezoid_work(f, old.u_owned, f_prev, u_prev)
        w_old += velocity_update(old.coef, f, old.v, dt_avg)
        old.u_vec.axpy(dt, old.v_vec)
        new.force.set_step(dt, dt_avg)
        new.u_fn.x.scatter_forward()
        new.force.evaluate()
        new.force.add_increment(new.v, dt_avg)
        new.u_vec.axpy(dt, new.v_vec)
        dt_prev = dt
        assert np.array_equal(new.u, old.u) and np.array_equal(new.v, old.v)
    assert new.force.work_local == w_old and new.force.trapezoid_local == trap_old
    assert np.array_equal(new.force.state, old.force.state)
    assert COMM.allreduce(float(new.force.state[..., 0].max())) > 0.0  # it yielded
    b = new.force.book()
    assert (b.work, b.dissipated) == (trap_old, old.force.plastic_work_local)
    assert b.stored == old.force.stored_energy_local()


# ---------------------------------------------------------------- stable_dt by hand
def _D(E_: float, nu: float) -> np.ndarray:
    """Isotropic D (Pa) on (rr, tt, zz, rz) with the engineering shear."""
    lam, mu = E_ * nu / ((1.0 + nu) * (1.0 - 2.0 * nu)), E_ / (2.0 * (1.0 + nu))
    D = np.full((4, 4), 0.0)
    D[:3, :3] = lam
    D[[0, 1, 2], [0, 1, 2]] += 2.0 * mu
    D[3, 3] = mu
    return D


def _B(N: np.ndarray, dNdr: np.ndarray, dNdz: np.ndarray, r: float) -> np.ndarray:
    """Strain (rr, tt, zz, rz engineering) of the dofs (u_r, u_z) node by node."""
    n = N.size
    B = np.zeros((4, 2 * n))
    B[0, 0::2], B[1, 0::2], B[2, 1::2] = dNdr, N / r, dNdz
    B[3, 0::2], B[3, 1::2] = dNdz, dNdr
    return B


def _largest_w2(K: np.ndarray, m: np.ndarray) -> float:
    s = 1.0 / np.sqrt(m)
    return float(np.linalg.eigvalsh(K * s[:, None] * s[None, :])[-1])


def _triangle_w2(xy: np.ndarray, D: np.ndarray) -> float:
    """The axisymmetric P1 triangle with the three-point degree-2 rule, row-sum mass."""
    d = xy[1:] - xy[:1]
    J = np.array([[d[0, 0], d[1, 0]], [d[0, 1], d[1, 1]]])  # d(r, z) / d(xi, eta)
    det = J[0, 0] * J[1, 1] - J[0, 1] * J[1, 0]
    grad = np.array([[-1.0, -1.0], [1.0, 0.0], [0.0, 1.0]]) @ np.linalg.inv(J)
    K = np.zeros((6, 6))
    for xi, eta in ((1 / 6, 1 / 6), (2 / 3, 1 / 6), (1 / 6, 2 / 3)):
        N = np.array([1.0 - xi - eta, xi, eta])
        r = N @ xy[:, 0]
        B = _B(N, grad[:, 0], grad[:, 1], r)
        K += (1 / 6) * abs(det) * 2.0 * math.pi * r * B.T @ D @ B
    area = 0.5 * abs(det)
    m = RHO * 2.0 * math.pi * area * (xy[:, 0].sum() + xy[:, 0]) / 12.0
    return _largest_w2(K, np.repeat(m, 2))


def _quad_w2(xy: np.ndarray, D: np.ndarray) -> float:
    """The axisymmetric B-bar Q1 (nodes (0,0), (1,0), (0,1), (1,1) of the unit square), 2 x 2
    Gauss, mass rho sum_q w_q N_a."""
    g = 0.5 / math.sqrt(3.0)
    Bs, ws, Ns = [], [], []
    for x in (0.5 - g, 0.5 + g):
        for y in (0.5 - g, 0.5 + g):
            N = np.array([(1 - x) * (1 - y), x * (1 - y), (1 - x) * y, x * y])
            dxi = np.array([-(1 - y), 1 - y, -y, y])
            deta = np.array([-(1 - x), -x, 1 - x, x])
            J = np.array([[dxi @ xy[:, 0], deta @ xy[:, 0]], [dxi @ xy[:, 1], deta @ xy[:, 1]]])
            grad = np.stack([dxi, deta], axis=1) @ np.linalg.inv(J)
            r = N @ xy[:, 0]
            Bs.append(_B(N, grad[:, 0], grad[:, 1], r))
            ws.append(0.25 * abs(np.linalg.det(J)) * 2.0 * math.pi * r)
            Ns.append(N)
    V = sum(ws)
    b_bar = sum(w * B[:3].sum(axis=0) for w, B in zip(ws, Bs)) / V
    K = np.zeros((8, 8))
    for w, B in zip(ws, Bs):
        Bb = B.copy()
        Bb[:3] += (b_bar - B[:3].sum(axis=0)) / 3.0
        K += w * Bb.T @ D @ Bb
    m = RHO * sum(w * N for w, N in zip(ws, Ns))
    return _largest_w2(K, np.repeat(m, 2))


# Both sides compute the largest eigenvalue of the same 6 x 6 (8 x 8) element problem by
# different sums: each within EIG (two_halves.py: LAPACK's backward error and the entries'
# roundings), two of them; on Q1 the Jacobians' products of coordinates up to R1 with the
# irrational Gauss points add 3 x 8 EPS R1 / H; then the square root, 2 / w.


@pytest.mark.parametrize("quadrilateral", [False, True], ids=["triangles", "quadrilaterals"])
def test_stable_dt_of_each_force_is_its_element_bound_by_hand(quadrilateral):
    model = _two_bodies(quadrilateral)
    integ = Integrator(model, 1e-9, model.axis_dofs())
    mesh = model.mesh
    geo = compat.geometry_dofs(mesh)
    element = _quad_w2 if quadrilateral else _triangle_w2
    got = {"elastic": integ.linear.stable_dt(), "plastic": integ.nonlinear[0].stable_dt()}
    jacobian = 3 * 8 * R1 / H if quadrilateral else 0.0
    bound = rounding(2 * (EIG + jacobian) + 4)
    for name, e in (("elastic", E), ("plastic", E_UPPER)):
        D = _D(e, NU)
        w2 = max((element(mesh.geometry.x[geo[c], :2], D) for c in model.owned_cells(name)),
                 default=0.0)
        dt = 2.0 / math.sqrt(COMM.allreduce(w2, op=MPI.MAX))
        assert got[name] == pytest.approx(dt, rel=bound), (name, got[name], dt)
    # the stiffer body's is the smaller, by sqrt(2.25) = 1.5 (the same cells)
    assert got["elastic"] / got["plastic"] == pytest.approx(1.5, rel=bound)


def test_finite_strain_stable_dt_is_min_L_over_c_of_the_current_cells():
    """Square cells of side h: h / (sqrt 2 c); compressed along z by 3/4 (exact on the dyadic
    mesh): L = h (3/4 h) / sqrt(h^2 + (3/4 h)^2) = (3/5) h."""
    E_, nu, rho = 117e9, 0.35, 8930.0
    h = 2.0 ** -9
    mesh = quad_bar(COMM, 2 * h, 20 * h, 2, 20)
    run = finite_body(mesh, FiniteJ2(E=E_, nu=nu, density=rho, yield_stress=400e6,
                                     hardening=100e6))
    c = math.sqrt(E_ * (1.0 - nu) / ((1.0 + nu) * (1.0 - 2.0 * nu) * rho))
    # A and the diagonals exact; L = A / sqrt(2 h^2) rounds twice, c about 8 times on each
    # side and its sqrt once, L / c once: 2 x 12
    assert run.force.stable_dt() == pytest.approx(h / (math.sqrt(2.0) * c), rel=rounding(24))
    run.u[1::2] = -0.25 * run.node_xy[:, 1]  # owned and ghost nodes: z -> 3/4 z
    assert run.force.stable_dt() == pytest.approx(0.6 * h / c, rel=rounding(24))
