"""impact_fenics.compat: the one module that knows the dolfinx version, and what it gives.

Oracles: the source text of the package (no other module reads the version or
spells an API that differs between dolfinx 0.5.2 and 0.11), and exact facts of
P1 triangles independent of the code under test (a linear field's gradient, a
point inside the triangle of its cell by barycentric coordinates, the centroid
as DG0's interpolation point, the trapezoidal rule on a linear function), and
the launcher's own rank variable against MPI's rank.
"""
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from mpi4py import MPI

from conftest import clean_mpi_env
from impact_fenics import compat, meshing
from roundoff import rounding

ROOT = Path(__file__).resolve().parents[1]
# where project code lives that runs on both stacks
CODE = [ROOT / "impact_fenics", ROOT / "demos", ROOT / "benchmarks", ROOT / "tests"]

# reading the version, or spelling what differs between 0.5.2 and 0.11: compat.py only
VERSION_READS = re.compile(r"dolfinx\s*\.\s*__version__|DOLFINX_VERSION|compat\.LEGACY|"
                           r"\bhas_adios2\b|dolfinx\.git_commit_hash")
OLD_OR_NEW_API = re.compile(
    r"\bgmshio\b|io\.gmsh\b|VectorFunctionSpace|fem\.FunctionSpace\(|fem\.functionspace\(|"
    r"BoundingBoxTree|\bbb_tree\b|compute_collisions(_points)?\(|form_compiler_params|"
    r"jit_params|form_compiler_options|jit_options|\.interpolation_points\b|"
    r"dofmap\.list\b|\.x\.petsc_vec|\.vector\b|\.eval\(|geometry\.dofmaps?\b|"
    r"\bnp\.trapz\b|\bnp\.trapezoid\b|\bScatterMode\.add\b|scatter_reverse\(")


def _sources():
    for base in CODE:
        for path in sorted(base.rglob("*.py")):
            if path.name in ("compat.py", "test_compat.py"):
                continue
            yield path, path.read_text()


def test_only_compat_reads_the_dolfinx_version():
    """No module but compat.py reads the dolfinx version or decides on it."""
    found = [f"{p.relative_to(ROOT)}:{text[:m.start()].count(chr(10)) + 1}: {m.group(0)}"
             for p, text in _sources() for m in VERSION_READS.finditer(text)]
    assert not found, "version checks outside impact_fenics/compat.py:\n" + "\n".join(found)


def test_only_compat_spells_the_apis_that_differ():
    """Calls that changed between dolfinx 0.5.2 and 0.11 go through compat's functions."""
    found = []
    for p, text in _sources():
        for m in OLD_OR_NEW_API.finditer(text):
            line = text.splitlines()[text[:m.start()].count("\n")]
            if line.lstrip().startswith("#"):
                continue
            found.append(f"{p.relative_to(ROOT)}:{text[:m.start()].count(chr(10)) + 1}: {m.group(0)}")
    assert not found, "route these through impact_fenics.compat:\n" + "\n".join(found)


def test_expression_eval_gives_the_gradient_of_a_linear_field(comm):
    """u = (a r + c z, b z) on P1: the centroid values of du_r/dr, du_r/dz and the whole
    gradient are exact (round-off), in the (cells, points * values) layout on both stacks."""
    import ufl
    from dolfinx import fem

    a, b, c = 1.5, -2.0, 0.25
    tmesh = meshing.bar(radius=0.05, length=0.1, h=0.025, comm=comm)
    V = compat.vector_space(tmesh.mesh, "Lagrange", 1)
    u = fem.Function(V)
    u.interpolate(lambda x: np.vstack([a * x[0] + c * x[1], b * x[1]]))
    cells = np.arange(tmesh.mesh.topology.index_map(2).size_local, dtype=np.int32)
    centroid = np.array([[1.0 / 3.0, 1.0 / 3.0]])
    g = compat.eval_expression(fem.Expression(ufl.grad(u), centroid), tmesh.mesh, cells)
    assert g.shape == (cells.size, 4)
    # sum_i grad(phi_i) u_i: the inverse Jacobian (8 roundings) and 3 terms of size
    # |u| / h that cancel to the gradient: 16 roundings of 3 |u|_max / h
    u_max = abs(a) * 0.05 + abs(c) * 0.1 + abs(b) * 0.1
    atol = rounding(16, 3 * u_max / 0.025)
    assert np.allclose(g, [a, c, 0.0, b], rtol=0, atol=atol)
    s = compat.eval_expression(fem.Expression(ufl.grad(u)[0, 0], centroid), tmesh.mesh, cells)
    assert s.shape == (cells.size, 1) and np.allclose(s, a, rtol=0, atol=atol)


def test_spaces_and_dofmap(comm):
    """P1 vector space: two components a node; each cell's dofs sit at its vertices; DG0
    interpolates at the centroid (1/3, 1/3)."""
    tmesh = meshing.bar(radius=0.05, length=0.1, h=0.025, comm=comm)
    msh = tmesh.mesh
    V = compat.vector_space(msh, "Lagrange", 1)
    assert V.dofmap.index_map_bs == 2
    n_nodes = msh.geometry.index_map().size_global
    assert V.dofmap.index_map.size_global == n_nodes
    dofs = compat.cell_dofs(V)
    n_cells = msh.topology.index_map(2).size_local + msh.topology.index_map(2).num_ghosts
    assert dofs.shape == (n_cells, 3)
    xy = V.tabulate_dof_coordinates()[:, :2]
    geo = compat.geometry_dofs(msh)
    # the dof coordinates: the cell's map at its vertices (sum_i phi_i x_i, 6 roundings of
    # the coordinates, 0.1 m at most)
    assert np.allclose(np.sort(xy[dofs].reshape(-1, 2), axis=0),
                       np.sort(msh.geometry.x[geo][:, :, :2].reshape(-1, 2), axis=0),
                       rtol=0, atol=rounding(6, 0.1))
    Q = compat.scalar_space(msh, "DG", 0)
    assert np.allclose(compat.interpolation_points(Q), [[1.0 / 3.0, 1.0 / 3.0]], rtol=0,
                       atol=rounding(2, 1.0 / 3.0))  # basix's 1/3: a rounding or two
    W = compat.vector_space(msh, "DG", 1)
    assert compat.cell_dofs(W).shape == (n_cells, 3) and W.dofmap.index_map_bs == 2


