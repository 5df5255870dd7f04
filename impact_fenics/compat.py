"""The one place that knows which FEniCSx it runs on: Debian's dolfinx 0.5.2 or the
current one (0.11 from the PyPI wheels, see scripts/setup_modern.sh).

Every call whose spelling differs between the two goes through a small function
here, so the rest of the package is written once. Nothing else in the package
reads ``dolfinx.__version__`` (``tests/test_compat.py`` checks it). Each function
states both spellings: "0.5:" is Debian's, "0.11:" the current.

Import order: the wheels' dolfinx, petsc4py and slepc4py find ``libmpi`` only
after ``mpi4py.MPI`` has loaded it, so ``impact_fenics/__init__.py`` imports
``mpi4py.MPI`` first (and so does this module).

The launcher differs with the MPI library, not with dolfinx: Debian's stack uses
OpenMPI (``mpirun``, ``OMPI_COMM_WORLD_RANK``, root needs two variables), the
wheels MPICH (``mpiexec`` beside the interpreter, ``PMI_RANK``).
"""
from __future__ import annotations

import os
import sys

from mpi4py import MPI  # before dolfinx/petsc4py: see above

import numpy as np
import dolfinx
import dolfinx.fem.petsc  # noqa: F401  (fem.petsc is a submodule: load it for every user)
from dolfinx import fem, geometry
from dolfinx import io as _io

DOLFINX_VERSION: tuple[int, int] = tuple(int(p) for p in dolfinx.__version__.split(".")[:2])
# 0.5/0.6 spelling (Debian bookworm) against the one from 0.7 on (VectorFunctionSpace,
# BoundingBoxTree, dofmap.list.array, interpolation_points() and Expression.eval(cells)
# changed together in 0.7); the form options were renamed in 0.6.
LEGACY = DOLFINX_VERSION < (0, 7)
_FORM_OPTIONS = DOLFINX_VERSION >= (0, 6)


# --------------------------------------------------------------------- versions
def versions() -> dict[str, str]:
    """The versions of the stack (dolfinx, PETSc, petsc4py, MPI library) for records."""
    import petsc4py
    from petsc4py import PETSc

    return {"dolfinx": dolfinx.__version__,
            "petsc": ".".join(str(v) for v in PETSc.Sys.getVersion()),
            "petsc4py": petsc4py.__version__,
            "mpi": MPI.Get_library_version().replace("\x00", "").splitlines()[0].strip()}


# ------------------------------------------------------------------------ mesh
def model_to_mesh(model, comm: MPI.Comm, rank: int, gdim: int):
    """(mesh, cell_tags, facet_tags) of a gmsh model built on ``rank``.

    0.5: ``io.gmshio.model_to_mesh`` returns that tuple; the mesh is ghosted by shared
    facet (every facet on a rank boundary sees both its cells).
    0.11: ``io.gmsh.model_to_mesh`` returns a named tuple (MeshData) with more fields,
    and without a partitioner the mesh has no ghost cells: one is passed that ghosts
    by shared facet, as on 0.5 (the facet-to-cell links of contact and of the checks
    of facet groups rely on it)."""
    if hasattr(_io, "gmsh") and hasattr(_io.gmsh, "model_to_mesh"):
        from dolfinx import mesh as _mesh

        partitioner = _mesh.create_cell_partitioner(_mesh.GhostMode.shared_facet, 2)
        data = _io.gmsh.model_to_mesh(model, comm, rank, gdim=gdim, partitioner=partitioner)
        if hasattr(data, "facet_tags"):
            return data.mesh, data.cell_tags, data.facet_tags
        return tuple(data)[:3]
    from dolfinx.io import gmshio

    msh, cell_tags, facet_tags = gmshio.model_to_mesh(model, comm, rank, gdim=gdim)
    return msh, cell_tags, facet_tags


def partitioner_on_fewer_ranks(fewer: int = 1):
    """A cell partitioner (for ``create_rectangle``, ``create_mesh``) that gives a mesh to
    ranks 0 .. size - 1 - ``fewer`` only: dolfinx's own (ghosting by shared facet; on
    0.5 by the mesh's ghost mode, shared facet by default) asked for ``fewer`` parts
    less. The last ``fewer`` ranks hold none of its cells: an empty share, which every
    piece of a scene must take.

    0.5: ``create_cell_partitioner()``, called as (comm, n_parts, tdim, cells, ghost_mode).
    0.11: ``create_cell_partitioner(ghost_mode, max_facet_to_cell_links)``, called as
    (comm, n_parts, cell_types, cells)."""
    from dolfinx import mesh as _mesh

    if LEGACY:
        base = _mesh.create_cell_partitioner()
    else:
        base = _mesh.create_cell_partitioner(_mesh.GhostMode.shared_facet, 2)

    def partition(comm, n_parts, *rest):
        if n_parts <= fewer:
            raise ValueError(f"a mesh on {n_parts} ranks cannot leave {fewer} of them empty")
        return base(comm, n_parts - fewer, *rest)
    return partition


