"""Bad input: one clear line naming the problem, a non-zero exit, no traceback, no output.

The launcher tests run a demo as a user would; the API tests check the
message of the error each bad input raises.
"""
import os
import subprocess
import sys

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
