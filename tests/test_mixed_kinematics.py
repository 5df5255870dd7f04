"""A linear body and a finite-strain body bonded on one Q1 mesh, stepped by the one
integrator under the step that follows the finite body's cells.

Oracles:

* The kinetic identity of the half-step scheme: each force's pass books
  h_n 1/2 (v_before + v_after) . f over the increment it makes, so the bookings of the
  passes a dof takes in turn (the linear one, then the finite one, on the nodes the two
  bodies share) add up to the change of 1/2 v M v exactly; over the run,
  1/2 |v^{N-1/2}|_M^2 + W_linear + W_finite = 1/2 |v^{-1/2}|_M^2 to round-off
  (roundoff.ledger: 32 roundings a dof a step, 4 a dof for the sums).
* The linear pass is the half-step scheme: one step from the integrator's state, v' = v +
  h_n (-K u) / m + the finite force's own increment (both written here from K and from the
  force's f), agrees to round-off with the integrator's step.
* The step is the policy's: min over the finite body's current cells of L / c and the
  linear body's element bound (its cells do not move), times the safety factor.
"""
import numpy as np
from mpi4py import MPI

from impact_fenics.bodies import Body, DeformableModel
from impact_fenics.integrator import Integrator
from impact_fenics.materials import FiniteJ2, LinearElastic
from impact_fenics.stability import parts_stable_dt
from impact_fenics.stepping import FollowingStep
from roundoff import ledger, rounding
from two_halves import two_halves

COMM = MPI.COMM_WORLD
R1, Z1, N_R, N_Z = 4e-3, 16e-3, 4, 16  # m: a rod of 4 x 16 squares of 1 mm
T_END = 6e-6  # s: about 30 waves' transits of a cell, a hundred steps
ANVIL = LinearElastic(E=50e9, nu=0.3, density=7850.0)  # slower than the rod: the rod limits
COPPER = FiniteJ2(E=117e9, nu=0.35, density=8930.0, yield_stress=200e6, hardening=100e6)


def _model() -> DeformableModel:
    tm = two_halves(COMM, (0.0, 0.0), (R1, Z1), N_R, N_Z, True, ("anvil", "rod"))
    return DeformableModel(tm, [Body("anvil", ANVIL), Body("rod", COPPER)])


def _squeeze(model: DeformableModel) -> np.ndarray:
    """v^{-1/2} (m/s): the rod's top moving down at 150 m/s, the anvil's bottom at rest,
    linear in z between (the rod yields near its top, the anvil stays elastic)."""
    x = model.node_xy[: model.n_owned // 2]
    v0 = np.zeros(model.n_owned)
    v0[1::2] = -150.0 * x[:, 1] / Z1
    v0[0::2] = 20.0 * x[:, 0] / R1
    return v0


def _kinetic(integ) -> float:
    return COMM.allreduce(0.5 * float(np.dot(integ.mass, integ.v_owned ** 2)))


def test_a_linear_and_a_finite_body_keep_the_kinetic_identity():
    model = _model()
    policy = FollowingStep(None, T_END)
    integ = Integrator(model, None, model.axis_dofs(), policy=policy)
    assert integ.linear is not None and not integ.linear.scaled and integ.A is None
    assert [f.material for f in integ.finite] == [COPPER]
    # the policy's limit: the finite body's cells and the linear body's fixed bound
    anvil = parts_stable_dt(model, integ.fixed, ["anvil"])
    assert policy.others == anvil
    assert policy.limit == min(integ.finite[0].stable_dt(), anvil)
    integ.set_initial(None, _squeeze(model))
    k0 = _kinetic(integ)
    steps = []
    while integ.t < T_END * (1.0 - 1e-12):
        integ.predict()
        steps.append(integ.step.h)
        integ.advance()
    assert len(set(steps)) > 2  # the step followed the cells
    eps_p = COMM.allreduce(float(integ.finite[0].state[..., 0].max(initial=0.0)), op=MPI.MAX)
    assert eps_p > 0.0  # the rod yielded
    work = COMM.allreduce(integ.linear.work_local + integ.finite[0].work_local)
    assert COMM.allreduce(integ.linear.work_local) > 0.0  # the anvil took energy
    residual = _kinetic(integ) + work - k0
    n_dofs = COMM.allreduce(model.n_owned)
    assert abs(residual) <= ledger(len(steps), n_dofs) * k0, residual / k0


def test_the_linear_pass_is_the_half_step_scheme():
    model = _model()
    integ = Integrator(model, None, model.axis_dofs(), policy=FollowingStep(None, T_END))
    integ.set_initial(None, _squeeze(model))
    free = np.ones(model.n_owned, dtype=bool)
    free[integ.fixed] = False
    K, mass = integ.linear.K, integ.mass
    Ku = K.createVecLeft()
    row_terms = COMM.allreduce(int(np.diff(K.getValuesCSR()[0]).max(initial=0)), op=MPI.MAX)
    K_inf = COMM.allreduce(float(np.abs(K.getValuesCSR()[2]).max(initial=0.0)), op=MPI.MAX) * row_terms
    for _ in range(25):
        integ.predict()  # a few steps so that u and the step are not their start's
        integ.advance()
    u0, v0 = integ.u_owned.copy(), integ.v_owned.copy()
    K.mult(integ.u_vec, Ku)
    integ.predict()
    h, h_avg = integ.step.h, integ.step.h_avg
    f_fin = integ.finite[0].f_owned  # the finite force of this step, f_int(u^n)
    v1 = v0 + np.where(free, h_avg * (-Ku.array - f_fin) / mass, 0.0)
    u1 = u0 + h * v1
    # one step from one state: a row of K u (row_terms), the scaling by h_n / m and the
    # sum with v (3), the finite increment (3); h v and its sum with u (2); on the
    # magnitudes |v| + h_n (|K|_inf max|u| + max|f|) / min m and |u| + h |v'|
    u_max = COMM.allreduce(float(np.abs(u0).max()), op=MPI.MAX)
    f_max = COMM.allreduce(float(np.abs(f_fin).max()), op=MPI.MAX)
    v_scale = COMM.allreduce(float(np.abs(v0).max()), op=MPI.MAX) + h_avg * (
        K_inf * u_max + f_max) / COMM.allreduce(float(mass.min()), op=MPI.MIN)
    bound_v = rounding(row_terms + 6, v_scale)
    assert np.abs(integ.v_owned - v1).max(initial=0.0) <= bound_v
    assert np.abs(integ.u_owned - u1).max(initial=0.0) <= rounding(2, u_max + h * v_scale) + h * bound_v
    integ.advance()
