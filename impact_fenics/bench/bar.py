"""The benchmark's bar: its mesh, Simulation and Integrator, a random state, and what a
step on it costs (bytes moved at least, time of the step and of MatMult)."""
from __future__ import annotations

import math
from contextlib import contextmanager

import numpy as np
from mpi4py import MPI

from ..materials import STEEL

BIG = 10 ** 9  # output_every / history_every that never comes


def bar_mesh(comm: MPI.Comm, dofs: int):
    """A structured steel bar r in [0, 0.5], z in [0, 1] (m) with about ``dofs`` dofs (h = dofs^-1/2)."""
    from .. import meshing

    h = 1.0 / math.sqrt(dofs)
    return meshing.bar(radius=0.5, length=1.0, h=h, structured=True, comm=comm), h


def bar_simulation(tmesh, n_steps: int, matrix_type: str = "aij", timers: bool = True):
    """scenes.elastic_bar (nu = 0.3) on a given mesh, no outputs."""
    from ..scenes import elastic_bar
    from ..simulation import Settings

    settings = Settings(cfl=0.9, n_steps=n_steps, output_every=BIG, history_every=BIG,
                        fields=False, out=None, quiet=True, matrix_type=matrix_type, timers=timers)
    return elastic_bar(settings, nu=0.3, tmesh=tmesh)


def bar_integrator(tmesh):
    """(model, integrator) of the bar alone: axis fixed, no loads, dt = 0.9 x the element
    bound, in a random state."""
    from ..bodies import Body, DeformableModel
    from ..integrator import Integrator
    from ..stability import critical_dt, element_omega_bound

    model = DeformableModel(tmesh, [Body("bar", STEEL)])
    dt = 0.9 * critical_dt(element_omega_bound(model, model.axis_dofs(owned=False)))
    integ = Integrator(model, dt, model.axis_dofs())
    random_state(integ)
    return model, integ


def random_state(integ, seed: int = 5) -> tuple[np.ndarray, np.ndarray]:
    """A random bounded state (no denormals to skew the timings): u ~ 1e-6 m, v ~ 1e-3 m/s."""
    rng = np.random.default_rng(seed + 7919 * integ.model.comm.rank)
    n = integ.model.n_owned
    u0, v0 = 1e-6 * rng.standard_normal(n), 1e-3 * rng.standard_normal(n)
    integ.set_initial(u0, v0)
    return integ.displacement(np.empty(n)), integ.velocity(np.empty(n))


def step_fn(integ):
    """One step of the integrator without contact: predict, then advance."""
    return lambda: (integ.predict(), integ.advance())


@contextmanager
def vectors(A, x_values, y_values=None):
    """x (right) and y (left) vectors of ``A`` holding these values; destroyed afterwards."""
    x, y = A.createVecRight(), A.createVecLeft()
    x.array[:] = x_values
    if y_values is not None:
        y.array[:] = y_values
    try:
        yield x, y
    finally:
        x.destroy()
        y.destroy()


def matrix_bytes(A, n_dofs: int) -> dict:
    """Bytes per dof a step and a MatMult move at least (no write-allocate, perfect reuse of x)."""
    from petsc4py import PETSc

    nnz = float(A.getInfo()["nz_used"])  # global sum
    ib = np.dtype(PETSc.IntType).itemsize
    per_row = nnz / n_dofs
    if A.getType().endswith("baij"):
        bs = A.getBlockSize()
        matrix = (8.0 * nnz + ib * nnz / bs ** 2 + ib / bs) / n_dofs
    else:
        matrix = (8.0 + ib) * per_row + ib
    return {"nnz": nnz, "nnz_per_row": per_row, "matrix_bytes_per_dof": matrix,
            "matmult_bytes_per_dof": matrix + 16.0,          # x read, y written
            "step_bytes_per_dof": matrix + 24.0 + 24.0}      # MatMultAdd x, y, z; VecAXPY x, y, y


def measure_step_variants(ctx, integ, what=("step", "matmult", "multadd", "axpy")) -> dict:
    """Integrator step, MatMult, MatMultAdd and VecAXPY on the integrator's own matrix
    (full :func:`common.timeit` records)."""
    A = integ.A
    rng = np.random.default_rng(3 + ctx.comm.rank)
    y0 = 1e-3 * rng.standard_normal(A.getLocalSize()[0])
    with vectors(A, integ.u_vec.array, y0) as (x, y):
        fns = {"step": step_fn(integ), "matmult": lambda: A.mult(x, y),
               "multadd": lambda: A.multAdd(x, y, y), "axpy": lambda: y.axpy(integ.dt, x)}
        return {k: ctx.timeit(fns[k]) for k in what}


def time_matmult(ctx, M, x_values) -> float:
    """Median seconds of y = M x."""
    with vectors(M, x_values) as (x, y):
        return ctx.median(lambda: M.mult(x, y))
