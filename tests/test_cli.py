"""The command line and the scene files: the same numbers as the demos, under mpirun too.

Oracles: the demos' own ``run()`` (the scene files in scenes/ must reproduce
them: on one rank they evaluate the same expressions, so exactly; on more the two
build and partition their meshes apart, so within the spread of a one-ulp change of
the scene's start, tests/roundoff.py), the library's scene builders, closed forms for
a hand-written .msh (mass rho pi R^2 L, load p pi R^2), and the progress
specification (a progress line on a terminal only, never with --quiet).
"""
import json
import math
import os
import select
import subprocess
import sys
import time

import numpy as np
import pytest
from mpi4py import MPI

from conftest import clean_mpi_env, load_demo
from impact_fenics import cli, scene_file, scenes
from impact_fenics.simulation import Settings
from roundoff import assert_runs_agree, assert_within_spread, one_ulp, rounding
from scene_texts import BAR, PAIR, RIGID, ROOT, launch, replace

serial_only = pytest.mark.skipif(MPI.COMM_WORLD.size > 1, reason="launches processes: serial only")
SCENES = os.path.join(ROOT, "scenes")
ENERGIES = ("kinetic", "strain", "external_work", "contact_work", "total")


def _shared_dir(tmp_path) -> str:
    """One output path for every rank (rank 0's tmp_path)."""
    return MPI.COMM_WORLD.bcast(str(tmp_path), root=0)


def _cli_run(scene: str, out: str, *args: str) -> dict:
    assert cli.main(["run", scene, "--out", out, "--quiet", *args]) == 0
    with open(os.path.join(out, "summary.json")) as f:
        return json.load(f)


def _history(out: str):
    """history.csv of a run directory (17 significant digits: every double reads back)."""
    return np.genfromtxt(os.path.join(out, "history.csv"), delimiter=",", names=True)


def _perturbed(text: str, key: str, value: float, base: str, name: str):
    """Under MPI: (summary, history) of the scene ``text`` run with the line ``key = value``
    (its load's peak) or ``key = [0.0, value]`` (its initial velocity) moved by one ulp,
    the spread of a whole-run comparison (tests/roundoff.py, class (c)). On one rank: None
    (compared exactly)."""
    if MPI.COMM_WORLD.size == 1:
        return None
    path = os.path.join(base, f"{name}_ulp.toml")
    old = next(line for line in text.splitlines() if line.startswith(f"{key} = "))
    new = (f"{key} = [0.0, {one_ulp(value)!r}]" if "[" in old else f"{key} = {one_ulp(value)!r}")
    if MPI.COMM_WORLD.rank == 0:
        with open(path, "w") as f:
            f.write(replace(text, old, new))
    MPI.COMM_WORLD.barrier()
    out = os.path.join(base, f"{name}_ulp")
    return _cli_run(path, out), _history(out)


def _energies_agree(got: dict, ref: dict, perturbed) -> None:
    scale = abs(ref["energy"]["total"])
    for key in ENERGIES:
        assert_runs_agree(got["energy"][key], ref["energy"][key],
                          None if perturbed is None else perturbed[0]["energy"][key],
                          ref["n_steps"], key, scale)


def test_bar_impact_scene_file_matches_the_demo(tmp_path):
    base = _shared_dir(tmp_path)
    path = os.path.join(SCENES, "bar_impact.toml")
    s_cli = _cli_run(path, os.path.join(base, "bar"))
    s_demo, _ = load_demo("bar_impact").run("film", None)
    ulp = _perturbed(open(path).read(), "velocity", 5.0, base, "bar")
    assert s_cli["n_steps"] == s_demo["n_steps"] == 500 and s_cli["dt"] == s_demo["dt"]
    assert s_cli["contact"]["n_constraints"] == s_demo["n_pairs"]
    assert_runs_agree(s_demo["contact_duration"], s_cli["contact_duration"],
                      None if ulp is None else ulp[0]["contact_duration"], 500, "contact_duration")
    assert s_cli["contact"]["first_contact_step"] == s_demo["contact"]["first_contact_step"]
    assert s_cli["contact"]["last_contact_step"] == s_demo["contact"]["last_contact_step"]
    _energies_agree(s_demo, s_cli, ulp)


