"""Node probes r and z: the current position X + u (m) of the node nearest a point.

Oracles, on triangles (the ``bar`` generator) and on Q1 quadrilaterals (``quad_bar``),
run through the command line on every rank of the test (the same closed forms bound
the serial and the parallel runs, so the two agree to those bounds):

* a rigid-body translation: a free elastic bar with a uniform initial velocity v along
  z and no contact or load. Every node moves by v t: z = Z + v t, r = R, to the
  round-off of the steps' accumulation (bound derived at :func:`_translation_bound`).
  X is the mesh's node nearest the point, found here by brute force over the
  generator's own mesh (a wrong node would be a cell size off);
* a node of a face held by [[fixed]] (both components) stays at X exactly, while the
  bar is pushed at its other end; a node on the axis keeps r = 0 exactly.
"""
import json
import math
import os
import subprocess
import sys

import numpy as np
import pytest
from dolfinx import mesh as dmesh
from mpi4py import MPI

from conftest import clean_mpi_env
from impact_fenics import cli, meshing, probes, scene_keys
from scene_texts import ROOT

COMM = MPI.COMM_WORLD
EPS = np.finfo(float).eps
R, L, H, N_R = 0.02, 0.04, 0.01, 2  # the bar r in [0, R], z in [0, L] (m), cell size (m)
V = 30.0  # m/s along z
DT, N_STEPS = 1e-6, 100  # s
E_SOFT = 1e3  # Pa: see _translation_bound

MESHES = {  # generator -> ([mesh] lines, the held face, the pushed face)
    "bar": (f'generator = "bar"\nradius = {R}\nlength = {L}\nh = {H}', "loaded_end", "free_end"),
    "quad_bar": (f'generator = "quad_bar"\nradius = {R}\nlength = {L}\nn_r = {N_R}',
                 "bottom", "top"),
}
# (name, point): near an interior node, near the top outer corner, near the axis's foot
POINTS = (("in", (0.0098, 0.0203)), ("corner", (0.0195, 0.0395)), ("axis", (0.001, 0.0012)))


def _scene(generator: str, E: float, velocity: float, time: str, more: str = "",
           points=POINTS) -> str:
    mesh = MESHES[generator][0]
    rows = "".join(f'\n[[probes]]\nname = "{q}_{name}"\npoint = [{p[0]}, {p[1]}]\n'
                   f'quantity = "{q}"\n' for name, p in points for q in ("r", "z"))
    return (f"[mesh]\n{mesh}\n\n[materials.m]\nE = {E}\nnu = 0.3\ndensity = 7850.0\n\n"
            f'[bodies.bar]\nmaterial = "m"\nvelocity = [0.0, {velocity}]\n\n{more}'
            f"[time]\n{time}\n\n[output]\nhistory_every = 1\nfields = false\n"
            f"plots = false\n{rows}")


def _run(tmp_path, name: str, text: str) -> np.ndarray:
    """history.csv of the scene ``text`` run through the CLI on every rank."""
    base = COMM.bcast(str(tmp_path), root=0)
    path = os.path.join(base, f"{name}.toml")
    if COMM.rank == 0:
        with open(path, "w") as f:
            f.write(text)
    COMM.barrier()
    out = os.path.join(base, name)
    assert cli.main(["run", path, "--out", out, "--quiet"]) == 0
    return np.genfromtxt(os.path.join(out, "history.csv"), delimiter=",", names=True)


def _nodes(generator: str) -> np.ndarray:
    """Every node (r, z) of the generator's mesh, gathered (m): quad_bar is dolfinx's
    rectangle of n_r x round(n_r L / R) quadrilaterals."""
    if generator == "bar":
        mesh = meshing.bar(radius=R, length=L, h=H).mesh
    else:
        mesh = dmesh.create_rectangle(COMM, [np.array([0.0, 0.0]), np.array([R, L])],
                                      [N_R, round(N_R * L / R)],
                                      cell_type=dmesh.CellType.quadrilateral)
    xy = np.concatenate(COMM.allgather(mesh.geometry.x[:, :2]))
    return np.unique(xy, axis=0)


def _nearest(nodes: np.ndarray, point) -> np.ndarray:
    """The node nearest ``point``, a tie to the smaller (r, z)."""
    d2 = (nodes[:, 0] - point[0]) ** 2 + (nodes[:, 1] - point[1]) ** 2
    return nodes[np.lexsort((nodes[:, 1], nodes[:, 0], d2))[0]]


