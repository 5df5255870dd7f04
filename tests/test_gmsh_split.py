"""A gmsh model of triangles and quadrilaterals read as one mesh per cell type.

The ring: an inner annulus r1 < r < r2 of unstructured triangles (cell group "inner")
and an outer annulus r2 < r < r3 of a structured n_r x n_z grid of quadrilaterals
("outer"), of height H, with the facet groups "bottom" (z = 0, both annuli), "top"
(z = H, both), "bore" (r = r1), "interface" (r = r2, between them) and "rim" (r = r3).
It is read from a .msh file (load_msh_meshes) and from the model as built
(to_dolfinx_meshes).

Oracles: the volume of revolution of each cell group, 2 pi int r dA, equals
pi (r2^2 - r1^2) H (inner) and pi (r3^2 - r2^2) H (outer), and each facet group's
length its side's length, to the round-off of the sums (bounds derived at
:func:`_volume_bound`, :func:`_length_bound`); the quadrilateral grid has n_r n_z
cells; the interface is a facet group of both meshes, on the same nodes. A cell group
of two types is refused in one line, as is a mixed msh 2 file (no surface boundaries);
``load_msh`` keeps refusing two types. A model of one cell type reads exactly as
``load_msh`` and ``_to_dolfinx`` read it (every array equal).
"""
import math
import os

import numpy as np
import pytest
import ufl
from dolfinx import fem
from mpi4py import MPI

from impact_fenics import meshing
from impact_fenics.compat import geometry_dofs
from impact_fenics.errors import InputError
from impact_fenics.mesh_split import load_msh_meshes, to_dolfinx_meshes
from roundoff import rounding

COMM = MPI.COMM_WORLD
R1, R2, R3, H = 0.01, 0.025, 0.04, 0.03  # the ring's radii and height (m)
H_TRI = 0.003                             # the triangles' size (m)
N_R, N_Z = 5, 10                          # the quadrilateral grid's intervals in r and z

FACETS = {"inner": {"bottom": R2 - R1, "top": R2 - R1, "bore": H, "interface": H},
          "outer": {"bottom": R3 - R2, "top": R3 - R2, "interface": H, "rim": H}}
VOLUMES = {"inner": math.pi * (R2 ** 2 - R1 ** 2) * H, "outer": math.pi * (R3 ** 2 - R2 ** 2) * H}


def _group(gmsh, dim: int, entities: list[int], name: str, tag: int) -> None:
    gmsh.model.addPhysicalGroup(dim, entities, tag)
    gmsh.model.setPhysicalName(dim, tag, name)


def _ring(gmsh, one_group: bool = False) -> None:
    """The ring (module docstring), meshed; ``one_group``: both annuli in the cell group
    "ring" (a group of two cell types)."""
    geo = gmsh.model.geo
    p = [geo.addPoint(r, z, 0, H_TRI) for z in (0.0, H) for r in (R1, R2, R3)]
    bottom = [geo.addLine(p[0], p[1]), geo.addLine(p[1], p[2])]
    top = [geo.addLine(p[4], p[3]), geo.addLine(p[5], p[4])]
    bore, interface, rim = geo.addLine(p[3], p[0]), geo.addLine(p[1], p[4]), geo.addLine(p[2], p[5])
    inner = geo.addPlaneSurface([geo.addCurveLoop([bottom[0], interface, top[0], bore])])
    outer = geo.addPlaneSurface([geo.addCurveLoop([bottom[1], rim, top[1], -interface])])
    for curve, n in ((bottom[1], N_R), (top[1], N_R), (rim, N_Z), (interface, N_Z)):
        geo.mesh.setTransfiniteCurve(curve, n + 1)
    geo.mesh.setTransfiniteSurface(outer)
    geo.mesh.setRecombine(2, outer)
    geo.synchronize()
    if one_group:
        _group(gmsh, 2, [inner, outer], "ring", 1)
    else:
        _group(gmsh, 2, [inner], "inner", 1)
        _group(gmsh, 2, [outer], "outer", 2)
    for name, curves, tag in (("bottom", bottom, 11), ("top", top, 12), ("bore", [bore], 13),
                              ("interface", [interface], 14), ("rim", [rim], 15)):
        _group(gmsh, 1, curves, name, tag)
    gmsh.model.mesh.generate(2)


