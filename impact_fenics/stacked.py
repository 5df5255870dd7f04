"""The stiffness and the lumped mass of several meshes over the scene's stacked numbering.

Each mesh k has its own stiffness K_k (N/m), assembled by dolfinx over its own
numbering (UFL on triangles, B-bar element matrices on quadrilaterals), and its own
lumped mass m_k (kg). A scene of several meshes multiplies one operator: with x the
scene vector and x_k its slice of mesh k,

    A x = sum_k K_k x_k,    M = diag(m_0, m_1, ...)

(the meshes share no dof: coupling between bodies goes through contact, not through A).

**The operator.** One AIJ matrix built once from the owned rows of each K_k in CSR form:
the rows of mesh k take the scene rows of its owned slice (rank q's rows are mesh 0's
owned rows on q, then mesh 1's, ...: the rows concatenated), a column j of mesh k's
numbering (node j // 2, component j % 2) becomes the scene column
``dofs.scene(k, j // 2, j % 2)``. That map is monotone within a mesh and sends the
columns a rank owns in mesh k to columns it owns in the scene, so every row keeps both
its split into owned and off-rank columns and its column order: PETSc's MatMult, which
sums a row's owned columns in CSR order and then its off-rank columns in CSR order,
does the same additions in the same order as K_k's own product, and A x equals
sum_k K_k x_k bit for bit. With one mesh the map is the identity and A equals K entry
for entry.

**The lumped mass.** Each mesh's owned row sums (kg), summed over ranks on its own mesh,
are copied into its owned slice of one scene Vec: a copy, exact.
"""
from __future__ import annotations

from typing import Sequence

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from .dofs import BS, SceneDofs
from .errors import require

AIJ_TYPES = (PETSc.Mat.Type.AIJ, PETSc.Mat.Type.SEQAIJ, PETSc.Mat.Type.MPIAIJ)


def _everywhere(dofs: SceneDofs, holds: bool) -> bool:
    """Whether ``holds`` on every rank (collective: every rank refuses together)."""
    return bool(dofs.comm.allreduce(int(holds), op=MPI.MIN))


def stacked_operator(dofs: SceneDofs, mats: Sequence[PETSc.Mat]) -> PETSc.Mat:
    """One AIJ matrix (N/m) over the stacked numbering of ``dofs`` whose rows of mesh k
    are K_k's owned rows, columns renumbered by ``dofs.scene(k, ., .)``: A x = sum_k K_k x_k
    (see the module). ``mats[k]`` is mesh k's assembled AIJ matrix over its own
    (dolfinx) numbering; it is read, not changed: the caller may destroy it once this
    returns. Collective on ``dofs.comm``."""
    require(len(mats) == dofs.n_meshes,
            f"a stacked operator needs one matrix per mesh: {len(mats)} for {dofs.n_meshes}")
    indptr_parts, cols_parts, vals_parts = [], [], []
    row_start = 0
    for k, (K, V) in enumerate(zip(mats, dofs.spaces)):
        require(K.getType() in AIJ_TYPES, f"mesh {k}'s matrix is {K.getType()}, not AIJ")
        im = V.dofmap.index_map
        first, n_rows = BS * im.local_range[0], BS * im.size_local
        laid_out = (K.getOwnershipRange() == (first, first + n_rows)
                    and K.getSize() == (BS * im.size_global, BS * im.size_global))
        require(_everywhere(dofs, laid_out), f"mesh {k}'s matrix is not laid out by its space's "
                "index map")
        indptr, cols, vals = K.getValuesCSR()  # owned rows, global columns sorted per row
        cols = np.asarray(cols, dtype=np.int64)
        indptr_parts.append(np.asarray(indptr[1:], dtype=np.int64) + row_start)
        cols_parts.append(dofs.scene(k, cols // BS, cols % BS))
        vals_parts.append(np.asarray(vals, dtype=PETSc.ScalarType))
        row_start += int(indptr[-1])
    indptr = np.concatenate([np.zeros(1, dtype=np.int64)] + indptr_parts).astype(PETSc.IntType)
    cols = np.concatenate(cols_parts).astype(PETSc.IntType)
    vals = np.concatenate(vals_parts)
    n = (dofs.n_owned, dofs.n_global)
    A = PETSc.Mat().createAIJ(size=(n, n), bsize=BS, csr=(indptr, cols, vals), comm=dofs.comm)
    A.assemble()
    return A


def stacked_mass(dofs: SceneDofs, masses: Sequence[np.ndarray]) -> PETSc.Vec:
    """The scene's lumped mass (kg) as a ghosted Vec: ``masses[k]`` (mesh k's owned row
    sums, both components, in its owned order, e.g. :func:`.operators.lumped_mass`)
    copied into mesh k's owned slice, ghosts filled by one forward scatter."""
    require(len(masses) == dofs.n_meshes,
            f"a stacked mass needs one vector per mesh: {len(masses)} for {dofs.n_meshes}")
    for k, m in enumerate(masses):
        s = dofs.owned_slice(k)
        require(_everywhere(dofs, np.shape(m) == (s.stop - s.start,)),
                f"mesh {k}'s mass does not have its slice's owned entries on every rank")
    vec = dofs.create_vec()
    owned = vec.array  # a view of the owned entries
    for k, m in enumerate(masses):
        owned[dofs.owned_slice(k)] = m
    vec.ghostUpdate(addv=PETSc.InsertMode.INSERT, mode=PETSc.ScatterMode.FORWARD)
    return vec