def test_elastic_wave_scene_file_matches_the_demo(tmp_path):
    base = _shared_dir(tmp_path)
    path = os.path.join(SCENES, "elastic_wave.toml")
    s_cli = _cli_run(path, os.path.join(base, "wave"))
    s_demo, sim = load_demo("elastic_wave").run(None)
    ulp = _perturbed(open(path).read(), "peak", 100e6, base, "wave")
    assert s_cli["dt"] == s_demo["dt"] and s_cli["n_steps"] == s_demo["n_steps"]  # cfl = 0.9
    _energies_agree(s_demo, s_cli, ulp)
    h_cli = _history(os.path.join(base, "wave"))
    h_demo = sim.history.data()
    for col in ("sigma_zz_0", "u_z_0", "sigma_zz_1", "u_z_1"):
        assert_runs_agree(h_demo[col], h_cli[col], None if ulp is None else ulp[1][col],
                          s_cli["n_steps"], col)


def test_punch_scene_file_is_the_demo_setup():
    """scenes/punch_indentation.toml states the demo's constants (its 22,600-cell run is
    compared on a small block below)."""
    demo = load_demo("punch_indentation")
    s = scene_file.read_scene(os.path.join(SCENES, "punch_indentation.toml"))
    assert s.mesh.generator == "punch_block" and s.mesh.params.get("breaks") is None
    assert s.time["dt"] == demo.DT and s.time["n_steps"] == demo.N_STEPS
    (c,) = s.contacts
    assert (c.surface, c.rigid, c.radius, c.method) == ("surface", "punch", 1.0, "dme")
    assert s.rigid["punch"].mass == 0.1
    (load,) = s.loads
    assert load.params == dict(peak=200e6, t_rise=1e-5, t_fall=9e-5, t_end=1e-4)
    assert load.area == math.pi * 1.0 ** 2
    assert [(f.facet, f.components) for f in s.fixed] == [("bottom", ["z"])]


def test_rigid_scene_matches_the_scene_builder(tmp_path):
    """A punch scene file and scenes.punch_indentation on the same small block agree: exactly
    on one rank, within the spread of a one-ulp change of the load's peak on more."""
    block = dict(width=0.3, depth=0.1, h_surface=0.02, grading=0.3, h_max=0.05,
                 breaks=((0.1, 5),))
    area = math.pi * 0.1 ** 2
    text = replace(replace(replace(RIGID, "area = 0.0314", f"area = {area!r}"),
                           "peak = 1e6", "peak = 2e8"), 'method = "dme"', 'method = "film"')
    base = _shared_dir(tmp_path)
    scene = os.path.join(base, "punch.toml")
    if MPI.COMM_WORLD.rank == 0:
        with open(scene, "w") as f:
            f.write(text)
    MPI.COMM_WORLD.barrier()
    out = os.path.join(base, "punch")
    s_cli = _cli_run(scene, out)
    settings = Settings(dt=1e-7, n_steps=20, output_every=50, quiet=True)
    sim = scenes.punch_indentation(settings, scenes.make_method("film"), radius=0.1,
                                   peak=2e8, t_rise=1e-6, t_fall=2e-6, t_end=3e-6, block=block)
    s_lib = sim.run()
    ulp = _perturbed(text, "peak", 2e8, base, "punch")
    _energies_agree(s_lib, s_cli, ulp)
    h_cli = _history(out)
    h_lib = sim.history.data()
    assert np.array_equal(h_cli["n_active"], h_lib["n_active"])
    for col in ("punch_u", "punch_force"):
        assert_runs_agree(h_lib[col], h_cli[col], None if ulp is None else ulp[1][col], 20, col)
    assert s_lib["contact"]["n_constraints"] == 6


def test_method_option_overrides_the_file(tmp_path):
    scene = tmp_path / "pair.toml"
    scene.write_text(PAIR)
    out = os.path.join(_shared_dir(tmp_path), "pair")
    s = _cli_run(str(scene), out, "--method", "dme")
    assert s["contact"]["method"] == "dme" and s["contact"]["method_info"]["restitution"] == 0.0


