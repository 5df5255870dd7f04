"""The output directory: a run never removes what it did not write, and one run at a time.

Oracles: the rule stated in impact_fenics/rundir.py and the README (a run
replaces only a run directory: one with the marker file, an empty one, or an
older run holding only run files; DIR.partial is the lock; a replaced run is
renamed aside before the new one moves in), checked on the file system: the
user's files byte for byte, the lock owner's pid in the one-line refusal, and
every intermediate state of a replacement.
"""
import json
import os
import shutil
import socket
import subprocess
import sys
import time

import pytest
from mpi4py import MPI

from conftest import clean_mpi_env
from impact_fenics import cli, rundir
from scene_texts import BAR, ROOT, replace

serial_only = pytest.mark.skipif(MPI.COMM_WORLD.size > 1, reason="launches processes: serial only")
COMM = MPI.COMM_WORLD
SHORT = replace(BAR, "n_steps = 100", "n_steps = 5")


def _shared(tmp_path) -> str:
    return COMM.bcast(str(tmp_path), root=0)


def _scene(base: str, text: str = SHORT) -> str:
    path = os.path.join(base, "bar.toml")
    if COMM.rank == 0:
        with open(path, "w") as f:
            f.write(text)
    COMM.barrier()
    return path


def _run(args, capsys) -> tuple[int, str]:
    """cli.main in this process: (exit code, stderr of rank 0, broadcast)."""
    try:
        code = cli.main(args)
    except SystemExit as exc:
        code = exc.code
    err = COMM.bcast(capsys.readouterr().err, root=0)
    return code, err


def _user_files(base: str) -> dict[str, bytes]:
    """A folder of a user's: a scene, notes and a subfolder."""
    files = {"notes.txt": b"three months of thesis notes\n", "scene.toml": b"title = 'x'\n",
             os.path.join("data", "raw.csv"): b"1,2,3\n"}
    if COMM.rank == 0:
        for name, content in files.items():
            os.makedirs(os.path.dirname(os.path.join(base, name)), exist_ok=True)
            with open(os.path.join(base, name), "wb") as f:
                f.write(content)
    COMM.barrier()
    return files


def _unchanged(base: str, files: dict[str, bytes]) -> bool:
    for name, content in files.items():
        with open(os.path.join(base, name), "rb") as f:
            if f.read() != content:
                return False
    return True


def test_a_folder_of_the_users_is_refused_and_kept(tmp_path, capsys):
    base = _shared(tmp_path)
    scene = _scene(base)
    folder = os.path.join(base, "thesis")
    files = _user_files(folder)
    code, err = _run(["run", scene, "--out", folder, "--quiet"], capsys)
    assert code == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "is not a run directory" in lines[0], err
    assert _unchanged(folder, files) and sorted(os.listdir(folder)) == ["data", "notes.txt",
                                                                        "scene.toml"]
    assert not os.path.exists(folder + ".partial")


def test_the_working_directory_is_refused(tmp_path, capsys, monkeypatch):
    base = _shared(tmp_path)
    scene = _scene(base)
    files = _user_files(base)
    monkeypatch.chdir(base)
    code, err = _run(["run", scene, "--out", ".", "--quiet"], capsys)
    assert code == 2 and err.count("\n") == 1 and "working directory" in err, err
    assert _unchanged(base, files)


def test_an_older_run_is_replaced_and_nothing_else_is_left(tmp_path, capsys):
    base = _shared(tmp_path)
    scene = _scene(base)
    out = os.path.join(base, "run")
    assert _run(["run", scene, "--out", out, "--quiet"], capsys)[0] == 0
    assert os.path.isfile(os.path.join(out, rundir.MARKER))
    assert not os.path.exists(os.path.join(out, rundir.LOCK))
    if COMM.rank == 0:  # a file of the old run that the new one does not write
        with open(os.path.join(out, "contact_pairs.csv"), "w") as f:
            f.write("old\n")
    COMM.barrier()
    assert _run(["run", scene, "--out", out, "--quiet"], capsys)[0] == 0
    assert not os.path.exists(os.path.join(out, "contact_pairs.csv"))
    assert sorted(os.listdir(base)) == ["bar.toml", "run"]  # no .partial, no .old-*


def test_an_older_run_without_the_marker_is_recognised(tmp_path):
    """Runs written before the marker existed hold summary.json and run files only."""
    old = tmp_path / "old"
    old.mkdir()
    for name in ("summary.json", "history.csv", "energy.csv", "fields.xdmf", "fields.h5",
                 "history.png", "sigma_zz_t1e-04.png", "contact_pairs_1.csv"):
        (old / name).write_text("x")
    assert rundir.is_run_directory(str(old))
    (old / "notes.txt").write_text("mine")
    assert not rundir.is_run_directory(str(old))
    empty = tmp_path / "empty"
    empty.mkdir()
    assert rundir.is_run_directory(str(empty))
    assert not rundir.is_run_directory(str(tmp_path / "missing"))


