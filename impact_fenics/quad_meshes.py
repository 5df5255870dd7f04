"""Structured quadrilateral meshes with named groups, for small-strain bodies on Q1.

A rectangle r0 <= r <= r1, z0 <= z <= z1 (m) of n_r x n_z bilinear quadrilaterals
(dolfinx's ``create_rectangle``, as :func:`quad_bar` builds the bar of a scene's
``generator = "quad_bar"``), one cell group and the facet groups of its four sides, so that a
:class:`~.bodies.DeformableModel` addresses it by name as a gmsh mesh.

:func:`rod_on_anvil` puts two such rectangles on one mesh, a rod standing on an anvil
block, as two cell groups whose faces share no node (a contact interface).
"""
from __future__ import annotations

import numpy as np
from mpi4py import MPI
from dolfinx import mesh as dmesh

from .errors import require
from .meshing import TaggedMesh

# the facet groups of the four sides; "axis" is the side r = r0 when r0 = 0, "inner" otherwise
SIDES = ("inner", "outer", "bottom", "top")


def quad_bar(comm: MPI.Comm, radius: float, length: float, n_r: int, n_z: int) -> dmesh.Mesh:
    """A cylinder 0 <= r <= radius, 0 <= z <= length (m) of n_r x n_z bilinear quadrilaterals."""
    require(radius > 0 and length > 0, "bar radius and length must be > 0 (m)")
    require(n_r >= 1 and n_z >= 1, "n_r and n_z must be >= 1")
    return dmesh.create_rectangle(comm, [np.array([0.0, 0.0]), np.array([radius, length])],
                                  [n_r, n_z], cell_type=dmesh.CellType.quadrilateral)


def quad_bar_cells_along(p: dict) -> int:
    """n_z of the quad_bar mesh of [mesh] parameters ``p``: square cells, round(n_r length /
    radius) along the bar."""
    return max(1, round(p["n_r"] * p["length"] / p["radius"]))


def face_nodes(mesh: dmesh.Mesh, z_face: float, tol: float) -> np.ndarray:
    """Owned nodes of the face Z = z_face (m) of a quadrilateral mesh, numbered as the dofs
    of a P1 vector space on ``mesh`` (a DeformableModel's nodes)."""
    from . import compat

    V = compat.vector_space(mesh, "Lagrange", 1)
    xy = V.tabulate_dof_coordinates()[: V.dofmap.index_map.size_local, :2]
    return np.flatnonzero(np.abs(xy[:, 1] - z_face) <= tol)


def one_body(mesh: dmesh.Mesh, body: str = "body") -> TaggedMesh:
    """``mesh`` with every cell (ghosts included) in the group ``body`` and no facet
    group: a mesh that is one body."""
    cmap = mesh.topology.index_map(mesh.topology.dim)
    cells = np.arange(cmap.size_local + cmap.num_ghosts, dtype=np.int32)
    cell_tags = dmesh.meshtags(mesh, mesh.topology.dim, cells, np.ones(cells.size, dtype=np.int32))
    no_facets = np.zeros(0, dtype=np.int32)
    facet_tags = dmesh.meshtags(mesh, mesh.topology.dim - 1, no_facets, no_facets)
    return TaggedMesh(mesh, cell_tags, facet_tags, {body: 1}, {})


def tag_rectangle(mesh: dmesh.Mesh, body: str = "body") -> TaggedMesh:
    """``mesh`` (quadrilaterals filling a rectangle) with every cell in the group ``body``
    and the facets of its sides in the groups ``axis`` (r = 0) or ``inner``, ``outer``,
    ``bottom`` and ``top``."""
    require(mesh.topology.cell_type == dmesh.CellType.quadrilateral,
            "tag_rectangle takes a mesh of quadrilaterals")
    comm = mesh.comm
    x = mesh.geometry.x[:, :2]
    lo = x.min(axis=0) if x.size else np.full(2, np.inf)
    hi = x.max(axis=0) if x.size else np.full(2, -np.inf)
    comm.Allreduce(MPI.IN_PLACE, lo, op=MPI.MIN)
    comm.Allreduce(MPI.IN_PLACE, hi, op=MPI.MAX)
    tol = 1e-10 * float(np.max(hi - lo))  # m: far above round-off, far below a cell
    names = dict(zip(SIDES, range(1, 5)))
    if abs(lo[0]) <= tol:
        names = {("axis" if k == "inner" else k): v for k, v in names.items()}
    sides = [lambda p: np.abs(p[0] - lo[0]) <= tol, lambda p: np.abs(p[0] - hi[0]) <= tol,
             lambda p: np.abs(p[1] - lo[1]) <= tol, lambda p: np.abs(p[1] - hi[1]) <= tol]
    tdim = mesh.topology.dim
    mesh.topology.create_connectivity(tdim - 1, tdim)
    facets, values = [], []
    for tag, marker in zip(names.values(), sides):
        f = dmesh.locate_entities_boundary(mesh, tdim - 1, marker)
        facets.append(f)
        values.append(np.full(f.size, tag, dtype=np.int32))
    facets = np.concatenate(facets).astype(np.int32)
    order = np.argsort(facets, kind="stable")
    facet_tags = dmesh.meshtags(mesh, tdim - 1, facets[order], np.concatenate(values)[order])
    cmap = mesh.topology.index_map(tdim)
    cells = np.arange(cmap.size_local + cmap.num_ghosts, dtype=np.int32)
    cell_tags = dmesh.meshtags(mesh, tdim, cells, np.ones(cells.size, dtype=np.int32))
    return TaggedMesh(mesh, cell_tags, facet_tags, {body: 1}, names,
                      info={"cell": "quadrilateral", "extent": (lo.tolist(), hi.tolist())})