def _translation_bound(n: np.ndarray, vt: np.ndarray, X) -> np.ndarray:
    """|z_n - (Z + v t_n)| at step n (m), and of r_n - R the stiffness's part.

    * The scheme moves u by fl(dt v) at each step (VecAXPY): n additions, each rounding
      to half an ulp of the running sum (<= |v t_n|), and the rounding of dt v leave
      (n + 1) eps/2 |v t_n|.
    * The time column t_n is a sum of n steps: n eps/2 t_n.
    * The probe's X + u, the test's Z + v t_n and v t_n round once each: 2.5 eps |Z + v t_n|
      (with half an ulp of |v t_n| <= that).
    * The stiffness: K times a uniform u_z is zero but for round-off, at most m eps
      sum_j |K_ij| |u| (m = 18, the longest row, Q1), which drives the free bar like a
      force per mass of at most m eps Omega^2 v t (Omega^2 = max_i sum_j |K_ij| / m_i);
      a mode's response to it is at most its double time integral, m eps (Omega t)^2 / 6
      |v t|. Omega^2 is about 18 c^2 / h^2 on this bar's triangles (6 on its
      quadrilaterals); with 1e4 c^2 / h^2 and the soft material (c = 0.414 m/s, h =
      0.01 m, t <= 1e-4 s: Omega t <= 0.414) the term stays below 0.6 eps |v t_n|."""
    return ((n + 1) * EPS / 2 * np.abs(vt) + n * EPS / 2 * np.abs(vt)
            + 2.5 * EPS * np.abs(X + vt) + STIFFNESS_ROUNDOFF * EPS * np.abs(vt))


STIFFNESS_ROUNDOFF = 0.6  # the last term of _translation_bound, in eps |v t_n|


def test_the_scene_reference_lists_every_probe_quantity():
    assert scene_keys.QUANTITIES == probes.QUANTITIES


@pytest.mark.parametrize("generator", sorted(MESHES))
def test_a_translating_bar_moves_every_probed_node_by_v_t(tmp_path, generator):
    h = _run(tmp_path, "translation", _scene(generator, E_SOFT, V,
                                             f"dt = {DT}\nn_steps = {N_STEPS}"))
    nodes = _nodes(generator)
    n, t = h["step"], h["time"]
    assert n[-1] == N_STEPS
    vt = V * t
    for name, point in POINTS:
        X = _nearest(nodes, point)
        z_err = np.abs(h[f"z_{name}"] - (X[1] + vt))
        assert np.all(z_err <= _translation_bound(n, vt, X[1])), (name, z_err.max())
        # r: u_r = 0 but for the stiffness's round-off (the last term of the bound)
        r_err = np.abs(h[f"r_{name}"] - X[0])
        assert np.all(r_err <= EPS * X[0] + STIFFNESS_ROUNDOFF * EPS * np.abs(vt)), name
    assert np.all(h["r_axis"] == 0.0)  # u_r = 0 on the axis, X = 0


@pytest.mark.parametrize("generator", sorted(MESHES))
def test_a_held_node_stays_at_its_position_exactly(tmp_path, generator):
    """The bar pushed at one end (1 MPa) and held at the other ([[fixed]] r and z): the
    node of the held face reads X, exactly, at every step; the pushed corner moves."""
    _, held, pushed = MESHES[generator]
    more = (f'[[fixed]]\nfacet = "{held}"\ncomponents = ["r", "z"]\n\n'
            f'[[loads]]\nfacet = "{pushed}"\npulse = "constant"\nvalue = 1e6\n\n')
    points = POINTS + (("foot", (0.0102, 0.0003)),)  # near the held face's node r = 0.01 m
    h = _run(tmp_path, "held", _scene(generator, 200e9, 0.0, "cfl = 0.5\nn_steps = 40",
                                      more, points))
    nodes = _nodes(generator)
    for name in ("axis", "foot"):  # nodes of the held face
        X = _nearest(nodes, dict(points)[name])
        assert X[1] == 0.0
        assert np.all(h[f"r_{name}"] == X[0]) and np.all(h[f"z_{name}"] == X[1]), name
    Xc = _nearest(nodes, dict(points)["corner"])
    # the pushed end moves down: by about p t c / E at the wave's arrival, far above round-off
    assert h["z_corner"][-1] < Xc[1] - 1e-3 * (1e6 / 200e9) * L
    assert math.isfinite(h["r_corner"][-1])


