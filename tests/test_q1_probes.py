"""Probes on Q1 quadrilaterals, and small-strain scene files on ``quad_bar``.

Oracles:

* a probe at a node reads that node's value exactly; inside a cell or on an edge, under
  a bilinear field u = a + b r + c z + d r z (in the Q1 space of a mesh of rectangles),
  it reads the field at the point to round-off;
* on the nu = 0 wave of tests/test_small_strain_q1.py (h = 0.01 m, a linear and an
  elastic J2 body) a probe at a cell's centre reads, every step, what that test reads
  directly: D times the cell's mean strain (the weighted mean of the J2 points'
  stresses) and the mean of the cell's nodal u_z, to round-off;
* scenes/elastic_wave_q1.toml run through the CLI against d'Alembert with the
  tolerances of the Python Q1 wave test; ParaView's default reader opens its fields
  (quadrilaterals, every cell once);
* a rigid punch striking the scene's bar (DME, FILM, penalty): the momentum of punch and
  bar is the punch's initial one to round-off (the contact force acts on both);
* what a quad_bar scene does not run is refused: exit 2, one line, nothing written.
"""
import math
import os
import xml.etree.ElementTree as ET

import numpy as np
import pytest
from dolfinx import fem
from mpi4py import MPI

from roundoff import rounding
from scene_texts import ROOT, launch, replace
from test_small_strain_q1 import (E, P0, PROBE_R, RHO, STATIONS, T_END, T_RISE, probe_cell)

from impact_fenics import cli, q1
from impact_fenics.bodies import Body, DeformableModel
from impact_fenics.quad_meshes import quad_bar
from impact_fenics.integrator import Integrator
from impact_fenics.internal_force.quadrature import QuadPointGeometry
from impact_fenics.loads import SurfaceLoad, Trapezoid
from impact_fenics.materials import LinearElastic
from impact_fenics.materials.j2 import J2
from impact_fenics.operators import elastic_stiffness
from impact_fenics.probes import Probes, arrival_time
from impact_fenics.quad_meshes import quad_rectangle, tag_rectangle
from impact_fenics.stability import critical_dt, element_omega_bound

COMM = MPI.COMM_WORLD
SCENE = os.path.join(ROOT, "scenes", "elastic_wave_q1.toml")
serial_only = pytest.mark.skipif(COMM.size > 1, reason="launches processes: serial only")


def read_probes(probes: Probes, u_owned: np.ndarray) -> np.ndarray:
    """The probes' values at the owned displacement ``u_owned`` (m): one raw row recorded,
    summed over the ranks, evaluated."""
    block = np.zeros(probes.n_raw)
    probes.recorder(u_owned, block)(0)
    COMM.Allreduce(MPI.IN_PLACE, block, op=MPI.SUM)
    return probes.values(block[None, :])[0]


# ------------------------------------------------------------------ a bilinear field
A_R, B_R, C_R, D_R = 1e-4, 2e-3, -3e-3, 5e-2  # u_r = a + b r + c z + d r z (m)
A_Z, B_Z, C_Z, D_Z = -2e-4, 4e-3, 1e-3, -7e-2  # u_z


