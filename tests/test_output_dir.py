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
import socket
import subprocess
import sys
import time

import pytest
from mpi4py import MPI

from conftest import clean_mpi_env
from impact_fenics import cli, rundir
from scene_texts import BAR, ROOT, replace, wait_for_loop

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
    """A run with plots, then one without: the pictures of the first go with it."""
    base = _shared(tmp_path)
    out = os.path.join(base, "run")
    assert _run(["run", _scene(base), "--out", out, "--quiet"], capsys)[0] == 0
    assert os.path.isfile(os.path.join(out, rundir.MARKER))
    assert not os.path.exists(os.path.join(out, rundir.LOCK))
    assert os.path.isfile(os.path.join(out, "history.png"))
    no_plots = _scene(base, replace(SHORT, "[output]\n", "[output]\nplots = false\n"))
    assert _run(["run", no_plots, "--out", out, "--quiet"], capsys)[0] == 0
    assert not os.path.exists(os.path.join(out, "history.png"))
    assert sorted(os.listdir(base)) == ["bar.toml", "run"]  # no .partial, no .old-*


def test_what_a_run_directory_is(tmp_path):
    """Empty, or marked and holding only what its run wrote. Without the marker a folder
    is the user's whatever it holds; a marker without a manifest (an older version's)
    vouches only for the names a run writes."""
    old = tmp_path / "old"
    old.mkdir()
    names = ("summary.json", "history.csv", "energy.csv", "fields.xdmf", "fields.h5",
             "history.png", "sigma_zz_t1.000000e-04.png", "contact_pairs_1.h5", "scene.toml")
    for name in names:
        (old / name).write_text("x")
    assert not rundir.is_run_directory(str(old))  # no marker: the user's
    (old / rundir.MARKER).write_text("impact_fenics 0.1 run directory\n")
    assert rundir.is_run_directory(str(old))
    (old / "notes.txt").write_text("mine")
    assert not rundir.is_run_directory(str(old))
    assert rundir.foreign_file(str(old)) == "'notes.txt' (no run wrote it)"
    empty = tmp_path / "empty"
    empty.mkdir()
    assert rundir.is_run_directory(str(empty))
    assert not rundir.is_run_directory(str(tmp_path / "missing"))
    # a manifest: exactly its files, at their sizes; an empty folder of the user's too
    new = tmp_path / "new"
    new.mkdir()
    (new / "history.csv").write_text("step\n")
    (new / rundir.MARKER).write_text(json.dumps({"files": {"history.csv": 5}}))
    assert rundir.is_run_directory(str(new))
    (new / "figures").mkdir()
    assert rundir.foreign_file(str(new)) == f"'figures{os.sep}' (no run wrote it)"
    (new / "figures").rmdir()
    (new / "history.csv").write_text("step\n1\n")
    assert rundir.foreign_file(str(new)) == "'history.csv' (changed since its run wrote it)"


@pytest.mark.parametrize("fail_at", [1, 2, 3, 4])
def test_a_replacement_interrupted_at_any_point_keeps_a_run(tmp_path, monkeypatch, fail_at):
    """Fail the k-th file-system operation of publishing a new run over an old one (the
    lock's removal, the old run renamed aside, the new one moved in, the old run's first
    file deleted): the old run or the new one (or both) is still on disk, complete."""
    if COMM.size > 1:
        pytest.skip("file-system states of rank 0; one rank suffices")
    final, staging = tmp_path / "run", tmp_path / "run.partial"
    final.mkdir()
    (final / rundir.MARKER).write_text(json.dumps({"status": "completed",
                                                   "files": {"summary.json": 7}}))
    (final / "summary.json").write_text("old run")
    staging.mkdir()
    (staging / rundir.MARKER).write_text("{}")
    (staging / rundir.LOCK).write_text("{}")
    (staging / "summary.json").write_text("new run")
    calls = {"n": 0}
    real = {"rename": os.rename, "remove": os.remove}

    def failing(name):
        def op(*args, **kwargs):
            calls["n"] += 1
            if calls["n"] == fail_at:
                raise OSError("simulated interruption")
            return real[name](*args, **kwargs)
        return op

    monkeypatch.setattr(rundir.os, "rename", failing("rename"))
    monkeypatch.setattr(rundir.os, "remove", failing("remove"))
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
    if fail_at == 4:  # only the old run's removal failed: the new run is in place
        assert (final / "summary.json").read_text() == "new run"


