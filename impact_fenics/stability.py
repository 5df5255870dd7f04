"""Stable time step of the undamped modified Euler scheme: dt < 2 / omega_max.

Two estimates that err in opposite directions:

* :func:`element_omega_bound` is an upper bound on omega_max (rad/s): the
  assembled K and lumped M are sums of element matrices, so every Rayleigh
  quotient x'Kx / x'Mx is at most the largest element eigenvalue. Its dt is
  conservative; it is the one that refuses input. One rule for both cell types:
  on triangles the element matrices are the UFL forms' on a broken space, on
  quadrilaterals the B-bar element matrices and Gauss-point masses K and M are
  built from (:mod:`.operators`, :mod:`.q1`). :func:`element_omega_bounds` gives
  each body's own bound (the largest over its cells): every body shares the run's
  step, and a body's own 2 / omega is what its smallest, stiffest cell costs.
* :func:`converged_omega_max` solves for the largest eigenvalue of M^-1 K (with
  the fixed dofs removed) to a tight tolerance with SLEPc. Its dt is the true
  limit; tests of stability measure against it.
"""
from __future__ import annotations

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc
from dolfinx import fem

from .bodies import DeformableModel
from .forms import lumped_mass_form, stiffness_form
from .compat import cell_dofs, compile_form, vector_space
from .operators import bbar_element_matrices

_CHUNK = 65536  # cells per batched eigenvalue call


def element_omega_bound(model: DeformableModel, fixed_local: np.ndarray) -> float:
    """Upper bound on omega_max (rad/s): the largest of :func:`element_omega_bounds`
    (a maximum over a partition of the cells: the same number as over all of them)."""
    return max(element_omega_bounds(model, fixed_local).values())


def element_omega_bounds(model: DeformableModel, fixed_local: np.ndarray) -> dict[str, float]:
    """Per body, an upper bound on its own omega_max (rad/s): the largest w of
    K_e v = w^2 M_e v over the body's cells (collective; every rank the same numbers).

    On triangles the element matrices come from assembling the same forms on a broken
    (DG1) space, whose matrix is block diagonal with one 6x6 block per cell. Dofs in
    ``fixed_local`` (local unrolled indices, ghosts included) are removed from each
    element problem: the bound then holds on the constrained space, and the tiny radial
    masses of axis nodes no longer dominate it. A body whose every dof is fixed has 0.
    """
    if model.quadrilateral:
        w2 = _quadrilateral_w2(model, fixed_local)
    else:
        w2 = _triangle_w2(model, fixed_local)
    model.comm.Allreduce(MPI.IN_PLACE, w2, op=MPI.MAX)
    return {name: float(np.sqrt(w)) for name, w in zip(model.part_names, w2)}


def _triangle_w2(model: DeformableModel, fixed_local: np.ndarray) -> np.ndarray:
    """Per part of ``model`` (triangles), the largest element eigenvalue w^2 (rad^2/s^2)
    over its owned cells (0 on a rank without any)."""
    V_dg = vector_space(model.mesh, "DG", 1)
    K = fem.petsc.assemble_matrix(compile_form(stiffness_form(V_dg, model.parts, model.geometry)))
    K.assemble()
    m_vec = fem.petsc.assemble_vector(compile_form(lumped_mass_form(V_dg, model.parts, model.geometry)))
    indptr, indices, data = K.getValuesCSR()
    start = K.getOwnershipRange()[0]
    K.destroy()
    with m_vec.localForm() as local:
        m = local.array_r.copy()
    m_vec.destroy()
    n_cells = model.mesh.topology.index_map(2).size_local
    bs = 2
    dofs = cell_dofs(V_dg)[:n_cells]
    dofs = (dofs[:, :, None] * bs + np.arange(bs)).reshape(n_cells, 6)
    cg = model.cell_dofs[:n_cells]
    cg = (cg[:, :, None] * bs + np.arange(bs)).reshape(n_cells, 6)
    is_fixed = np.zeros(model.n_local, dtype=bool)
    is_fixed[fixed_local] = True
    free = ~is_fixed[cg]
    import scipy.sparse as sp

    n_rows = indptr.size - 1
    A = sp.csr_matrix((data, indices - start, indptr), shape=(n_rows, n_rows))
    w2_cell = np.zeros(n_cells)  # each owned cell's largest element eigenvalue
    for lo in range(0, n_cells, _CHUNK):
        d = dofs[lo:lo + _CHUNK]
        rows = np.repeat(d, 6, axis=1)
        cols = np.tile(d, (1, 6))
        Ke = np.asarray(A[rows.ravel(), cols.ravel()]).reshape(-1, 6, 6)
        s = np.where(free[lo:lo + _CHUNK], 1.0 / np.sqrt(m[d]), 0.0)
        Ke = Ke * s[:, :, None] * s[:, None, :]
        if Ke.shape[0]:
            w2_cell[lo:lo + Ke.shape[0]] = np.linalg.eigvalsh(Ke)[:, -1]
    return np.array([w2_cell[model.owned_cells(name)].max(initial=0.0)
                     for name in model.part_names])


