"""One gmsh model of triangles and quadrilaterals read as one mesh per cell type.

dolfinx's gmsh reader takes one cell type (0.5 crashes on two, 0.11 builds a
mixed-topology mesh the solver cannot use). The model is written once (rank 0), and
for each cell type reopened with the other type's surfaces removed
(``gmsh.model.removeEntities(..., recursive=True)``: their interiors, and the curves
and points that bound no kept surface), the physical groups left empty dropped, and
nodes and elements numbered anew (the reader reads node tags 1..N). Each mesh keeps
the cell groups it holds and the facet groups that bound its cells, by name; a curve
between two surfaces of different types (a named interface) is a facet group of both
meshes. A cell group holding both types is refused: a body lives on one mesh.

A model of one cell type is read as :func:`meshing._to_dolfinx` reads it: the same
single mesh, from the same model, with no file written.
"""
from __future__ import annotations

import os
import shutil
import tempfile

import numpy as np
from mpi4py import MPI

from . import meshing
from .compat import model_to_mesh
from .errors import InputError, require
from .meshing import TaggedMesh

CELL_NAMES = {3: "triangle", 4: "quadrilateral"}  # corners of a first-order cell -> name


def load_msh_meshes(path: str, comm: MPI.Comm = MPI.COMM_WORLD) -> list[TaggedMesh]:
    """Read a 2D .msh file (r = x, z = y) into one :class:`TaggedMesh` per cell type,
    triangles first; a file of one cell type gives the one mesh of ``load_msh``."""
    require(os.path.isfile(path), f"mesh file '{path}' does not exist")

    def build(gmsh):
        meshing._open_msh(gmsh, path, mixed=True)

    return to_dolfinx_meshes(comm, build, {"source": os.path.abspath(path)},
                             where=f"mesh file '{path}'")


def to_dolfinx_meshes(comm: MPI.Comm, build, info: dict,
                      where: str = "the mesh") -> list[TaggedMesh]:
    """Run ``build(gmsh)`` on rank 0 (it must leave a meshed model) and read it on every
    rank as one mesh per cell type; ``where`` names the model in errors."""
    gmsh = meshing._gmsh()
    plan, error, folder = None, None, None
    if comm.rank == 0:
        meshing._fresh_model(gmsh)
        try:
            build(gmsh)
            kinds = _kinds(gmsh, where)
            plan = [None]
            if len(kinds) > 1:
                folder = tempfile.mkdtemp(prefix="impact_fenics_split_")
                _write(gmsh, os.path.join(folder, "model.msh"))
                plan = [(kind, CELL_NAMES[_corners(gmsh, kind)]) for kind in kinds]
        except InputError as exc:
            error = str(exc)
        except Exception as exc:  # gmsh raises plain Exceptions for unreadable files
            error = f"mesh could not be built or read: {exc}"
    meshes = []
    try:
        plan, error = comm.bcast((plan, error), root=0)
        if error is not None:
            if comm.rank == 0:
                meshing._restart_gmsh()  # a failed read can leave gmsh's model list broken
            raise InputError(error)
        for kind in plan:
            meshes.append(_read(comm, gmsh, kind, folder, info, where))
    finally:
        if folder is not None:
            shutil.rmtree(folder, ignore_errors=True)
    return meshes


def _read(comm: MPI.Comm, gmsh, kind: tuple[int, str] | None, folder: str | None,
          info: dict, where: str) -> TaggedMesh:
    """The mesh of the cells of ``kind`` (gmsh's element type and its name; None: the
    model as built), on every rank."""
    names, error = None, None
    if comm.rank == 0:
        try:
            if kind is not None:
                gmsh.clear()
                gmsh.open(os.path.join(folder, "model.msh"))
                _keep_only(gmsh, kind[0], where)
            names = meshing._physical_names(gmsh)
            if not names[0]:
                error = f"{where} has no physical group of cells (dimension 2)"
        except InputError as exc:
            error = str(exc)
        except Exception as exc:
            error = f"mesh could not be built or read: {exc}"
    names, error = comm.bcast((names, error), root=0)
    if error is not None:
        if comm.rank == 0:
            meshing._restart_gmsh()  # a failed read can leave gmsh's model list broken
        raise InputError(error)
    msh, cell_tags, facet_tags = model_to_mesh(gmsh.model, comm, 0, gdim=2)
    if comm.rank == 0:
        gmsh.model.remove()
    msh.topology.create_connectivity(1, 2)
    if kind is not None:
        info = info | {"cells": kind[1]}
    return TaggedMesh(msh, cell_tags, facet_tags, names[0], names[1], info)


