""".msh files a user may hand the reader: each is read, or refused in one line.

dolfinx 0.5's gmsh reader ends the process (a segmentation fault or an abort from
the C library) on some files, and on 0.11 builds meshes the solver cannot use; the
reader refuses those before dolfinx sees them. Each file is written with gmsh here
(a rectangle of about 20 cells), run through the command line as a user would, on
every rank of the test: a refused file exits 2 with one line "error: ..." that names
the problem, no traceback, no run directory (tests/test_bad_input.py's helper).

Oracle for the files that are read: the lumped mass of the body equals rho pi R^2 L
(a ring of radius R and height L) to round-off.
"""
import json
import math
import os
import subprocess
import sys

import numpy as np
import pytest
from mpi4py import MPI

from conftest import clean_mpi_env
from impact_fenics import meshing
from roundoff import rounding
from scene_texts import ROOT
from test_bad_input import _refused
from test_cli import _disk_msh

COMM = MPI.COMM_WORLD
serial_only = pytest.mark.skipif(COMM.size > 1, reason="launches processes: serial only")
R, L, H = 0.02, 0.04, 0.01  # the rectangle [0, R] x [0, L] and the cell size (m)
RHO = 7850.0  # kg/m^3

SCENE = """\
[mesh]
file = "{file}"

[materials.steel]
E = 200e9
nu = 0.3
density = 7850.0

[bodies.{body}]
material = "steel"
velocity = [0.0, -1.0]

[time]
dt = 1e-8
n_steps = 3
"""


def _rectangle(gmsh, kind: str) -> None:
    """The model of ``kind``: the rectangle [0, R] x [0, L] in the cell group "disk",
    its bottom and top in the facet groups "bottom" and "top", meshed at size H, with
    the one change the kind names."""
    occ = gmsh.model.occ
    if kind == "box":  # a 3D file
        volume = occ.addBox(0, 0, 0, R, L, R)
        occ.synchronize()
        gmsh.model.addPhysicalGroup(3, [volume], 1)
        gmsh.model.setPhysicalName(3, 1, "disk")
        gmsh.option.setNumber("Mesh.MeshSizeMax", 2 * H)
        gmsh.model.mesh.generate(3)
        return
    if kind == "two_types":  # the user's anvil (triangles) under a rod (quadrilaterals)
        anvil = occ.addRectangle(0, -L / 2, 0, 2 * R, L / 2)
        rod = occ.addRectangle(0, 0, 0, R / 2, L)
        occ.fragment([(2, anvil)], [(2, rod)])
        occ.synchronize()
        surfaces = [tag for _, tag in gmsh.model.getEntities(2)]
        for k, (tag, name) in enumerate(zip(surfaces, ("anvil", "rod"))):
            gmsh.model.addPhysicalGroup(2, [tag], k + 1)
            gmsh.model.setPhysicalName(2, k + 1, name)
        gmsh.model.mesh.setRecombine(2, surfaces[1])
        gmsh.option.setNumber("Mesh.MeshSizeMax", H)
        gmsh.model.mesh.generate(2)
        return
    surface = occ.addRectangle(0, 0, 0, R, L)
    other = occ.addRectangle(2 * R, 0, 0, R, L) if kind == "unmeshed" else None
    if kind == "xz_plane":  # the section drawn in gmsh's x-z plane
        occ.rotate([(2, surface)], 0, 0, 0, 1, 0, 0, math.pi / 2)
    off = occ.addPoint(2 * R, 0, 0) if kind == "point_off" else None
    line_off = (occ.addLine(occ.addPoint(2 * R, 0, 0), occ.addPoint(2 * R, L, 0))
                if kind == "line_off" else None)
    occ.synchronize()
    # the sides by their midpoints' (z, r): bottom, axis, outer side, top
    bottom, left, right, top = sorted(
        (tag for _, tag in gmsh.model.getBoundary([(2, surface)], oriented=False)),
        key=lambda c: tuple(np.round(occ.getCenterOfMass(1, c)[1::-1], 9)))
    groups = [] if kind == "lines_only" else [(2, [surface], 1, "disk")]
    if kind == "two_cell_groups":
        groups.append((2, [surface], 2, "core"))
    groups += [(1, [bottom], 11, "bottom"), (1, [top], 12, "top")]
    if kind == "two_facet_groups":
        groups.append((1, [bottom, right], 13, "bottom_right"))
    if kind == "line_off":
        groups.append((1, [line_off], 13, "beside"))
    if kind == "point_off":
        groups.append((0, [off], 14, "beside"))
    if kind == "corner_point":
        corner = gmsh.model.getBoundary([(1, bottom)], oriented=False)[0][1]
        groups.append((0, [corner], 14, "corner"))
    if kind == "empty_groups":
        groups += [(2, [], 3, "nothing"), (1, [], 15, "no_side")]
    if kind == "unmeshed":  # a group whose surface holds no mesh
        groups.append((2, [other], 2, "unmeshed"))
    for dim, entities, tag, name in groups:
        gmsh.model.addPhysicalGroup(dim, entities, tag)
        gmsh.model.setPhysicalName(dim, tag, name)
    if kind in ("quadrilaterals", "one_group_two_types"):
        gmsh.model.mesh.setRecombine(2, surface)
    if kind == "quadrilaterals":  # a structured grid: every cell a quadrilateral
        for curve, n in ((bottom, R / H), (top, R / H), (left, L / H), (right, L / H)):
            gmsh.model.mesh.setTransfiniteCurve(curve, int(round(n)) + 1)
        gmsh.model.mesh.setTransfiniteSurface(surface)
    gmsh.option.setNumber("Mesh.MeshSizeMax", H)
    gmsh.option.setNumber("Mesh.RecombinationAlgorithm", 0 if kind == "one_group_two_types"
                          else 1)  # 0: the simple recombination leaves triangles
    gmsh.model.mesh.generate(2)
    gmsh.option.setNumber("Mesh.RecombinationAlgorithm", 1)
    if kind == "second_order":
        gmsh.model.mesh.setOrder(2)
    if other is not None:  # the other rectangle's mesh removed
        gmsh.model.mesh.clear([(2, other)] + gmsh.model.getBoundary(
            [(2, other)], combined=False, oriented=False, recursive=True)
            + gmsh.model.getBoundary([(2, other)], combined=False, oriented=False))


