"""Meshes of the scenes: gmsh generators on rank 0, read on every rank with gdim = 2.

Every generator returns a :class:`TaggedMesh` whose cell and facet groups are
known by name. Lengths are in metres; r = x[0] >= 0, z = x[1]. ``load_msh``
reads a .msh file with named physical groups through the same path.
"""
from __future__ import annotations

import math
import os
from dataclasses import dataclass, field

import numpy as np
from mpi4py import MPI
from dolfinx import mesh as dmesh

from . import interrupts
from .compat import model_to_mesh
from .errors import InputError, require

with interrupts.kept():  # gmsh's module (dolfinx's reader imports it) sets SIGINT to SIG_DFL
    import gmsh  # noqa: F401


@dataclass
class TaggedMesh:
    """A dolfinx mesh with its cell and facet tags, addressed by group name."""

    mesh: dmesh.Mesh
    cell_tags: dmesh.MeshTags
    facet_tags: dmesh.MeshTags
    cell_names: dict[str, int]
    facet_names: dict[str, int]
    info: dict = field(default_factory=dict)

    def cell_tag(self, name: str) -> int:
        """Integer tag of the cell group ``name``; a clear error if the mesh lacks it."""
        if name not in self.cell_names:
            raise InputError(f"mesh has no cell group named '{name}' "
                             f"(it has: {', '.join(sorted(self.cell_names)) or 'none'})")
        return self.cell_names[name]

    def facet_tag(self, name: str) -> int:
        """Integer tag of the facet group ``name``; a clear error if the mesh lacks it."""
        if name not in self.facet_names:
            raise InputError(f"mesh has no facet group named '{name}' "
                             f"(it has: {', '.join(sorted(self.facet_names)) or 'none'})")
        return self.facet_names[name]

    def facets(self, name: str) -> np.ndarray:
        """Local indices of the facets in group ``name``."""
        return self.facet_tags.find(self.facet_tag(name))

    def cells(self, name: str) -> np.ndarray:
        """Local indices of the cells in group ``name``."""
        return self.cell_tags.find(self.cell_tag(name))


_GMSH_READY = False


def _gmsh():
    """The gmsh module, initialised once per process (gmsh 4.8 has no isInitialized)."""
    global _GMSH_READY
    with interrupts.kept():
        import gmsh

    if not _GMSH_READY:
        # newer gmsh sets SIGINT to SIG_DFL in initialize(), and SIGTERM in C
        with interrupts.masked(), interrupts.kept():
            gmsh.initialize()
        _GMSH_READY = True
        _INITIAL.update({option: gmsh.option.getNumber(option) for option in _SHAPING})
    gmsh.option.setNumber("General.Terminal", 0)
    gmsh.option.setNumber("General.Verbosity", 1)
    return gmsh


def start_gmsh() -> None:
    """Initialise gmsh now (once per process): its initialize() resets signal actions in C,
    so a run does it at start-up, before it reports its estimate (interrupts.masked)."""
    _gmsh()


def _restart_gmsh() -> None:
    global _GMSH_READY
    import gmsh

    with interrupts.kept():  # gmsh.finalize() puts back the handler of its import time
        gmsh.finalize()
    _GMSH_READY = False


def _physical_names(gmsh) -> tuple[dict[str, int], dict[str, int]]:
    cells, facets = {}, {}
    for dim, tag in gmsh.model.getPhysicalGroups():
        name = gmsh.model.getPhysicalName(dim, tag) or str(tag)
        if dim == 2:
            cells[name] = tag
        elif dim == 1:
            facets[name] = tag
    return cells, facets


# gmsh options that a generator may change, reset before every mesh
_DEFAULTS = {"Mesh.MeshSizeExtendFromBoundary": 1, "Mesh.MeshSizeFromPoints": 1,
             "Mesh.MeshSizeFromCurvature": 0, "Mesh.Algorithm": 6}
# options that a caller's own gmsh work in the same process may have changed (gmsh
# keeps them across models): put back to their values at initialisation before
# every mesh, so a generated mesh never depends on what ran before it
_SHAPING = ("Mesh.MeshSizeMax", "Mesh.MeshSizeMin", "Mesh.MeshSizeFactor",
            "Mesh.RecombineAll", "Mesh.RecombinationAlgorithm", "Mesh.ElementOrder",
            "Mesh.SecondOrderLinear", "Mesh.Smoothing", "Mesh.Optimize",
            "Mesh.SubdivisionAlgorithm")
_INITIAL: dict[str, float] = {}


def _fresh_model(gmsh) -> None:
    """An empty model with the options reset: no model, field or option left over from an
    earlier mesh (rank 0)."""
    gmsh.clear()
    for option, value in (_INITIAL | _DEFAULTS).items():
        gmsh.option.setNumber(option, value)
    gmsh.model.add("impact_fenics")


def _to_dolfinx(comm: MPI.Comm, build, info: dict) -> TaggedMesh:
    """Run ``build(gmsh)`` on rank 0 (it must leave a meshed model), read on all ranks."""
    gmsh = _gmsh()
    names = None
    error = None
    if comm.rank == 0:
        _fresh_model(gmsh)
        try:
            build(gmsh)
            names = _physical_names(gmsh)
            if not names[0]:
                error = "mesh has no physical group of cells (dimension 2)"
        except InputError as exc:
            error = str(exc)
        except Exception as exc:  # gmsh raises plain Exceptions for unreadable files
            error = f"mesh could not be built or read: {exc}"
    error = comm.bcast(error, root=0)
    if error is not None:
        if comm.rank == 0:
            _restart_gmsh()  # a failed read can leave gmsh's model list broken
        raise InputError(error)
    names = comm.bcast(names, root=0)
    msh, cell_tags, facet_tags = model_to_mesh(gmsh.model, comm, 0, gdim=2)
    if comm.rank == 0:
        gmsh.model.remove()
    msh.topology.create_connectivity(1, 2)
    return TaggedMesh(msh, cell_tags, facet_tags, names[0], names[1], info)


def load_msh(path: str, comm: MPI.Comm = MPI.COMM_WORLD) -> TaggedMesh:
    """Read a 2D .msh file whose physical groups carry names (r = x, z = y)."""
    require(os.path.isfile(path), f"mesh file '{path}' does not exist")

    def build(gmsh):
        _open_msh(gmsh, path)

    return _to_dolfinx(comm, build, {"source": os.path.abspath(path)})


def _open_msh(gmsh, path: str, mixed: bool = False) -> None:
    """Open a .msh file in gmsh and refuse, in one line, what the reader cannot take.

    dolfinx's gmsh reader (0.5) ends the process (a segmentation fault, an abort or a
    failed assertion) on cells outside every 2D physical group, on cells of two types,
    on node tags with gaps (numbered anew here), on a group of an unmeshed entity,
    on a cell in two groups, on a line that is no cell's side and on a point group
    whose point is no cell's node, and keeps a side that is in two groups in one of
    them only; on 0.11 it builds a mesh the solver cannot use (several cell types,
    second-order cells) or stops MPI. A mesh holds one cell type: ``mixed`` lets
    triangles and quadrilaterals through for a reader that splits the model by cell
    type (:mod:`impact_fenics.mesh_split`)."""
    gmsh.open(path)
    where = f"mesh file '{path}'"
    if gmsh.model.getDimension() != 2:
        raise InputError(f"{where} is not a 2D (r, z) mesh")
    tags, xyz, _ = gmsh.model.mesh.getNodes()
    if not tags.size:
        raise InputError(f"{where} holds no mesh nodes")
    # (a mesh in the x-z plane reads as a flat section: cells of zero area)
    xyz = xyz.reshape(-1, 3)
    extent = float(np.ptp(xyz[:, :2], axis=0).max())
    # gmsh places a node within Geometry.Tolerance (1e-8 of the model's size) of its plane
    if np.ptp(xyz[:, 2]) > 1e-8 * extent:
        raise InputError(f"{where}: its nodes span {np.ptp(xyz[:, 2]):.4g} m in gmsh's z, so "
                         "the mesh is not in a plane z = constant; draw the section in the "
                         "x-y plane (r = x, z = y)")
    _refuse_loose_surfaces(gmsh, where)
    # dolfinx's reader asserts node tags 1..n without gaps; a file edited (a surface's mesh
    # cleared) or written by another tool may have gaps: number the nodes anew
    gmsh.model.mesh.renumberNodes()
    _refuse_unmeshed_entities(gmsh, where)
    _refuse_entities_in_two_groups(gmsh, where)
    _refuse_cell_types(gmsh, where, mixed)
    _refuse_lines_off_the_cells(gmsh, where)
    _refuse_points_off_the_cells(gmsh, where)


