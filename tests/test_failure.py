"""Failure that loses nothing: a diverging run and a signalled run keep a readable directory.

Oracles: the specification of the command line (exit codes 3 and 128 + signal,
one line on stderr naming the step and the stable dt) and the output format
(the XDMF refers to an HDF5 file holding every dataset it names; the CSV and
XDMF hold exactly the rows and time steps the output schedule gives for the
step at which the run stopped).
"""
import json
import math
import os
import re
import signal
import subprocess
import sys
import xml.etree.ElementTree as ET

import numpy as np
import pytest
from mpi4py import MPI

from conftest import clean_mpi_env
from impact_fenics import cli
from scene_texts import BAR, ROOT, launch, replace, wait_for_loop

serial_only = pytest.mark.skipif(MPI.COMM_WORLD.size > 1, reason="launches processes: serial only")

# dt three times the element bound: the highest mode grows about 30x per step
DIVERGING = replace(replace(BAR, "cfl = 0.9", "cfl = 3.0\nforce_dt = true"),
                    "output_every = 10", "output_every = 5")


def _xdmf_steps(path) -> dict[str, list[float]]:
    """Output times of every field (one grid per time, a piece per rank), checking that each
    field's dataset exists in its piece's .h5."""
    import h5py

    series = ET.parse(path).getroot().find("Domain/Grid")
    out: dict[str, list[float]] = {}
    h5_files = set()
    for step in series.findall("Grid"):
        t = float(step.find("Time").get("Value"))
        for piece in step.findall("Grid"):
            for attr in piece.findall("Attribute"):
                source = attr.find("DataItem").text.strip().partition("|")[0]  # Xdmf3 slab
                filename, _, dataset = source.partition(":")
                h5 = os.path.join(os.path.dirname(path), filename)
                h5_files.add(h5)
                with h5py.File(h5, "r") as f:
                    assert dataset in f, dataset
            for name in {a.get("Name") for a in piece.findall("Attribute")}:
                if not out.get(name) or out[name][-1] != t:
                    out.setdefault(name, []).append(t)
    assert h5_files and all(os.path.isfile(f) for f in h5_files)
    return out