def _one_type(gmsh) -> None:
    """The inner annulus alone (triangles), with its facet groups."""
    s, c = meshing._rectangle(gmsh, R1, 0.0, R2, H, H_TRI)
    _group(gmsh, 2, [s], "inner", 1)
    for name, curve, tag in (("bottom", c[0], 11), ("interface", c[1], 14), ("top", c[2], 12),
                             ("bore", c[3], 13)):
        _group(gmsh, 1, [curve], name, tag)
    gmsh.model.mesh.generate(2)


def _write(tmp_path, name: str, draw, version: float = 4.1) -> str:
    """``draw(gmsh)``'s model written on rank 0 as ``name``.msh (msh ``version``)."""
    path = os.path.join(COMM.bcast(str(tmp_path), root=0), f"{name}.msh")
    if COMM.rank == 0:
        meshing.start_gmsh()
        import gmsh

        gmsh.clear()
        gmsh.model.add(name)
        draw(gmsh)
        gmsh.option.setNumber("Mesh.MshFileVersion", version)
        gmsh.write(path)
        gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
        gmsh.clear()
    COMM.barrier()
    return path


def _ring_meshes(tmp_path, source: str):
    if source == "file":
        return load_msh_meshes(_write(tmp_path, "ring", _ring))
    return to_dolfinx_meshes(COMM, _ring, {})


def _owned(tmesh, dim: int, entities: np.ndarray) -> int:
    """How many of the local ``entities`` of dimension ``dim`` this rank owns, summed."""
    n_local = tmesh.mesh.topology.index_map(dim).size_local
    return COMM.allreduce(int(np.count_nonzero(entities < n_local)))


def _kappa(tmesh, cells: np.ndarray) -> float:
    """The largest (|J00 J11| + |J01 J10|) / |det J| at vertex 0 of ``cells`` (1 on an
    axis-aligned rectangle): how much the subtraction in det J magnifies its roundings."""
    x = tmesh.mesh.geometry.x[:, :2]
    conn = geometry_dofs(tmesh.mesh)[cells]
    if not len(conn):
        return COMM.allreduce(1.0, op=MPI.MAX)
    a, b = x[conn[:, 1]] - x[conn[:, 0]], x[conn[:, 2]] - x[conn[:, 0]]
    terms = np.abs(a[:, 0] * b[:, 1]) + np.abs(a[:, 1] * b[:, 0])
    return COMM.allreduce(float(np.max(terms / np.abs(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]))),
                          op=MPI.MAX)


def _volume_bound(n_cells: int, kappa: float, volume: float) -> float:
    """|computed - exact| of a group's volume of revolution.

    Exactness: the cells tile the annulus' section exactly (a mesh is conforming, and
    gmsh puts a straight line's nodes at p0 + t (p1 - p0), exactly on a line r or z =
    constant); on a triangle r is affine and det J constant, on a straight-sided
    quadrilateral r is bilinear and det J affine, so 2 pi r |det J| is of degree <= 2
    in each variable and the degree-2 rule integrates it exactly. Round-off: each
    cell's value is a positive term with at most 40 roundings (4 coordinate
    differences, det J, then per point (<= 4) r, the products with 2 pi, |det J| and
    the weight, and the sum over the points), the subtraction in det J magnified by
    kappa; summing the n cells' terms (over ranks too) adds n - 1 roundings of at most
    the total; the exact value pi (ra^2 - rb^2) H itself takes 8."""
    return rounding(n_cells + 40 * kappa + 8, volume)


def _length_bound(n_facets: int, length: float) -> float:
    """|computed - exact| of a facet group's length: each side on a line r or z =
    constant has length sqrt(dr^2 + dz^2) with one difference exactly zero (a
    difference, a square, a correctly rounded sqrt: 3 roundings, 8 counted); the sum of
    n positive sides adds n - 1; the exact length (a difference of two radii) takes 1."""
    return rounding(n_facets + 8, length)


def _volume(tmesh, name: str) -> float:
    """2 pi int r dA over the cells of ``name`` (m^3), on every rank."""
    x = ufl.SpatialCoordinate(tmesh.mesh)
    dx = ufl.Measure("dx", domain=tmesh.mesh, subdomain_data=tmesh.cell_tags,
                     metadata={"quadrature_degree": 2})
    form = fem.form(2.0 * math.pi * x[0] * dx(tmesh.cell_tag(name)))
    return COMM.allreduce(fem.assemble_scalar(form))