def _group_name(gmsh, dim: int, tag: int) -> str:
    return gmsh.model.getPhysicalName(dim, tag) or str(tag)


def _refuse_loose_surfaces(gmsh, where: str) -> None:
    """Cells outside every 2D physical group (dolfinx 0.5 crashes on them)."""
    if not gmsh.model.getPhysicalGroups(2):
        raise InputError(f"{where} has no physical group of cells (dimension 2): put every "
                         "surface in a named physical group (a body)")
    loose = [tag for _, tag in gmsh.model.getEntities(2)
             if not len(gmsh.model.getPhysicalGroupsForEntity(2, tag))
             and len(gmsh.model.mesh.getElements(2, tag)[0])]
    if loose:
        raise InputError(f"{where}: surface(s) {', '.join(map(str, loose))} "
                         "have cells but no 2D physical group; put every surface in a "
                         "named physical group (a body)")


def _refuse_unmeshed_entities(gmsh, where: str) -> None:
    """A physical group naming a surface, curve or point that holds no mesh (dolfinx 0.5's
    reader fails an assertion; 0.11 makes a body of no cells)."""
    for dim, tag in gmsh.model.getPhysicalGroups():
        for entity in gmsh.model.getEntitiesForPhysicalGroup(dim, tag):
            if not len(gmsh.model.mesh.getElements(dim, entity)[0]):
                what = ("point", "curve", "surface")[dim]
                raise InputError(f"{where}: the group '{_group_name(gmsh, dim, tag)}' holds "
                                 f"{what} {entity}, which has no mesh; mesh it, or take it "
                                 "out of the group")


def _refuse_entities_in_two_groups(gmsh, where: str) -> None:
    """A surface in two cell groups (its cells read twice: a crash), or a curve in two
    facet groups (its sides kept in one of them: a group silently short)."""
    for dim, what, kind, advice in ((2, "cells", "cell", "a cell belongs to one body: put "
                                     "each surface in one 2D physical group"),
                                    (1, "sides", "facet", "a side is read into one group "
                                     "only: put each curve in one 1D physical group")):
        for _, tag in gmsh.model.getEntities(dim):
            groups = gmsh.model.getPhysicalGroupsForEntity(dim, tag)
            if len(groups) > 1 and len(gmsh.model.mesh.getElements(dim, tag)[0]):
                names = " and ".join(f"'{_group_name(gmsh, dim, g)}'" for g in groups)
                entity = ("curve", "surface")[dim - 1]
                raise InputError(f"{where}: the {what} of {entity} {tag} are in the {kind} "
                                 f"groups {names}; {advice}")


def _cell_kind(gmsh, kind: int) -> str:
    """'3-node triangles', '4-node quadrilaterals', '6-node triangles', ... of gmsh's type."""
    name, _, _, nodes, _, corners = gmsh.model.mesh.getElementProperties(kind)[:6]
    shape = {3: "triangles", 4: "quadrilaterals"}.get(corners, name.split()[0].lower() + "s")
    return f"{nodes}-node {shape}"


def _cell_kinds(gmsh) -> dict[int, list[str]]:
    """gmsh element type -> the names of the cell groups that hold cells of it."""
    kinds: dict[int, list[str]] = {}
    for dim, tag in gmsh.model.getPhysicalGroups(2):
        for entity in gmsh.model.getEntitiesForPhysicalGroup(dim, tag):
            for kind in gmsh.model.mesh.getElementTypes(2, entity):
                names = kinds.setdefault(int(kind), [])
                if _group_name(gmsh, dim, tag) not in names:
                    names.append(_group_name(gmsh, dim, tag))
    return kinds


def _refuse_cell_types(gmsh, where: str, mixed: bool = False) -> None:
    """Second-order cells, and (unless ``mixed``) cells of more than one type (one cell
    type per mesh)."""
    kinds = _cell_kinds(gmsh)
    said = [f"{_cell_kind(gmsh, k)} in {', '.join(repr(n) for n in names)}"
            for k, names in sorted(kinds.items())]
    higher = [s for k, s in zip(sorted(kinds), said)
              if gmsh.model.mesh.getElementProperties(k)[2] > 1]
    if higher:
        raise InputError(f"{where} has second-order cells ({'; '.join(higher)}); the solver's "
                         "cells are first order: mesh with element order 1 (gmsh -order 1, "
                         "Mesh.ElementOrder = 1)")
    if len(kinds) > 1 and not mixed:
        raise InputError(f"{where} mixes cell types ({'; '.join(said)}); a mesh holds one cell "
                         "type for now (several meshes in one scene are to come): mesh every "
                         "body with one cell type (all triangles, or every surface recombined "
                         "into quadrilaterals)")


def _refuse_lines_off_the_cells(gmsh, where: str) -> None:
    """Line groups hold sides of cells (facets); a line that is no cell's side crashes
    dolfinx 0.5's reader. Second-order lines are refused with the cells."""
    sides = []
    for _, tag in gmsh.model.getEntities(2):
        for kind, nodes in zip(*gmsh.model.mesh.getElements(2, tag)[::2]):
            props = gmsh.model.mesh.getElementProperties(kind)
            conn = nodes.astype(np.int64).reshape(-1, props[3])[:, :props[5]]  # the corners
            sides.append(np.sort(np.stack([conn, np.roll(conn, -1, axis=1)], axis=2)
                                 .reshape(-1, 2), axis=1))
    sides = np.concatenate(sides) if sides else np.zeros((0, 2), np.int64)
    base = int(sides.max()) + 1 if sides.size else 1  # a side (a, b), a < b, is a * base + b
    known = np.unique(sides[:, 0] * base + sides[:, 1])
    for dim, tag in gmsh.model.getPhysicalGroups(1):
        for entity in gmsh.model.getEntitiesForPhysicalGroup(dim, tag):
            for kind, nodes in zip(*gmsh.model.mesh.getElements(1, entity)[::2]):
                props = gmsh.model.mesh.getElementProperties(kind)
                if props[2] > 1:
                    raise InputError(f"{where} has second-order lines in the facet group "
                                     f"'{_group_name(gmsh, dim, tag)}'; the solver's cells "
                                     "are first order: mesh with element order 1 (gmsh "
                                     "-order 1, Mesh.ElementOrder = 1)")
                ends = np.sort(nodes.astype(np.int64).reshape(-1, props[3])[:, :2], axis=1)
                off = (ends[:, 1] >= base) | ~np.isin(ends[:, 0] * base + ends[:, 1], known)
                if off.any():
                    raise InputError(f"{where}: {int(off.sum())} line(s) of the facet group "
                                     f"'{_group_name(gmsh, dim, tag)}' (curve {entity}) are "
                                     "not sides of any cell; a facet group holds sides of the "
                                     "cells: put only curves that bound a meshed surface in it")


def _refuse_points_off_the_cells(gmsh, where: str) -> None:
    """A point group whose point is no node of a cell crashes dolfinx 0.5's reader (a
    point group on a cell's node is read, and unused)."""
    used = [nodes for _, tag in gmsh.model.getEntities(2)
            for nodes in gmsh.model.mesh.getElements(2, tag)[2]]
    used = np.concatenate(used) if used else np.zeros(0, np.uint64)
    for dim, tag in gmsh.model.getPhysicalGroups(0):
        for entity in gmsh.model.getEntitiesForPhysicalGroup(dim, tag):
            nodes = gmsh.model.mesh.getNodes(0, entity)[0]
            if not np.isin(nodes, used).all():
                raise InputError(f"{where}: the point group '{_group_name(gmsh, dim, tag)}' "
                                 f"holds point {entity}, which is no node of a cell; the "
                                 "solver reads cell and facet groups only: remove the point "
                                 "group (or put its point on a meshed surface)")