def _check_diverged_dir(out, message):
    with open(os.path.join(out, "summary.json")) as f:
        s = json.load(f)
    assert s["status"] == "diverged"
    step = int(re.search(r"diverged at step (\d+)", message).group(1))
    stable = float(re.search(r"stable dt <= ([0-9.e+-]+) s", message).group(1))
    assert math.isclose(stable, s["dt_critical"], rel_tol=1e-3)  # printed to 4 digits
    assert s["dt"] > s["dt_critical"]
    assert 0 < step < s["n_steps"] and s["stopped_at_step"] == step + 1
    energy = np.genfromtxt(os.path.join(out, "energy.csv"), delimiter=",", names=True)
    if "the energy" in message:  # the energy check at an output step: its row is kept
        assert step % 5 == 0 and int(energy["step"][-1]) == step
    else:  # the per-step velocity check: the energy rows of the outputs before the step
        assert "moves at" in message and int(energy["step"][-1]) == 5 * ((step - 1) // 5)
    history = np.genfromtxt(os.path.join(out, "history.csv"), delimiter=",", names=True)
    assert int(history["step"][-1]) == step + 1
    fields = _xdmf_steps(os.path.join(out, "fields.xdmf"))
    assert len(fields["displacement"]) == step // 5 + 1  # states 0, 5, ..., up to the failing step
    for name in ("history.png", "energy.png"):
        assert os.path.getsize(os.path.join(out, name)) > 0


@serial_only
def test_diverging_run_exits_3_and_keeps_its_directory(tmp_path):
    (tmp_path / "scene.toml").write_text(DIVERGING)
    out = tmp_path / "out"
    proc = launch(["run", tmp_path / "scene.toml", "--out", out, "--quiet"])
    lines = [ln for ln in proc.stderr.splitlines() if ln.strip()]
    assert proc.returncode == 3, proc.stderr
    assert len(lines) == 1 and lines[0].startswith("error: run diverged at step "), proc.stderr
    assert "Traceback" not in proc.stderr
    assert not os.path.exists(str(out) + ".partial")
    _check_diverged_dir(str(out), lines[0])


def test_diverging_run_in_process(tmp_path, capsys):
    out = MPI.COMM_WORLD.bcast(str(tmp_path / "out"), root=0)
    (tmp_path / "scene.toml").write_text(DIVERGING)
    with pytest.raises(SystemExit) as exit_:
        cli.main(["run", str(tmp_path / "scene.toml"), "--out", out, "--quiet"])
    assert exit_.value.code == 3
    err = capsys.readouterr().err.strip()
    message = MPI.COMM_WORLD.bcast(err, root=0)
    assert message.count("\n") == 0 and message.startswith("error: run diverged")
    _check_diverged_dir(out, message)


@serial_only
def test_a_full_disk_exits_4_in_one_line(tmp_path, capsys, monkeypatch):
    # the history table's worker thread meets a full disk (its write raises ENOSPC, as
    # os.write does then): the command line's specification is one line naming the file
    # and the cause, exit 4, and no published directory (the staging one stays, as a
    # crash leaves it). Serial: under MPI the failing rank aborts every rank.
    import errno

    from impact_fenics import output

    def full(fd, data):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
    monkeypatch.setattr(output, "write_all", full)
    (tmp_path / "scene.toml").write_text(BAR)
    out = str(tmp_path / "out")
    with pytest.raises(SystemExit) as exit_:
        cli.main(["run", str(tmp_path / "scene.toml"), "--out", out, "--quiet"])
    assert exit_.value.code == 4
    err = [ln for ln in capsys.readouterr().err.splitlines() if not ln.startswith("warning")]
    assert err == [f"error: [Errno {errno.ENOSPC}] writing the table to history.csv failed: "
                   f"{os.strerror(errno.ENOSPC)}"]
    assert not os.path.exists(out) and os.path.isdir(out + ".partial")


LONG = replace(replace(BAR, "n_steps = 100", "n_steps = 5000000"),
               "output_every = 10", "output_every = 1000\nhistory_every = 10")


@serial_only
@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT], ids=["SIGTERM", "SIGINT"])
def test_signal_stops_cleanly(tmp_path, sig):
    (tmp_path / "scene.toml").write_text(LONG)
    out = tmp_path / "out"
    cmd = [sys.executable, "-m", "impact_fenics", "run", str(tmp_path / "scene.toml"),
           "--out", str(out), "--quiet"]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env=clean_mpi_env(), cwd=ROOT)
    wait_for_loop(proc, out)
    proc.send_signal(sig)
    stdout, stderr = proc.communicate(timeout=60)
    lines = [ln for ln in stderr.splitlines() if ln.strip()]
    assert proc.returncode == 128 + sig.value, stderr
    assert len(lines) == 1 and f"interrupted by {sig.name}" in lines[0], stderr
    assert "Traceback" not in stderr
    assert out.is_dir() and not os.path.exists(str(out) + ".partial")
    with open(out / "summary.json") as f:
        s = json.load(f)
    stopped = s["stopped_at_step"]
    assert s["status"] == f"interrupted by {sig.name}"
    assert 0 < stopped < s["n_steps"]  # serial: the flag is read every step
    assert f"at step {stopped} of {s['n_steps']}" in lines[0]
    fields = _xdmf_steps(str(out / "fields.xdmf"))
    n_out = stopped // 1000 + 1  # states 0, 1000, ... up to the stop
    assert all(len(times) == n_out for times in fields.values())
    history = np.genfromtxt(out / "history.csv", delimiter=",", names=True)
    assert history["step"].size == (stopped - 1) // 10 + 1
    assert int(history["step"][-1]) == 10 * ((stopped - 1) // 10) + 1


def test_divergence_is_caught_between_outputs(tmp_path, capsys):
    """With outputs only at the first and last step, a run at 3x the stable dt is stopped
    by the per-step velocity check: the unstable mode grows about 30x a step, so the
    runaway speed (the wave speed) is passed within a few steps and the check, every
    DIVERGENCE_EVERY steps, reports it before the second check (not at the last step)."""
    from impact_fenics.checks import DIVERGENCE_EVERY

    out = MPI.COMM_WORLD.bcast(str(tmp_path / "out"), root=0)
    (tmp_path / "scene.toml").write_text(replace(DIVERGING, "output_every = 5",
                                                 "output_every = 1000\nenergy_every = 1000"))
    with pytest.raises(SystemExit) as exit_:
        cli.main(["run", str(tmp_path / "scene.toml"), "--out", out, "--quiet"])
    assert exit_.value.code == 3
    message = MPI.COMM_WORLD.bcast(capsys.readouterr().err.strip(), root=0)
    step = int(re.search(r"diverged at step (\d+)", message).group(1))
    assert "moves at" in message and step < 2 * DIVERGENCE_EVERY, message
    with open(os.path.join(out, "summary.json")) as f:
        assert json.load(f)["stopped_at_step"] == step + 1


def test_the_velocity_check_sees_every_write():
    """The runaway check reads the numpy array that the loop and the contact write (a
    cached norm would hide a runaway), and a NaN on one rank is a NaN on every rank (the
    ranks must agree to stop together; PETSc's inf-norm under MPICH does not)."""
    from impact_fenics.checks import OwnedVec

    v = np.zeros(4)
    vec = OwnedVec(v, MPI.COMM_WORLD)
    rank = MPI.COMM_WORLD.rank
    for k, value in enumerate((3.0, 4.0, np.nan)):
        if rank == 0:
            v[k] = value
        norm = vec.norm_inf()
        assert (np.isnan(norm) if np.isnan(value) else norm == value)