def _disk_msh(radius: float, length: float, nr: int, nz: int) -> str:
    """A gmsh 2.2 file: the rectangle [0, radius] x [0, length] in right triangles, with the
    cell group "disk" and the facet groups "bottom" (z = 0) and "top" (z = length)."""
    xs = [radius * i / nr for i in range(nr + 1)]
    zs = [length * j / nz for j in range(nz + 1)]

    def node(i, j):
        return 1 + j * (nr + 1) + i

    nodes = [f"{node(i, j)} {x!r} {z!r} 0" for j, z in enumerate(zs) for i, x in enumerate(xs)]
    elems = []  # (type, physical, entity, nodes)
    for i in range(nr):
        elems += [(1, 11, 1, (node(i, 0), node(i + 1, 0))), (1, 12, 3, (node(i, nz), node(i + 1, nz)))]
    for j in range(nz):
        for i in range(nr):
            a, b, c, d = node(i, j), node(i + 1, j), node(i + 1, j + 1), node(i, j + 1)
            elems += [(2, 1, 1, (a, b, c)), (2, 1, 1, (a, c, d))]
    rows = [f"{k + 1} {t} 2 {p} {e} " + " ".join(map(str, ns)) for k, (t, p, e, ns) in enumerate(elems)]
    return "\n".join(["$MeshFormat", "2.2 0 8", "$EndMeshFormat", "$PhysicalNames", "3",
                      '1 11 "bottom"', '1 12 "top"', '2 1 "disk"', "$EndPhysicalNames",
                      "$Nodes", str(len(nodes)), *nodes, "$EndNodes",
                      "$Elements", str(len(rows)), *rows, "$EndElements", ""])


MSH_SCENE = """\
[mesh]
file = "disk.msh"

[materials.steel]
E = 200e9
nu = 0.3
density = 7850.0

[bodies.disk]
material = "steel"

[[loads]]
facet = "bottom"
pulse = "constant"
value = 1e6

[time]
dt = 1e-7
n_steps = 5
"""


def test_scene_from_a_msh_file(tmp_path):
    """Mass and load of a body read from a .msh with named groups match the closed forms."""
    (tmp_path / "disk.msh").write_text(_disk_msh(0.02, 0.04, 2, 4))
    (tmp_path / "disk.toml").write_text(MSH_SCENE)
    sim = scene_file.build(scene_file.read_scene(str(tmp_path / "disk.toml")), {"quiet": True})
    rho, R, L = 7850.0, 0.02, 0.04
    # round-off: each of the 15 nodes' lumped masses sums its cells' quadrature (about 30
    # roundings), the body's mass sums the nodes (15 more); the closed form rounds 5 times
    n_nodes = 3 * 5
    assert math.isclose(sim.body_mass["disk"], rho * math.pi * R ** 2 * L,
                        rel_tol=rounding(30 + n_nodes + 5))
    (load,) = sim.loads
    push = MPI.COMM_WORLD.allreduce(float(load.force[load.dofs % 2 == 1].sum()))
    # the 2 facets' 2 pi r weighted integrals (about 10 roundings each) summed on 3 nodes
    assert math.isclose(push, math.pi * R ** 2, rel_tol=rounding(20 + 3 + 3))  # N per Pa, +z


def test_msh_file_without_the_named_group(tmp_path, capsys):
    (tmp_path / "disk.msh").write_text(_disk_msh(0.02, 0.04, 2, 4))
    (tmp_path / "disk.toml").write_text(replace(MSH_SCENE, "[bodies.disk]", "[bodies.rod]"))
    with pytest.raises(SystemExit) as exit_:
        cli.main(["run", str(tmp_path / "disk.toml"), "--out", str(tmp_path / "o"), "--quiet"])
    assert exit_.value.code == 2
    if MPI.COMM_WORLD.rank == 0:
        assert capsys.readouterr().err.strip() == (
            "error: [bodies.rod] the mesh has no cell group named 'rod' (it has: disk)")


