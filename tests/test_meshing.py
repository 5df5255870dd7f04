"""Mesh generators: structured grids are structured, and contact faces pair for any h.

Oracles: counting (a structured grid of alternating diagonals over n_r x n_z
intervals has 2 n_r n_z triangles and its nodes on the grid lines), and the
node-to-node pairing of two faces split into the same number of equal
intervals (round(radius / h)), whether radius / h is whole or not.
"""
import numpy as np
import pytest
from mpi4py import MPI

from impact_fenics import meshing
from impact_fenics.bodies import Body, DeformableModel
from impact_fenics.contact import pair_surfaces
from impact_fenics.compat import geometry_dofs
from impact_fenics.materials import LinearElastic


def owned_cells(tmesh, name: str) -> int:
    n_local = tmesh.mesh.topology.index_map(2).size_local
    return MPI.COMM_WORLD.allreduce(int(np.count_nonzero(tmesh.cells(name) < n_local)))


# gmsh places a node within its geometric tolerance (Geometry.Tolerance, 1e-8 of the
# model's size by default), by its own arithmetic: that, not a count of our roundings,
# bounds how far a structured node is from its grid point (an unstructured one is a
# good fraction of an element off)
GMSH_TOLERANCE = 1e-8


def on_grid(tmesh, name: str, z0: float, dr: float, dz: float, size: float) -> bool:
    """Every node of the cells of ``name`` on the grid r = i dr, z = z0 + j dz (``size``:
    the model's largest extent, m)."""
    cells = tmesh.cells(name)
    nodes = np.unique(geometry_dofs(tmesh.mesh)[cells].ravel())
    x = tmesh.mesh.geometry.x[nodes, :2]
    tol = GMSH_TOLERANCE * size
    ok = (np.allclose(x[:, 0] / dr, np.round(x[:, 0] / dr), rtol=0, atol=tol / dr)
          and np.allclose((x[:, 1] - z0) / dz, np.round((x[:, 1] - z0) / dz), rtol=0,
                          atol=tol / dz))
    return MPI.COMM_WORLD.allreduce(ok, op=MPI.LAND)


@pytest.mark.parametrize("h", [0.02, 0.03])  # radius / h whole, and not (0.1 / 0.03 = 3.33)
def test_coaxial_bars_structured_are_structured(h):
    radius, ls, lt = 0.1, 0.12, 0.09
    tmesh = meshing.coaxial_bars(radius=radius, striker_length=ls, target_length=lt, h=h,
                                 structured=True)
    n_r = round(radius / h)
    for name, length, z0 in (("striker", ls, -ls), ("target", lt, 0.0)):
        n_z = round(length / h)
        assert owned_cells(tmesh, name) == 2 * n_r * n_z, name
        assert on_grid(tmesh, name, z0, radius / n_r, length / n_z, ls + lt), name


@pytest.mark.parametrize("structured", [False, True])
def test_contact_faces_pair_when_radius_over_h_is_not_whole(structured):
    radius, h = 0.1, 0.03
    tmesh = meshing.coaxial_bars(radius=radius, striker_length=0.12, target_length=0.09, h=h,
                                 structured=structured)
    model = DeformableModel(tmesh, [Body("striker", LinearElastic()),
                                    Body("target", LinearElastic())])
    pairs = pair_surfaces(model, "striker_contact", "target_contact")
    assert pairs.n == round(radius / h) + 1
    assert np.allclose(np.sort(pairs.r), np.linspace(0.0, radius, round(radius / h) + 1),
                       rtol=0, atol=GMSH_TOLERANCE * (0.12 + 0.09))


def _gathered_x(tmesh) -> np.ndarray:
    """Every node's (r, z) on every rank, in one order (sorted rows)."""
    n_owned = tmesh.mesh.geometry.index_map().size_local
    x = np.concatenate(MPI.COMM_WORLD.allgather(tmesh.mesh.geometry.x[:n_owned, :2]))
    return x[np.lexsort((x[:, 1], x[:, 0]))]


@pytest.mark.parametrize("structured", [False, True])
def test_a_mesh_does_not_depend_on_gmsh_options_set_before_it(structured):
    """gmsh keeps options across models: a caller's own gmsh work (a size cap, quadrilaterals,
    second order) must not change the next generated mesh. Oracle: the same generator
    call from gmsh's initial options gives the same cells and the same nodes (exactly:
    the same arithmetic on the same input)."""
    def make():
        return meshing.coaxial_bars(radius=0.1, striker_length=0.12, target_length=0.09,
                                    h=0.03, structured=structured)

    clean = make()
    meshing.start_gmsh()
    import gmsh

    changed = {"Mesh.MeshSizeMax": 0.007, "Mesh.RecombineAll": 1, "Mesh.ElementOrder": 2,
               "Mesh.MeshSizeFactor": 0.5}
    for option, value in changed.items():
        gmsh.option.setNumber(option, value)
    after = make()
    for option in changed:  # the generator (rank 0 meshes) left gmsh at its initial options
        assert MPI.COMM_WORLD.rank != 0 or gmsh.option.getNumber(option) == meshing._INITIAL[option], option
    for name in ("striker", "target"):
        assert owned_cells(after, name) == owned_cells(clean, name), name
    assert np.array_equal(_gathered_x(after), _gathered_x(clean))