def msh_size(path: str, comm: MPI.Comm = MPI.COMM_WORLD) -> dict:
    """What a .msh file holds, without building the mesh (rank 0 reads it, every rank gets
    the answer): {"groups": {name: (cells, smallest element size h in m: the side of the
    equilateral triangle, or square, of the smallest cell's area)}, "nodes": the nodes of
    the cells, "size": the largest extent in r or z (m), "cells" and "facets": the group
    names}, "quadrilaterals": every cell a quadrilateral (the step estimate's Q1 bound).
    Refuses what :func:`load_msh` refuses."""
    require(os.path.isfile(path), f"mesh file '{path}' does not exist")
    out, error = None, None
    if comm.rank == 0:
        gmsh = _gmsh()
        gmsh.clear()
        try:
            _open_msh(gmsh, path)
            tags, xyz, _ = gmsh.model.mesh.getNodes()
            xy = np.zeros((int(tags.max()) + 1, 2))
            xy[tags.astype(np.int64)] = xyz.reshape(-1, 3)[:, :2]
            groups, used, corner_counts = {}, [], set()
            for dim, tag in gmsh.model.getPhysicalGroups(2):
                name = gmsh.model.getPhysicalName(dim, tag) or str(tag)
                cells, h = 0, np.inf
                for entity in gmsh.model.getEntitiesForPhysicalGroup(dim, tag):
                    types, _, nodes = gmsh.model.mesh.getElements(2, entity)
                    for kind, conn in zip(types, nodes):
                        props = gmsh.model.mesh.getElementProperties(kind)
                        corners = props[5]  # (of props[3] nodes a cell)
                        conn = conn.astype(np.int64).reshape(-1, props[3])[:, :corners]
                        p = xy[conn]
                        area = 0.5 * np.abs(np.sum(p[:, :, 0] * np.roll(p[:, :, 1], -1, 1)
                                                   - np.roll(p[:, :, 0], -1, 1) * p[:, :, 1],
                                                   axis=1))
                        shape = (math.sqrt(3.0) / 4.0) if corners == 3 else 1.0
                        cells += conn.shape[0]
                        corner_counts.add(int(corners))
                        h = min(h, float(np.sqrt(area.min() / shape)))
                        used.append(conn.ravel())
                groups[name] = (cells, h)
            nodes = np.unique(np.concatenate(used)) if used else np.zeros(0, np.int64)
            box = xy[nodes]
            names = _physical_names(gmsh)
            out = {"groups": groups, "nodes": int(nodes.size),
                   "size": float(np.ptp(box, axis=0).max()) if box.size else 0.0,
                   "cells": sorted(names[0]), "facets": sorted(names[1]),
                   "quadrilaterals": corner_counts == {4}}
        except InputError as exc:
            error = str(exc)
        except Exception as exc:  # gmsh raises plain Exceptions for unreadable files
            error = f"mesh could not be built or read: {exc}"
        gmsh.clear()
    out, error = comm.bcast((out, error), root=0)
    if error is not None:
        if comm.rank == 0:
            _restart_gmsh()
        raise InputError(error)
    return out


# ----------------------------------------------------------------------------- helpers

def _rectangle(gmsh, r0, z0, r1, z1, h, n_r=None, structured=False):
    """Rectangle [r0, r1] x [z0, z1] in the geo kernel. Returns the surface and its
    curves (bottom, right, top, left). ``n_r`` fixes the intervals along r on the
    bottom and top curves (so that faces of touching bodies pair node to node).

    The meshing constraints are set in the geo kernel (``geo.mesh``): they are
    applied at every synchronisation, so a second rectangle does not erase the
    first one's (constraints set on the model are lost when the geo kernel
    synchronises again)."""
    geo = gmsh.model.geo
    p = [geo.addPoint(r0, z0, 0, h), geo.addPoint(r1, z0, 0, h),
         geo.addPoint(r1, z1, 0, h), geo.addPoint(r0, z1, 0, h)]
    c = [geo.addLine(p[0], p[1]), geo.addLine(p[1], p[2]),
         geo.addLine(p[2], p[3]), geo.addLine(p[3], p[0])]
    s = geo.addPlaneSurface([geo.addCurveLoop(c)])
    if n_r is not None:
        for k in (0, 2):
            geo.mesh.setTransfiniteCurve(c[k], n_r + 1)
    if structured:
        n_z = max(1, int(round((z1 - z0) / h)))
        for k in (1, 3):
            geo.mesh.setTransfiniteCurve(c[k], n_z + 1)
        geo.mesh.setTransfiniteSurface(s, "Alternate")
    geo.synchronize()
    return s, c


def _block_split_top(geo, x_break: float, width: float, depth: float,
                     h: float) -> tuple[int, list[int]]:
    """A block 0 <= x <= width, -depth <= y <= 0 (m) of element size ``h`` whose top is
    split at ``x_break``: its surface and its lines, each drawn from its successor's
    corner (the top under the body above [0, x_break], the rest of the top, the side,
    the bottom, the axis), the loop counter-clockwise."""
    p = [geo.addPoint(0, 0, 0, h), geo.addPoint(x_break, 0, 0, h),
         geo.addPoint(width, 0, 0, h), geo.addPoint(width, -depth, 0, h),
         geo.addPoint(0, -depth, 0, h)]
    lines = [geo.addLine(p[(k + 1) % 5], p[k]) for k in range(5)]
    return geo.addPlaneSurface([geo.addCurveLoop(lines[::-1])]), lines


def _group(gmsh, dim: int, entities: list[int], name: str, tag: int) -> None:
    gmsh.model.addPhysicalGroup(dim, entities, tag)
    gmsh.model.setPhysicalName(dim, tag, name)


def _block_outline(gmsh, breaks_r: list[float], width: float, depth: float, h_surface: float,
                   h_max: float) -> tuple[int, list[int], int, int, int]:
    """The block r in [0, width], z in [-depth, 0] (m) with its surface split at ``breaks_r``:
    returns the plane surface and its curves (surface pieces, far side, bottom, axis)."""
    geo = gmsh.model.geo
    top = [geo.addPoint(r, 0.0, 0.0, h_surface) for r in [0.0] + list(breaks_r) + [width]]
    corner_far = geo.addPoint(width, -depth, 0.0, h_max)
    corner_axis = geo.addPoint(0.0, -depth, 0.0, h_max)
    surface = [geo.addLine(top[k], top[k + 1]) for k in range(len(top) - 1)]
    far = geo.addLine(top[-1], corner_far)
    bottom = geo.addLine(corner_far, corner_axis)
    axis = geo.addLine(corner_axis, top[0])
    s = geo.addPlaneSurface([geo.addCurveLoop(surface + [far, bottom, axis])])
    return s, surface, far, bottom, axis


def _graded_size(gmsh, curves: list[int], h_surface: float, grading: float,
                 h_max: float) -> None:
    """Element size h_surface + grading * (distance to ``curves``), capped at h_max (m)."""
    field = gmsh.model.mesh.field
    dist = field.add("Distance")
    field.setNumbers(dist, "CurvesList", curves)
    field.setNumber(dist, "NumPointsPerCurve", 2000)
    size = field.add("MathEval")
    field.setString(size, "F", f"Min({h_surface} + {grading} * F{dist}, {h_max})")
    field.setAsBackgroundMesh(size)
    for option in ("ExtendFromBoundary", "FromPoints", "FromCurvature"):
        gmsh.option.setNumber(f"Mesh.MeshSize{option}", 0)


def _generate(gmsh) -> None:
    gmsh.option.setNumber("Mesh.Algorithm", 6)
    gmsh.model.mesh.generate(2)


# ----------------------------------------------------------------------------- scenes

