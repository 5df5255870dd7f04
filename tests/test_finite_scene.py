"""A finite-strain scene through `impact-fenics run`, like every other scene (Simulation).

Oracles, none taken from the writer under test:

* the run directory: the marker, the copied scene, no DIR.partial left; a user's folder
  is refused before anything is written (rundir.py's rule);
* fields.xdmf read with ElementTree and h5py: one temporal collection, one grid per
  output time (every output_every steps from t = 0, and the end time), each piece of
  every grid holding every field; the cells are quadrilaterals listed once over the
  pieces, their nodes going round the cell (the shoelace area is the cell's), and
  their ring volumes
  sum(2 pi r_c A) add up to pi R^2 L (exact for a rectangle, whose centroid is its
  mean radius: round-off only, counted as in tests/roundoff.py), on any number of ranks;
* the displacement written at the end time moves the node that started at (0, L) to
  the final length of the summary (two paths, the field writer and the tracked node,
  adding the same two doubles: equal);
* energy.csv's balance is round-off at every row (the scheme's kinetic identity,
  kinetic + strain + plastic + work_gap - contact work = E_0 exactly in exact
  arithmetic: roundoff.ledger); history.csv's probes at the tracked nodes give the
  summary's final length to a few roundings of L;
* bad input: one line naming the table and the key, exit 2, nothing written;
* a signal in the loop stops the run at a step boundary with a complete directory.
"""
import json
import math
import os
import signal
import xml.etree.ElementTree as ET

import h5py
import numpy as np
import pytest
from mpi4py import MPI

from impact_fenics import cli
from impact_fenics.integrator import Integrator
from pvbatch_run import pvbatch_json
from roundoff import ledger, rounding
from scene_texts import COPPER_J2, launch, replace

COMM = MPI.COMM_WORLD
serial_only = pytest.mark.skipif(COMM.size > 1, reason="launches processes: serial only")
R, L, V0 = 3.2e-3, 32.4e-3, 227.0
# the Taylor bar on a 2 x 20 mesh, 8 us: the face is on the wall and yields (eps_p > 1)
TAYLOR = f"""title = "short Taylor bar"
[mesh]
generator = "quad_bar"
radius = {R!r}
length = {L!r}
n_r = 2

{COPPER_J2}
[bodies.bar]
material = "copper"
velocity = [0.0, -{V0!r}]
strain = "finite"

[wall]
z = 0.0
method = "film"

[time]
t_end = 8e-6
cfl = 0.5
dt_interval = 10

[output]
history_every = 3
output_every = 25
"""
FIELDS = {"displacement", "velocity", "sigma_rr", "sigma_zz", "sigma_tt", "sigma_rz",
          "von_mises", "eps_p_eq", "body_id"}


def _item(item, base):
    """An HDF DataItem, 'file:/path' or Xdmf3's hyperslab 'file:/path|start:stride:count:shape'."""
    source, _, slab = item.text.strip().partition("|")
    name, _, ds = source.partition(":")
    index = ...
    if slab:
        start, stride, count = (np.array(p.split(), dtype=int) for p in slab.split(":")[:3])
        index = tuple(slice(a, a + s * c, s) for a, s, c in zip(start, stride, count))
    with h5py.File(os.path.join(base, name), "r") as f:
        return f[ds][index].reshape([int(d) for d in item.get("Dimensions").split()])


@pytest.fixture(scope="module")
def taylor_run(tmp_path_factory):
    base = COMM.bcast(str(tmp_path_factory.mktemp("finite_scene")), root=0)
    scene = os.path.join(base, "taylor.toml")
    if COMM.rank == 0:
        with open(scene, "w") as f:
            f.write(TAYLOR)
    COMM.barrier()
    out = os.path.join(base, "run")
    assert cli.main(["run", scene, "--out", out, "--quiet"]) == 0
    with open(os.path.join(out, "summary.json")) as f:
        return out, json.load(f)