def _length(tmesh, name: str) -> float:
    """The length of the facet group ``name`` (m), on every rank."""
    ds = ufl.Measure("ds", domain=tmesh.mesh, subdomain_data=tmesh.facet_tags)
    one = fem.Constant(tmesh.mesh, 1.0)
    return COMM.allreduce(fem.assemble_scalar(fem.form(one * ds(tmesh.facet_tag(name)))))


@pytest.mark.parametrize("source", ["file", "model"])
def test_the_ring_splits_into_a_triangle_and_a_quadrilateral_mesh(tmp_path, source):
    meshes = _ring_meshes(tmp_path, source)
    assert [m.mesh.topology.cell_type.name for m in meshes] == ["triangle", "quadrilateral"]
    assert [sorted(m.cell_names) for m in meshes] == [["inner"], ["outer"]]
    for tmesh, body in zip(meshes, ("inner", "outer")):
        assert tmesh.info.get("cells") == tmesh.mesh.topology.cell_type.name
        assert sorted(tmesh.facet_names) == sorted(FACETS[body])
        cells = tmesh.cells(body)
        n_cells = _owned(tmesh, 2, cells)
        assert n_cells == _owned(tmesh, 2, np.arange(tmesh.mesh.topology.index_map(2).size_local))
        volume = _volume(tmesh, body)
        bound = _volume_bound(n_cells, _kappa(tmesh, cells), VOLUMES[body])
        assert abs(volume - VOLUMES[body]) <= bound, (body, volume, VOLUMES[body], bound)
        for name, exact in FACETS[body].items():
            length = _length(tmesh, name)
            bound = _length_bound(_owned(tmesh, 1, tmesh.facets(name)), exact)
            assert abs(length - exact) <= bound, (body, name, length, exact, bound)
    assert _owned(meshes[1], 2, meshes[1].cells("outer")) == N_R * N_Z  # the structured grid


def _vertex_rz(mesh) -> np.ndarray:
    """(r, z) of every local vertex (a first-order cell lists its vertices and its
    geometry nodes in one order)."""
    c2v = mesh.topology.connectivity(2, 0)
    dofs = geometry_dofs(mesh)
    rz = np.empty((mesh.topology.index_map(0).size_local
                   + mesh.topology.index_map(0).num_ghosts, 2))
    rz[c2v.array.reshape(dofs.shape).ravel()] = mesh.geometry.x[dofs.ravel(), :2]
    return rz


def _facet_ends(tmesh, facets: np.ndarray) -> np.ndarray:
    """(r_a, z_a, r_b, z_b) of the owned ``facets``, ends in lexicographic order, rows
    sorted, gathered from every rank."""
    mesh = tmesh.mesh
    mesh.topology.create_connectivity(1, 0)
    owned = facets[facets < mesh.topology.index_map(1).size_local]
    ends = _vertex_rz(mesh)[mesh.topology.connectivity(1, 0).array.reshape(-1, 2)[owned]]
    order = np.lexsort((ends[:, :, 1], ends[:, :, 0]), axis=1)
    ends = np.take_along_axis(ends, order[:, :, None], axis=1).reshape(-1, 4)
    ends = np.concatenate(COMM.allgather(ends))
    return ends[np.lexsort(ends.T[::-1])]


def test_the_interface_is_a_facet_group_of_both_meshes_on_the_same_nodes(tmp_path):
    """The two meshes' interface sides are the same N_Z sides on r = r2 (the meshes are
    conforming: the same gmsh nodes, so the same coordinates, exactly)."""
    ends = [_facet_ends(tmesh, tmesh.facets("interface"))
            for tmesh in _ring_meshes(tmp_path, "file")]
    assert len(ends[0]) == N_Z
    assert np.array_equal(ends[0], ends[1])
    assert np.all(ends[0][:, [0, 2]] == R2)


def _refusal(call) -> str:
    """The InputError of ``call()`` (raised on every rank), checked to be one line."""
    with pytest.raises(InputError) as caught:
        call()
    message = str(caught.value)
    assert "\n" not in message
    return message