def bilinear(xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    r, z = xy[..., 0], xy[..., 1]
    return A_R + B_R * r + C_R * z + D_R * r * z, A_Z + B_Z * r + C_Z * z + D_Z * r * z


NODES = [(0.0, 0.1), (0.01, 0.13), (0.04, 0.25), (0.03, 0.19)]  # (r, z) m: mesh nodes
INSIDE = [(0.0137, 0.1412), (0.0333, 0.2291), (0.02, 0.1777), (0.0051, 0.16)]  # cells, an edge


def test_probe_reads_nodes_exactly_and_a_bilinear_field_to_round_off():
    """On rectangles 0.01 x 0.03 m, r in [0, 0.04], z in [0.1, 0.25]."""
    tm = quad_rectangle(COMM, 0.0, 0.1, 0.04, 0.25, 4, 5, "body")
    model = DeformableModel(tm, [Body("body", LinearElastic(E=E, nu=0.3, density=RHO))])
    owned_xy = model.node_xy[: model.n_owned // 2]
    ur, uz = bilinear(owned_xy)
    u_owned = np.column_stack([ur, uz]).ravel()
    points = NODES + INSIDE
    specs = [(f"{q}_{k}", p, q) for k, p in enumerate(points) for q in ("u_r", "u_z")]
    got = read_probes(Probes(model, specs), u_owned).reshape(-1, 2)
    for k, p in enumerate(NODES):  # the value stored at the node nearest to p
        d = np.hypot(owned_xy[:, 0] - p[0], owned_xy[:, 1] - p[1])
        i = int(np.argmin(d)) if d.size else -1
        best, rank = COMM.allreduce((float(d[i]) if i >= 0 else np.inf, COMM.rank), op=MPI.MINLOC)
        assert best <= 1e-12
        node = COMM.bcast(u_owned[2 * i: 2 * i + 2] if COMM.rank == rank else None, root=rank)
        assert got[k, 0] == node[0] and got[k, 1] == node[1]
    exact = np.column_stack(bilinear(np.array(INSIDE)))
    # round-off: the point's reference coordinates carry a few roundings of 1 (Newton's
    # last step), times the field's variation over a cell (< its size here), and the
    # interpolation sums four products: 64 roundings of the largest value
    scale = float(np.max(np.abs(exact)))
    if COMM.rank == 0:
        print(f"bilinear field: probe error {np.max(np.abs(got[len(NODES):] - exact)):.3g} m "
              f"of {scale:.3g} m")
    assert np.max(np.abs(got[len(NODES):] - exact)) <= rounding(64, scale)


def test_reference_point_inverts_the_bilinear_map_of_a_distorted_cell():
    """xi of x(xi0) is xi0 on a cell that is not a parallelogram (Newton's iterations)."""
    X = np.array([[0.0, 0.0], [1.0, 0.1], [0.2, 0.9], [1.3, 1.2]])
    for xi0 in ([0.3, 0.7], [0.9, 0.05], [0.5, 0.5]):
        x = q1.shape_functions(np.array([xi0]))[0][0] @ X
        assert np.max(np.abs(q1.reference_point(X, x) - xi0)) <= rounding(16)


# ------------------------------------------------------------------ the nu = 0 wave
@pytest.mark.parametrize("kind", ["linear", "j2", "j2_yielding"])
def test_probe_reads_the_q1_wave_as_the_direct_read(kind):
    """tests/test_small_strain_q1.py's wave at h = 0.01 m, its probe cells (nearest
    centroid to (0.02, z)) read by probes at their centroids, every step to T_END; a J2 bar
    whose yield stress is 0.6 P0 (it yields behind the front) also by its eps_p_eq
    probes against the mean of the points' equivalent plastic strains."""
    h = 0.01
    n_r, n_z = round(0.05 / h), round(1.0 / h)
    tm = tag_rectangle(quad_bar(COMM, 0.05, 1.0, n_r, n_z), "bar")
    material = (LinearElastic(E=E, nu=0.0, density=RHO) if kind == "linear"
                else J2(E=E, nu=0.0, density=RHO,
                        yield_stress=0.6 * P0 if kind == "j2_yielding" else 1e300))
    quantities = ("sigma_zz", "u_z") + (("eps_p_eq",) if kind != "linear" else ())
    nq = len(quantities)
    model = DeformableModel(tm, [Body("bar", material)])
    dt = 0.9 * critical_dt(element_omega_bound(model, model.axis_dofs(owned=False)))
    load = SurfaceLoad(model, "bottom", Trapezoid(P0, T_RISE, 1e-4, 1.2e-4))
    integ = Integrator(model, dt, model.axis_dofs(), loads=[load])
    cells = [probe_cell(model, (PROBE_R, z)) for z in STATIONS]
    specs = [(f"{q}_{i}", (float(c[0]), float(c[1])), q)
             for i, (_, c) in enumerate(cells) for q in quantities]
    probes = Probes(model, specs, integ.nonlinear)
    owned = model.owned_cells("bar")
    geo = [QuadPointGeometry(model, owned[[k]]) if k >= 0 else None for k, _ in cells]
    D = elastic_stiffness(material)
    u_local = fem.Function(model.V)
    eps = np.zeros((1, 4))
    n_steps = int(math.ceil(T_END / dt))
    direct, probed = np.zeros((n_steps, 2 * nq)), np.zeros((n_steps, 2 * nq))
    for n in range(n_steps):
        u_local.x.array[: model.n_owned] = integ.u_owned
        u_local.x.scatter_forward()
        # recorded before the step's point update: the probe reruns it (what predict does)
        probed[n] = read_probes(probes, integ.u_owned)
        integ.predict()
        integ.advance()
        for i, ((k, _), g) in enumerate(zip(cells, geo)):
            if k < 0:
                continue
            if kind == "linear":
                q1.mean_strain(g.dofs, g.dNdr, g.dNdz, g.N, g.inv_r, g.w, u_local.x.array, eps)
                direct[n, nq * i] = float((D @ eps[0])[2])
            else:
                f = integ.nonlinear[0]
                direct[n, nq * i] = float(f.qs.sigma[k, :, 2] @ f.geometry.w[k]
                                          / f.geometry.w[k].sum())
                direct[n, nq * i + 2] = float(f.qs.state[k, :, 0].mean())  # eps_bar_p
            direct[n, nq * i + 1] = float(u_local.x.array[2 * g.dofs[0] + 1].mean())
    direct = COMM.allreduce(direct, op=MPI.SUM)  # one rank holds each cell
    # round-off: a sum of four products (D eps, the weighted mean, the centroid's weights
    # 1/4 to a few roundings) against numpy's: 16 roundings of the column's largest value
    if COMM.rank == 0:
        largest = np.max(np.abs(direct), axis=0)
        rel = np.max(np.abs(probed - direct), axis=0) / np.where(largest > 0, largest, 1.0)
        print(f"Q1 wave {kind}: probe - direct read / the column's largest: {rel}")
    if kind == "j2":
        assert not np.any(direct[:, 2::nq])  # it never yields
    for col in range(2 * nq):
        scale = float(np.max(np.abs(direct[:, col])))
        assert scale > 0.0 or kind == "j2"
        assert np.max(np.abs(probed[:, col] - direct[:, col])) <= rounding(16, scale), col


def test_q1_probes_in_compiled_steps_equal_python_steps(tmp_path_factory):
    """A Q1 bar struck by its initial velocity (no loads: the loop runs compiled blocks)
    with u and stress probes: everything the run writes equals the Python steps' run, bit
    for bit (tests/test_step_block.py's oracle)."""
    from impact_fenics.simulation import Simulation
    from test_step_block import _same, _settings

    tm = tag_rectangle(quad_bar(COMM, 0.05, 0.4, 4, 32), "bar")

    def make(out, compiled):
        model = DeformableModel(tm, [Body("bar", LinearElastic(E=E, nu=0.3, density=RHO))])
        sim = Simulation(model, _settings(out, compiled, n_steps=80, output_every=20),
                         fixed=[model.facet_dofs("top", 1)],
                         initial_velocity={"bar": (0.0, 5.0)})
        for q in ("sigma_zz", "sigma_rr", "u_r", "u_z"):
            sim.add_probe(f"{q}_obs", (0.0213, 0.3117), q)
        return sim
    got = _same(make, tmp_path_factory, "q1_block", expect_contact=False)
    assert np.max(np.abs(got["history.u_z_obs"])) > 0.0
    assert np.max(np.abs(got["history.sigma_zz_obs"])) > 0.0


# ------------------------------------------------------------------ the scene file
def _history(out: str):
    return np.genfromtxt(os.path.join(out, "history.csv"), delimiter=",", names=True)


@pytest.fixture(scope="module")
def scene_run(tmp_path_factory):
    out = COMM.bcast(str(tmp_path_factory.mktemp("q1_scene") / "wave") if COMM.rank == 0
                     else None, root=0)
    assert cli.main(["run", SCENE, "--out", out, "--quiet"]) == 0
    import json

    with open(os.path.join(out, "summary.json")) as f:
        return out, json.load(f)


def test_scene_wave_against_dalembert(scene_run):
    """The tolerances of the Python Q1 wave test at the scene's h = 0.005 m: arrival of the
    ramp's half level within h / c0 of z / c0 + t_rise / 2, the speed between the probes
    within h / (their distance), plateau stress and velocity within (h / l)^2 (l = c0 t_rise
    = 0.1 m), sigma = -rho c0 v within twice that."""
    out, summary = scene_run
    h, z = 0.005, (0.3025, 0.6025)  # the scene's cells and probe points (cell centres)
    hist = _history(out)
    t = hist["time"]
    c0 = math.sqrt(E / RHO)
    arrivals = [arrival_time(t, -hist[f"sigma_zz_{i}"], 0.5 * P0) for i in range(2)]
    for zi, ti in zip(z, arrivals):
        assert abs(ti - (zi / c0 + T_RISE / 2)) <= h / c0
    speed = (z[1] - z[0]) / (arrivals[1] - arrivals[0])
    window = (t > arrivals[0] + 3e-5) & (t < arrivals[0] + 7e-5)
    stress = float(np.mean(hist["sigma_zz_0"][window]))
    velocity = float(np.polyfit(t[window], hist["u_z_0"][window], 1)[0])
    if COMM.rank == 0:
        print(f"Q1 scene: speed {speed:.1f} vs c0 {c0:.1f} m/s, plateau {stress / 1e6:.3f} MPa, "
              f"v {velocity:.5f} m/s vs {P0 / (RHO * c0):.5f}, {summary['n_steps']} steps")
    assert abs(speed - c0) / c0 <= h / (z[1] - z[0])
    tol = (h / 0.1) ** 2
    v_exact = P0 / (RHO * c0)
    assert abs(stress + P0) <= tol * P0
    assert abs(velocity - v_exact) <= tol * v_exact
    assert abs(stress + RHO * c0 * velocity) <= 2 * tol * P0


def test_scene_fields_are_quadrilaterals_paraview_opens(scene_run):
    """fields.xdmf's pieces are Quadrilateral; pvbatch's default reader (if installed) sees
    every cell once at every time, with sigma_zz on the cells."""
    out, summary = scene_run
    from pvbatch_run import pvbatch_json

    n_cells = 10 * 200
    result = None
    if COMM.rank == 0:
        root = ET.parse(os.path.join(out, "fields.xdmf")).getroot()
        types = {t.get("TopologyType") for t in root.iter("Topology")}
        assert types == {"Quadrilateral"}, types
        result = pvbatch_json(os.path.join(out, "fields.xdmf"))
    result = COMM.bcast(result, root=0)
    if result is None:
        pytest.skip("pvbatch (ParaView) is not installed: the topology is checked from the file")
    assert len(result["times"]) >= 2
    for step in result["steps"]:
        assert sum(b["cells"] for b in step["blocks"]) == n_cells
        assert all(b["arrays"]["sigma_zz"]["where"] == "cell" for b in step["blocks"])
    assert result["warped_points"] > 0


# ------------------------------------------------------------------ a rigid punch
PUNCH_MASS, PUNCH_V = 5.0, -5.0  # kg, m/s


def punch_scene(method: str) -> str:
    """The scene's bar without its load, struck on its top face by a rigid punch."""
    with open(SCENE) as f:
        text = f.read()
    load = text[text.index("[[loads]]"): text.index("[time]")]
    return replace(text, load, f"""[rigid.punch]
mass = {PUNCH_MASS}              # kg
velocity = {PUNCH_V}          # m/s

[[contact]]
surface = "top"
rigid = "punch"
radius = 0.05
method = "{method}"

""")


@pytest.mark.parametrize("method", ["dme", "film", "penalty"])
def test_rigid_punch_on_a_q1_scene_conserves_momentum(tmp_path, method):
    """No support: the punch's impulse on the bar is the bar's momentum gain. Round-off:
    each step's contact force is one number applied to both, its spread over the face's
    11 nodes and the momentum sums over 2211 nodes round: n_steps x 64 roundings of
    m v0 (the measured error is about 1e-13 of it)."""
    base = COMM.bcast(str(tmp_path), root=0)
    scene, out = os.path.join(base, "punch.toml"), os.path.join(base, "run")
    if COMM.rank == 0:
        with open(scene, "w") as f:
            f.write(punch_scene(method))
    COMM.barrier()
    assert cli.main(["run", scene, "--out", out, "--quiet"]) == 0
    import json

    with open(os.path.join(out, "summary.json")) as f:
        s = json.load(f)
    (impact,) = s["impact"]
    bar = s["bodies"]["bar"]
    p0 = PUNCH_MASS * PUNCH_V
    p = PUNCH_MASS * impact["velocity_upper_after"] + bar["mass"] * bar["velocity_z_final"]
    if COMM.rank == 0:
        print(f"Q1 punch {method}: momentum error {abs(p - p0) / abs(p0):.3g} of m v0, punch "
              f"{impact['velocity_upper_after']:.4g} m/s, bar {bar['velocity_z_final']:.4g} m/s")
    assert impact["velocity_upper_after"] > PUNCH_V  # it was slowed
    assert abs(p - p0) <= rounding(64 * s["n_steps"], abs(p0))


# ------------------------------------------------------------------ refusals
REFUSALS = [
    ("two bodies", ('[bodies.bar]\nmaterial = "steel"',
                    '[bodies.bar]\nmaterial = "steel"\n\n[bodies.rod]\nmaterial = "steel"'),
     '[mesh] generator = "quad_bar" makes one body; the scene has 2 ([bodies])'),
    ("contact of deformable faces",
     ("[time]", '[[contact]]\nlower = "bottom"\nupper = "top"\nmethod = "film"\n\n[time]'),
     '[contact #1] a contact between deformable faces needs two bodies: [mesh] generator = '
     '"quad_bar" makes one'),
]


@serial_only
@pytest.mark.parametrize("edit, expected", [c[1:] for c in REFUSALS], ids=[c[0] for c in REFUSALS])
def test_quad_bar_scene_refusals_one_line_exit_2(tmp_path, edit, expected):
    scene = tmp_path / "scene.toml"
    with open(SCENE) as f:
        scene.write_text(replace(f.read(), *edit))
    proc = launch(["run", str(scene), "--quiet", "--out", str(tmp_path / "out")])
    lines = [ln for ln in proc.stderr.splitlines() if ln.strip()]
    assert proc.returncode == 2, proc.stderr
    assert len(lines) == 1 and lines[0].startswith("error: " + expected), proc.stderr
    assert "Traceback" not in proc.stderr + proc.stdout
    assert not (tmp_path / "out").exists() and not (tmp_path / "out.partial").exists()