def test_the_scene_file_is_the_literatures_taylor_bar():
    """scenes/taylor_bar.toml reads as a finite-strain scene with the Taylor bar of the
    literature (copper, R = 3.2 mm, L = 32.4 mm, 227 m/s, 80 us: docs/taylor_bar.md)."""
    from impact_fenics import scene_file

    sc = scene_file.read_scene(os.path.join(os.path.dirname(__file__), "..", "scenes",
                                            "taylor_bar.toml"))
    assert sc.finite and sc.mesh.generator == "quad_bar"
    assert sc.mesh.params["radius"] == 3.2e-3 and sc.mesh.params["length"] == 32.4e-3
    m = sc.materials[sc.bodies[0].material]
    assert (m.model, m.E, m.nu, m.density, m.yield_stress, m.hardening) == (
        "j2", 117e9, 0.35, 8930.0, 400e6, 100e6)
    assert sc.bodies[0].velocity == (0.0, -227.0) and sc.time["t_end"] == 80e-6
    assert (sc.wall.z, sc.wall.method) == (0.0, "film")


def test_run_directory_and_summary(taylor_run):
    out, s = taylor_run
    assert not os.path.exists(out + ".partial")
    names = set(os.listdir(out))
    assert {".impact_fenics_run", "scene.toml", "summary.json", "history.csv", "history.png",
            "energy.csv", "contact_pairs.h5", "fields.xdmf"} <= names
    assert s["status"] == "completed" and s["n_ranks"] == COMM.size
    # the loop stops once t >= t_end (1 - 1e-12) (stepping.FollowingStep: a sum of steps
    # that lands within that of t_end ends the run), so the end time is t_end to 1e-12
    assert s["t_end"] == pytest.approx(8e-6, rel=1e-12)
    # the lumped mass is exact: round-off (a node's mass about 30 roundings, the sums one
    # per node of the 3 x 21)
    K0 = 0.5 * 8930.0 * math.pi * R * R * L * V0 ** 2
    assert s["energy_initial"] == pytest.approx(K0, rel=rounding(40 + 2 * 3 * 21))
    assert abs(s["energy"]["balance_error"]) <= ledger(s["n_steps"], s["n_dofs"]) * K0
    assert s["eps_p_max"] > 0.5 and s["contact"]["method"] == "film"
    assert 0 < s["dt_range"][0] <= s["dt_range"][1]
    # in contact from the first step to the last: under a varying step the duration runs
    # between the history's first and last rows with contact, t^1 and t_end (a count of
    # steps times the first dt overstates it once the cells crush and the step shrinks)
    (c,) = s["impact"]
    assert c["last_contact_time"] == s["t_end"]
    assert s["contact_duration"] == c["last_contact_time"] - c["first_contact_time"]
    assert s["contact_duration"] == pytest.approx(s["t_end"] - s["dt_range"][1], rel=1e-9)
    for key in ("final_length", "final_face_radius", "plastic_work", "stored_elastic",
                "j_min", "version", "date", "command_line", "setup_time", "scene_file",
                "timing", "step_time_median"):
        assert key in s, key
    # the material's force kernels (closures: compiled once per process) and the loop's
    # kernels compile at set-up, never inside the timed loop
    assert s["timing"]["compiled_in_loop"] == []


def test_energy_rows_and_tracked_nodes(taylor_run):
    out, s = taylor_run
    with open(os.path.join(out, "energy.csv")) as f:
        head = f.readline().strip().split(",")
    e = np.loadtxt(os.path.join(out, "energy.csv"), delimiter=",", skiprows=1, ndmin=2)
    assert e[-1, head.index("step")] == s["n_steps"] - 1  # the row of the last step
    bound = ledger(s["n_steps"], s["n_dofs"]) * s["energy_initial"]
    assert np.abs(e[:, head.index("balance_error")]).max() <= bound
    with open(os.path.join(out, "history.csv")) as f:
        head = f.readline().strip().split(",")
    h = np.loadtxt(os.path.join(out, "history.csv"), delimiter=",", skiprows=1, ndmin=2)
    # the probes at the nodes that start at (0, L), (0, 0) and (R, 0): a probe interpolates
    # its cell's four nodes at the point's reference coordinates, so at a node its value
    # is the node's to a few roundings of the positions' scale (16 eps L)
    length = (L + h[-1, head.index("u_z_top")]) - h[-1, head.index("u_z_bottom")]
    radius = R + h[-1, head.index("u_r_corner")]
    tol = 16 * np.finfo(float).eps * L
    assert abs(length - s["final_length"]) <= tol
    assert abs(radius - s["final_face_radius"]) <= tol


