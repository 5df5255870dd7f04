"""A finite-strain body from a .msh file of quadrilaterals, through `impact-fenics run`.

The file is the bar of ``generator = "quad_bar"`` (radius 4 mm, length 20 mm, 2 x 10
square cells) written with gmsh's Python API: a transfinite rectangle recombined into
quadrilaterals, its surface the cell group "bar" (the body), its bottom the facet group
"bottom", each node moved onto the generator's (gmsh places transfinite nodes within
~1e-14 m of the grid, which alone moves the step by some 1e-12 of itself, far above
round-off). A copper bar (Hencky J2) strikes the wall at 150 m/s.

Oracle: the same bar from the generator. dolfinx numbers a file's nodes and cells in
another order than create_rectangle's, so the nodal sums of the internal force run in
another order: the runs agree to round-off grown over the run, class (c) of
tests/roundoff.py: |file - generator| <= n_steps x (the spread of the generator's run
after a one-ulp change of its initial velocity + a step's 32 roundings of the field),
for every output's displacement (matched by reference coordinates) and cell stress
sigma_zz (matched by centroid), on the same output times (the step follows the cells:
within the same bound of their own). The run is the file's: its cells are read as
quadrilaterals (the written topology), and the bar yields (eps_p_eq > 0).

A file of triangles for a finite-strain body is refused in one line that says why,
exit 2, nothing written (also in tests/test_finite_on_triangles.py).
"""
import json
import os

import numpy as np
import pytest
from mpi4py import MPI

from impact_fenics import cli, meshing
from impact_fenics.quad_meshes import quad_bar
from impact_fenics.xdmf import FieldSeries
from roundoff import assert_within_spread, one_ulp
from scene_texts import COPPER_J2
from test_cli import _disk_msh

COMM = MPI.COMM_WORLD
R, L, N_R, N_Z = 4e-3, 20e-3, 2, 10  # m, m, cells across and along (square cells)
V0 = 150.0  # m/s
SCENE = ("""title = "finite-strain bar"
[mesh]
{mesh}

"""
         + COPPER_J2  # no braces: SCENE.format leaves it as it is
         + """
[bodies.bar]
material = "copper"
velocity = [0.0, {v}]
strain = "finite"

[wall]
z = 0.0
method = "film"

[time]
t_end = 2e-6
cfl = 0.5
dt_interval = 10

[output]
output_every = 5
""")
GENERATOR = f'generator = "quad_bar"\nradius = {R!r}\nlength = {L!r}\nn_r = {N_R}'
FILE = 'file = "bar.msh"'


def write_quadrilaterals(path: str) -> None:
    """The bar [0, R] x [0, L] in N_R x N_Z quadrilaterals (gmsh's Python API)."""
    gmsh = meshing._gmsh()
    gmsh.clear()
    geo = gmsh.model.geo
    p = [geo.addPoint(x, y, 0) for x, y in ((0, 0), (R, 0), (R, L), (0, L))]
    c = [geo.addLine(p[i], p[(i + 1) % 4]) for i in range(4)]
    s = geo.addPlaneSurface([geo.addCurveLoop(c)])
    for curve, n in zip(c, (N_R, N_Z, N_R, N_Z)):
        geo.mesh.setTransfiniteCurve(curve, n + 1)
    geo.mesh.setTransfiniteSurface(s)
    geo.mesh.setRecombine(2, s)
    geo.synchronize()
    gmsh.model.addPhysicalGroup(2, [s], 1)
    gmsh.model.setPhysicalName(2, 1, "bar")
    gmsh.model.addPhysicalGroup(1, [c[0]], 11)
    gmsh.model.setPhysicalName(1, 11, "bottom")
    gmsh.model.mesh.generate(2)
    # gmsh's transfinite nodes sit within ~1e-14 m of the grid; each is put on the
    # generator's node (create_rectangle's coordinates), so that the two bars differ only
    # in their numbering
    exact = quad_bar(MPI.COMM_SELF, R, L, N_R, N_Z).geometry.x[:, :2]
    tags, xyz, _ = gmsh.model.mesh.getNodes()
    for tag, x in zip(tags, xyz.reshape(-1, 3)):
        k = np.argmin(np.hypot(*(exact - x[:2]).T))
        assert np.hypot(*(exact[k] - x[:2])) < 1e-9  # m: far below h, far above gmsh's error
        gmsh.model.mesh.setNode(int(tag), [exact[k, 0], exact[k, 1], 0.0], [])
    gmsh.write(path)
    gmsh.clear()