@serial_only
def test_console_script_under_mpirun(tmp_path):
    """`impact-fenics` on 2 ranks and `python -m impact_fenics` on 1 give the same run."""
    script = os.path.join(os.path.dirname(sys.executable), "impact-fenics")
    assert os.path.isfile(script), "reinstall: pip install --no-build-isolation -e ."
    pair = replace(PAIR, "n_steps = 20", "n_steps = 200")
    (tmp_path / "pair.toml").write_text(pair)
    # the spread of a whole-run comparison (2 ranks against 1): the striker one ulp faster
    (tmp_path / "ulp.toml").write_text(replace(pair, "velocity = [0.0, 5.0]",
                                               f"velocity = [0.0, {one_ulp(5.0)!r}]"))
    summaries = []
    py = [sys.executable, "-m", "impact_fenics"]
    for n, cmd, scene in ((1, py, "pair"), (2, [script], "pair"), (1, py, "ulp")):
        out = tmp_path / f"{scene}_n{n}"
        subprocess.run([os.path.join(ROOT, "scripts", "mpirun.sh"), "-n", str(n), *cmd, "run",
                        str(tmp_path / f"{scene}.toml"), "--out", str(out)], check=True,
                       capture_output=True, timeout=300, env=clean_mpi_env(), cwd=ROOT)
        with open(out / "summary.json") as f:
            summaries.append(json.load(f))
    one, two, ulp = summaries
    assert (one["n_ranks"], two["n_ranks"]) == (1, 2)
    for key in ENERGIES:
        assert_within_spread(two["energy"][key], one["energy"][key], ulp["energy"][key], 200,
                             key, scale=abs(one["energy"]["total"]))
    assert two["contact"]["last_contact_step"] == one["contact"]["last_contact_step"]


def _run_in_terminal(args, timeout=120.0, launcher=()) -> tuple[int, str]:
    """Run the command line (after ``launcher``, e.g. mpirun -n 2) with stdout and stderr on a
    pseudo-terminal; return (code, text)."""
    import pty

    master, slave = pty.openpty()
    proc = subprocess.Popen([*launcher, sys.executable, "-m", "impact_fenics", *map(str, args)],
                            stdin=subprocess.DEVNULL, stdout=slave, stderr=slave,
                            env=clean_mpi_env(), cwd=ROOT)
    os.close(slave)
    chunks, deadline = [], time.monotonic() + timeout
    while time.monotonic() < deadline:
        ready, _, _ = select.select([master], [], [], 1.0)
        if ready:
            try:
                data = os.read(master, 65536)
            except OSError:  # the terminal closed with the process
                break
            if not data:
                break
            chunks.append(data)
        elif proc.poll() is not None:
            break
    if proc.poll() is None:  # out of time: do not leave it running
        proc.kill()
    os.close(master)
    return proc.wait(timeout=10), b"".join(chunks).decode(errors="replace")


@serial_only
def test_progress_only_on_a_terminal(tmp_path):
    (tmp_path / "bar.toml").write_text(BAR)
    code, text = _run_in_terminal(["run", tmp_path / "bar.toml", "--out", tmp_path / "a"])
    assert code == 0, text
    assert "step 100/100" in text and "steps/s" in text and "ETA" in text
    code, quiet = _run_in_terminal(["run", tmp_path / "bar.toml", "--out", tmp_path / "b",
                                    "--quiet"])
    assert code == 0 and "steps/s" not in quiet and quiet.strip() == ""
    proc = launch(["run", tmp_path / "bar.toml", "--out", tmp_path / "c"])  # stdout: a pipe
    assert proc.returncode == 0 and "completed" in proc.stdout
    assert "steps/s" not in proc.stdout + proc.stderr