@pytest.mark.parametrize("fail_at", [1, 2, 3])
def test_a_replacement_interrupted_at_any_point_keeps_a_run(tmp_path, monkeypatch, fail_at):
    """Fail the k-th file-system operation of publishing a new run over an old one: the
    old run or the new one (or both) is still on disk, complete."""
    if COMM.size > 1:
        pytest.skip("file-system states of rank 0; one rank suffices")
    final, staging = tmp_path / "run", tmp_path / "run.partial"
    final.mkdir()
    (final / rundir.MARKER).write_text("old")
    (final / "summary.json").write_text("old run")
    staging.mkdir()
    (staging / rundir.MARKER).write_text("new")
    (staging / rundir.LOCK).write_text("{}")
    (staging / "summary.json").write_text("new run")
    calls = {"n": 0}
    real = {"rename": os.rename, "rmtree": shutil.rmtree}

    def failing(name):
        def op(*args, **kwargs):
            calls["n"] += 1
            if calls["n"] == fail_at:
                raise OSError("simulated interruption")
            return real[name](*args, **kwargs)
        return op

    monkeypatch.setattr(rundir.os, "rename", failing("rename"))
    monkeypatch.setattr(rundir.shutil, "rmtree", failing("rmtree"))
    try:
        rundir._publish(str(staging), str(final))
    except OSError:
        pass
    monkeypatch.undo()
    runs = set()
    for d in tmp_path.iterdir():
        if (d / "summary.json").is_file():
            runs.add((d / "summary.json").read_text())
    assert runs and runs <= {"old run", "new run"}
    if fail_at == 3:  # only the old run's removal failed: the new run is in place
        assert (final / "summary.json").read_text() == "new run"


def _write_lock(staging: str, pid: int) -> None:
    if COMM.rank == 0:
        os.makedirs(staging)
        with open(os.path.join(staging, rundir.LOCK), "w") as f:
            json.dump({"pid": pid, "host": socket.gethostname(),
                       "started": "2026-01-01T00:00:00"}, f)
    COMM.barrier()


def test_a_second_run_into_a_locked_directory_is_refused(tmp_path, capsys):
    base = _shared(tmp_path)
    scene = _scene(base)
    out = os.path.join(base, "run")
    pid = COMM.bcast(os.getpid(), root=0)  # a live process holds the lock
    _write_lock(out + ".partial", pid)
    code, err = _run(["run", scene, "--out", out, "--quiet"], capsys)
    assert code == 2 and err.count("\n") == 1, err
    assert f"another run is writing it (pid {pid} on {socket.gethostname()}" in err
    assert not os.path.exists(out)
    assert os.listdir(out + ".partial") == [rundir.LOCK]  # the other run's files untouched


def test_the_lock_of_a_dead_run_is_taken_over(tmp_path, capsys):
    base = _shared(tmp_path)
    scene = _scene(base)
    out = os.path.join(base, "run")
    dead = None
    if COMM.rank == 0:
        proc = subprocess.Popen(["true"])
        proc.wait()
        dead = proc.pid
    dead = COMM.bcast(dead, root=0)
    _write_lock(out + ".partial", dead)
    code, err = _run(["run", scene, "--out", out, "--quiet"], capsys)
    assert code == 0
    assert f"took over the output of a run that died (pid {dead}" in err
    assert os.path.isfile(os.path.join(out, "summary.json"))
    assert not os.path.exists(out + ".partial")


@serial_only
def test_two_concurrent_runs_one_is_refused(tmp_path):
    """Two command lines into one directory: the second is refused naming the first;
    the first finishes with its own files."""
    long = replace(BAR, "n_steps = 100", "n_steps = 5000000")
    (tmp_path / "long.toml").write_text(long)
    (tmp_path / "short.toml").write_text(SHORT)
    out = tmp_path / "run"
    env = clean_mpi_env()
    first = subprocess.Popen([sys.executable, "-m", "impact_fenics", "run",
                              str(tmp_path / "long.toml"), "--out", str(out), "--quiet"],
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                             env=env, cwd=ROOT)
    try:
        deadline = time.monotonic() + 60
        while not os.path.isfile(os.path.join(str(out) + ".partial", rundir.LOCK)):
            assert first.poll() is None and time.monotonic() < deadline, first.communicate()
            time.sleep(0.02)
        second = subprocess.run([sys.executable, "-m", "impact_fenics", "run",
                                 str(tmp_path / "short.toml"), "--out", str(out), "--quiet"],
                                capture_output=True, text=True, env=env, cwd=ROOT, timeout=120)
        lines = [ln for ln in second.stderr.splitlines() if ln.strip()]
        assert second.returncode == 2 and len(lines) == 1, second.stderr
        assert f"another run is writing it (pid {first.pid} on" in lines[0]
        energy = os.path.join(str(out) + ".partial", "energy.csv")
        while not (os.path.isfile(energy) and len(open(energy).readlines()) >= 2):
            assert first.poll() is None and time.monotonic() < deadline, first.communicate()
            time.sleep(0.02)  # the first run is in its loop: a stop keeps its directory
    finally:
        first.terminate()
        first.communicate(timeout=60)
    assert first.returncode == 143
    with open(out / "summary.json") as f:
        s = json.load(f)
    assert s["n_steps"] == 5000000 and s["status"] == "interrupted by SIGTERM"
