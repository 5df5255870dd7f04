"""Static solves with the assembled stiffness K (N/m): the indentation stiffness of a
rigid face and the flexibility of a set of surface dofs.

Both solve K u = f with some dofs prescribed (u = 0 on the fixed dofs, a rigid
displacement on a face) by a direct factorisation (MUMPS, any number of ranks).
Prescribed dofs are eliminated symmetrically: their columns move to the right-hand
side, their rows become the identity. The reactions are K u on the prescribed dofs.
"""
from __future__ import annotations

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from .bodies import DeformableModel


def owned(model: DeformableModel, dofs: np.ndarray) -> np.ndarray:
    """The global indices among ``dofs`` that this rank owns."""
    lo, hi = model.offset, model.offset + model.n_owned
    return dofs[(dofs >= lo) & (dofs < hi)]


def _factor(A: PETSc.Mat) -> PETSc.KSP:
    ksp = PETSc.KSP().create(A.getComm())
    ksp.setOperators(A)
    ksp.setType("preonly")
    pc = ksp.getPC()
    pc.setType("lu")
    pc.setFactorSolverType("mumps")
    ksp.setUp()
    return ksp


def _constrained(K: PETSc.Mat, rows: np.ndarray, values: np.ndarray,
                 load: PETSc.Vec | None = None) -> tuple[PETSc.Mat, PETSc.Vec]:
    """A copy of K with the owned global ``rows`` prescribed to ``values`` and the
    matching right-hand side (minus K times the prescribed values, plus ``load``)."""
    A = K.copy()
    x = A.createVecRight()
    x.set(0.0)
    x.setValues(rows.astype(PETSc.IntType), values)
    x.assemble()
    b = A.createVecLeft()
    if load is None:
        b.set(0.0)
    else:
        load.copy(b)
    A.zeroRowsColumns(rows.astype(PETSc.IntType), diag=1.0, x=x, b=b)
    return A, b


def rigid_indentation(model: DeformableModel, K: PETSc.Mat, fixed: np.ndarray,
                      face: np.ndarray, delta: float) -> float:
    """Force (N, compressive > 0) that holds the owned z dofs ``face`` (global indices)
    at u_z = -delta (m), the owned ``fixed`` dofs (global) at zero, everything else free."""
    rows = np.concatenate([fixed, face])
    values = np.concatenate([np.zeros(fixed.size), np.full(face.size, -delta)])
    A, b = _constrained(K, rows, values)
    u = A.createVecRight()
    ksp = _factor(A)
    ksp.solve(b, u)
    reaction = K.createVecLeft()
    K.mult(u, reaction)
    lo = reaction.getOwnershipRange()[0]
    local = float(reaction.array[face - lo].sum())
    for obj in (ksp, A, b, u, reaction):
        obj.destroy()
    return -model.comm.allreduce(local, op=MPI.SUM)


def flexibility(model: DeformableModel, K: PETSc.Mat, fixed: np.ndarray,
                dofs: np.ndarray) -> np.ndarray:
    """Flexibility (m/N) of the z ``dofs`` (global indices, the same list on every rank):
    entry (i, j) is the downward displacement of dof i under a unit downward force on
    dof j, with the owned ``fixed`` dofs (global) held at zero. Replicated on every rank."""
    A, b = _constrained(K, fixed, np.zeros(fixed.size))
    ksp = _factor(A)
    lo, hi = b.getOwnershipRange()
    mine = (dofs >= lo) & (dofs < hi)
    u = A.createVecRight()
    phi = np.zeros((dofs.size, dofs.size))
    for j, dof in enumerate(dofs):
        b.set(0.0)
        if lo <= dof < hi:
            b.setValue(int(dof), -1.0)
        b.assemble()
        ksp.solve(b, u)
        phi[mine, j] = -u.array[dofs[mine] - lo]
    for obj in (ksp, A, b, u):
        obj.destroy()
    model.comm.Allreduce(MPI.IN_PLACE, phi, op=MPI.SUM)
    return phi
