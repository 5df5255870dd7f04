"""The stacked dof numbering (impact_fenics.dofs): exact integer oracles.

Two meshes, a triangle rectangle and a quadrilateral rectangle beside it, each
partitioned by dolfinx over all ranks; one mesh alone must keep dolfinx's numbers.
Runs unchanged on 1, 2 and 3 ranks."""
from __future__ import annotations

import numpy as np
import pytest
from mpi4py import MPI
from petsc4py import PETSc
from dolfinx import fem, mesh as dmesh

from impact_fenics import compat
from impact_fenics.dofs import SceneDofs

COMM = MPI.COMM_WORLD


def _space(lo, hi, n, cell_type):
    mesh = dmesh.create_rectangle(COMM, [np.array(lo, dtype=float), np.array(hi, dtype=float)],
                                  n, cell_type)
    return compat.vector_space(mesh, "Lagrange", 1)


@pytest.fixture(scope="module")
def two():
    return SceneDofs([_space([0.0, -1.0], [2.0, 0.0], [8, 4], dmesh.CellType.triangle),
                      _space([0.0, 0.0], [0.5, 2.0], [2, 8], dmesh.CellType.quadrilateral)])


def _scene_indices_filled(dofs: SceneDofs) -> np.ndarray:
    """Owned entries set to their scene index, one forward ghost update: the local array."""
    vec = dofs.create_vec()
    lo, hi = vec.getOwnershipRange()
    vec.array[:] = np.arange(lo, hi, dtype=float)
    vec.ghostUpdate(addv=PETSc.InsertMode.INSERT, mode=PETSc.ScatterMode.FORWARD)
    with vec.localForm() as loc:
        out = loc.array.copy()
    vec.destroy()
    return out


def test_each_rank_owns_one_contiguous_range(two):
    vec = two.create_vec()
    lo, hi = vec.getOwnershipRange()
    vec.destroy()
    assert (lo, hi) == (two.offset, two.offset + two.n_owned)
    ranges = COMM.allgather((lo, hi))
    assert ranges[0][0] == 0 and ranges[-1][1] == two.n_global
    assert all(a[1] == b[0] for a, b in zip(ranges, ranges[1:]))
    # every mesh's owned dofs, and only those, map into this rank's range, each once,
    # mesh after mesh (the owned slices)
    for k, V in enumerate(two.spaces):
        im = V.dofmap.index_map
        g = im.local_range[0] + np.arange(im.size_local)
        idx = two.scene(k, g[:, None], np.arange(2)).ravel()
        assert np.array_equal(idx, lo + np.arange(two.owned_off[k], two.owned_off[k + 1]))
    # with the contiguous ranges above, a bijection onto 0 .. n_global - 1
    total = sum(2 * V.dofmap.index_map.size_global for V in two.spaces)
    assert two.n_global == total


def test_one_forward_update_fills_every_mesh_ghosts(two):
    local = _scene_indices_filled(two)
    assert local.size == two.n_local
    # every local entry equals its scene index: the owned ones by construction, the
    # ghosts of each mesh through the scatter, computed from dolfinx's own global blocks
    expected = np.empty(two.n_local, dtype=np.int64)
    for k, V in enumerate(two.spaces):
        im = V.dofmap.index_map
        n = im.size_local + im.num_ghosts
        g = np.asarray(im.local_to_global(np.arange(n, dtype=np.int32)), dtype=np.int64)
        unrolled = (2 * two.local_blocks[k][:, None] + np.arange(2)).ravel()
        expected[unrolled] = two.scene(k, g[:, None], np.arange(2)).ravel()
    assert np.array_equal(local.astype(np.int64), expected)
    assert np.array_equal(two.local_to_scene(), expected)
    n_ghosts = COMM.allreduce(two.n_local - two.n_owned)
    if COMM.size > 1:
        assert n_ghosts > 0  # the check above covered ghosts of both meshes


def test_remapped_dofmaps_point_into_each_mesh_slices(two):
    for k, V in enumerate(two.spaces):
        im = V.dofmap.index_map
        cd = two.cell_dofs(k)
        own = compat.cell_dofs(V) < im.size_local
        owned_blocks = (two.owned_off[k] // 2, two.owned_off[k + 1] // 2)
        ghost_blocks = (two.ghost_off[k] // 2, two.ghost_off[k + 1] // 2)
        assert np.all((cd[own] >= owned_blocks[0]) & (cd[own] < owned_blocks[1]))
        assert np.all((cd[~own] >= ghost_blocks[0]) & (cd[~own] < ghost_blocks[1]))
        assert cd.dtype == np.int32 and cd.shape == compat.cell_dofs(V).shape


@pytest.mark.parametrize("cell_type", [dmesh.CellType.triangle, dmesh.CellType.quadrilateral])
def test_one_mesh_is_the_identity(cell_type):
    V = _space([0.0, 0.0], [1.0, 3.0], [3, 9], cell_type)
    dofs = SceneDofs([V])
    im = V.dofmap.index_map
    n = im.size_local + im.num_ghosts
    g = np.asarray(im.local_to_global(np.arange(n, dtype=np.int32)), dtype=np.int64)
    # scene index == dolfinx's global dof index, local layout == dolfinx's
    assert np.array_equal(dofs.scene(0, g[:, None], np.arange(2)).ravel(),
                          (2 * g[:, None] + np.arange(2)).ravel())
    assert np.array_equal(dofs.local_to_scene(), (2 * g[:, None] + np.arange(2)).ravel())
    assert np.array_equal(dofs.cell_dofs(0), compat.cell_dofs(V))
    assert (dofs.offset, dofs.n_owned, dofs.n_global) == (
        2 * im.local_range[0], 2 * im.size_local, 2 * im.size_global)
    # the same Vec layout as dolfinx's own ghosted vector
    vec = dofs.create_vec()
    ref_fn = fem.Function(V)  # kept alive: its vector wraps the Function's memory (0.11)
    ref = compat.petsc_vec(ref_fn)
    assert vec.getOwnershipRange() == ref.getOwnershipRange()
    assert vec.getBlockSize() == ref.getBlockSize() == 2
    assert np.array_equal(_scene_indices_filled(dofs), dofs.local_to_scene().astype(float))
    vec.destroy()