def test_fields_one_grid_per_output_with_every_field(taylor_run):
    out, s = taylor_run
    root = ET.parse(os.path.join(out, "fields.xdmf")).getroot()
    series = root.findall("Domain/Grid")
    assert len(series) == 1 and series[0].get("CollectionType") == "Temporal"
    steps = series[0].findall("Grid")
    names = [g.get("Name") for g in steps]
    n = s["n_steps"]
    assert names == [f"step_{k}" for k in range(0, n, 25)] + ([f"step_{n}"] if n % 25 else [])
    assert float(steps[-1].find("Time").get("Value")) == s["t_end"]  # written with repr()
    volume = 0.0
    n_cells = 0
    for step in steps:
        pieces = step.findall("Grid")
        assert len(pieces) == COMM.size
        for p in pieces:
            topo = p.find("Topology")
            assert topo.get("TopologyType") == "Quadrilateral" and topo.get("NodesPerElement") == "4"
            arrays = {a.get("Name"): a for a in p.findall("Attribute")}
            assert set(arrays) == FIELDS
            if step is steps[0]:
                xy = _item(p.find("Geometry/DataItem"), out)
                cells = _item(topo.find("DataItem"), out).astype(int)
                c = xy[cells]  # (m, 4, 2), nodes going round the cell
                x, y = c[..., 0], c[..., 1]
                area = 0.5 * (x * np.roll(y, -1, axis=1) - np.roll(x, -1, axis=1) * y).sum(axis=1)
                # going round: the shoelace area is the cell's (a bow-tie order gives 0);
                # its 8 products and sums round on the coordinates' size, R L
                assert np.allclose(np.abs(area), (R / 2) * (L / 20), rtol=0,
                                   atol=rounding(8, R * L))
                volume += float((2 * math.pi * c[..., 0].mean(axis=1) * np.abs(area)).sum())
                n_cells += cells.shape[0]
    assert n_cells == s["n_cells"] == 2 * 20
    # each ring: its area's rounding relative to the area (8 R L / A), the centroid and
    # the products (8); the sum of 40 rings (40)
    cell = (R / 2) * (L / 20)
    assert volume == pytest.approx(math.pi * R * R * L, rel=rounding(8 * R * L / cell + 48))
    # the last displacement moves the node (0, L) to the summary's final length
    z_top = []
    for p in steps[-1].findall("Grid"):
        xy = _item(p.find("Geometry/DataItem"), out)
        u = _item(p.find("Attribute[@Name='displacement']/DataItem"), out)
        # the node (0, L): 1e-12 m, far above round-off, far below h
        k = np.flatnonzero(np.hypot(xy[:, 0], xy[:, 1] - L) < 1e-12)
        z_top += list(xy[k, 1] + u[k, 1])
    assert z_top and np.all(np.array(z_top) == s["final_length"])