@serial_only
def test_progress_under_mpirun_follows_the_launchers_terminal(tmp_path):
    """Under a launcher the rank's own stdout says nothing of the user's: OpenMPI gives ranks a
    pseudo-terminal even when mpirun writes to a file, MPICH gives them a pipe even when
    mpiexec runs in a terminal. The progress line shows when the launcher's output is a
    terminal, and a redirected log holds no carriage return."""
    (tmp_path / "bar.toml").write_text(BAR)
    mpirun = (os.path.join(ROOT, "scripts", "mpirun.sh"), "-n", "2")
    code, text = _run_in_terminal(["run", tmp_path / "bar.toml", "--out", tmp_path / "a"],
                                  launcher=mpirun)
    assert code == 0, text
    assert "step 100/100" in text and "steps/s" in text
    log = tmp_path / "run.log"
    with open(log, "w") as f:
        proc = subprocess.run([*mpirun, sys.executable, "-m", "impact_fenics", "run",
                               str(tmp_path / "bar.toml"), "--out", str(tmp_path / "b")],
                              stdin=subprocess.DEVNULL, stdout=f, stderr=subprocess.STDOUT,
                              env=clean_mpi_env(), cwd=ROOT, timeout=300)
    text = log.read_text()
    assert proc.returncode == 0 and "completed" in text, text
    assert "\r" not in text and "steps/s" not in text


# ---------------------------------------------------------------- --version, check, estimates
@serial_only
def test_version():
    from importlib import metadata

    proc = launch(["--version"])
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout == f"impact-fenics {metadata.version('impact_fenics')}\n"


def _folder(base: str) -> dict:
    """Every file under ``base`` with its bytes."""
    found = {}
    for root, _, files in os.walk(base):
        for name in files:
            with open(os.path.join(root, name), "rb") as f:
                found[os.path.relpath(os.path.join(root, name), base)] = f.read()
    return found


def test_check_prints_the_estimate_and_writes_nothing(tmp_path, capsys):
    """`impact-fenics check SCENE`: exit 0, the estimate printed, no file written or
    changed (not even the output directory); a bad scene: exit 2 in one line."""
    base = _shared_dir(tmp_path)
    if MPI.COMM_WORLD.rank == 0:
        with open(os.path.join(base, "pair.toml"), "w") as f:
            f.write(PAIR)
        with open(os.path.join(base, "bad.toml"), "w") as f:
            f.write(replace(PAIR, "nu = 0.3", "nu = 0.7"))
    MPI.COMM_WORLD.barrier()
    before = _folder(base)
    capsys.readouterr()
    out = os.path.join(base, "out")
    assert cli.main(["check", os.path.join(base, "pair.toml"), "--out", out]) == 0
    printed = capsys.readouterr()
    if MPI.COMM_WORLD.rank == 0:
        assert "estimate: " in printed.out and "checked" in printed.out, printed.out
        assert "warning" not in printed.err and "error" not in printed.err, printed.err
    with pytest.raises(SystemExit) as exit_:
        cli.main(["check", os.path.join(base, "bad.toml"), "--out", out])
    assert exit_.value.code == 2
    err = [ln for ln in capsys.readouterr().err.splitlines() if ln.strip()]
    if MPI.COMM_WORLD.rank == 0:
        assert len(err) == 1 and err[0].startswith("error: [materials.steel] nu = 0.7"), err
    MPI.COMM_WORLD.barrier()
    assert _folder(base) == before


def test_check_counts_a_mesh_file_as_read(tmp_path, capsys):
    """A mesh file's cells and dofs in the estimate are those of the file (4 x 8 squares
    cut in two: 64 triangles on 5 x 9 nodes), read without building the mesh."""
    base = _shared_dir(tmp_path)
    if MPI.COMM_WORLD.rank == 0:
        with open(os.path.join(base, "disk.msh"), "w") as f:
            f.write(_disk_msh(0.02, 0.04, 4, 8))
        with open(os.path.join(base, "disk.toml"), "w") as f:
            f.write(MSH_SCENE)
    MPI.COMM_WORLD.barrier()
    capsys.readouterr()
    assert cli.main(["check", os.path.join(base, "disk.toml"), "--out",
                     os.path.join(base, "out")]) == 0
    if MPI.COMM_WORLD.rank == 0:
        assert "estimate: 64 cells, 90 dofs, 5 steps," in capsys.readouterr().out