def bar(radius: float = 0.05, length: float = 1.0, h: float = 0.01, structured: bool = True,
        comm: MPI.Comm = MPI.COMM_WORLD) -> TaggedMesh:
    """(a) A single bar r in [0, radius], z in [0, length] (m), element size h (m).

    Groups: cells "bar"; facets "loaded_end" (z = 0), "free_end" (z = length),
    "lateral" (r = radius), "axis" (r = 0).
    """
    require(radius > 0 and length > 0 and h > 0, "bar: radius, length and h must be > 0 (m)")

    def build(gmsh):
        n_r = max(1, int(round(radius / h)))
        s, c = _rectangle(gmsh, 0.0, 0.0, radius, length, h, n_r=n_r, structured=structured)
        _group(gmsh, 2, [s], "bar", 1)
        for name, curve, tag in (("loaded_end", c[0], 11), ("lateral", c[1], 12),
                                 ("free_end", c[2], 13), ("axis", c[3], 14)):
            _group(gmsh, 1, [curve], name, tag)
        _generate(gmsh)

    return _to_dolfinx(comm, build, {"scene": "bar", "radius": radius, "length": length, "h": h})


def block(width: float = 0.1, height: float = 1.0, h: float = 0.01,
          quadrilaterals: bool = False, comm: MPI.Comm = MPI.COMM_WORLD) -> TaggedMesh:
    """A block x in [0, width], y in [0, height] (m), element size h (m), for a plane-strain
    scene (its section; an axisymmetric one reads it as a bar r in [0, width]): a
    structured grid of round(width / h) x round(height / h) squares, each two triangles of
    alternating diagonals, or one quadrilateral (Q1) with ``quadrilaterals``.

    Groups: cells "block"; facets "bottom" (y = 0), "right" (x = width), "top"
    (y = height), "left" (x = 0).
    """
    require(width > 0 and height > 0 and h > 0, "block: width, height and h must be > 0 (m)")

    def build(gmsh):
        n_x = max(1, int(round(width / h)))
        s, c = _rectangle(gmsh, 0.0, 0.0, width, height, h, n_r=n_x, structured=True)
        if quadrilaterals:
            gmsh.model.geo.mesh.setRecombine(2, s)
            gmsh.model.geo.synchronize()
        _group(gmsh, 2, [s], "block", 1)
        for name, curve, tag in (("bottom", c[0], 11), ("right", c[1], 12),
                                 ("top", c[2], 13), ("left", c[3], 14)):
            _group(gmsh, 1, [curve], name, tag)
        _generate(gmsh)

    return _to_dolfinx(comm, build, {"scene": "block", "width": width, "height": height,
                                     "h": h})


def flat_punch_block(half_width: float = 0.01, width: float = 0.05, depth: float = 0.05,
                     n_punch: int = 4, grading: float = 1.25, refine: int = 0,
                     quadrilaterals: bool = True, comm: MPI.Comm = MPI.COMM_WORLD) -> TaggedMesh:
    """The half section x in [0, width], y in [-depth, 0] (m) of a block under a flat punch
    of half-width ``half_width`` (m; the symmetry plane x = 0), for a plane-strain scene
    with ``symmetry = "x=0"``: a structured grid graded toward the punch's corner
    (half_width, 0), Q1 with ``quadrilaterals`` (else each cell two triangles).

    Its lines are x = 0, half_width, width and y = -depth, 0; along x and y the cells
    shrink geometrically by ``grading`` per cell toward x = half_width and y = 0:
    ``n_punch`` cells on [0, half_width] and as many on [half_width, width] and on
    [-depth, 0] as make the first cell there no larger than the corner's. ``refine``
    halves every cell that many times (each line's count doubled and its ratio
    square-rooted: nested meshes, the corner's cell h_corner halved each time).

    Groups: cells "block"; facets "punch_face" (y = 0, x <= half_width), "surface" (y = 0,
    x >= half_width), "side" (x = width), "bottom" (y = -depth), "axis" (x = 0).
    """
    require(half_width > 0 and width > half_width and depth > 0,
            "flat_punch_block: need half_width > 0 and width > half_width, depth > 0 (m)")
    require(n_punch >= 1 and grading >= 1.0 and refine >= 0,
            "flat_punch_block: need n_punch >= 1, grading >= 1 and refine >= 0")
    q = grading
    h0 = half_width / n_punch if q == 1.0 else half_width * (q - 1) / (q ** n_punch - 1)

    def count(length: float) -> int:
        """Cells of ratio q from h0 that cover ``length`` (m): the least n with
        h0 (q^n - 1) / (q - 1) >= length, so gmsh's first cell is at most h0."""
        if q == 1.0:
            return max(1, math.ceil(length / h0 - 1e-9))
        return max(1, math.ceil(math.log1p(length * (q - 1) / h0) / math.log(q) - 1e-9))

    split = 2 ** refine
    n_p, n_out, n_y = (n * split for n in (n_punch, count(width - half_width), count(depth)))
    q_fine = q ** (1.0 / split)
    h_corner = h0 if q == 1.0 else half_width * (q_fine - 1) / (q_fine ** n_p - 1)

    def build(gmsh):
        geo = gmsh.model.geo
        xs, ys = (0.0, half_width, width), (-depth, 0.0)
        p = {(i, j): geo.addPoint(xs[i], ys[j], 0, h0) for i in range(3) for j in range(2)}
        # every line drawn away from the corner's lines, so the progression grows outward
        top0 = geo.addLine(p[1, 1], p[0, 1])      # punch face, from the corner to the axis
        top1 = geo.addLine(p[1, 1], p[2, 1])      # free surface, from the corner outward
        bot0 = geo.addLine(p[1, 0], p[0, 0])
        bot1 = geo.addLine(p[1, 0], p[2, 0])
        axis = geo.addLine(p[0, 1], p[0, 0])      # vertical lines, from y = 0 downward
        mid = geo.addLine(p[1, 1], p[1, 0])
        side = geo.addLine(p[2, 1], p[2, 0])
        for line, n in ((top0, n_p), (bot0, n_p), (top1, n_out), (bot1, n_out),
                        (axis, n_y), (mid, n_y), (side, n_y)):
            geo.mesh.setTransfiniteCurve(line, n + 1, "Progression", q_fine)
        left = geo.addPlaneSurface([geo.addCurveLoop([-top0, mid, bot0, -axis])])
        right = geo.addPlaneSurface([geo.addCurveLoop([top1, side, -bot1, -mid])])
        for s in (left, right):
            geo.mesh.setTransfiniteSurface(s, "Alternate")
            if quadrilaterals:
                geo.mesh.setRecombine(2, s)
        geo.synchronize()
        _group(gmsh, 2, [left, right], "block", 1)
        for name, curves, tag in (("punch_face", [top0], 11), ("surface", [top1], 12),
                                  ("side", [side], 13), ("bottom", [bot0, bot1], 14),
                                  ("axis", [axis], 15)):
            _group(gmsh, 1, curves, name, tag)
        _generate(gmsh)

    return _to_dolfinx(comm, build, {"scene": "flat_punch_block", "half_width": half_width,
                                     "width": width, "depth": depth, "n_punch": n_punch,
                                     "grading": grading, "refine": refine,
                                     "h_corner": h_corner})


def coaxial_bars(radius: float = 0.1, striker_length: float = 0.8, target_length: float = 0.85,
                 h: float = 0.02, structured: bool = False,
                 comm: MPI.Comm = MPI.COMM_WORLD) -> TaggedMesh:
    """(b) Two coaxial bars touching at z = 0: the striker in z in [-striker_length, 0],
    the target in z in [0, target_length], both of the given radius (m).

    Both contact faces are split into round(radius/h) equal intervals, so their
    nodes pair one to one. Groups: cells "striker", "target"; facets
    "striker_contact", "target_contact", "striker_end", "target_end",
    "striker_lateral", "target_lateral", "axis".
    """
    require(radius > 0 and striker_length > 0 and target_length > 0 and h > 0,
            "coaxial_bars: radius, lengths and h must be > 0 (m)")

    def build(gmsh):
        _two_bars(gmsh, radius, striker_length, target_length, h, h, structured)

    return _to_dolfinx(comm, build, {"scene": "coaxial_bars", "radius": radius, "h": h,
                                     "striker_length": striker_length,
                                     "target_length": target_length})