def test_a_held_face_stays_on_the_wall(tmp_path_factory):
    """[wall] face = "held" (the Taylor references' condition): u_z = 0 on the face Z = 0
    through the run, read back from the last grid of fields.xdmf (round-off), the
    face's nodes sliding outward (u_r > 0 at the rim), and the face's stop at t = 0
    booked as impact_face_loss = 1/2 m_face v0^2, where the row-sum lumped mass of the
    face is half the bottom cell row's, rho pi R^2 (L / 20) / 2, exactly (the Q1 shape
    functions are linear in Z and the 2 pi R weight does not depend on Z): round-off
    (each face node's mass about 30 roundings, their sum 3, 1/2 m v0^2 3 more)."""
    base = COMM.bcast(str(tmp_path_factory.mktemp("held_face")), root=0)
    scene = os.path.join(base, "held.toml")
    if COMM.rank == 0:
        with open(scene, "w") as f:
            f.write(replace(TAYLOR, 'method = "film"', 'method = "film"\nface = "held"'))
    COMM.barrier()
    out = os.path.join(base, "run")
    assert cli.main(["run", scene, "--out", out, "--quiet"]) == 0
    with open(os.path.join(out, "summary.json")) as f:
        s = json.load(f)
    assert s["wall_face"] == "held"
    m_face = 0.5 * 8930.0 * math.pi * R * R * (L / 20)
    assert s["impact_face_loss"] == pytest.approx(0.5 * m_face * V0 ** 2, rel=rounding(40))
    root = ET.parse(os.path.join(out, "fields.xdmf")).getroot()
    u_face, r_face = [], []
    for p in root.findall("Domain/Grid")[0].findall("Grid")[-1].findall("Grid"):
        xy = _item(p.find("Geometry/DataItem"), out)
        u = _item(p.find("Attribute[@Name='displacement']/DataItem"), out)
        k = np.flatnonzero(np.abs(xy[:, 1]) < 1e-12)  # the face Z = 0 (m): far above round-off
        u_face += list(u[k, 1])
        r_face += list(xy[k, 0] + u[k, 0])
    u_face, r_face = COMM.allgather(u_face), COMM.allgather(r_face)
    u_face = np.concatenate([np.asarray(a, dtype=float) for a in u_face])
    r_face = np.concatenate([np.asarray(a, dtype=float) for a in r_face])
    # zero to round-off of the bar's length (the face's nodes are wall candidates too, and
    # the wall's projection u = z_wall - Z of a node on it keeps the rounding of its
    # coordinate Z, a few 1e-18 m)
    assert u_face.size >= 3 and np.abs(u_face).max() <= rounding(4, L)
    # the written geometry and the tracked node's coordinate: the same point through two
    # maps (a few roundings of R)
    assert r_face.max() == pytest.approx(s["final_face_radius"], rel=rounding(4))
    assert r_face.max() > R


def test_paraview_default_reader_opens_the_quadrilaterals(taylor_run):
    out, s = taylor_run
    result = pvbatch_json(os.path.join(out, "fields.xdmf")) if COMM.rank == 0 else None
    result = COMM.bcast(result, root=0)
    if result is None:
        pytest.skip("pvbatch (ParaView) is not installed: the structure is checked from the files")
    for step in result["steps"]:
        assert sum(b["cells"] for b in step["blocks"]) == s["n_cells"]
        for block in step["blocks"]:
            assert set(block["arrays"]) == FIELDS
    assert result["warped_points"] > 0


def test_plot_renders_the_quadrilaterals(taylor_run):
    """`impact-fenics plot` on the finite run: a PNG of eps_p_eq at the end time."""
    out, s = taylor_run
    assert cli.main(["plot", out, "--field", "eps_p_eq", "--times", repr(s["t_end"])]) == 0
    if COMM.rank == 0:
        pngs = [n for n in os.listdir(out) if n.startswith("eps_p_eq_t") and n.endswith(".png")]
        assert len(pngs) == 1 and os.path.getsize(os.path.join(out, pngs[0])) > 1000


@serial_only
def test_progress_only_on_a_terminal(tmp_path):
    from test_cli import _run_in_terminal

    (tmp_path / "s.toml").write_text(TAYLOR)
    code, text = _run_in_terminal(["run", tmp_path / "s.toml", "--out", tmp_path / "a"])
    assert code == 0, text
    assert "t = 8.0000e-06 of 8.0000e-06 s" in text and "steps/s" in text and "ETA" in text
    proc = launch(["run", tmp_path / "s.toml", "--out", tmp_path / "b"])  # stdout: a pipe
    assert proc.returncode == 0 and "short Taylor bar: completed" in proc.stdout
    assert "steps/s" not in proc.stdout + proc.stderr