def quad_rectangle(comm: MPI.Comm, r0: float, z0: float, r1: float, z1: float, n_r: int,
                   n_z: int, body: str = "body") -> TaggedMesh:
    """The rectangle r0 <= r <= r1, z0 <= z <= z1 (m) of n_r x n_z quadrilaterals, tagged
    as :func:`tag_rectangle` does; ``info['h']`` the larger cell side (m)."""
    require(0.0 <= r0 < r1 and z0 < z1, f"a rectangle needs 0 <= r0 < r1 and z0 < z1 (m); got "
            f"r {r0}..{r1}, z {z0}..{z1}")
    require(n_r >= 1 and n_z >= 1, "n_r and n_z must be >= 1")
    mesh = dmesh.create_rectangle(comm, [np.array([r0, z0]), np.array([r1, z1])], [n_r, n_z],
                                  cell_type=dmesh.CellType.quadrilateral)
    tm = tag_rectangle(mesh, body)
    tm.info["h"] = max((r1 - r0) / n_r, (z1 - z0) / n_z)
    return tm


def rod_on_anvil(comm: MPI.Comm, radius: float, length: float, n_r: int, n_z: int,
                 anvil_radius: float, anvil_depth: float) -> TaggedMesh:
    """A rod 0 <= r <= radius, 0 <= z <= length (m) of n_r x n_z quadrilaterals standing on
    an anvil block 0 <= r <= anvil_radius, -anvil_depth <= z <= 0 (m), one mesh of two
    structured Q1 cell groups that share no node (the faces at z = 0 are a contact
    interface). The anvil's cells are squares of the rod's radial size h = radius / n_r
    where its sizes allow (round(anvil_radius / h) x round(anvil_depth / h) cells), so
    its top matches the rod's face node for node at r <= radius at set-up.

    Groups: cells "rod", "anvil"; facets "rod_contact" (the rod's face z = 0),
    "rod_lateral", "rod_end" (z = length), "anvil_contact" (the anvil's top),
    "anvil_lateral", "anvil_bottom", "axis" (both bodies')."""
    from .meshing import _generate, _group, _to_dolfinx

    require(radius > 0 and length > 0, "rod radius and length must be > 0 (m)")
    require(n_r >= 1 and n_z >= 1, "n_r and n_z must be >= 1")
    require(anvil_radius >= radius, f"anvil radius = {anvil_radius} m: must be at least the "
            f"rod's ({radius} m)")
    require(anvil_depth > 0, f"anvil depth = {anvil_depth} m: must be > 0")
    h = radius / n_r
    m_r, m_z = max(1, round(anvil_radius / h)), max(1, round(anvil_depth / h))

    def rectangle(geo, r0, z0, r1, z1, nr, nz):
        p = [geo.addPoint(r0, z0, 0, h), geo.addPoint(r1, z0, 0, h),
             geo.addPoint(r1, z1, 0, h), geo.addPoint(r0, z1, 0, h)]
        c = [geo.addLine(p[k], p[(k + 1) % 4]) for k in range(4)]  # bottom, right, top, left
        s = geo.addPlaneSurface([geo.addCurveLoop(c)])
        for k, n in ((0, nr), (2, nr), (1, nz), (3, nz)):
            geo.mesh.setTransfiniteCurve(c[k], n + 1)
        geo.mesh.setTransfiniteSurface(s, "Alternate")
        geo.mesh.setRecombine(2, s)
        return s, c

    def build(gmsh):
        geo = gmsh.model.geo
        rod, c1 = rectangle(geo, 0.0, 0.0, radius, length, n_r, n_z)
        anvil, c2 = rectangle(geo, 0.0, -anvil_depth, anvil_radius, 0.0, m_r, m_z)
        geo.synchronize()
        _group(gmsh, 2, [rod], "rod", 1)
        _group(gmsh, 2, [anvil], "anvil", 2)
        for name, curves, tag in (("rod_contact", [c1[0]], 11), ("rod_lateral", [c1[1]], 12),
                                  ("rod_end", [c1[2]], 13), ("anvil_contact", [c2[2]], 14),
                                  ("anvil_lateral", [c2[1]], 15), ("anvil_bottom", [c2[0]], 16),
                                  ("axis", [c1[3], c2[3]], 17)):
            _group(gmsh, 1, curves, name, tag)
        _generate(gmsh)

    tm = _to_dolfinx(comm, build, {"scene": "rod_on_anvil", "radius": radius,
                                   "length": length, "n_r": n_r, "n_z": n_z,
                                   "anvil_radius": anvil_radius, "anvil_depth": anvil_depth})
    tm.info["h"] = h
    tm.info["anvil_cells"] = (m_r, m_z)
    return tm