def _two_bars(gmsh, radius: float, striker_length: float, target_length: float,
              h_striker: float, h_target: float, structured: bool,
              quadrilaterals: bool = False) -> None:
    """The striker [-striker_length, 0] and the target [0, target_length] (m) of radius
    ``radius``, each face with round(radius / h) equal intervals of its body's size h,
    and the groups of :func:`coaxial_bars`; meshed (``quadrilaterals``: each structured
    surface recombined into quadrilaterals)."""
    s1, c1 = _rectangle(gmsh, 0.0, -striker_length, radius, 0.0, h_striker,
                        n_r=max(1, int(round(radius / h_striker))), structured=structured)
    s2, c2 = _rectangle(gmsh, 0.0, 0.0, radius, target_length, h_target,
                        n_r=max(1, int(round(radius / h_target))), structured=structured)
    if quadrilaterals:
        for s in (s1, s2):
            gmsh.model.geo.mesh.setRecombine(2, s)
        gmsh.model.geo.synchronize()
    _group(gmsh, 2, [s1], "striker", 1)
    _group(gmsh, 2, [s2], "target", 2)
    for name, curves, tag in (("striker_end", [c1[0]], 11), ("striker_lateral", [c1[1]], 12),
                              ("striker_contact", [c1[2]], 13), ("target_contact", [c2[0]], 14),
                              ("target_lateral", [c2[1]], 15), ("target_end", [c2[2]], 16),
                              ("axis", [c1[3], c2[3]], 17)):
        _group(gmsh, 1, curves, name, tag)
    _generate(gmsh)


def coaxial_bars_sized(radius: float = 0.05, striker_length: float = 0.2,
                       target_length: float = 0.2, h_striker: float = 0.01,
                       h_target: float = 0.01 * 2 / 3, structured: bool = True,
                       quadrilaterals: bool = False,
                       comm: MPI.Comm = MPI.COMM_WORLD) -> TaggedMesh:
    """Two coaxial bars touching at z = 0 with their own element sizes (m): the striker
    in z in [-striker_length, 0] (size h_striker), the target in [0, target_length]
    (size h_target). Each face has round(radius/h) equal intervals, so with unequal
    sizes (e.g. 3:2) the contact faces do not match node to node (node-to-segment
    contact). Groups as :func:`coaxial_bars`. ``quadrilaterals`` (with ``structured``):
    Q1 cells, for finite-strain bodies.
    """
    require(radius > 0 and striker_length > 0 and target_length > 0 and h_striker > 0
            and h_target > 0, "coaxial_bars_sized: radius, lengths and sizes must be > 0 (m)")
    require(structured or not quadrilaterals,
            "coaxial_bars_sized: quadrilaterals need the structured mesh")

    def build(gmsh):
        _two_bars(gmsh, radius, striker_length, target_length, h_striker, h_target, structured,
                  quadrilaterals)

    return _to_dolfinx(comm, build, {"scene": "coaxial_bars_sized", "radius": radius,
                                     "h_striker": h_striker, "h_target": h_target,
                                     "striker_length": striker_length,
                                     "target_length": target_length})


def nosed_striker_on_block(nose_radius: float = 0.02, shank_length: float = 0.03,
                           block_width: float = 0.06, block_depth: float = 0.04,
                           h_striker: float = 0.02 / 8, h_block: float = 0.02 / 12,
                           comm: MPI.Comm = MPI.COMM_WORLD) -> TaggedMesh:
    """(c) A striker of radius ``nose_radius`` (m) with a hemispherical nose touching a flat
    block at the axis: the nose centre at (0, nose_radius), the shank above it up to
    z = nose_radius + shank_length; the block r in [0, block_width], z in [-block_depth, 0],
    its top split at r = nose_radius. Element sizes h_striker and h_block (m) differ, so
    the faces do not match.

    Groups: cells "striker", "block"; facets "nose", "striker_lateral", "striker_end",
    "block_contact" (the top under the nose, r <= nose_radius), "block_top" (the rest),
    "block_lateral", "block_bottom", "axis".
    """
    require(nose_radius > 0 and shank_length > 0 and block_depth > 0 and h_striker > 0
            and h_block > 0, "nosed_striker_on_block: lengths and sizes must be > 0 (m)")
    require(block_width > nose_radius, "nosed_striker_on_block: the block must be wider "
                                       "than the striker")

    def build(gmsh):
        geo = gmsh.model.geo
        R, top = nose_radius, nose_radius + shank_length
        tip, centre = geo.addPoint(0, 0, 0, h_striker), geo.addPoint(0, R, 0, h_striker)
        rim, shoulder = geo.addPoint(R, R, 0, h_striker), geo.addPoint(R, top, 0, h_striker)
        crown = geo.addPoint(0, top, 0, h_striker)
        nose = geo.addCircleArc(tip, centre, rim)
        lateral, end = geo.addLine(rim, shoulder), geo.addLine(shoulder, crown)
        axis_s = geo.addLine(crown, tip)
        striker = geo.addPlaneSurface([geo.addCurveLoop([nose, lateral, end, axis_s])])
        b = [geo.addPoint(0, 0, 0, h_block), geo.addPoint(R, 0, 0, h_block),
             geo.addPoint(block_width, 0, 0, h_block),
             geo.addPoint(block_width, -block_depth, 0, h_block),
             geo.addPoint(0, -block_depth, 0, h_block)]
        lines = [geo.addLine(b[k], b[(k + 1) % 5]) for k in range(5)]
        block = geo.addPlaneSurface([geo.addCurveLoop(lines)])
        geo.synchronize()
        _group(gmsh, 2, [striker], "striker", 1)
        _group(gmsh, 2, [block], "block", 2)
        for name, curves, tag in (("nose", [nose], 11), ("striker_lateral", [lateral], 12),
                                  ("striker_end", [end], 13), ("block_contact", [lines[0]], 14),
                                  ("block_top", [lines[1]], 15), ("block_lateral", [lines[2]], 16),
                                  ("block_bottom", [lines[3]], 17),
                                  ("axis", [axis_s, lines[4]], 18)):
            _group(gmsh, 1, curves, name, tag)
        _generate(gmsh)

    return _to_dolfinx(comm, build, {"scene": "nosed_striker_on_block",
                                     "nose_radius": nose_radius, "h_striker": h_striker,
                                     "h_block": h_block})