def colliding_cells(mesh, x: np.ndarray):
    """Adjacency list point -> local cells that contain it; ``x`` is (n, 3) in m.

    0.5: ``BoundingBoxTree(mesh, tdim)`` + ``compute_collisions(tree, x)``.
    0.11: ``bb_tree(mesh, tdim)`` + ``compute_collisions_points(tree, x)``."""
    tdim = mesh.topology.dim
    if LEGACY:
        tree = geometry.BoundingBoxTree(mesh, tdim)
        candidates = geometry.compute_collisions(tree, x)
    else:
        tree = geometry.bb_tree(mesh, tdim)
        candidates = geometry.compute_collisions_points(tree, x)
    return geometry.compute_colliding_cells(mesh, candidates, x)


# ---------------------------------------------------------------------- spaces
def vector_space(mesh, family: str = "Lagrange", degree: int = 1, dim: int = 2):
    """The ``dim``-component space of ``family`` ("Lagrange" or "DG") and ``degree``.

    0.5: ``fem.VectorFunctionSpace(mesh, (family, degree))``.
    0.11: ``fem.functionspace(mesh, (family, degree, (dim,)))``."""
    if LEGACY:
        return fem.VectorFunctionSpace(mesh, (family, degree), dim=dim)
    return fem.functionspace(mesh, (family, degree, (dim,)))


def scalar_space(mesh, family: str = "DG", degree: int = 0):
    """A scalar space, e.g. DG0 (one value per cell).

    0.5: ``fem.FunctionSpace(mesh, (family, degree))``.
    0.11: ``fem.functionspace(mesh, (family, degree))``."""
    if LEGACY:
        return fem.FunctionSpace(mesh, (family, degree))
    return fem.functionspace(mesh, (family, degree))


def cell_dofs(V) -> np.ndarray:
    """The dofmap as a (num_local_cells incl. ghosts, dofs per cell) array of block indices.

    0.5: ``V.dofmap.list`` is an AdjacencyList (``.array`` flat).
    0.11: ``V.dofmap.list`` is already the 2D array."""
    dofs = V.dofmap.list
    if hasattr(dofs, "array") and not isinstance(dofs, np.ndarray):
        return dofs.array.reshape(-1, V.dofmap.dof_layout.num_dofs)
    return dofs


def geometry_dofs(mesh) -> np.ndarray:
    """The geometry dofmap as a (num_local_cells, nodes per cell) array: rows index
    ``mesh.geometry.x``.

    0.5: ``mesh.geometry.dofmap`` is an AdjacencyList.
    0.11: ``mesh.geometry.dofmaps[0]``, a 2D array (``dofmap`` is deprecated)."""
    geo = mesh.geometry
    if LEGACY:
        return geo.dofmap.array.reshape(geo.dofmap.num_nodes, -1)
    return geo.dofmaps[0] if hasattr(geo, "dofmaps") else geo.dofmap


def interpolation_points(V) -> np.ndarray:
    """Reference points at which ``V``'s element interpolates (for fem.Expression).

    0.5: ``V.element.interpolation_points()`` (a method).
    0.11: ``V.element.interpolation_points`` (a property)."""
    pts = V.element.interpolation_points
    return pts() if callable(pts) else pts


def petsc_vec(u):
    """The PETSc Vec over ``u.x.array`` (owned + ghosts).

    0.5: ``u.vector``.  0.11: ``u.x.petsc_vec``."""
    return u.vector if LEGACY else u.x.petsc_vec


# ----------------------------------------------------------- forms, expressions
def compile_form(form):
    """Compile a UFL form with fresh option dicts (0.5's fem.form shares its defaults).

    0.5: ``fem.form(form, form_compiler_params={}, jit_params={})``.
    0.11: ``fem.form(form, form_compiler_options={}, jit_options={})``."""
    if _FORM_OPTIONS:
        return fem.form(form, form_compiler_options={}, jit_options={})
    return fem.form(form, form_compiler_params={}, jit_params={})


def scatter_add(x) -> None:
    """Add the ghost entries of the dolfinx vector ``x`` (``u.x``) into their owners.

    0.5: ``x.scatter_reverse(la.ScatterMode.add)``.
    0.11: ``x.scatter_reverse(la.InsertMode.add)``."""
    from dolfinx import la

    mode = la.ScatterMode.add if hasattr(la, "ScatterMode") else la.InsertMode.add
    x.scatter_reverse(mode)