def _gapped(text: str) -> str:
    """The gmsh 2.2 file ``text`` with every node tag doubled (tags with gaps, as a file
    edited or written by another tool may have)."""
    lines, out, section = text.splitlines(), [], None
    for line in lines:
        if line.startswith("$"):
            section = line
        elif section == "$Nodes" and " " in line:
            tag, rest = line.split(" ", 1)
            line = f"{2 * int(tag)} {rest}"
        elif section == "$Elements" and " " in line:
            f = line.split()
            head = 3 + int(f[2])  # number, type, count of tags, the tags
            line = " ".join(f[:head] + [str(2 * int(n)) for n in f[head:]])
        out.append(line)
    return "\n".join(out) + "\n"


def _write(kind: str, base: str) -> str:
    """Write ``kind``.msh into ``base`` on rank 0 (gmsh as the reader holds it); its path."""
    path = os.path.join(base, f"{kind}.msh")
    if COMM.rank == 0 and kind == "gapped_nodes":  # a rectangle of 2 x 4 cells in 2.2 text
        with open(path, "w") as f:
            f.write(_gapped(_disk_msh(R, L, 2, 4)))
    elif COMM.rank == 0:
        meshing.start_gmsh()
        import gmsh

        gmsh.clear()
        gmsh.model.add(kind)
        _rectangle(gmsh, kind)
        gmsh.write(path)
        gmsh.clear()
    COMM.barrier()
    return path


def _scene(kind: str, body: str = "disk") -> str:
    return SCENE.format(file=f"{kind}.msh", body=body)


def _base(tmp_path) -> str:
    return COMM.bcast(str(tmp_path), root=0)


# kind -> (the scene's body, words of the refusal). "before": what dolfinx 0.5.2's reader
# did with the file before it was refused here.
REFUSED = {
    # before: segmentation fault (exit 139) or a C library abort (exit 134)
    "two_types": ("rod", "mixes cell types (3-node triangles in 'anvil'; 4-node "
                         "quadrilaterals in 'rod'); a mesh holds one cell type for now"),
    # before: a traceback (an assertion in dolfinx's reader)
    "one_group_two_types": ("disk", "mixes cell types (3-node triangles in 'disk'; 4-node "
                                    "quadrilaterals in 'disk')"),
    # before: read with a second-order geometry under first-order fields
    "second_order": ("disk", "has second-order cells (6-node triangles in 'disk'); the "
                             "solver's cells are first order"),
    # before: refused (no change)
    "box": ("disk", "is not a 2D (r, z) mesh"),
    # before: a traceback (the estimate's min() of no cell groups)
    "lines_only": ("disk", "has no physical group of cells (dimension 2)"),
    # before: a C library abort (exit 134)
    "two_cell_groups": ("disk", "the cells of surface 1 are in the cell groups 'disk' and "
                                "'core'; a cell belongs to one body"),
    # before: a C library abort (exit 134)
    "line_off": ("disk", "line(s) of the facet group 'beside' (curve 5) are not sides of "
                         "any cell"),
    # before: segmentation fault (exit 139)
    "point_off": ("disk", "the point group 'beside' holds point 5, which is no node of a cell"),
    # before: read, with the bottom's sides in "bottom" only (a load on "bottom_right"
    # would have missed them)
    "two_facet_groups": ("disk", "the sides of curve 1 are in the facet groups 'bottom' and "
                                 "'bottom_right'; a side is read into one group only"),
    # before: a traceback (an assertion in dolfinx's reader) on 0.5; a body of no cells,
    # no mass, on 0.11
    "unmeshed": ("disk", "the group 'unmeshed' holds surface 2, which has no mesh"),
    # before: refused as a stable step of 6e-22 s (the section is flat in r, z)
    "xz_plane": ("disk", "m in gmsh's z, so the mesh is not in a plane z = constant"),
}


