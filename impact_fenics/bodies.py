"""Deformable bodies on one mesh: the function space, the parts and the dof maps.

All deformable bodies share one vector space (u_r, u_z) of degree 1: P1 on a mesh of
triangles, Q1 on a mesh of quadrilaterals (the small-strain bodies of a Q1 mesh take
mean dilatation, B-bar: :mod:`.q1`; a finite-strain body, F-bar, needs quadrilaterals). Dof indices here are local, unrolled
(2 * node + component) and, unless said otherwise, owned by this rank: they index the
local arrays of the PETSc vectors directly.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc
from dolfinx import fem, mesh as dmesh

from .compat import vector_space
from .dofs import SceneDofs
from .errors import FINITE_STRAIN_NEEDS_QUADRILATERALS, InputError, require
from .forms import STIFFNESS_DEGREE, Material, Part, cell_measure
from .geometry import AXISYMMETRIC_GEOMETRY, Geometry
from .materials import INTERFACE, interface_of, is_finite, missing_attributes
from .meshing import TaggedMesh

R, Z = 0, 1  # displacement components


@dataclass
class Body:
    """A deformable body: the name of its cell group and its material."""

    name: str
    material: Material


# What the solver reads of a material, per kinematics: materials.INTERFACE
_KIND_WORDS = {"small linear": " linear", "small": " path-dependent", "finite": " finite-strain"}


def check_material(body: Body) -> None:
    """Refuse, in one line naming the class and the attribute, a material that lacks
    what the solver reads of it (materials.INTERFACE of its kinematics)."""
    m = body.material
    missing = missing_attributes(m)
    if missing:
        kind = interface_of(m)
        word = "" if "linear" in missing else _KIND_WORDS[kind]
        raise InputError(f"body '{body.name}': the material {type(m).__name__} has no "
                         f"attribute '{missing[0]}' (a{word} material needs "
                         f"{', '.join(INTERFACE[kind])})")


def check_quadrilateral_material(body: Body) -> None:
    """Refuse, in one line, a linear material whose stress is not a constant map D of the
    strain: the B-bar stiffness of a quadrilateral is built from D, not from a UFL form."""
    from .cell_fields import stiffness_matrix

    m = body.material
    if m.linear and stiffness_matrix(m) is None:
        raise InputError(f"body '{body.name}': the stress of {type(m).__name__} is not a "
                         "constant map of the strain, which a linear body on quadrilaterals "
                         "needs (its B-bar stiffness is built from that map)")


class DeformableModel:
    """The space, the parts and the dof maps of the deformable bodies of a scene, on a
    mesh of triangles or of quadrilaterals (:attr:`quadrilateral`), in the section's
    :attr:`geometry` (axisymmetric, or plane strain of a thickness t: :mod:`.geometry`)."""

    def __init__(self, tmesh: TaggedMesh, bodies: list[Body], degree: int = STIFFNESS_DEGREE,
                 geometry: Geometry = AXISYMMETRIC_GEOMETRY):
        require(len(bodies) > 0, "a scene needs at least one deformable body")
        self.geometry = geometry
        for b in bodies:  # a match to Mohr-Coulomb in plane strain means nothing elsewhere
            require(geometry.plane or getattr(b.material, "match", None) != "plane_strain",
                    f"body '{b.name}': match = \"plane_strain\" (the plane-strain match to "
                    "Mohr-Coulomb) needs geometry = \"plane_strain\" (the model is "
                    "axisymmetric)")
        cell_type = tmesh.mesh.topology.cell_type
        if cell_type not in (dmesh.CellType.triangle, dmesh.CellType.quadrilateral):
            raise InputError(f"the mesh's cells are {cell_type.name}s: small strain runs on "
                             "triangles (P1) and quadrilaterals (Q1)")
        self.quadrilateral = cell_type == dmesh.CellType.quadrilateral
        for b in bodies:
            check_material(b)
            if is_finite(b.material):
                if not self.quadrilateral:
                    raise InputError(f"body '{b.name}': the mesh's cells are triangles: "
                                     f"{FINITE_STRAIN_NEEDS_QUADRILATERALS}")
            elif self.quadrilateral:
                check_quadrilateral_material(b)
        self.tmesh = tmesh
        self.mesh = tmesh.mesh
        self.comm = self.mesh.comm
        self.bodies = {b.name: b for b in bodies}
        self.V = vector_space(self.mesh, "Lagrange", 1)
        # the scene's numbering (one mesh: dolfinx's own) and the dofmap in its local
        # block indices, which every kernel reads
        self.dofs = SceneDofs([self.V])
        self.cell_dofs: np.ndarray = self.dofs.cell_dofs(0)
        self.bs = self.V.dofmap.index_map_bs
        self.n_owned = self.dofs.n_owned
        self._body_blocks: dict[str, np.ndarray] | None = None  # (body_dofs, on first call)
        self.n_global = self.dofs.n_global
        self.offset = self.dofs.offset
        covered = 0
        self.parts: list[Part] = []
        self.part_names: list[str] = [b.name for b in bodies]  # the body of each part
        for b in bodies:
            tag = tmesh.cell_tag(b.name)
            covered += tmesh.cells(b.name).size
            self.parts.append((b.material, cell_measure(self.mesh, tmesh.cell_tags, tag, degree)))
        n_cells = self.mesh.topology.index_map(2).size_local + self.mesh.topology.index_map(2).num_ghosts
        if self.comm.allreduce(int(covered < n_cells)):
            raise InputError("some cells belong to no body: every cell group of the mesh "
                             f"must be a body (bodies given: {', '.join(self.bodies)})")
        # coordinates of the local nodes (owned first, then ghosts), (n_nodes, 2)
        self.node_xy = self.V.tabulate_dof_coordinates()[:, :2].copy()
        self.n_local = self.node_xy.shape[0] * self.bs
        # the model's extent (m), the same on every partition
        lo = self.node_xy.min(axis=0) if self.node_xy.size else np.full(2, np.inf)
        hi = self.node_xy.max(axis=0) if self.node_xy.size else np.full(2, -np.inf)
        self.comm.Allreduce(MPI.IN_PLACE, lo, op=MPI.MIN)
        self.comm.Allreduce(MPI.IN_PLACE, hi, op=MPI.MAX)
        self.length_scale = float(np.max(hi - lo))

    # --------------------------------------------------------------- dof maps
    def _unrolled(self, blocks: np.ndarray, component: int, owned: bool) -> np.ndarray:
        if owned:
            blocks = blocks[blocks < self.n_owned // self.bs]
        return np.sort(blocks * self.bs + component).astype(np.int32)

    def facet_dofs(self, facet_name: str, component: int, owned: bool = True) -> np.ndarray:
        """Unrolled dofs of ``component`` on the facets of group ``facet_name``
        (owned ones, or all local ones with ``owned=False``)."""
        facets = self.tmesh.facets(facet_name)
        if self.comm.allreduce(facets.size) == 0:
            raise InputError(f"facet group '{facet_name}' is empty")
        return self._unrolled(fem.locate_dofs_topological(self.V, 1, facets), component, owned)

    def body_dofs(self, body: str, component: int) -> np.ndarray:
        """Owned unrolled dofs of ``component`` of the nodes of body ``body``: every owned
        node that a cell of the body touches on any rank. Collective on the first call
        (it finds every body's nodes then)."""
        require(body in self.bodies, f"no body named '{body}' (bodies: {', '.join(self.bodies)})")
        if self._body_blocks is None:
            self._body_blocks = self._owned_body_blocks()
        return self._unrolled(self._body_blocks[body], component, owned=True)

    def _owned_body_blocks(self) -> dict[str, np.ndarray]:
        """Per body, the owned nodes (blocks) its cells touch on any rank: 1 on the nodes of
        its owned cells (ghost nodes included), summed into their owners by a reverse
        scatter. A node whose cells of a body all sit on another rank and meet this rank's
        cells at that node only is in none of this rank's cells of the body (ghosting by
        shared facet does not bring them), and still belongs to it. Collective."""
        mark = self.dofs.create_vec()
        out = {}
        for name in self.bodies:
            blocks = self.cell_dofs[self.owned_cells(name)].ravel()
            with mark.localForm() as local:
                local.set(0.0)
                local.array[self.bs * blocks] = 1.0
            mark.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
            out[name] = (np.flatnonzero(mark.array_r[::self.bs] > 0.0)).astype(np.int32)
        mark.destroy()
        return out

    def axis_dofs(self, owned: bool = True) -> np.ndarray:
        """Radial dofs of the nodes on the axis r = 0 (u_r = 0 there); in plane strain the
        x dofs of the nodes on a declared symmetry plane x = 0, and none without one."""
        if not self.geometry.held_first:
            return np.zeros(0, dtype=np.int32)
        tol = 1e-10 * max(self.length_scale, 1e-300)
        return self._unrolled(np.flatnonzero(np.abs(self.node_xy[:, R]) <= tol), R, owned)

    def owned_cells(self, body: str) -> np.ndarray:
        """Local indices of the cells of ``body`` owned by this rank (sorted)."""
        n_owned = self.mesh.topology.index_map(2).size_local
        cells = self.tmesh.cells(body)
        return np.sort(cells[cells < n_owned]).astype(np.int32)

    def part_body(self, part: Part) -> str:
        """The name of the body of ``part`` (one of :attr:`parts`)."""
        for name, p in zip(self.part_names, self.parts):
            if p is part:
                return name
        raise ValueError("not a part of this model")

    def dof_coordinates(self, dofs: np.ndarray) -> np.ndarray:
        """(r, z) in m of the nodes of owned unrolled ``dofs``."""
        return self.node_xy[dofs // self.bs]

    def to_global(self, dofs: np.ndarray) -> np.ndarray:
        """Global (PETSc) indices of owned unrolled ``dofs``."""
        return (dofs + self.offset).astype(np.int32)