def test_a_cell_group_of_two_types_is_refused_in_one_line(tmp_path):
    path = _write(tmp_path, "one_group", lambda gmsh: _ring(gmsh, one_group=True))
    message = _refusal(lambda: load_msh_meshes(path))
    assert message == (f"mesh file '{path}': the cell group 'ring' holds 3-node triangles and "
                       "4-node quadrilaterals; a body lives on one mesh of one cell type: mesh "
                       "each cell group's surfaces with one cell type")
    message = _refusal(lambda: to_dolfinx_meshes(COMM, lambda g: _ring(g, one_group=True), {}))
    assert message.startswith("the mesh: the cell group 'ring' holds 3-node triangles and")


def test_a_mixed_msh2_file_is_refused_in_one_line(tmp_path):
    """msh 2 stores no surface's bounding curves: the split cannot tell which curves and
    nodes go with a removed surface (it loses nodes of kept cells)."""
    path = _write(tmp_path, "ring2", _ring, version=2.2)
    message = _refusal(lambda: load_msh_meshes(path))
    assert message.startswith(f"mesh file '{path}' mixes cell types but does not store which "
                              "curves bound its surfaces")
    assert message.endswith("write it in the msh 4 format (gmsh -format msh4)")


def test_load_msh_keeps_refusing_two_types(tmp_path):
    path = _write(tmp_path, "ring", _ring)
    message = _refusal(lambda: meshing.load_msh(path))
    assert message.startswith(f"mesh file '{path}' mixes cell types (3-node triangles in "
                              "'inner'; 4-node quadrilaterals in 'outer'); a mesh holds one "
                              "cell type for now")


def _cells(tmesh) -> np.ndarray:
    """Every owned cell as its vertices' (r, z) (lexicographic order) and its tag,
    rows sorted, gathered from every rank: the mesh whatever the partition."""
    mesh = tmesh.mesh
    n_owned = mesh.topology.index_map(2).size_local
    tag = np.full(n_owned, -1.0)
    tagged = tmesh.cell_tags.indices < n_owned
    tag[tmesh.cell_tags.indices[tagged]] = tmesh.cell_tags.values[tagged]
    corners = _vertex_rz(mesh)[mesh.topology.connectivity(2, 0).array.reshape(
        n_owned + mesh.topology.index_map(2).num_ghosts, -1)[:n_owned]]
    order = np.lexsort((corners[:, :, 1], corners[:, :, 0]), axis=1)
    corners = np.take_along_axis(corners, order[:, :, None], axis=1).reshape(n_owned, -1)
    rows = np.concatenate(COMM.allgather(np.column_stack([corners, tag])))
    return rows[np.lexsort(rows.T[::-1])]


def _same(a, b) -> None:
    """Two TaggedMeshes equal: the same cells, tags, facet groups and names whatever the
    partition (dolfinx 0.5's partitioner need not cut one mesh alike twice under MPI),
    and in serial array for array."""
    assert (a.cell_names, a.facet_names, a.info) == (b.cell_names, b.facet_names, b.info)
    assert np.array_equal(_cells(a), _cells(b))
    for name in a.facet_names:
        assert np.array_equal(_facet_ends(a, a.facets(name)), _facet_ends(b, b.facets(name)))
    if COMM.size == 1:
        assert np.array_equal(a.mesh.geometry.x, b.mesh.geometry.x)
        assert np.array_equal(geometry_dofs(a.mesh), geometry_dofs(b.mesh))
        for tags in ("cell_tags", "facet_tags"):
            assert np.array_equal(getattr(a, tags).indices, getattr(b, tags).indices)
            assert np.array_equal(getattr(a, tags).values, getattr(b, tags).values)


def test_one_cell_type_reads_as_before(tmp_path):
    """From a file, and from a model as a generator leaves it (here: the file opened, as
    two gmsh runs of one generator need not place interior nodes alike: the first mesh
    of a process differs from later ones by a few ulp)."""
    path = _write(tmp_path, "one_type", _one_type)
    meshes = load_msh_meshes(path)
    assert len(meshes) == 1
    _same(meshes[0], meshing.load_msh(path))

    def build(gmsh):
        gmsh.open(path)

    meshes = to_dolfinx_meshes(COMM, build, {"scene": "annulus"})
    assert len(meshes) == 1
    _same(meshes[0], meshing._to_dolfinx(COMM, build, {"scene": "annulus"}))