def test_the_first_run_says_it_compiles(tmp_path, capsys, monkeypatch):
    """Where numba's cache is cold (jit_watch.cold_share, tests/test_jit_watch.py), the
    estimate counts the compile and the run says "compiling kernels (first run only)"
    before the silent seconds of compiling; ``check``, which compiles nothing, counts
    it in the estimate only."""
    base = _shared_dir(tmp_path)
    if MPI.COMM_WORLD.rank == 0:
        with open(os.path.join(base, "pair.toml"), "w") as f:
            f.write(PAIR)
    MPI.COMM_WORLD.barrier()
    capsys.readouterr()
    scene, out = os.path.join(base, "pair.toml"), os.path.join(base, "out")
    monkeypatch.setattr(scene_file, "kernels_cold", lambda scene: 1.0)
    assert cli.main(["check", scene, "--out", out]) == 0
    said = capsys.readouterr().out
    if MPI.COMM_WORLD.rank == 0:
        assert ", compiling 30 s)" in said and "compiling kernels" not in said, said
    assert cli.main(["run", scene, "--out", out]) == 0
    said = capsys.readouterr().out
    if MPI.COMM_WORLD.rank == 0:
        assert "compiling kernels (first run only)" in said, said
    monkeypatch.setattr(scene_file, "kernels_cold", lambda scene: 0.0)
    assert cli.main(["run", scene, "--out", out]) == 0
    assert "compiling" not in capsys.readouterr().out


# The shipped scenes, each estimated before meshing and then run: the oracle is the run
# (its dofs and steps as counted, the bytes it wrote as the files' sizes). The target is
# 2x either way; the Taylor bar runs on 4 x 40 quadrilaterals instead of 8 x 81 (its
# steps at 80 us are 10x those of the undeformed cells there, 14x on 8 x 81: the
# estimate's 14x is within 2x of both). The shipped scenes run without a warning.
SHIPPED = sorted(os.path.splitext(name)[0] for name in os.listdir(SCENES)
                 if name.endswith(".toml"))


@pytest.mark.parametrize("name", SHIPPED)
def test_the_estimate_of_each_shipped_scene_is_within_2x_of_its_run(tmp_path, capsys, name):
    base = _shared_dir(tmp_path)
    path = os.path.join(SCENES, f"{name}.toml")
    if name == "taylor_bar":
        with open(path) as f:
            text = replace(f.read(), "n_r = 8", "n_r = 4")
        path = os.path.join(base, f"{name}.toml")
        if MPI.COMM_WORLD.rank == 0:
            with open(path, "w") as f:
                f.write(text)
        MPI.COMM_WORLD.barrier()
    est = scene_file.estimate(scene_file.read_scene(path), MPI.COMM_WORLD)
    out = os.path.join(base, "run")
    capsys.readouterr()
    s = _cli_run(path, out)
    err = capsys.readouterr().err
    assert "warning" not in err, err
    written = sum(os.path.getsize(os.path.join(out, f)) for f in os.listdir(out))
    for what, guess, real in (("dofs", est.dofs, s["n_dofs"]), ("steps", est.n_steps, s["n_steps"]),
                              ("bytes", est.disk, written)):
        assert 0.5 <= guess / real <= 2.0, (what, guess, real)


@pytest.mark.parametrize("given, rows", [("", [0, 10, 19]), ("energy_every = 3\n",
                                                             [0, 3, 6, 9, 12, 15, 18, 19])],
                         ids=["default", "every_3"])
def test_energy_rows_have_their_own_cadence(tmp_path, given, rows):
    """[output] energy_every (steps; default 10): the energy rows at steps 0, k, 2k, ... and
    the last (19 of 20), whatever output_every (5 here) is."""
    scene = tmp_path / "pair.toml"
    scene.write_text(replace(PAIR, "output_every = 10\n", "output_every = 5\n" + given))
    out = os.path.join(_shared_dir(tmp_path), "run")
    _cli_run(str(scene), out)
    energy = np.genfromtxt(os.path.join(out, "energy.csv"), delimiter=",", names=True)
    assert energy["step"].tolist() == rows
