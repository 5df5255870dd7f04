"""Structured quadrilateral meshes with named groups, for small-strain bodies on Q1.

A rectangle r0 <= r <= r1, z0 <= z <= z1 (m) of n_r x n_z bilinear quadrilaterals
(dolfinx's ``create_rectangle``, as :func:`quad_bar` builds the bar of a scene's
``generator = "quad_bar"``), one cell group and the facet groups of its four sides, so that a
:class:`~.bodies.DeformableModel` addresses it by name as a gmsh mesh.
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