def shpb(bar_diameter: float = 0.02, striker_length: float = 0.2, incident_length: float = 1.0,
         transmitter_length: float = 0.6, specimen_diameter: float = 0.01,
         specimen_length: float = 0.005, h_bar: float = 0.001, h_specimen: float = 0.00025,
         structured: bool = True, bar_yield_stress: float | None = None,
         quadrilaterals: bool = False, comm: MPI.Comm = MPI.COMM_WORLD) -> TaggedMesh:
    """A split Hopkinson pressure bar on the axis (m): the striker z in [-striker_length, 0],
    the incident bar [0, L_i], the specimen [L_i, L_i + L_s] and the transmitter bar
    [L_i + L_s, L_i + L_s + L_t], L_i = incident_length, L_s = specimen_length,
    L_t = transmitter_length. The striker and the bars have the diameter ``bar_diameter``
    and the element size ``h_bar``, the specimen ``specimen_diameter`` (at most the bars')
    and ``h_specimen``; each face has round(radius / h) equal intervals, so the striker and
    the incident bar pair node to node and the specimen's faces (finer) take node-to-segment
    contact on the bars' ends.

    Groups: cells "striker", "incident", "specimen", "transmitter"; facets "striker_end",
    "striker_face", "incident_struck", "incident_face", "specimen_front", "specimen_back",
    "transmitter_face", "transmitter_end", "lateral" (every body's), "axis".

    ``quadrilaterals`` (with ``structured``): each body's structured grid recombined into
    Q1 cells (a finite-strain specimen needs them; the bars are small strain on Q1).

    ``bar_yield_stress`` (Pa) shapes nothing: the scene's check of the bars' stress
    (:func:`impact_fenics.shpb.run_analysis.bar_stress_warning`) reads it from the same table.
    """
    require(min(bar_diameter, striker_length, incident_length, transmitter_length,
                specimen_diameter, specimen_length, h_bar, h_specimen) > 0,
            "shpb: diameters, lengths and sizes must be > 0 (m)")
    require(structured or not quadrilaterals, "shpb: quadrilaterals need the structured mesh")
    require(specimen_diameter <= bar_diameter, f"shpb: specimen_diameter = {specimen_diameter} m "
            f"is larger than bar_diameter = {bar_diameter} m: the specimen must sit on the bars' ends")
    a, b = 0.5 * bar_diameter, 0.5 * specimen_diameter
    z = (-striker_length, 0.0, incident_length, incident_length + specimen_length,
         incident_length + specimen_length + transmitter_length)

    def build(gmsh):
        curves = []
        for k, (name, radius, h) in enumerate((("striker", a, h_bar), ("incident", a, h_bar),
                                               ("specimen", b, h_specimen),
                                               ("transmitter", a, h_bar))):
            s, c = _rectangle(gmsh, 0.0, z[k], radius, z[k + 1], h,
                              n_r=max(1, int(round(radius / h))), structured=structured)
            if quadrilaterals:
                gmsh.model.geo.mesh.setRecombine(2, s)
                gmsh.model.geo.synchronize()
            _group(gmsh, 2, [s], name, k + 1)
            curves.append(c)
        (s_, i_, p_, t_) = curves
        for tag, (name, lines) in enumerate((
                ("striker_end", [s_[0]]), ("striker_face", [s_[2]]),
                ("incident_struck", [i_[0]]), ("incident_face", [i_[2]]),
                ("specimen_front", [p_[0]]), ("specimen_back", [p_[2]]),
                ("transmitter_face", [t_[0]]), ("transmitter_end", [t_[2]]),
                ("lateral", [c[1] for c in curves]), ("axis", [c[3] for c in curves])), 11):
            _group(gmsh, 1, lines, name, tag)
        _generate(gmsh)

    return _to_dolfinx(comm, build, {"scene": "shpb", "bar_radius": a, "specimen_radius": b,
                                     "h_bar": h_bar, "h_specimen": h_specimen,
                                     "striker_length": striker_length,
                                     "incident_length": incident_length,
                                     "specimen_length": specimen_length,
                                     "transmitter_length": transmitter_length})


# Surface intervals of the punch block: breaks at r = 1, 3, 6 m with 106, 201 and
# 302 intervals give 107, 308 and 610 surface nodes with r <= 1, 3 and 6 m.
PUNCH_SURFACE_BREAKS = ((1.0, 106), (3.0, 201), (6.0, 302))


def punch_block(width: float = 6.9, depth: float = 0.45, h_surface: float = 0.01,
                grading: float = 0.055, h_max: float = 0.25,
                breaks: tuple[tuple[float, int], ...] = PUNCH_SURFACE_BREAKS,
                comm: MPI.Comm = MPI.COMM_WORLD) -> TaggedMesh:
    """(c) The indented block r in [0, width], z in [-depth, 0] (m).

    The surface z = 0 is split at the radii of ``breaks`` with the given numbers
    of equal intervals (about h_surface each); beyond the last break, and with
    depth, the element size grows as h_surface + grading * distance from the
    contact surface, up to h_max. Groups: cells "block"; facets "surface"
    (z = 0), "axis" (r = 0), "far" (r = width), "bottom" (z = -depth).
    """
    r_last = breaks[-1][0]
    require(width > r_last and depth > 0 and h_surface > 0,
            f"punch_block: need width > {r_last} m and depth, h_surface > 0")

    def build(gmsh):
        s, surface, far, bottom, axis = _block_outline(gmsh, [b[0] for b in breaks], width,
                                                       depth, h_surface, h_max)
        gmsh.model.geo.synchronize()
        for curve, (_, n) in zip(surface, breaks):
            gmsh.model.mesh.setTransfiniteCurve(curve, n + 1)
        _graded_size(gmsh, surface[:len(breaks)], h_surface, grading, h_max)
        _group(gmsh, 2, [s], "block", 1)
        _group(gmsh, 1, surface, "surface", 11)
        _group(gmsh, 1, [axis], "axis", 12)
        _group(gmsh, 1, [far], "far", 13)
        _group(gmsh, 1, [bottom], "bottom", 14)
        gmsh.option.setNumber("Mesh.Algorithm", 5)
        gmsh.model.mesh.generate(2)

    return _to_dolfinx(comm, build, {"scene": "punch_block", "width": width, "depth": depth,
                                     "h_surface": h_surface, "grading": grading})


def punch_on_block(punch_radius: float = 1.0, punch_height: float = 0.05, width: float = 6.9,
                   depth: float = 0.45, h_surface: float = 0.01, grading: float = 0.055,
                   h_max: float = 0.25, breaks: tuple[tuple[float, int], ...] = PUNCH_SURFACE_BREAKS,
                   comm: MPI.Comm = MPI.COMM_WORLD) -> TaggedMesh:
    """(d) A deformable punch cylinder resting on the block of :func:`punch_block`.

    The block is meshed exactly as by :func:`punch_block` with the same arguments
    (same surface breaks, size field and algorithm); ``punch_radius`` (m) must be
    one of the break radii. The punch r in [0, punch_radius], z in [0,
    punch_height] (m) is a structured grid of alternating diagonals whose bottom
    face has the same intervals as the block surface under it, so the two faces
    pair node to node (its nodes coincide with the block's but are distinct).

    Groups: cells "block", "punch"; facets "contact" (block surface r <=
    punch_radius), "surface" (the rest of the block surface), "punch_contact"
    (punch bottom), "punch_top", "punch_lateral", "axis" (both bodies), "far",
    "bottom".
    """
    radii_b = [b[0] for b in breaks]
    require(width > radii_b[-1] and depth > 0 and h_surface > 0 and punch_height > 0,
            f"punch_on_block: need width > {radii_b[-1]} m and depth, h_surface, punch_height > 0")
    require(any(abs(punch_radius - r) <= 1e-12 * max(1.0, r) for r in radii_b),
            f"punch_on_block: punch_radius = {punch_radius} m must be one of the break radii "
            f"{radii_b} (the faces pair node to node)")
    k_punch = next(k for k, r in enumerate(radii_b) if abs(punch_radius - r) <= 1e-12 * max(1.0, r))

    def build(gmsh):
        s, surface, far, bottom, axis = _block_outline(gmsh, radii_b, width, depth, h_surface,
                                                       h_max)
        geo = gmsh.model.geo
        # the punch: its own points on z = 0 (coincident with the block's, not shared)
        n_r = sum(n for _, n in breaks[:k_punch + 1])
        n_z = max(1, int(round(punch_height / (punch_radius / n_r))))
        q = [geo.addPoint(0.0, 0.0, 0.0, h_surface), geo.addPoint(punch_radius, 0.0, 0.0, h_surface),
             geo.addPoint(punch_radius, punch_height, 0.0, h_surface),
             geo.addPoint(0.0, punch_height, 0.0, h_surface)]
        pc = [geo.addLine(q[0], q[1]), geo.addLine(q[1], q[2]), geo.addLine(q[2], q[3]),
              geo.addLine(q[3], q[0])]
        sp = geo.addPlaneSurface([geo.addCurveLoop(pc)])
        geo.synchronize()
        for curve, (_, n) in zip(surface, breaks):
            gmsh.model.mesh.setTransfiniteCurve(curve, n + 1)
        # the punch bottom: equal intervals, as many as the block surface under it has;
        # pairing needs equal node radii, so the block curves under the punch must have
        # equal spacing too: one break (or breaks of equal spacing) under the punch
        spacing = {round((r1 - r0) / n, 14) for (r0, (r1, n)) in
                   zip([0.0] + radii_b[:k_punch], breaks[:k_punch + 1])}
        if len(spacing) > 1:
            raise InputError("punch_on_block: the block surface under the punch must have "
                             "equal intervals (one break up to punch_radius)")
        for curve, n in ((pc[0], n_r), (pc[2], n_r), (pc[1], n_z), (pc[3], n_z)):
            gmsh.model.mesh.setTransfiniteCurve(curve, n + 1)
        gmsh.model.mesh.setTransfiniteSurface(sp, "Alternate")
        _graded_size(gmsh, surface[:len(breaks)], h_surface, grading, h_max)
        _group(gmsh, 2, [s], "block", 1)
        _group(gmsh, 2, [sp], "punch", 2)
        _group(gmsh, 1, surface[:k_punch + 1], "contact", 11)
        _group(gmsh, 1, surface[k_punch + 1:], "surface", 12)
        _group(gmsh, 1, [axis, pc[3]], "axis", 13)
        _group(gmsh, 1, [far], "far", 14)
        _group(gmsh, 1, [bottom], "bottom", 15)
        _group(gmsh, 1, [pc[0]], "punch_contact", 16)
        _group(gmsh, 1, [pc[1]], "punch_lateral", 17)
        _group(gmsh, 1, [pc[2]], "punch_top", 18)
        gmsh.option.setNumber("Mesh.Algorithm", 5)
        gmsh.model.mesh.generate(2)

    return _to_dolfinx(comm, build, {"scene": "punch_on_block", "width": width, "depth": depth,
                                     "h_surface": h_surface, "grading": grading,
                                     "punch_radius": punch_radius, "punch_height": punch_height})