def _corners(gmsh, kind: int) -> int:
    return int(gmsh.model.mesh.getElementProperties(kind)[5])


def _kinds(gmsh, where: str) -> list[int]:
    """The model's first-order cell types (gmsh's), triangles first; refuses second-order
    cells and a cell group of two types, and a mixed model whose surfaces do not know
    their boundaries."""
    meshing._refuse_cell_types(gmsh, where, mixed=True)
    kinds = meshing._cell_kinds(gmsh)
    groups: dict[str, list[int]] = {}
    for kind, names in kinds.items():
        for name in names:
            groups.setdefault(name, []).append(kind)
    for name, held in groups.items():
        if len(held) > 1:
            said = " and ".join(meshing._cell_kind(gmsh, k) for k in sorted(held))
            raise InputError(f"{where}: the cell group '{name}' holds {said}; a body lives on "
                             "one mesh of one cell type: mesh each cell group's surfaces "
                             "with one cell type")
    if len(kinds) > 1:
        blind = [tag for _, tag in gmsh.model.getEntities(2)
                 if len(gmsh.model.mesh.getElementTypes(2, tag))
                 and not gmsh.model.getBoundary([(2, tag)], oriented=False)]
        if blind:
            # a msh 2 file: its surfaces' bounding curves are not stored, so removing a
            # surface cannot tell which curves and nodes go with it
            raise InputError(f"{where} mixes cell types but does not store which curves "
                             f"bound its surfaces ({', '.join(map(str, blind))}), as msh 2 "
                             "files do not: write it in the msh 4 format (gmsh -format msh4)")
    return sorted(kinds, key=lambda kind: _corners(gmsh, kind))


def _write(gmsh, path: str) -> None:
    """The model as a msh 4.1 file, whatever a caller set (the caller's option put back)."""
    version = gmsh.option.getNumber("Mesh.MshFileVersion")
    gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
    try:
        gmsh.write(path)
    finally:
        gmsh.option.setNumber("Mesh.MshFileVersion", version)


def _keep_only(gmsh, kind: int, where: str) -> None:
    """Remove every surface that holds no cell of gmsh type ``kind``, with the curves and
    points that bound no kept surface, and the physical groups left empty; number nodes
    and elements anew (1..N)."""
    model = gmsh.model
    drop = [(2, tag) for _, tag in model.getEntities(2)
            if kind not in model.mesh.getElementTypes(2, tag)]
    model.removeEntities(drop, recursive=True)
    empty = [(dim, tag) for dim, tag in model.getPhysicalGroups()
             if not len(model.getEntitiesForPhysicalGroup(dim, tag))]
    if empty:
        model.removePhysicalGroups(empty)
    model.mesh.renumberNodes()
    model.mesh.renumberElements()
    # what the reader must not see: a kept cell on a node that went with a removed
    # surface, a facet group's line or a point group's point off the kept cells
    tags = model.mesh.getNodes()[0]
    used = [nodes for _, tag in model.getEntities(2) for nodes in model.mesh.getElements(2, tag)[2]]
    if used and not np.isin(np.concatenate(used), tags).all():
        raise InputError(f"{where}: the cells of one type use nodes of the other type's "
                         "surfaces; the model cannot be split by cell type")
    meshing._refuse_lines_off_the_cells(gmsh, where)
    meshing._refuse_points_off_the_cells(gmsh, where)
