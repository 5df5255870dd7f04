"""One stacked dof numbering over the meshes of a scene.

Each mesh k carries a vector space of degree 1 (P1 or Q1, block size 2), partitioned
by dolfinx over all ranks on its own. The scene numbers every dof once: rank q owns
the owned dofs of mesh 0 on q, then those of mesh 1 on q, and so on, one contiguous
range per rank. With ``n[q, k]`` the unrolled owned size of mesh k on rank q,

    start[q]       = sum_{q' < q} sum_k n[q', k]          (scene offset of rank q)
    prefix[q, k]   = sum_{k' < k} n[q, k']
    scene(k, g, c) = start[q] + prefix[q, k] + 2 (g - range_k[q]) + c

where g is a global block (node) index of mesh k, q its owner, c the component. The
map is monotone in g within a mesh; with one mesh it is the identity.

A rank's local layout is ``[owned_0 | owned_1 | ... | ghosts_0 | ghosts_1 | ...]``:
the owned dofs of mesh k are the slice ``owned_off[k]:owned_off[k + 1]``, its ghosts
the slice ``ghost_off[k]:ghost_off[k + 1]`` of the local (ghosted) array. Every offset
is even, so block (node) indices are offsets / 2 plus dolfinx's own.
"""
from __future__ import annotations

from typing import Sequence

import numpy as np
from petsc4py import PETSc

from . import compat
from .errors import require

BS = 2  # the block size of every space: (u_r, u_z)


class SceneDofs:
    """The stacked numbering of the vector spaces ``spaces`` (one per mesh, all on one
    communicator, block size 2)."""

    def __init__(self, spaces: Sequence):
        require(len(spaces) > 0, "a scene needs at least one mesh")
        self.spaces = list(spaces)
        self.comm = self.spaces[0].mesh.comm
        for V in self.spaces:
            require(V.dofmap.index_map_bs == BS,
                    f"a scene's spaces have block size {BS}, not {V.dofmap.index_map_bs}")
        comm = self.comm
        self.rank, self.size = comm.rank, comm.size
        n_meshes = len(self.spaces)
        imaps = [V.dofmap.index_map for V in self.spaces]
        # one allgather: every rank's (first owned block, owned blocks) of every mesh
        mine = np.array([[im.local_range[0], im.size_local] for im in imaps],
                        dtype=np.int64).ravel()
        table = np.array(comm.allgather(mine), dtype=np.int64).reshape(self.size, n_meshes, 2)
        # block_range[k][q]: the first global block of mesh k owned by rank q (size + 1)
        self.block_range = [np.append(table[:, k, 0], table[-1, k, 0] + table[-1, k, 1])
                            for k in range(n_meshes)]
        counts = BS * table[:, :, 1]                                  # n[q, k]
        self.counts = counts
        self.start = np.concatenate([[0], np.cumsum(counts.sum(axis=1))[:-1]]).astype(np.int64)
        self.prefix = np.zeros((self.size, n_meshes), dtype=np.int64)
        self.prefix[:, 1:] = np.cumsum(counts, axis=1)[:, :-1]
        self.n_global = int(counts.sum())
        # this rank: owned and ghost slices of the local layout
        self.owned_off = np.concatenate([[0], np.cumsum(counts[self.rank])]).astype(np.int64)
        self.n_owned = int(self.owned_off[-1])
        n_ghosts = [BS * im.num_ghosts for im in imaps]
        self.ghost_off = self.n_owned + np.concatenate([[0], np.cumsum(n_ghosts)]).astype(np.int64)
        self.n_local = int(self.ghost_off[-1])
        self.offset = int(self.start[self.rank])  # the scene index of the first owned dof
        # the ghosts' scene block indices, mesh after mesh (each in dolfinx's ghost order)
        self.ghost_blocks = np.concatenate(
            [self.scene(k, np.asarray(im.ghosts, dtype=np.int64), 0) // BS
             for k, im in enumerate(imaps)]).astype(PETSc.IntType)
        # each mesh's local block -> the scene's local block, and its dofmap through it
        self.local_blocks = []
        self._cell_dofs = []
        for k, (V, im) in enumerate(zip(self.spaces, imaps)):
            blocks = np.concatenate([
                self.owned_off[k] // BS + np.arange(im.size_local, dtype=np.int64),
                self.ghost_off[k] // BS + np.arange(im.num_ghosts, dtype=np.int64)])
            self.local_blocks.append(blocks.astype(np.int32))
            self._cell_dofs.append(np.ascontiguousarray(
                self.local_blocks[k][compat.cell_dofs(V)], dtype=np.int32))

    @property
    def n_meshes(self) -> int:
        return len(self.spaces)

    def scene(self, k: int, g: np.ndarray, c: np.ndarray | int) -> np.ndarray:
        """Scene global (unrolled) indices of component ``c`` of the global blocks ``g``
        of mesh ``k`` (any shapes that broadcast)."""
        g = np.asarray(g, dtype=np.int64)
        rng = self.block_range[k]
        q = np.searchsorted(rng, g, side="right") - 1
        return self.start[q] + self.prefix[q, k] + BS * (g - rng[q]) + np.asarray(c, dtype=np.int64)

    def owned_slice(self, k: int) -> slice:
        """Mesh ``k``'s owned dofs in the owned (and local) array: ``owned_off[k]`` to
        ``owned_off[k + 1]``, in mesh k's own owned order."""
        return slice(int(self.owned_off[k]), int(self.owned_off[k + 1]))

    def cell_dofs(self, k: int) -> np.ndarray:
        """Mesh ``k``'s dofmap (local cells incl. ghosts, dofs per cell) in the scene's
        local block indices (int32)."""
        return self._cell_dofs[k]

    def local_to_scene(self) -> np.ndarray:
        """The scene global index of every local (owned, then ghost) unrolled dof."""
        out = np.empty(self.n_local, dtype=np.int64)
        out[:self.n_owned] = self.offset + np.arange(self.n_owned)
        g = self.ghost_blocks.astype(np.int64)
        out[self.n_owned:] = (BS * g[:, None] + np.arange(BS)).ravel()
        return out

    def function_vec(self):
        """A scene Vec and the ``fem.Function`` of mesh 0 that the generic force path
        reads: with one mesh the Function's own ghosted vector, whose layout is the
        scene's (the identity). Several meshes: not yet (a Function per mesh, its
        slices copied in before each evaluation). Keep the Function while the Vec is
        used: on 0.11 the Vec wraps the Function's memory."""
        from dolfinx import fem

        require(self.n_meshes == 1, "a Function over the scene needs one mesh")
        fn = fem.Function(self.spaces[0])
        return compat.petsc_vec(fn), fn

    def create_vec(self) -> PETSc.Vec:
        """A ghosted PETSc Vec over the scene (block size 2), zeroed."""
        vec = PETSc.Vec().createGhost(self.ghost_blocks, size=(self.n_owned, self.n_global),
                                      bsize=BS, comm=self.comm)
        vec.set(0.0)
        with vec.localForm() as loc:
            loc.set(0.0)
        return vec