@pytest.mark.skipif(COMM.size > 1, reason="launches processes: serial only")
@pytest.mark.parametrize("generator", sorted(MESHES))
def test_two_ranks_report_what_one_rank_does(tmp_path, generator):
    """The translation on 2 ranks (the owner of each node reports it) against 1 rank: each
    within its bound of the closed form, so within twice that bound of each other; the
    held face's nodes equal."""
    text = _scene(generator, E_SOFT, V, f"dt = {DT}\nn_steps = {N_STEPS}")
    one = _run(tmp_path, "one", text)
    path, out = tmp_path / "two.toml", tmp_path / "two"
    path.write_text(text)
    subprocess.run([os.path.join(ROOT, "scripts", "mpirun.sh"), "-n", "2", sys.executable,
                    "-m", "impact_fenics", "run", str(path), "--out", str(out), "--quiet"],
                   check=True, capture_output=True, timeout=300, env=clean_mpi_env(), cwd=ROOT)
    two = np.genfromtxt(out / "history.csv", delimiter=",", names=True)
    with open(out / "summary.json") as f:
        assert json.load(f)["n_ranks"] == 2
    assert np.array_equal(one["time"], two["time"])
    vt = V * one["time"]
    for name, _ in POINTS:
        for q in ("r", "z"):
            col = f"{q}_{name}"
            bound = 2 * _translation_bound(one["step"], vt, np.abs(one[col]))
            assert np.all(np.abs(two[col] - one[col]) <= bound), col


@pytest.mark.parametrize("generator", sorted(MESHES))
def test_a_displacement_probe_reads_the_field_at_its_point(tmp_path, generator):
    """u_z probes against the node probes of the same run (the bar pushed at one end, held
    at the other): on a node a u_z probe reads that node's u_z = z - Z; at the midpoint of
    a cell edge on a node row, the mean of the edge's two nodes' u_z, whichever of the two
    cells touching the edge holds the point (the field is continuous there; a cell mean
    would take in a node above or below the row).

    Bound per row: the node probe's X + u and the test's z - Z round once each (eps |Z|
    with Z <= L); the interpolation weights come from differences of coordinates up to L
    on cells of H (L / H of their digits cancel), a few roundings each, then 3-4 products
    and sums on nodal values up to max |u|: EPS (6 L / H + 5) max |u|; and the mesh's own
    offset of its nodes from the points (below)."""
    _, held, pushed = MESHES[generator]
    node, left = (0.01, 0.02), (0.0, 0.02)  # two neighbouring nodes of the row z = 0.02
    mid = (0.005, 0.02)  # the midpoint of their edge
    more = (f'[[fixed]]\nfacet = "{held}"\ncomponents = ["r", "z"]\n\n'
            f'[[loads]]\nfacet = "{pushed}"\npulse = "constant"\nvalue = 1e6\n\n'
            + "".join(f'[[probes]]\nname = "uz_{name}"\npoint = [{p[0]}, {p[1]}]\n'
                      f'quantity = "u_z"\n\n' for name, p in (("node", node), ("mid", mid))))
    points = (("node", node), ("left", left))
    h = _run(tmp_path, "field", _scene(generator, 200e9, 0.0, "cfl = 0.5\nn_steps = 40",
                                       more, points))
    nodes = _nodes(generator)
    Xn, Xl = _nearest(nodes, node), _nearest(nodes, left)
    # the mesh's nodes are the points to the round-off of the generator's arithmetic; an
    # offset delta moves the interpolated value by at most |grad u| delta <= 2 max|u| / H delta
    delta = max(np.abs(Xn - node).max(), np.abs(Xl - left).max())
    assert delta <= 1e-6 * H  # the probes' nodes are these, not neighbours
    u_node, u_left = h["z_node"] - Xn[1], h["z_left"] - Xl[1]
    u_max = max(np.abs(u_node).max(), np.abs(u_left).max())
    assert u_max > 1e-3 * (1e6 / 200e9) * L  # the wave has moved the row
    bound = 2 * EPS * L + EPS * (6 * L / H + 5) * u_max + 2 * u_max / H * delta
    assert np.all(np.abs(h["uz_node"] - u_node) <= bound)
    assert np.all(np.abs(h["uz_mid"] - 0.5 * (u_node + u_left)) <= bound)