def _dead_pid() -> int:
    """The pid of a process that has ended (rank 0's, on every rank)."""
    dead = None
    if COMM.rank == 0:
        proc = subprocess.Popen(["true"])
        proc.wait()
        dead = proc.pid
    return COMM.bcast(dead, root=0)


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
    dead = _dead_pid()
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
        deadline = time.monotonic() + 300  # against a hang only: a first run compiles
        while not os.path.isfile(os.path.join(str(out) + ".partial", rundir.LOCK)):
            assert first.poll() is None and time.monotonic() < deadline, first.communicate()
            time.sleep(0.02)
        second = subprocess.run([sys.executable, "-m", "impact_fenics", "run",
                                 str(tmp_path / "short.toml"), "--out", str(out), "--quiet"],
                                capture_output=True, text=True, env=env, cwd=ROOT, timeout=120)
        lines = [ln for ln in second.stderr.splitlines() if ln.strip()]
        assert second.returncode == 2 and len(lines) == 1, second.stderr
        assert f"another run is writing it (pid {first.pid} on" in lines[0]
        wait_for_loop(first, out)  # the first run is in its loop: a stop keeps its directory
    finally:
        first.terminate()
        first.communicate(timeout=60)
    assert first.returncode == 143
    with open(out / "summary.json") as f:
        s = json.load(f)
    assert s["n_steps"] == 5000000 and s["status"] == "interrupted by SIGTERM"


# ----------------------------------------------------------------------------- nothing a user saved is lost
# Each case below deleted a user's file before the manifest rule (a run directory lists
# the files its run wrote; only those are ever removed).

def _write(path: str, content: bytes) -> None:
    if COMM.rank == 0:
        os.makedirs(os.path.dirname(path), exist_ok=True)
        with open(path, "wb") as f:
            f.write(content)
    COMM.barrier()


def _summary(path: str) -> dict:
    with open(os.path.join(path, "summary.json")) as f:
        return json.load(f)


def test_a_users_file_inside_an_earlier_run_is_kept(tmp_path, capsys):
    """Notes and a post-processing folder saved in a run directory: the next run into it
    is refused in one line that names the first of them; the earlier run is untouched."""
    base = _shared(tmp_path)
    scene = _scene(base)
    out = os.path.join(base, "run")
    assert _run(["run", scene, "--out", out, "--quiet"], capsys)[0] == 0
    before = COMM.bcast(sorted(os.listdir(out)), root=0)
    notes = {"my_notes.txt": b"the wave arrives at 20 us\n",
             os.path.join("post", "plot.py"): b"import numpy\n"}
    for name, content in notes.items():
        _write(os.path.join(out, name), content)
    code, err = _run(["run", scene, "--out", out, "--quiet"], capsys)
    assert code == 2 and err.count("\n") == 1, err
    assert "my_notes.txt" in err and "no run wrote" in err, err
    assert _unchanged(out, notes)
    assert sorted(os.listdir(out)) == sorted(before + ["my_notes.txt", "post"])
    assert not os.path.exists(out + ".partial")


def test_a_changed_run_file_is_kept(tmp_path, capsys):
    """A run file the user appended to is no longer only the run's: refused, kept."""
    base = _shared(tmp_path)
    scene = _scene(base)
    out = os.path.join(base, "run")
    assert _run(["run", scene, "--out", out, "--quiet"], capsys)[0] == 0
    if COMM.rank == 0:
        with open(os.path.join(out, "history.csv"), "a") as f:
            f.write("# my remark\n")
    COMM.barrier()
    code, err = _run(["run", scene, "--out", out, "--quiet"], capsys)
    assert code == 2 and err.count("\n") == 1 and "history.csv" in err, err
    with open(os.path.join(out, "history.csv")) as f:
        assert f.read().endswith("# my remark\n")


def test_a_folder_that_looks_like_an_old_run_is_not_one(tmp_path, capsys):
    """summary.json and a picture, but no marker: a folder of the user's, refused."""
    base = _shared(tmp_path)
    scene = _scene(base)
    folder = os.path.join(base, "paper_figures")
    files = {"summary.json": b"{}\n", "figure_3.png": b"\x89PNG my figure"}
    for name, content in files.items():
        _write(os.path.join(folder, name), content)
    assert not rundir.is_run_directory(folder)
    code, err = _run(["run", scene, "--out", folder, "--quiet"], capsys)
    assert code == 2 and err.count("\n") == 1 and "not a run directory" in err, err
    assert _unchanged(folder, files) and sorted(os.listdir(folder)) == sorted(files)


def test_a_diverged_rerun_keeps_the_complete_run(tmp_path, capsys):
    """A run that diverges (dt three times the stable limit, forced) into the directory of
    a complete run: the complete run stays in DIR, the diverged one goes beside it."""
    base = _shared(tmp_path)
    scene = _scene(base)
    out = os.path.join(base, "run")
    assert _run(["run", scene, "--out", out, "--quiet"], capsys)[0] == 0
    unstable = _scene(os.path.join(base), replace(
        replace(SHORT, "cfl = 0.9", "cfl = 3.0\nforce_dt = true"), "n_steps = 5",
        "n_steps = 2000"))
    code, err = _run(["run", unstable, "--out", out, "--quiet"], capsys)
    assert code == 3, err
    assert f"{out}.diverged" in err and f"complete run in {out}/ is kept" in err, err
    assert _summary(out)["status"] == "completed" and _summary(out)["n_steps"] == 5
    assert _summary(out + ".diverged")["status"] == "diverged"
    # the next complete run replaces the complete one; the diverged one stays beside it
    stable = _scene(base, SHORT)
    assert _run(["run", stable, "--out", out, "--quiet"], capsys)[0] == 0
    assert _summary(out + ".diverged")["status"] == "diverged"


