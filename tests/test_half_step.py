"""The half-step loop of the small-strain integrator (its steps from a step policy).

Oracles:

* Under a constant step the half-step loop is the modified Euler scheme: the run equals,
  array for array (u, v after every step, the quadrature force's stresses and work), the
  scheme written here (A = -dt M^-1 K built here, one MatMultAdd, the quadrature force's
  own increment with coef = -dt / m computed here, u += dt v), on a linear and a J2 body
  sharing one mesh; both through the default constant policy and through a policy that
  is not the constant class but returns the same h every step (the general path: h_n =
  1/2 (h + h) = h exactly, nothing rescaled).
* A step that changes (linear bodies): each step, from the integrator's state, the scheme
  of the half steps written here, v' = v + h_n (-K u) / m on the free dofs, u' = u +
  h_{n+1/2} v', agrees to round-off (the integrator multiplies A = -h_n M^-1 K, the
  same expression in another order); t is the sum of the steps taken, and the forces
  are rescaled only on the steps where (h_{n+1/2}, h_n) changes.
"""
import numpy as np
import pytest
from mpi4py import MPI
from petsc4py import PETSc

from impact_fenics.bodies import Body, DeformableModel
from impact_fenics.integrator import Integrator
from impact_fenics.materials import LinearElastic
from impact_fenics.stepping import ConstantStep
from roundoff import rounding
from test_forces import E, N_R, N_Z, NU, R0, R1, RHO, Z1, _two_bodies, previous_path
from two_halves import two_halves

COMM = MPI.COMM_WORLD
DT = 4e-6  # s: far below a cell's transit time 0.125 m / 8.9e3 m/s


class SameStep:
    """A policy that is not the constant one and returns ``h`` (s) every step."""

    def __init__(self, h: float):
        self.h = h

    def first(self) -> float:
        return self.h

    def next(self, n: int, t: float) -> float:
        return self.h


class Steps:
    """A policy of given steps (s), one per step, in order."""

    def __init__(self, steps: list[float]):
        self.steps = steps

    def first(self) -> float:
        return self.steps[0]

    def next(self, n: int, t: float) -> float:
        return self.steps[n]


