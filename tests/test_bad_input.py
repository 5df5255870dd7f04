"""Bad input: one clear line naming the problem, a non-zero exit, no traceback, no output.

The launcher tests run a demo as a user would; the API tests check the
message of the error each bad input raises.
"""
import json
import os
import subprocess
import sys
import time

import pytest
from mpi4py import MPI

from conftest import clean_mpi_env
from impact_fenics import meshing, scenes
from impact_fenics.bodies import Body, DeformableModel
from impact_fenics.errors import InputError
from impact_fenics.loads import SurfaceLoad, Trapezoid
from impact_fenics.materials import LinearElastic
from impact_fenics.simulation import Settings

ROOT = os.path.join(os.path.dirname(__file__), "..")
serial_only = pytest.mark.skipif(MPI.COMM_WORLD.size > 1, reason="launches processes: serial only")


def _launch(args, tmp_path):
    out = tmp_path / "out"
    cmd = [sys.executable, os.path.join(ROOT, "demos", "elastic_wave.py"), "--quiet",
           "--out", str(out)] + args
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=120, env=clean_mpi_env())
    return proc, out


@serial_only
@pytest.mark.parametrize("args, words", [
    (["--cfl", "1.2"], "above the stable limit"),
    (["--nu", "0.5"], "Poisson's ratio"),
    (["--nu", "0.7"], "Poisson's ratio"),
    (["--h", "-0.01"], "must be > 0"),
])
def test_demo_refuses_bad_input_in_one_line(tmp_path, args, words):
    proc, out = _launch(args, tmp_path)
    assert proc.returncode == 2
    lines = [ln for ln in proc.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("error: ") and words in lines[0], proc.stderr
    assert "Traceback" not in proc.stderr + proc.stdout
    assert not out.exists() and not os.path.exists(str(out) + ".partial")


def test_missing_cell_group_is_named():
    tmesh = meshing.bar(radius=0.05, length=0.1, h=0.02)
    with pytest.raises(InputError, match="no cell group named 'rod'"):
        DeformableModel(tmesh, [Body("rod", LinearElastic())])


def test_missing_facet_group_is_named():
    tmesh = meshing.bar(radius=0.05, length=0.1, h=0.02)
    model = DeformableModel(tmesh, [Body("bar", LinearElastic())])
    with pytest.raises(InputError, match="no facet group named 'top'"):
        SurfaceLoad(model, "top", Trapezoid(1e6, 1e-5, 2e-5, 3e-5))


@pytest.mark.parametrize("nu", [0.5, 0.51, -1.0])
def test_poisson_ratio_out_of_range(nu):
    with pytest.raises(InputError, match="Poisson's ratio"):
        LinearElastic(nu=nu)


def test_dt_above_limit_names_both_values():
    with pytest.raises(InputError, match=r"dt = 1e-05 s is above the stable limit"):
        scenes.elastic_bar(Settings(dt=1e-5, n_steps=5, quiet=True), h=0.02, length=0.2)


# ------------------------------------------------------------------ the command line
# Each bad input: exit 2, one line naming it, no output directory (nor .partial), and
# no file outside the run's own directory removed or changed (a snapshot of tmp_path).

from impact_fenics import cli  # noqa: E402
from scene_texts import BAR, PAIR, replace  # noqa: E402
from test_cli import MSH_SCENE, _disk_msh  # noqa: E402

COMM = MPI.COMM_WORLD


def _snapshot(base: str) -> dict:
    out = {}
    for root, _, files in os.walk(base):
        for name in files:
            path = os.path.join(root, name)
            with open(path, "rb") as f:
                out[os.path.relpath(path, base)] = f.read()
    return out


def _cli(tmp_path, capsys, text: str | None, args: list[str], files: dict | None = None):
    """Write the scene (and files) into a shared folder, run cli.main in this process;
    return (code, stdout, stderr, folder, snapshot before)."""
    base = COMM.bcast(str(tmp_path), root=0)
    if COMM.rank == 0:
        for name, content in ({"scene.toml": text} if text is not None else {}).items():
            with open(os.path.join(base, name), "w") as f:
                f.write(content)
        for name, content in (files or {}).items():
            with open(os.path.join(base, name), "w") as f:
                f.write(content)
    COMM.barrier()
    before = _snapshot(base)
    capsys.readouterr()
    try:
        code = cli.main([a.replace("{base}", base) for a in args])
    except SystemExit as exc:
        code = exc.code
    out, err = COMM.bcast(capsys.readouterr() if COMM.rank == 0 else None, root=0)
    return code, out, err, base, before


def _refused(tmp_path, capsys, text, words, args=None, files=None, out_name="out"):
    args = args or ["run", "{base}/scene.toml", "--out", f"{{base}}/{out_name}", "--quiet"]
    code, out, err, base, before = _cli(tmp_path, capsys, text, args, files)
    lines = [ln for ln in err.splitlines() if ln.strip() and not ln.startswith("warning: ")]
    assert code == 2, err
    assert len(lines) == 1 and lines[0].startswith("error: ") and words in lines[0], err
    assert "Traceback" not in err + out
    assert not os.path.exists(os.path.join(base, out_name))
    assert not os.path.exists(os.path.join(base, out_name) + ".partial")
    after = _snapshot(base)
    COMM.barrier()  # every rank has read the folder before a next call rewrites its scene
    assert after == before  # nothing outside the run's directory touched
    return lines[0]


def test_msh_surface_without_a_physical_group(tmp_path, capsys):
    """dolfinx's gmsh reader segfaults on such a file (PETSc signal 11): refused before it sees it."""
    text = _disk_msh(0.02, 0.04, 2, 4).splitlines()
    last = max(k for k, ln in enumerate(text) if " 2 2 1 1 " in ln)  # the last triangle
    text[last] = text[last].replace(" 2 2 1 1 ", " 2 2 0 2 ")  # no physical group, entity 2
    _refused(tmp_path, capsys, MSH_SCENE, "surface(s) 2 have cells but no 2D physical group",
             files={"disk.msh": "\n".join(text)})


def test_a_billion_steps_are_refused_before_anything_is_allocated(tmp_path, capsys):
    line = _refused(tmp_path, capsys, replace(BAR, "n_steps = 100", "n_steps = 1000000000"),
                    "more than the")
    assert "[mesh] the run needs about" in line and "force = true or --force" in line


def test_a_mesh_beyond_the_memory_is_refused_before_meshing(tmp_path, capsys):
    t0 = time.perf_counter()
    _refused(tmp_path, capsys, replace(BAR, "h = 0.01", "h = 1e-5"), "cells")
    assert time.perf_counter() - t0 < 60  # not meshed: meshing 4e7 cells takes many minutes


def test_the_estimate_counts_a_structured_mesh_exactly(tmp_path, capsys):
    """A structured bar of n_r x n_z intervals has 2 n_r n_z cells: the printed estimate
    and the run agree."""
    code, out, err, base, _ = _cli(tmp_path, capsys, replace(BAR, "n_steps = 100", "n_steps = 5"),
                                   ["run", "{base}/scene.toml", "--out", "{base}/out"])
    assert code == 0, err
    assert "estimate: 40 cells," in out  # radius 0.02 / h 0.01 = 2, length 0.1 / 0.01 = 10
    with open(os.path.join(base, "out", "summary.json")) as f:
        assert json.load(f)["n_cells"] == 40


def test_t_end_shorter_than_dt_is_refused(tmp_path, capsys):
    text = replace(replace(BAR, "cfl = 0.9", "dt = 1e-7"), "n_steps = 100", "t_end = 1e-8")
    _refused(tmp_path, capsys, text, "t_end = 1e-08 s is shorter than one step dt = 1e-07 s")


def test_the_same_surface_in_two_contacts_is_refused(tmp_path, capsys):
    twice = PAIR.replace("[[loads]]", """[[contact]]
lower = "striker_contact"
upper = "target_contact"
method = "dme"

[[loads]]""")
    _refused(tmp_path, capsys, twice, "[contact #2] the surface 'striker_contact' is already "
                                      "in [contact #1]")


def test_a_probe_on_the_interface_of_two_bodies_is_refused(tmp_path, capsys):
    _refused(tmp_path, capsys, replace(PAIR, "point = [0.01, 0.02]", "point = [0.01, 0.0]"),
             "lies on the interface of the bodies striker and target")


def test_an_empty_out_and_a_directory_as_scene_are_refused(tmp_path, capsys):
    _refused(tmp_path, capsys, BAR, "--out '': the output directory name is empty",
             args=["run", "{base}/scene.toml", "--out", "", "--quiet"])
    _refused(tmp_path, capsys, BAR, "is a directory: give the .toml file",
             args=["run", "{base}", "--quiet"])


def test_plot_times_outside_the_run_are_refused(tmp_path, capsys):
    code, _, err, base, _ = _cli(tmp_path, capsys, replace(BAR, "n_steps = 100", "n_steps = 20"),
                                 ["run", "{base}/scene.toml", "--out", "{base}/run", "--quiet"])
    assert code == 0, err
    _refused(tmp_path, capsys, None, "--times 1: outside the run, which covers 0 to",
             args=["plot", "{base}/run", "--times", "1.0"])


def _warnings(err: str) -> list[str]:
    return [ln for ln in err.splitlines() if ln.startswith("warning: ")]


def test_keys_the_method_ignores_are_named(tmp_path, capsys):
    text = replace(PAIR, 'method = "film"\n', 'method = "film"\nrestitution = 0.0\n')
    code, _, err, _, _ = _cli(tmp_path, capsys, text,
                              ["run", "{base}/scene.toml", "--out", "{base}/run", "--quiet"])
    assert code == 0, err
    assert _warnings(err) == ['warning: [contact #1] restitution = 0.0 is ignored by method = '
                              '"film" (only dme reads it)']


def _c1(E: float, nu: float, rho: float) -> float:
    """Dilatational wave speed (m/s), closed form."""
    return (E * (1 - nu) / ((1 + nu) * (1 - 2 * nu) * rho)) ** 0.5


@pytest.mark.parametrize("old, new, words", [
    ("density = 7850.0", "density = 7.85",
     f"[materials.steel] wave speed {_c1(200e9, 0.3, 7.85):.4g} m/s is outside"),
    ("E = 200e9", "E = 210.0",
     f"[materials.steel] wave speed {_c1(210.0, 0.3, 7850.0):.4g} m/s is outside"),
    ("length = 0.1", "length = 200.0", "[mesh] the model is 200 m across"),
], ids=["density_in_g", "E_in_Pa_not_GPa", "millimetres"])
def test_implausible_values_warn_in_one_line_each(tmp_path, capsys, old, new, words):
    text = replace(replace(BAR, "n_steps = 100", "n_steps = 3"), old, new)
    if new.startswith("length"):
        text = replace(text, "h = 0.01", "h = 20.0")
    code, _, err, _, _ = _cli(tmp_path, capsys, text,
                              ["run", "{base}/scene.toml", "--out", "{base}/run", "--quiet"])
    assert code == 0, err
    assert any(words in w for w in _warnings(err)), err


# ------------------------------------------------------------------ units, disk
def _warned_then_refused(tmp_path, capsys, text: str, words: list[str]) -> str:
    """The run is refused (exit 2, one error line holding ``words``, nothing written) and
    the warnings about the implausible values come before the error."""
    line = _refused(tmp_path, capsys, text, "")
    for w in words:
        assert w in line, line
    return line


def test_a_density_in_g_per_cm3_is_named_in_the_dt_refusal(tmp_path, capsys):
    """Density 7.85 (g/cm^3 for steel) with a fixed dt: the stable limit falls by
    sqrt(1000); the refusal says the dt is above it and that the density is implausible,
    after a warning that said so first."""
    text = replace(replace(BAR, "cfl = 0.9", "dt = 1e-6"), "density = 7850.0", "density = 7.85")
    code, _, err, _, _ = _cli(tmp_path, capsys, text, ["run", "{base}/scene.toml", "--out",
                                                      "{base}/out", "--quiet"])
    assert code == 2
    if COMM.rank == 0:
        lines = [ln for ln in err.splitlines() if ln.strip()]
        assert lines[0].startswith("warning: [materials.steel] wave speed") and \
            "the density 7.85 kg/m^3 is implausible (g/cm^3?)" in lines[0], err
        assert lines[-1].startswith("error: [time] dt = 1e-06 s is above the stable limit"), err
    _warned_then_refused(tmp_path, capsys, text, [
        "is above the stable limit",
        "; the density 7.85 kg/m^3 of [materials.steel] is implausible (g/cm^3?)"])


def test_a_mesh_in_millimetres_is_named_in_the_step_refusal(tmp_path, capsys):
    """The bar drawn in millimetres (20 x 100 with 10 mm elements read as metres): its step
    from cfl outlasts the run; the refusal names the elements' size as the likely cause."""
    text = replace(BAR, "n_steps = 100", "t_end = 1e-4")
    for old, new in (("radius = 0.02", "radius = 20.0"), ("length = 0.1", "length = 100.0"),
                     ("h = 0.01", "h = 10.0"), ("point = [0.01, 0.05]", "point = [10.0, 50.0]")):
        text = replace(text, old, new)
    _warned_then_refused(tmp_path, capsys, text, [
        "[time] t_end = 0.0001 s is shorter than one step",
        "; the elements are 10 m (a mesh in millimetres?)"])


def test_outputs_beyond_the_free_disk_are_refused_unless_forced(tmp_path, capsys, monkeypatch):
    """The estimate of the outputs (here some 100 kB: the fields, the tables, the
    pictures) against the free space of the output's disk, 10 kB here: refused in one
    line before anything is written; --force runs it."""
    from types import SimpleNamespace

    from impact_fenics import resources

    def small_disk(path):
        return SimpleNamespace(total=10**9, used=10**9 - 10**4, free=10**4)

    monkeypatch.setattr(resources.shutil, "disk_usage", small_disk)
    text = replace(BAR, "n_steps = 100", "n_steps = 20")
    line = _refused(tmp_path, capsys, text, "[output] the run writes about")
    assert "more than the 10 kB free in" in line and "--force" in line
    code, _, err, base, _ = _cli(tmp_path, capsys, text, ["run", "{base}/scene.toml", "--out",
                                                          "{base}/out", "--quiet", "--force"])
    assert code == 0, err
    assert os.path.isfile(os.path.join(base, "out", "summary.json"))