def wedge_half_width(wedge_angle: float, tip_radius: float, wedge_height: float) -> float:
    """The half width (m) at the top of the wedge of :func:`wedge_on_block`: the flank,
    tangent to the tip's circle at x = R cos(a), y = R (1 - sin a) (a the half angle),
    rises to y = wedge_height at x = R cos a + (wedge_height - R (1 - sin a)) tan a."""
    a = math.radians(0.5 * wedge_angle)
    return tip_radius * math.cos(a) + (wedge_height - tip_radius * (1.0 - math.sin(a))) * math.tan(a)


def wedge_on_block(wedge_angle: float = 90.0, tip_radius: float = 0.0005,
                   wedge_height: float = 0.01, block_width: float = 0.02,
                   block_depth: float = 0.01, h_wedge: float = 0.00025,
                   h_block: float = 0.00025, comm: MPI.Comm = MPI.COMM_WORLD) -> TaggedMesh:
    """The half section (x >= 0, a symmetry plane on x = 0) of a deformable wedge bit of
    included angle ``wedge_angle`` (deg) whose round tip (radius ``tip_radius``, m)
    touches a block at the origin, for a plane-strain scene with ``symmetry = "x=0"``.

    The wedge: the tip's arc, centred at (0, R), from the tip (0, 0) to where the flank
    (at half the angle from the y axis) is tangent to it, the flank up to y =
    ``wedge_height`` (half width :func:`wedge_half_width` there), its top and x = 0. The
    block x in [0, block_width], y in [-block_depth, 0], its top split at the wedge's half
    width. Triangles (P1) of sizes h_wedge and h_block (m), unstructured.

    Groups: cells "wedge", "block"; facets "wedge_face" (the arc and the flank),
    "wedge_top" (y = wedge_height), "block_contact" (the top under the wedge),
    "block_top" (the rest of the top), "block_side" (x = block_width), "block_bottom"
    (y = -block_depth), "axis" (x = 0, both bodies).
    """
    require(0.0 < wedge_angle < 180.0, f"wedge_on_block: wedge_angle = {wedge_angle} deg must "
            "be in (0, 180)")
    require(tip_radius > 0 and wedge_height > 0 and block_depth > 0 and h_wedge > 0
            and h_block > 0, "wedge_on_block: tip_radius, wedge_height, block_depth and the "
                             "sizes must be > 0 (m)")
    a = math.radians(0.5 * wedge_angle)
    require(wedge_height > tip_radius * (1.0 - math.sin(a)), "wedge_on_block: wedge_height "
            f"= {wedge_height} m must reach above the tip's arc, R (1 - sin(angle/2)) = "
            f"{tip_radius * (1.0 - math.sin(a)):.6g} m")
    half = wedge_half_width(wedge_angle, tip_radius, wedge_height)
    require(block_width > half, f"wedge_on_block: block_width = {block_width} m must exceed "
            f"the wedge's half width {half:.6g} m")

    def build(gmsh):
        geo = gmsh.model.geo
        R = tip_radius
        tip, centre = geo.addPoint(0, 0, 0, h_wedge), geo.addPoint(0, R, 0, h_wedge)
        tangent = geo.addPoint(R * math.cos(a), R * (1.0 - math.sin(a)), 0, h_wedge)
        shoulder = geo.addPoint(half, wedge_height, 0, h_wedge)
        crown = geo.addPoint(0, wedge_height, 0, h_wedge)
        arc = geo.addCircleArc(tip, centre, tangent)
        flank, top = geo.addLine(tangent, shoulder), geo.addLine(shoulder, crown)
        axis_w = geo.addLine(crown, tip)
        wedge = geo.addPlaneSurface([geo.addCurveLoop([arc, flank, top, axis_w])])
        block, lines = _block_split_top(geo, half, block_width, block_depth, h_block)
        geo.synchronize()
        _group(gmsh, 2, [wedge], "wedge", 1)
        _group(gmsh, 2, [block], "block", 2)
        for name, curves, tag in (("wedge_face", [arc, flank], 11), ("wedge_top", [top], 12),
                                  ("block_contact", [lines[0]], 13),
                                  ("block_top", [lines[1]], 14), ("block_side", [lines[2]], 15),
                                  ("block_bottom", [lines[3]], 16),
                                  ("axis", [axis_w, lines[4]], 17)):
            _group(gmsh, 1, curves, name, tag)
        _generate(gmsh)

    return _to_dolfinx(comm, build, {"scene": "wedge_on_block", "wedge_angle": wedge_angle,
                                     "tip_radius": tip_radius, "wedge_height": wedge_height,
                                     "half_width": half, "h_wedge": h_wedge, "h_block": h_block})