@pytest.mark.parametrize("kind", sorted(REFUSED))
def test_a_file_the_reader_cannot_take_is_refused_in_one_line(tmp_path, capsys, kind):
    body, words = REFUSED[kind]
    _write(kind, _base(tmp_path))
    line = _refused(tmp_path, capsys, _scene(kind, body), words)
    assert f"mesh file '{os.path.join(_base(tmp_path), kind + '.msh')}'" in line


def test_two_cell_types_say_what_to_do(tmp_path, capsys):
    _write("two_types", _base(tmp_path))
    line = _refused(tmp_path, capsys, _scene("two_types", "rod"), "mixes cell types")
    assert line.endswith("mesh every body with one cell type (all triangles, or every "
                         "surface recombined into quadrilaterals)")


@serial_only
def test_the_users_file_under_mpirun_is_refused_not_crashed(tmp_path):
    """The reported file (triangles and quadrilaterals) on 2 ranks, as a user launches it:
    exit 2 (it was 139), the one line, no run directory."""
    _write("two_types", str(tmp_path))
    (tmp_path / "scene.toml").write_text(_scene("two_types", "rod"))
    out = tmp_path / "out"
    proc = subprocess.run([os.path.join(ROOT, "scripts", "mpirun.sh"), "-n", "2",
                           sys.executable, "-m", "impact_fenics", "run",
                           str(tmp_path / "scene.toml"), "--out", str(out)],
                          capture_output=True, text=True, timeout=300, env=clean_mpi_env(),
                          cwd=ROOT)
    lines = [ln for ln in proc.stderr.splitlines() if ln.startswith("error: ")]
    assert proc.returncode == 2, proc.stderr
    assert len(lines) == 1 and "mixes cell types" in lines[0], proc.stderr
    assert "Traceback" not in proc.stderr + proc.stdout
    assert not out.exists() and not os.path.exists(str(out) + ".partial")


def _run(base: str, kind: str) -> dict:
    from impact_fenics import cli

    path = os.path.join(base, f"{kind}.toml")
    if COMM.rank == 0:
        with open(path, "w") as f:
            f.write(_scene(kind))
    COMM.barrier()
    out = os.path.join(base, f"{kind}_out")
    assert cli.main(["run", path, "--out", out, "--quiet"]) == 0
    with open(os.path.join(out, "summary.json")) as f:
        return json.load(f)


@pytest.mark.parametrize("kind", ["quadrilaterals", "corner_point", "empty_groups",
                                  "gapped_nodes"])
def test_a_file_the_reader_takes_runs(tmp_path, kind):
    """Quadrilaterals only, a point group on a cell's node, empty groups and node tags
    with gaps (a traceback before: an assertion in dolfinx's reader) are read: the
    body's mass is rho pi R^2 L."""
    base = _base(tmp_path)
    _write(kind, base)
    summary = _run(base, kind)
    # round-off: each node's lumped mass sums its cells' quadrature (about 30 roundings),
    # the body's mass sums the nodes (n_dofs / 2 terms); the closed form rounds 5 times
    assert math.isclose(summary["bodies"]["disk"]["mass"], RHO * math.pi * R ** 2 * L,
                        rel_tol=rounding(30 + summary["n_dofs"] // 2 + 5))


@pytest.mark.parametrize("kind", ["quadrilaterals", "corner_point"])
def test_the_step_estimate_knows_the_cell_type(tmp_path, kind):
    """The estimate reads a file of quadrilaterals as Q1 (its bound on the step, not the
    triangles'): msh_size says whether every cell is a quadrilateral (an exact count)."""
    base = _base(tmp_path)
    path = _write(kind, base)
    assert meshing.msh_size(path)["quadrilaterals"] == (kind == "quadrilaterals")