@serial_only
def test_an_interrupted_rerun_keeps_the_complete_run(tmp_path):
    """Ctrl-C during a re-run into the directory of a complete run: the complete run stays
    in DIR, the interrupted one is kept in DIR.interrupted, and the stop line says so."""
    (tmp_path / "short.toml").write_text(SHORT)
    (tmp_path / "long.toml").write_text(replace(BAR, "n_steps = 100", "n_steps = 5000000"))
    out = tmp_path / "run"
    env = clean_mpi_env()
    done = subprocess.run([sys.executable, "-m", "impact_fenics", "run",
                           str(tmp_path / "short.toml"), "--out", str(out), "--quiet"],
                          capture_output=True, text=True, env=env, cwd=ROOT, timeout=300)
    assert done.returncode == 0, done.stderr
    second = subprocess.Popen([sys.executable, "-m", "impact_fenics", "run",
                               str(tmp_path / "long.toml"), "--out", str(out), "--quiet"],
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                              env=env, cwd=ROOT)
    try:
        wait_for_loop(second, out)  # a state the run writes: its first energy row
    finally:
        second.send_signal(2)  # SIGINT, as Ctrl-C
        _, err = second.communicate(timeout=120)
    assert second.returncode == 130, err
    assert f"{out}.interrupted" in err and f"complete run in {out}/ is kept" in err, err
    assert _summary(str(out))["status"] == "completed"
    assert _summary(str(out))["n_steps"] == 5
    assert _summary(str(out) + ".interrupted")["status"] == "interrupted by SIGINT"


def test_a_dead_runs_staging_directory_keeps_the_users_files(tmp_path, capsys):
    """A run died; the user saved a file in its DIR.partial. Taking over removes only the
    dead run's own files: here the user's file is named and nothing is removed."""
    base = _shared(tmp_path)
    scene = _scene(base)
    out = os.path.join(base, "run")
    dead = _dead_pid()
    _write_lock(out + ".partial", dead)
    _write(os.path.join(out + ".partial", "history.csv"), b"step,time\n0,0\n")
    mine = {"what_went_wrong.txt": b"it died at step 8000\n"}
    _write(os.path.join(out + ".partial", "what_went_wrong.txt"), mine["what_went_wrong.txt"])
    code, err = _run(["run", scene, "--out", out, "--quiet"], capsys)
    assert code == 2 and err.count("\n") == 1 and "what_went_wrong.txt" in err, err
    assert _unchanged(out + ".partial", mine)
    assert os.path.isfile(os.path.join(out + ".partial", "history.csv"))
    COMM.barrier()  # every rank has looked before the file moves
    # the user moves the file out: the dead run's own files go, the run takes over
    if COMM.rank == 0:
        os.remove(os.path.join(out + ".partial", "what_went_wrong.txt"))
    COMM.barrier()
    code, err = _run(["run", scene, "--out", out, "--quiet"], capsys)
    assert code == 0 and "took over the output of a run that died" in err, err
    assert _summary(out)["status"] == "completed"


@pytest.mark.parametrize("route", ["--out", "[output] dir"])
def test_a_tilde_is_the_home_directory(tmp_path, capsys, monkeypatch, route):
    base = _shared(tmp_path)
    home = os.path.join(base, "home")
    work = os.path.join(base, "work")
    if COMM.rank == 0:
        os.makedirs(home)
        os.makedirs(work)
    COMM.barrier()
    monkeypatch.setenv("HOME", home)
    monkeypatch.chdir(work)
    if route == "--out":
        code, err = _run(["run", _scene(base), "--out", "~/runs/x", "--quiet"], capsys)
    else:
        text = SHORT.replace("[output]\n", "[output]\ndir = \"~/runs/x\"\n")
        code, err = _run(["run", _scene(base, text), "--quiet"], capsys)
    assert code == 0, err
    assert _summary(os.path.join(home, "runs", "x"))["status"] == "completed"
    assert os.listdir(work) == []


def test_every_file_a_run_writes_has_a_run_files_name(tmp_path, capsys):
    """The names by which a dead run's staging directory is cleaned (rundir.RUN_FILE)
    cover every file a run writes: contact pairs, probes, plots, fields, a finite-strain
    run; else a dead run's own file would block the next run forever."""
    from scene_texts import PAIR
    from test_finite_scene import TAYLOR

    base = _shared(tmp_path)
    for k, text in enumerate((PAIR, TAYLOR)):
        out = os.path.join(base, f"run{k}")
        code, err = _run(["run", _scene(base, text), "--out", out, "--quiet"], capsys)
        assert code == 0, err
        names = sorted(os.listdir(out))
        h5 = "fields.h5" if COMM.size == 1 else f"fields_p{COMM.size - 1}.h5"
        assert h5 in names and "history.png" in names, names
        assert all(rundir.RUN_FILE.match(n) for n in names), names