class TopLoad:
    """A load on the top nodes' z dofs (N per Pa, 1e-3 each) with a ramp history (Pa)
    that makes t^n matter: the attributes the integrator reads of a surface load."""

    def __init__(self, model):
        n = model.n_owned
        top = np.flatnonzero(np.isclose(model.node_xy[: n // 2, 1], Z1))
        self.dofs = (2 * top + 1).astype(np.int32)
        self.force = np.full(self.dofs.size, 1e-3)
        self.name = "top"

    @staticmethod
    def history(t: float) -> float:
        return 1e8 * (1.0 + t / 1e-5)


def _initial(model) -> np.ndarray:
    n = model.n_owned
    x = model.node_xy[: n // 2]
    v0 = np.zeros(n)
    v0[0::2], v0[1::2] = 30.0 * (x[:, 0] - R0), 80.0 * x[:, 1] ** 2  # shear and stretch
    return v0


@pytest.mark.parametrize("policy", ["default", "constant", "same_step"])
def test_constant_half_step_is_modified_euler_array_for_array(policy):
    model = _two_bodies(False)
    fixed = model.axis_dofs()
    pol = {"default": None, "constant": ConstantStep(DT, None, 1.0, n_steps=40),
           "same_step": SameStep(DT)}[policy]
    load = TopLoad(model)
    integ = Integrator(model, DT, fixed, [load], policy=pol)
    assert integ.step.constant == (policy != "same_step")
    n = model.n_owned
    v0 = _initial(model)
    integ.set_initial(None, v0)

    mass = integ.mass
    A, u_fn, u, v, euler = previous_path(model, integ, DT, fixed, v0)
    predict = integ.predictor()
    for k in range(40):
        A.multAdd(u, v, v)
        u_fn.x.scatter_forward()
        euler.add_velocity_increment(u_fn.x.array[:n], v.array)
        v.array[load.dofs] += DT * load.force / mass[load.dofs] * load.history(k * DT)
        u.axpy(DT, v)
        predict()
        integ.advance()
        assert np.array_equal(integ.u_owned, u_fn.x.array[:n])
        assert np.array_equal(integ.v_owned, v.array)
        if integ.step.constant:  # t^n = n h (else the sum of the steps, rounded)
            assert integ.t == (k + 1) * DT
    force = integ.nonlinear[0]
    assert force.deformation_work_local == euler.deformation_work_local
    assert force.plastic_work_local == euler.plastic_work_local
    assert np.array_equal(force.qs.sigma, euler.qs.sigma)
    assert COMM.allreduce(int((force.qs.state[..., 0] > 0.0).sum())) > 0  # it yielded


def test_changing_step_takes_h_n_for_v_and_h_for_u():
    steps = [DT] * 3 + [0.75 * DT] * 3 + [0.5 * DT, 0.9 * DT, 0.9 * DT]
    tm = two_halves(COMM, (R0, 0.0), (R1, Z1), N_R, N_Z, False, ("lower", "upper"))
    model = DeformableModel(tm, [Body(name, LinearElastic(E=E, nu=NU, density=RHO))
                                 for name in ("lower", "upper")])
    fixed = model.axis_dofs()
    load = TopLoad(model)
    integ = Integrator(model, DT, fixed, [load], policy=Steps(steps))
    assert not integ.step.constant
    integ.set_initial(None, _initial(model))
    n = model.n_owned
    free = np.ones(n, dtype=bool)
    free[fixed] = False
    K, mass = integ.K, integ.mass
    Ku = K.createVecLeft()
    K_inf = K.norm(PETSc.NormType.INFINITY)  # max row sum of |K_ij| (N/m)
    lo, hi = K.getOwnershipRange()
    row_terms = COMM.allreduce(max(K.getRow(i)[0].size for i in range(lo, hi)), op=MPI.MAX)
    rescaled = []
    set_step = integ.linear.set_step

    def spy(h, h_avg):
        rescaled.append((h, h_avg))
        set_step(h, h_avg)
    integ.linear.set_step = spy  # (the half steps call it through the instance)
    t, h_prev = 0.0, None
    for k, h in enumerate(steps):
        h_avg = h if h_prev is None else 0.5 * (h_prev + h)
        u0, v0 = integ.u_owned.copy(), integ.v_owned.copy()
        K.mult(integ.u_vec, Ku)
        v1 = v0 + np.where(free, h_avg * -Ku.array / mass, 0.0)
        v1[load.dofs] += h_avg * load.force * load.history(t) / mass[load.dofs]
        u1 = u0 + h * v1
        integ.predict()
        integ.advance()
        # one step from one state: a row of K u (row_terms products and sums), the scaling
        # by h_n / m (2), the sum with v (1), the load's h_n f / m times its value (3) and
        # its sum (1); then h v and its sum with u (2); on the magnitudes |v| + h_n
        # (|K|_inf max|u| + max f p(t)) / min m and |u| + h |v'|
        u_max = COMM.allreduce(float(np.abs(u0).max()), op=MPI.MAX)
        v_scale = COMM.allreduce(float(np.abs(v0).max()), op=MPI.MAX) + h_avg * (
            K_inf * u_max + 1e-3 * load.history(t)) / COMM.allreduce(float(mass.min()), op=MPI.MIN)
        bound_v = rounding(row_terms + 7, v_scale)
        assert np.abs(integ.v_owned - v1).max(initial=0.0) <= bound_v
        assert np.abs(integ.u_owned - u1).max(initial=0.0) <= \
            rounding(2, u_max + h * v_scale) + h * bound_v
        t += h
        h_prev = h
        assert integ.t == t  # the sum of the steps, in their order
    # rescaled where (h, h_n) changed: steps 3, 4 (h_n = 7/8 then 3/4 dt), 6, 7, 8
    assert [p for p in rescaled] == [
        (steps[k], 0.5 * (steps[k - 1] + steps[k])) for k in (3, 4, 6, 7, 8)]