def _run(base: str, name: str, mesh: str, v: float) -> tuple[str, dict]:
    scene = os.path.join(base, f"{name}.toml")
    if COMM.rank == 0:
        with open(scene, "w") as f:
            f.write(SCENE.format(mesh=mesh, v=repr(-v)))
    COMM.barrier()
    out = os.path.join(base, name)
    assert cli.main(["run", scene, "--out", out, "--quiet"]) == 0
    with open(os.path.join(out, "summary.json")) as f:
        return out, json.load(f)


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    base = COMM.bcast(str(tmp_path_factory.mktemp("finite_msh")), root=0)
    if COMM.rank == 0:
        write_quadrilaterals(os.path.join(base, "bar.msh"))
    COMM.barrier()
    return {name: _run(base, name, mesh, v) for name, mesh, v in
            (("file", FILE, V0), ("generator", GENERATOR, V0),
             ("perturbed", GENERATOR, one_ulp(V0)))}


def _sorted(keys: np.ndarray, values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The rows of ``values`` in the order of their points ``keys`` (m), each point once
    (the pieces repeat their shared nodes), keyed to 1e-9 m (far below h, far above the
    coordinates' round-off)."""
    key = np.round(keys / 1e-9).astype(np.int64)
    key, first = np.unique(key, axis=0, return_index=True)
    return key, values[first]


def _frames(out: str) -> tuple[np.ndarray, list, list]:
    """(output times, [displacements by node], [sigma_zz by cell]) of a run."""
    f = FieldSeries(os.path.join(out, "fields.xdmf"))
    assert f.cells.shape[1] == 4  # read as quadrilaterals
    centroids = f.points[f.cells].mean(axis=1)
    u = [_sorted(f.points, f.values("displacement", k)) for k in range(len(f.times))]
    s = [_sorted(centroids, f.values("sigma_zz", k)) for k in range(len(f.times))]
    return f.times, u, s


def test_a_quadrilateral_file_runs_as_the_generators_bar(runs):
    (out_f, s_f), (out_g, s_g), (out_p, _) = runs["file"], runs["generator"], runs["perturbed"]
    assert s_f["n_cells"] == s_g["n_cells"] == N_R * N_Z
    assert s_f["n_steps"] == s_g["n_steps"]
    n = s_g["n_steps"]
    (t_f, u_f, sz_f), (t_g, u_g, sz_g), (t_p, u_p, sz_p) = (_frames(o) for o in
                                                            (out_f, out_g, out_p))
    assert_within_spread(t_f, t_g, t_p, n, "output times", scale=float(t_g[-1]))
    for k in range(len(t_g)):
        for got, ref, pert, what in ((u_f[k], u_g[k], u_p[k], "displacement"),
                                     (sz_f[k], sz_g[k], sz_p[k], "sigma_zz")):
            assert np.array_equal(got[0], ref[0]) and np.array_equal(pert[0], ref[0])
            assert_within_spread(got[1], ref[1], pert[1], n, f"{what} at output {k}")
    assert s_f["bodies"]["bar"]["strain"] == "finite" and s_f["eps_p_max"] > 0.0


def test_a_triangle_file_for_a_finite_body_is_refused(tmp_path_factory, capsys):
    base = COMM.bcast(str(tmp_path_factory.mktemp("finite_tri_msh")), root=0)
    scene = os.path.join(base, "tri.toml")
    if COMM.rank == 0:
        with open(os.path.join(base, "bar.msh"), "w") as f:
            f.write(_disk_msh(R, L, N_R, N_Z).replace('"disk"', '"bar"'))
        with open(scene, "w") as f:
            f.write(SCENE.format(mesh=FILE, v=repr(-V0)))
    COMM.barrier()
    with pytest.raises(SystemExit) as exit_:
        cli.main(["run", scene, "--out", os.path.join(base, "out"), "--quiet"])
    assert exit_.value.code == 2
    err = [ln for ln in capsys.readouterr().err.splitlines() if ln.strip()]
    if COMM.rank == 0:
        assert err == [f'error: [mesh] file = "{os.path.join(base, "bar.msh")}": the file\'s '
                       "cells are triangles (recombine its surfaces in gmsh): finite strain "
                       "needs quadrilaterals: constant-strain triangles lock under isochoric "
                       "plastic flow"], err
    assert not os.path.exists(os.path.join(base, "out"))