def eval_expression_into(expr, mesh, cells: np.ndarray, out: np.ndarray) -> np.ndarray:
    """Values of a compiled ``fem.Expression`` on ``cells`` written into ``out``, a
    C-contiguous (n_cells, n_points * value_size) array (no allocation in a loop).

    0.5: ``expr.eval(cells, values=out)``.
    0.11: ``expr.eval(mesh, cells, values=...)`` with ``out`` viewed as
    (n_cells, n_points, value_size)."""
    if LEGACY:
        expr.eval(cells, values=out)
    else:
        n_points = expr.X().shape[0]  # (no -1 in the shapes: a rank may have no cells)
        expr.eval(mesh, cells, values=out.reshape(out.shape[0], n_points, out.shape[1] // n_points))
    return out


def quadrature_vector_space(mesh, degree: int, dim: int):
    """A ``dim``-component quadrature space of the default rule of ``degree`` (one value
    set per quadrature point; state and stresses at the points).

    0.5: ``ufl.VectorElement("Quadrature", cell, degree=, dim=, quad_scheme="default")``.
    0.11: ``basix.ufl.quadrature_element(cell, value_shape=(dim,), degree=)``."""
    if LEGACY:
        import ufl

        element = ufl.VectorElement("Quadrature", mesh.ufl_cell(), degree=degree, dim=dim,
                                    quad_scheme="default")
        return fem.FunctionSpace(mesh, element)
    import basix.ufl

    element = basix.ufl.quadrature_element(mesh.basix_cell(), value_shape=(dim,),
                                           degree=degree)
    return fem.functionspace(mesh, element)


def eval_expression(expr, mesh, cells: np.ndarray) -> np.ndarray:
    """Values of a compiled ``fem.Expression`` on ``cells``: (n_cells, n_points * value_size).

    0.5: ``expr.eval(cells)`` gives that shape.
    0.11: ``expr.eval(mesh, cells)`` gives (n_cells, n_points, *value_shape)."""
    if LEGACY:
        return expr.eval(cells)
    values = expr.eval(mesh, cells)
    return values.reshape(values.shape[0], int(np.prod(values.shape[1:])))  # 0 cells too


# ---------------------------------------------------------------------- output
def has_vtx() -> bool:
    """Whether ADIOS2 output (``io.VTXWriter``, ParaView's ADIOS2VTXReader) is available:
    built into the 0.11 wheels; absent from Debian's 0.5.2."""
    return bool(getattr(dolfinx, "has_adios2", False)) and hasattr(_io, "VTXWriter")


# ------------------------------------------------------------------------ numpy
def trapezoid(y: np.ndarray, x: np.ndarray) -> float:
    """Trapezoidal rule: numpy 2 renamed ``np.trapz`` to ``np.trapezoid``."""
    rule = getattr(np, "trapezoid", None) or getattr(np, "trapz")
    return float(rule(y, x))


# -------------------------------------------------------------------- launcher
# the variables a launcher puts into its children (OpenMPI/PMIx, MPICH/Hydra)
LAUNCHER_ENV_PREFIXES = ("OMPI_", "PMIX_", "OPAL_", "ORTE_", "HYDRA_", "HYDI_", "PMI_",
                         "MPI_LOCALRANKID", "MPI_LOCALNRANKS")


def clean_launcher_env(env: dict | None = None) -> dict:
    """``env`` (default: this process's) without a launcher's variables, for starting
    a fresh launcher or a serial child."""
    env = dict(os.environ if env is None else env)
    return {k: v for k, v in env.items() if not k.startswith(LAUNCHER_ENV_PREFIXES)}


def mpi_launcher(root: str | os.PathLike | None = None) -> list[str]:
    """The command that starts this interpreter's stack on N ranks (append ``-n N ...``).

    OpenMPI (Debian): ``scripts/mpirun.sh`` (root variables, --oversubscribe).
    MPICH (the wheels): the ``mpiexec`` beside this interpreter (scripts/mpirun.sh
    picks that too when it is given this interpreter)."""
    if root is not None:
        script = os.path.join(os.fspath(root), "scripts", "mpirun.sh")
        if os.path.isfile(script):
            return [script]
    beside = os.path.join(os.path.dirname(sys.executable), "mpiexec")
    if "MPICH" in MPI.Get_library_version() and os.access(beside, os.X_OK):
        return [beside]
    return ["mpiexec"] if "MPICH" in MPI.Get_library_version() else ["mpirun", "--oversubscribe"]


def launcher_rank_variable() -> str:
    """The environment variable that holds a process's rank under the launcher.

    OpenMPI: ``OMPI_COMM_WORLD_RANK``.  MPICH (Hydra): ``PMI_RANK``."""
    return "PMI_RANK" if "MPICH" in MPI.Get_library_version() else "OMPI_COMM_WORLD_RANK"


def launcher_ctrl_c_signal() -> int:
    """The signal the ranks receive when the launcher gets SIGINT (Ctrl-C in its terminal).

    OpenMPI's ``mpirun``: SIGTERM, then SIGKILL about a second later.
    MPICH's Hydra ``mpiexec``: SIGINT itself, and it waits for the ranks (a second
    Ctrl-C aborts them)."""
    import signal

    return signal.SIGINT if "MPICH" in MPI.Get_library_version() else signal.SIGTERM