def cylinder_on_block(radius: float = 0.01, gap: float = 0.0, block_width: float = 0.01,
                      block_depth: float = 0.01, h_contact: float = 0.0001,
                      h_far: float = 0.001, contact_zone: float = 0.001,
                      contact_angle: float = 30.0, quarter: bool = False, block: bool = True,
                      comm: MPI.Comm = MPI.COMM_WORLD) -> TaggedMesh:
    """The half section (x >= 0, a symmetry plane on x = 0) of a long cylinder of radius
    ``radius`` (m) whose lowest line (0, gap) is ``gap`` (m) above a block x in
    [0, block_width], y in [-block_depth, 0], for a plane-strain scene with
    ``symmetry = "x=0"``; node to segment ready (the cylinder's contact arc and the
    block's top are facet groups of their own, on nodes of their own).

    The cylinder, centred at (0, R + gap): its arc from the lowest point up to
    ``contact_angle`` (deg) from it ("cylinder_contact"), the rest of the arc
    ("cylinder_arc") up to the top (0, 2R + gap), and x = 0; with ``quarter`` only the
    quarter below its diametral plane y = R + gap (a face "cylinder_top" there, to load
    it). Triangles (P1), unstructured: size h_contact (m) within ``contact_zone`` (m) of
    the lowest point and of the block's top under it, growing to h_far (m) over 20 h_far.
    Without ``block`` the cylinder alone (on a wall, say).

    Groups: cells "cylinder" (and "block"); facets "cylinder_contact", "cylinder_arc",
    "cylinder_top" (with ``quarter``), "axis" (x = 0, both bodies), "block_top"
    (y = 0), "block_side" (x = block_width), "block_bottom" (y = -block_depth).
    """
    _cylinder_refusals(radius, gap, block_width, block_depth, h_contact, h_far, contact_zone,
                       contact_angle, block)
    a = math.radians(contact_angle)
    R, y0 = radius, gap

    def build(gmsh):
        geo = gmsh.model.geo
        tip = geo.addPoint(0.0, y0, 0.0, h_contact)
        centre = geo.addPoint(0.0, y0 + R, 0.0, h_far)
        mid = geo.addPoint(R * math.sin(a), y0 + R * (1 - math.cos(a)), 0.0, h_far)
        side = geo.addPoint(R, y0 + R, 0.0, h_far)
        near = geo.addCircleArc(tip, centre, mid)
        far = [geo.addCircleArc(mid, centre, side)]
        if quarter:
            top = geo.addLine(side, centre)
            axis = geo.addLine(centre, tip)
            loop = [near] + far + [top, axis]
        else:
            crown = geo.addPoint(0.0, y0 + 2 * R, 0.0, h_far)
            far.append(geo.addCircleArc(side, centre, crown))
            axis = geo.addLine(crown, tip)
            loop = [near] + far + [axis]
        s = geo.addPlaneSurface([geo.addCurveLoop(loop)])
        tips = [tip]
        if block:
            corner = [geo.addPoint(0.0, 0.0, 0.0, h_contact),
                      geo.addPoint(block_width, 0.0, 0.0, h_far),
                      geo.addPoint(block_width, -block_depth, 0.0, h_far),
                      geo.addPoint(0.0, -block_depth, 0.0, h_far)]
            lines = [geo.addLine(corner[i], corner[(i + 1) % 4]) for i in range(4)]
            s_block = geo.addPlaneSurface([geo.addCurveLoop(lines)])
            tips.append(corner[0])
        geo.synchronize()
        field = gmsh.model.mesh.field
        dist = field.add("Distance")
        field.setNumbers(dist, "PointsList", tips)
        size = field.add("Threshold")
        field.setNumber(size, "InField", dist)
        field.setNumber(size, "SizeMin", h_contact)
        field.setNumber(size, "SizeMax", h_far)
        field.setNumber(size, "DistMin", contact_zone)
        field.setNumber(size, "DistMax", contact_zone + 20 * h_far)
        field.setAsBackgroundMesh(size)
        for option in ("MeshSizeExtendFromBoundary", "MeshSizeFromPoints",
                       "MeshSizeFromCurvature"):
            gmsh.option.setNumber(f"Mesh.{option}", 0)
        _group(gmsh, 2, [s], "cylinder", 1)
        groups = [("cylinder_contact", [near], 11), ("cylinder_arc", far, 12)]
        if quarter:
            groups.append(("cylinder_top", [top], 13))
        groups.append(("axis", [axis] + ([lines[3]] if block else []), 14))
        if block:
            _group(gmsh, 2, [s_block], "block", 2)
            groups += [("block_top", [lines[0]], 15), ("block_bottom", [lines[2]], 16),
                       ("block_side", [lines[1]], 17)]
        for name, curves, tag in groups:
            _group(gmsh, 1, curves, name, tag)
        _generate(gmsh)

    return _to_dolfinx(comm, build, {"scene": "cylinder_on_block", "radius": radius,
                                     "gap": gap, "h_contact": h_contact, "h_far": h_far})


def _cylinder_refusals(radius, gap, block_width, block_depth, h_contact, h_far, contact_zone,
                       contact_angle, block=True) -> None:
    """The one-line refusals of :func:`cylinder_on_block`'s sizes (m) and angle (deg)."""
    require(radius > 0 and h_contact > 0 and h_far > 0 and contact_zone > 0,
            "cylinder_on_block: radius, h_contact, h_far and contact_zone must be > 0 (m)")
    require(gap >= 0, f"cylinder_on_block: gap = {gap} m must be >= 0")
    require(0.0 < contact_angle < 90.0, f"cylinder_on_block: contact_angle = {contact_angle} "
            "deg must be in (0, 90)")
    require(h_contact <= h_far < radius, f"cylinder_on_block: the sizes must satisfy h_contact "
            f"({h_contact} m) <= h_far ({h_far} m) < radius ({radius} m)")
    if block:
        require(block_depth > 0, f"cylinder_on_block: block_depth = {block_depth} m must be > 0")
        arc = radius * math.sin(math.radians(contact_angle))
        require(block_width > arc, f"cylinder_on_block: block_width = {block_width} m must "
                f"exceed the contact arc's half width R sin(contact_angle) = {arc:.6g} m")


def check_generator(generator: str, params: dict) -> None:
    """Refuse bad parameters ``params`` (a scene's; the generator's defaults fill the rest)
    of :func:`cylinder_on_block` or :func:`striker_on_plate` in one line, before any mesh
    is made."""
    import inspect

    function, refusals = {"cylinder_on_block": (cylinder_on_block, _cylinder_refusals),
                          "striker_on_plate": (striker_on_plate, _striker_refusals)}[generator]
    p = {k: v.default for k, v in inspect.signature(function).parameters.items()
         if k != "comm"}
    p.update(params)
    names = [k for k in inspect.signature(refusals).parameters]
    refusals(**{k: p[k] for k in names})


def striker_on_plate(striker_half_width: float = 0.002, striker_length: float = 0.01,
                     gap: float = 0.0, plate_half_span: float = 0.02,
                     plate_thickness: float = 0.002, h_striker: float = 0.0005,
                     h_plate: float = 0.00025, comm: MPI.Comm = MPI.COMM_WORLD) -> TaggedMesh:
    """The half section (x >= 0, a symmetry plane on x = 0) of a flat-ended striker across
    a plate, for a plane-strain scene with ``symmetry = "x=0"``: the striker x in
    [0, striker_half_width], y in [gap, gap + striker_length], over the plate x in
    [0, plate_half_span], y in [-plate_thickness, 0] (m), on nodes of their own (node to
    segment or node pairs ready). Triangles (P1) of sizes h_striker and h_plate (m),
    unstructured; the plate's top split at the striker's half width.

    Groups: cells "striker", "plate"; facets "striker_face" (y = gap), "striker_top",
    "striker_side" (x = striker_half_width), "plate_contact" (the top under the striker),
    "plate_top" (the rest of the top), "plate_bottom" (y = -plate_thickness),
    "plate_end" (x = plate_half_span), "axis" (x = 0, both bodies).
    """
    _striker_refusals(striker_half_width, striker_length, gap, plate_half_span,
                      plate_thickness, h_striker, h_plate)

    def build(gmsh):
        geo = gmsh.model.geo
        w, y0, y1 = striker_half_width, gap, gap + striker_length
        s = [geo.addPoint(0, y0, 0, h_striker), geo.addPoint(w, y0, 0, h_striker),
             geo.addPoint(w, y1, 0, h_striker), geo.addPoint(0, y1, 0, h_striker)]
        c = [geo.addLine(s[k], s[(k + 1) % 4]) for k in range(4)]  # face, side, top, axis
        striker = geo.addPlaneSurface([geo.addCurveLoop(c)])
        plate, lines = _block_split_top(geo, w, plate_half_span, plate_thickness, h_plate)
        geo.synchronize()
        _group(gmsh, 2, [striker], "striker", 1)
        _group(gmsh, 2, [plate], "plate", 2)
        for name, curves, tag in (("striker_face", [c[0]], 11), ("striker_side", [c[1]], 12),
                                  ("striker_top", [c[2]], 13), ("plate_contact", [lines[0]], 14),
                                  ("plate_top", [lines[1]], 15), ("plate_end", [lines[2]], 16),
                                  ("plate_bottom", [lines[3]], 17),
                                  ("axis", [c[3], lines[4]], 18)):
            _group(gmsh, 1, curves, name, tag)
        _generate(gmsh)

    return _to_dolfinx(comm, build, {"scene": "striker_on_plate", "h_striker": h_striker,
                                     "h_plate": h_plate})


def _striker_refusals(striker_half_width, striker_length, gap, plate_half_span,
                      plate_thickness, h_striker, h_plate) -> None:
    """The one-line refusals of :func:`striker_on_plate`'s sizes (m)."""
    require(striker_half_width > 0 and striker_length > 0 and plate_half_span > 0
            and plate_thickness > 0 and h_striker > 0 and h_plate > 0,
            "striker_on_plate: the widths, lengths, thickness and sizes must be > 0 (m)")
    require(gap >= 0, f"striker_on_plate: gap = {gap} m must be >= 0")
    require(plate_half_span > striker_half_width, f"striker_on_plate: plate_half_span = "
            f"{plate_half_span} m must exceed striker_half_width = {striker_half_width} m")