def test_colliding_cells_contain_the_point(comm):
    """Every cell reported for a point holds it (barycentric coordinates in [0, 1])."""
    tmesh = meshing.bar(radius=0.05, length=0.1, h=0.025, comm=comm)
    msh = tmesh.mesh
    x = np.array([[0.0123, 0.0456, 0.0]])
    cells = compat.colliding_cells(msh, x).links(0)
    geo = compat.geometry_dofs(msh)
    for cell in cells:
        p = msh.geometry.x[geo[cell], :2]
        M = np.vstack([p.T, np.ones(3)])
        lam = np.linalg.solve(M, np.array([x[0, 0], x[0, 1], 1.0]))
        # a 3 x 3 solve: about 9 roundings times the condition number of M
        assert lam.min() >= -rounding(9 * np.linalg.cond(M))
    assert comm.allreduce(len(cells)) >= 1


def test_gmsh_meshes_see_both_cells_of_every_interior_facet(comm):
    """A gmsh mesh is ghosted by shared facet on both stacks: a facet has one local cell
    exactly when it lies on the rectangle's boundary (r = 0 or R, z = 0 or L; the oracle
    is geometry), also where two ranks' cells meet."""
    R, L = 0.05, 0.1
    msh = meshing.bar(radius=R, length=L, h=0.0125, comm=comm).mesh
    top = msh.topology
    for d in ((1, 2), (1, 0), (2, 0)):
        top.create_connectivity(*d)
    f2c, f2v, c2v = top.connectivity(1, 2), top.connectivity(1, 0), top.connectivity(2, 0)
    geo = compat.geometry_dofs(msh)  # P1: a cell's nodes in the order of its vertices
    tol = 1e-9  # m: far above the coordinates' round-off (1e-18 m), far below h = 0.0125 m
    n_owned = top.index_map(1).size_local
    assert comm.allreduce(n_owned) > 0
    for f in range(n_owned):  # an owned facet sees all its cells
        cells = f2c.links(f)
        cv = c2v.links(cells[0])
        nodes = [geo[cells[0]][np.flatnonzero(cv == v)[0]] for v in f2v.links(f)]
        xy = msh.geometry.x[nodes, :2]
        on_boundary = (np.all(np.abs(xy[:, 0]) < tol) or np.all(np.abs(xy[:, 0] - R) < tol)
                       or np.all(np.abs(xy[:, 1]) < tol) or np.all(np.abs(xy[:, 1] - L) < tol))
        assert cells.size == (1 if on_boundary else 2), (f, xy)


def test_trapezoid_is_exact_on_a_linear_function():
    x = np.linspace(0.0, 2.0, 7)
    # 7 points: the function (2 roundings), 6 intervals of 3 roundings, summed (6)
    assert compat.trapezoid(3.0 * x + 1.0, x) == pytest.approx(8.0, rel=rounding(2 + 3 * 6 + 6))


def test_petsc_vec_views_the_function_array(comm):
    from dolfinx import fem
    from petsc4py import PETSc

    tmesh = meshing.bar(radius=0.05, length=0.1, h=0.025, comm=comm)
    u = fem.Function(compat.vector_space(tmesh.mesh))
    vec = compat.petsc_vec(u)
    u.x.array[:] = 2.0
    assert vec.getSize() == u.function_space.dofmap.index_map.size_global * 2
    # a sum of 2.0s: every partial sum is an integer below 2^53, so exact
    assert vec.norm(PETSc.NormType.NORM_1) == 2.0 * vec.getSize()


@pytest.mark.skipif(MPI.COMM_WORLD.size > 1, reason="launches the launcher itself: serial run only")
def test_launcher_and_rank_variable():
    """The launcher of this stack starts 2 ranks of this interpreter; its rank variable
    is each process's MPI rank."""
    code = ("import os; from mpi4py import MPI; c = MPI.COMM_WORLD; "
            f"rows = c.gather((c.rank, os.environ[{compat.launcher_rank_variable()!r}], c.size)); "
            "c.rank == 0 and print('\\n'.join(' '.join(map(str, r)) for r in rows))")
    proc = subprocess.run(compat.mpi_launcher(ROOT) + ["-n", "2", sys.executable, "-c", code],
                          capture_output=True, text=True, timeout=120, env=clean_mpi_env(),
                          cwd=ROOT)
    assert proc.returncode == 0, proc.stderr
    rows = sorted(line.split() for line in proc.stdout.splitlines() if line.strip())
    assert rows == [["0", "0", "2"], ["1", "1", "2"]]


def test_versions_name_the_stack():
    v = compat.versions()
    from petsc4py import PETSc

    assert v["petsc"] == ".".join(map(str, PETSc.Sys.getVersion()))
    assert v["mpi"] and MPI.Get_library_version().startswith(v["mpi"]) and "\x00" not in v["mpi"]