def test_a_users_folder_is_refused(tmp_path, capsys):
    base = COMM.bcast(str(tmp_path), root=0)
    scene, out = os.path.join(base, "s.toml"), os.path.join(base, "mine")
    if COMM.rank == 0:
        os.makedirs(out)
        with open(os.path.join(out, "thesis.tex"), "w") as f:
            f.write("mine\n")
        with open(scene, "w") as f:
            f.write(TAYLOR)
    COMM.barrier()
    with pytest.raises(SystemExit) as exit_:
        cli.main(["run", scene, "--out", out, "--quiet"])
    assert exit_.value.code == 2
    if COMM.rank == 0:
        assert "is not a run directory" in capsys.readouterr().err
        assert os.listdir(out) == ["thesis.tex"] and not os.path.exists(out + ".partial")


def test_a_signal_in_the_loop_leaves_a_complete_directory(tmp_path, monkeypatch, capsys):
    """SIGINT at step 5: serially the run stops after that step, under MPI at the next
    agreement (step 64) or the end; the directory is published with its summary, and the
    one line says where it stopped in time of t_end (the steps of a run whose step follows
    its cells are not known ahead)."""
    base = COMM.bcast(str(tmp_path), root=0)
    scene, out = os.path.join(base, "s.toml"), os.path.join(base, "run")
    if COMM.rank == 0:
        with open(scene, "w") as f:
            f.write(TAYLOR)
    COMM.barrier()
    real = Integrator.advance

    def advance(self):  # (the step is taken: the state is n + 1 when it returns)
        if self.n == 6 and COMM.rank == COMM.size - 1:
            os.kill(os.getpid(), signal.SIGINT)
        return real(self)

    monkeypatch.setattr(Integrator, "advance", advance)
    code = cli.main(["run", scene, "--out", out, "--quiet"])
    assert code == 128 + signal.SIGINT
    with open(os.path.join(out, "summary.json")) as f:
        s = json.load(f)
    assert s["status"] == "interrupted by SIGINT"
    assert s["n_steps"] == (7 if COMM.size == 1 else 64)
    assert not os.path.exists(out + ".partial")
    if COMM.rank == 0:
        lines = [ln for ln in capsys.readouterr().err.splitlines() if ln.startswith("stopped:")]
        assert len(lines) == 1 and f"at step {s['n_steps']}, t = " in lines[0], lines
        assert lines[0].split(", t = ")[1].startswith(f"{1e6 * s['t_end']:.5g} us of 8 us")


# bad input: (id, (old, new) edit of TAYLOR, the start of the message after "error: ")
CASES = [
    ("finite on triangles", ("n_r = 2", "h = 1e-3"),
     '[mesh] generator = "bar": a finite-strain body needs generator = "quad_bar"'),
    ("held face without finite strain", ('strain = "finite"\n\n[wall]\nz = 0.0\nmethod = "film"',
                                         '\n[wall]\nz = 0.0\nmethod = "film"\nface = "held"'),
     '[wall] face = "held": a finite-strain body\'s condition'),
    ("bad strain", ('strain = "finite"', 'strain = "large"'),
     '[bodies.bar] strain = "large": use one of small, finite'),
    ("bad wall method", ('method = "film"', 'method = "glue"'),
     '[wall] method = "glue": use one of film, dme, penalty'),
    ("unknown wall key", ('method = "film"', 'method = "film"\nroughness = 0.2'),
     "[wall] unknown key 'roughness'"),
    ("negative penalty", ('method = "film"', 'method = "penalty"\npenalty = -1e9'),
     "[wall] penalty = -1000000000.0: must be > 0"),
    ("penalty above the bound", ('method = "film"', 'method = "penalty"\npenalty = 1e15'),
     "[wall] penalty: beta_max = "),
    ("wall cuts the bar", ("z = 0.0", "z = 0.001"), "[wall] the wall z = 0.001 m cuts the body"),
    ("cfl above 1", ("cfl = 0.5", "cfl = 1.5"), "[time] cfl = 1.5: must be <= 1"),
    ("n_steps", ("t_end = 8e-6", "n_steps = 100"), "[time] n_steps: the finite-strain step varies"),
    ("node pairs on one bar", ("[time]", '[[contact]]\nlower = "a"\nupper = "b"\n'
                                              'method = "film"\n\n[time]'),
     "[contact #1] a contact between deformable faces needs two bodies: [mesh] generator = "
     '"quad_bar" makes one'),
    ("probe named as a tracked node's", ("[time]", '[[probes]]\nname = "u_z_top"\nquantity = '
                                                    '"u_z"\npoint = [0.0, 1e-3]\n\n[time]'),
     '[probes #1] name = "u_z_top": the bar\'s tracked nodes\' probe has it'),
    ("viscous finite J2", ("hardening = 100e6", "hardening = 100e6\nviscosity = 1.0"),
     '[materials.copper] viscosity = 1.0: the finite-strain form of model = "j2" (FiniteJ2) '
     "has no such parameter"),
    ("elastic at finite strain", ('model = "j2"\nE = 117e9\nnu = 0.35\ndensity = 8930.0\n'
                                  'yield_stress = 400e6\nhardening = 100e6',
                                  'model = "elastic"\nE = 117e9\nnu = 0.35\ndensity = 8930.0'),
     '[materials.copper] model = "elastic" has a small-strain form only: its body needs '
     'strain = "small" (at finite strain an elastic solid is model = "neo_hookean")'),
    ("bad n_r", ("n_r = 2", "n_r = 0"), "[mesh] n_r = 0: must be an integer >= 1"),
    ("bad face", ('method = "film"', 'method = "film"\nface = "glued"'),
     '[wall] face = "glued": use one of contact, held'),
    ("held face off the wall", ("z = 0.0", 'z = -0.001\nface = "held"'),
     '[wall] face = "held": it keeps the bar\'s face Z = 0 on the wall and needs z = 0'),
]