def _quadrilateral_w2(model: DeformableModel, fixed_local: np.ndarray) -> np.ndarray:
    """:func:`_triangle_w2` on a quadrilateral mesh: K_e the B-bar element matrix (the
    elastic one of a path-dependent body), M_e the cell's lumped masses, fixed dofs
    removed."""
    is_fixed = np.zeros(model.n_local, dtype=bool)
    is_fixed[fixed_local] = True
    w2 = np.zeros(len(model.parts))
    for i, part in enumerate(model.parts):
        g, Ke = bbar_element_matrices(model, part)
        m = np.repeat(g.node_masses(part[0].density), 2, axis=1)  # (n, 8), dof order 2 a + c
        dofs = (2 * g.dofs[:, :, None] + np.arange(2)).reshape(-1, 8)
        for lo in range(0, Ke.shape[0], _CHUNK):
            d = dofs[lo:lo + _CHUNK]
            s = np.where(is_fixed[d], 0.0, 1.0 / np.sqrt(m[lo:lo + _CHUNK]))
            S = Ke[lo:lo + _CHUNK] * s[:, :, None] * s[:, None, :]
            if S.shape[0]:
                w2[i] = max(w2[i], float(np.linalg.eigvalsh(S)[:, -1].max()))
    return w2


def ghosted_dofs(model: DeformableModel, owned: np.ndarray) -> np.ndarray:
    """Local (ghosted) indices of the dofs given as owned local ones: their owners mark
    them, one forward scatter shares the marks (collective)."""
    f = fem.Function(model.V)
    f.x.array[:] = 0.0
    f.x.array[owned] = 1.0
    f.x.scatter_forward()
    return np.flatnonzero(f.x.array > 0.5).astype(np.int32)


def parts_stable_dt(model: DeformableModel, fixed_owned: np.ndarray, names: list[str]) -> float:
    """2 / omega (s) of the element bound over the bodies ``names``, with the owned (local)
    dofs ``fixed_owned`` removed: a force's own stable step (collective)."""
    omega = element_omega_bounds(model, ghosted_dofs(model, fixed_owned))
    return critical_dt(max(omega[name] for name in names))


def converged_omega_max(K: PETSc.Mat, mass: np.ndarray, fixed_global: np.ndarray,
                        tol: float = 1e-10) -> float:
    """omega_max (rad/s) of M^-1 K with the fixed dofs removed, by SLEPc Krylov-Schur.

    ``mass`` holds the owned lumped masses (kg); ``fixed_global`` the global
    indices of the owned fixed dofs.
    """
    from slepc4py import SLEPc

    S = K.copy()
    d = S.createVecRight()
    d.array[:] = 1.0 / np.sqrt(mass)
    S.diagonalScale(d, d)
    S.zeroRowsColumns(fixed_global.astype(PETSc.IntType), diag=0.0)
    eps = SLEPc.EPS().create(K.getComm())
    eps.setOperators(S)
    eps.setProblemType(SLEPc.EPS.ProblemType.HEP)
    eps.setWhichEigenpairs(SLEPc.EPS.Which.LARGEST_REAL)
    eps.setDimensions(1)
    eps.setTolerances(tol, 10000)
    eps.solve()
    if eps.getConverged() < 1:
        raise RuntimeError("SLEPc did not converge on omega_max")
    w2 = eps.getEigenvalue(0).real
    eps.destroy(), S.destroy(), d.destroy()
    return float(np.sqrt(w2))


def critical_dt(omega_max: float) -> float:
    """Stability limit 2 / omega_max (s) of the undamped modified Euler scheme (infinite
    for omega_max = 0: nothing moves)."""
    return 2.0 / omega_max if omega_max > 0.0 else float("inf")