def _write(tmp, edit):
    scene = tmp / "scene.toml"
    text = replace(TAYLOR, *edit)
    if edit == ("n_r = 2", "h = 1e-3"):  # the same bar of triangles
        text = replace(text, 'generator = "quad_bar"', 'generator = "bar"')
    scene.write_text(text)
    return ["run", str(scene), "--quiet", "--out", str(tmp / "out")]


@serial_only
@pytest.mark.parametrize("edit, expected", [c[1:] for c in CASES], ids=[c[0] for c in CASES])
def test_bad_finite_scene_one_line_exit_2(tmp_path, edit, expected):
    proc = launch(_write(tmp_path, edit))
    lines = [ln for ln in proc.stderr.splitlines() if ln.strip()]
    assert proc.returncode == 2, proc.stderr
    assert len(lines) == 1 and lines[0].startswith("error: " + expected), proc.stderr
    assert "Traceback" not in proc.stderr + proc.stdout
    assert not (tmp_path / "out").exists() and not (tmp_path / "out.partial").exists()


@pytest.mark.parametrize("edit, expected", [c[1:] for c in CASES], ids=[c[0] for c in CASES])
def test_bad_finite_scene_in_process(tmp_path, capsys, edit, expected):
    with pytest.raises(SystemExit) as exit_:
        cli.main(_write(tmp_path, edit))
    assert exit_.value.code == 2
    err = [ln for ln in capsys.readouterr().err.splitlines() if ln.strip()]
    if COMM.rank == 0:
        assert len(err) == 1 and err[0].startswith("error: " + expected), err
    assert not (tmp_path / "out").exists() and not (tmp_path / "out.partial").exists()


def test_an_energy_cadence_is_taken_at_finite_strain(tmp_path):
    """[output] energy_every, as in every scene: the energy rows every 5 steps and at the
    last."""
    base = COMM.bcast(str(tmp_path), root=0)
    scene, out = os.path.join(base, "scene.toml"), os.path.join(base, "out")
    if COMM.rank == 0:
        with open(scene, "w") as f:
            f.write(replace(TAYLOR, "output_every = 25", "output_every = 25\nenergy_every = 5"))
    COMM.barrier()
    assert cli.main(["run", scene, "--quiet", "--out", out]) == 0
    with open(os.path.join(out, "summary.json")) as f:
        n = json.load(f)["n_steps"]
    e = np.loadtxt(os.path.join(out, "energy.csv"), delimiter=",", skiprows=1, ndmin=2)
    assert e[:, 0].tolist() == list(range(0, n - 1, 5)) + [n - 1]
