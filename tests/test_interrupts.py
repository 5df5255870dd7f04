"""SIGINT and SIGTERM at every moment of a run: one line, exit 128 + signal, nothing lost.

Oracles: the specification in impact_fenics/interrupts.py and docs/outputs.md
(before the run nothing is written and an older run in the directory is kept;
in the loop the run stops at the next step (serial) or at the next multiple of
64 steps or after the last step (MPI, where the ranks agree); after the last
step the output is finished and complete), checked on the files. In-process
tests send the signal from inside the run at a chosen step (to one rank only
under MPI, so the agreement is tested); the subprocess tests send it as a user
or a batch system does (serial pass only; the MPI ones launch mpirun), each once
the program has reached the moment the test is about, as the program shows it: MPI's
library mapped (start-up: the package's one-line handling is installed before it
loads), the estimate line (set-up: printed before meshing, after the handlers are in
place), the first output row in the staging directory (the loop). Never after a fixed
time: how long start-up takes depends on the machine and its load.
"""
import json
import os
import select
import signal
import subprocess
import sys
import time
import uuid

import pytest
from mpi4py import MPI

from conftest import clean_mpi_env
from impact_fenics import interrupts, plotting, scenes
from impact_fenics.compat import launcher_ctrl_c_signal, launcher_rank_variable
from impact_fenics.integrator import Integrator
from impact_fenics.simulation import Settings, Simulation
from scene_texts import BAR, ROOT, wait_for_loop
from test_failure import LONG

serial_only = pytest.mark.skipif(MPI.COMM_WORLD.size > 1, reason="launches processes: serial only")
COMM = MPI.COMM_WORLD
N_STEPS = 200


def _bar(out: str) -> Simulation:
    return scenes.elastic_bar(Settings(cfl=0.9, n_steps=N_STEPS, output_every=50, quiet=True,
                                       out=out), h=0.01, length=0.1, radius=0.02)


def _signal_self(sig=signal.SIGINT, rank=None) -> None:
    """Send ``sig`` to this process, on ``rank`` only (default: the last rank)."""
    if COMM.rank == (COMM.size - 1 if rank is None else rank):
        os.kill(os.getpid(), sig)


def _at_step(monkeypatch, step: int) -> None:
    """Send SIGINT to the last rank when the loop reaches ``step`` (in its contact phase:
    the step is taken, the state is n + 1 when the integrator accepts it)."""
    real = Integrator.advance

    def advance(self):
        if self.n == step:
            _signal_self()
        return real(self)

    monkeypatch.setattr(Integrator, "advance", advance)


def _summary(out: str) -> dict:
    with open(os.path.join(out, "summary.json")) as f:
        return json.load(f)


def _old_run(out: str) -> None:
    """An older run in ``out`` (marker and a summary) that must survive a stop before the run."""
    if COMM.rank == 0:
        os.makedirs(out)
        with open(os.path.join(out, ".impact_fenics_run"), "w") as f:
            f.write("old\n")
        with open(os.path.join(out, "summary.json"), "w") as f:
            f.write('{"status": "old"}\n')
    COMM.barrier()


def test_signal_during_set_up_writes_nothing(tmp_path, monkeypatch):
    out = COMM.bcast(str(tmp_path / "run"), root=0)
    _old_run(out)
    sim = _bar(out)
    real = Simulation._field_writer

    def writer(self, staging):
        _signal_self()  # while the output expressions are compiled
        return real(self, staging)

    monkeypatch.setattr(Simulation, "_field_writer", writer)
    with pytest.raises(interrupts.Interrupted) as exc:
        sim.run()
    assert exc.value.signum == signal.SIGINT and exc.value.exit_code == 130
    assert not os.path.exists(out + ".partial")
    assert _summary(out) == {"status": "old"}  # the older run is untouched


@pytest.mark.parametrize("step", [5, N_STEPS - 10], ids=["early", "last_steps"])
def test_signal_in_the_loop_stops_with_a_complete_directory(tmp_path, monkeypatch, step):
    out = COMM.bcast(str(tmp_path / "run"), root=0)
    sim = _bar(out)
    _at_step(monkeypatch, step)
    summary = sim.run()
    # serial: the step after; MPI: the next multiple of 64, or the last step
    expected = step + 1 if COMM.size == 1 else min(64 * (step // 64 + 1), N_STEPS)
    assert sim.status == summary["status"] == "interrupted by SIGINT"
    assert summary["stopped_at_step"] == expected and sim.signal == signal.SIGINT
    assert _summary(out)["stopped_at_step"] == expected
    assert not os.path.exists(out + ".partial")
    with open(os.path.join(out, "history.csv")) as f:
        assert len(f.read().splitlines()) == expected + 1  # header + one row per step


def test_signal_while_plotting_finishes_the_directory(tmp_path, monkeypatch):
    out = COMM.bcast(str(tmp_path / "run"), root=0)
    sim = _bar(out)
    real = plotting.write_history_plots

    def plots(*args, **kwargs):
        _signal_self(rank=0)  # plots are drawn on rank 0
        return real(*args, **kwargs)

    monkeypatch.setattr(plotting, "write_history_plots", plots)
    summary = sim.run()
    assert sim.status == "completed" and sim.signal == signal.SIGINT
    assert "SIGINT after the last step" in _summary(out)["interrupted"]
    assert summary["stopped_at_step"] == N_STEPS
    for name in ("energy.png", "fields.xdmf", "history.csv", "summary.json"):
        assert os.path.getsize(os.path.join(out, name)) > 0
    assert not os.path.exists(out + ".partial")


# ------------------------------------------------------------------ as a user sends them

def _cli(args, env=None):
    return subprocess.Popen([sys.executable, "-m", "impact_fenics", *map(str, args)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env=env or clean_mpi_env(), cwd=ROOT)


# The state a test waits for is checked again and again until it holds; the deadline
# only keeps a broken program from hanging the suite, it is no assumption on timing.
DEADLINE = 300.0  # s


def _wait_for_mpi(proc) -> None:
    """Wait until the process has MPI's library mapped: it is importing the package, whose
    start-up handling (interrupts.held_at_start) is installed before mpi4py loads the
    library (a signal before Python runs any of the package's code is Python's, not the
    program's)."""
    deadline = time.monotonic() + DEADLINE
    while True:
        try:
            with open(f"/proc/{proc.pid}/maps") as f:
                if "libmpi" in f.read():
                    return
        except OSError:
            pass
        assert proc.poll() is None and time.monotonic() < deadline, proc.communicate()
        time.sleep(0.005)


def _wait_for_line(proc, prefix: str) -> str:
    """Wait until the process has printed a line starting with ``prefix`` on its stdout
    (read unbuffered from the pipe, so that the rest stays for communicate())."""
    fd = proc.stdout.fileno()
    deadline = time.monotonic() + DEADLINE
    text = b""
    while True:
        for line in text.split(b"\n")[:-1]:  # complete lines only
            if line.startswith(prefix.encode()):
                return line.decode()
        ready, _, _ = select.select([fd], [], [], 0.1)
        if ready:
            chunk = os.read(fd, 65536)
            assert chunk, (text.decode(errors="replace"), proc.communicate())  # closed
            text += chunk
        assert proc.poll() is None and time.monotonic() < deadline, (text, proc.communicate())


# the line the command line prints during set-up, before meshing (rank 0; the handlers
# of every rank are in place: MPI_Init, which each rank enters within them, has returned)
SET_UP_LINE = "estimate"


@serial_only
@pytest.mark.parametrize("sig, phase", [(signal.SIGINT, "imports"), (signal.SIGTERM, "set_up")],
                         ids=["SIGINT_imports", "SIGTERM_set_up"])
def test_signal_before_the_run_prints_one_line(tmp_path, sig, phase):
    """A signal while the package is imported (MPI starts) or the scene is built: one
    line, exit 128 + signum, the older run untouched. The signal goes once MPI's library
    is mapped (the message says start-up, or set-up if the program got there first), or
    once the estimate line is printed (set-up: before meshing)."""
    (tmp_path / "bar.toml").write_text(BAR)
    out = str(tmp_path / "run")
    _old_run(out)
    quiet = ["--quiet"] if phase == "imports" else []  # --quiet prints no estimate
    proc = _cli(["run", tmp_path / "bar.toml", "--out", out, *quiet])
    if phase == "imports":
        _wait_for_mpi(proc)
        phases = ("start-up", "set-up")
    else:
        _wait_for_line(proc, SET_UP_LINE)
        phases = ("set-up",)
    proc.send_signal(sig)
    _, err = proc.communicate(timeout=DEADLINE)
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert proc.returncode == 128 + sig.value, err
    assert lines in ([f"stopped: interrupted by {sig.name} during {p}; nothing was written"]
                     for p in phases), err
    assert _summary(out) == {"status": "old"} and not os.path.exists(out + ".partial")


# the launcher's rank variable: OMPI_COMM_WORLD_RANK (OpenMPI), PMI_RANK (MPICH's Hydra)
RANK_VARIABLE = launcher_rank_variable().encode()


def _rank_pids(tag: str) -> dict[int, int]:
    """{rank: pid} of the MPI ranks whose environment holds IMPACT_TEST_TAG=tag."""
    ranks = {}
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            try:
                with open(f"/proc/{entry}/environ", "rb") as f:
                    env = dict(v.split(b"=", 1) for v in f.read().split(b"\0") if b"=" in v)
            except OSError:
                continue
            if env.get(b"IMPACT_TEST_TAG") == tag.encode() and RANK_VARIABLE in env:
                ranks[int(env[RANK_VARIABLE])] = int(entry)
    return ranks


def _mpirun(args, tag):
    env = clean_mpi_env()
    env["IMPACT_TEST_TAG"] = tag
    return subprocess.Popen([os.path.join(ROOT, "scripts", "mpirun.sh"), "-n", "2",
                             sys.executable, "-m", "impact_fenics", *map(str, args)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env=env, cwd=ROOT)


@serial_only
def test_a_signal_inside_a_whole_block_is_acted_on_after_it():
    """interrupts.whole() around the compiled modules' imports: the handler does not raise
    inside (an exception in a compiled module's initialisation comes out as an
    ImportError with a traceback), and the signal stops the program when the block ends."""
    old = {sig: signal.getsignal(sig) for sig in interrupts.SIGNALS}
    installed = interrupts.STATE.installed
    interrupts.clear()
    reached = False
    try:
        interrupts.install()
        with pytest.raises(interrupts.Interrupted) as stop:
            with interrupts.whole():
                signal.raise_signal(signal.SIGTERM)
                reached = True  # the handler ran and only set the flag
        assert reached and stop.value.signum == signal.SIGTERM
    finally:
        for sig, handler in old.items():
            signal.signal(sig, handler)
        interrupts.STATE.installed = installed
        interrupts.clear()


def test_a_signal_during_the_agreement_is_kept_for_the_next():
    """A signal that reaches a rank while it waits in the agreement's reduction (after its
    flag was read as 0) must stay pending: the ranks agree on it the next time. The
    reduction is replaced by one that delivers the signal inside it, as happens when a
    rank waits there for a slower one (a lost SIGINT let a 'stopped' run go on)."""
    class SignalInside:
        size = 2

        def allreduce(self, value, op=None):
            interrupts.STATE.signum = signal.SIGINT  # the handler runs inside the wait
            return value  # every rank's flag was 0 when read

    interrupts.clear()
    try:
        assert interrupts.agree(SignalInside()) == 0
        assert interrupts.pending() == signal.SIGINT
    finally:
        interrupts.clear()


@serial_only
@pytest.mark.parametrize("to", ["both", "rank1"])
def test_signal_to_the_ranks_under_mpirun(tmp_path, to):
    """A batch system signals every rank (SIGTERM); a stray kill one rank (SIGINT): the
    ranks agree at the next multiple of 64 steps and rank 0 reports in one line."""
    (tmp_path / "scene.toml").write_text(LONG)
    out = tmp_path / "run"
    tag = uuid.uuid4().hex
    proc = _mpirun(["run", tmp_path / "scene.toml", "--out", out, "--quiet"], tag)
    wait_for_loop(proc, out)
    pids = _rank_pids(tag)
    assert sorted(pids) == [0, 1], pids
    sig = signal.SIGTERM if to == "both" else signal.SIGINT
    for rank in ([0, 1] if to == "both" else [1]):
        os.kill(pids[rank], sig)
    _, err = proc.communicate(timeout=120)
    lines = [ln for ln in err.splitlines() if ln.startswith(("stopped:", "error:"))]
    assert len(lines) == 1 and f"interrupted by {sig.name}" in lines[0], err
    assert "Traceback" not in err
    s = _summary(str(out))
    assert s["status"] == f"interrupted by {sig.name}" and s["n_ranks"] == 2
    assert s["stopped_at_step"] % 64 == 0 and 0 < s["stopped_at_step"] < s["n_steps"]
    assert not os.path.exists(str(out) + ".partial")


@serial_only
def test_ctrl_c_on_the_launcher_stops_the_run_cleanly(tmp_path):
    """Ctrl-C in the launcher's terminal (SIGINT to its process group: the launcher and the
    ranks): the ranks get the launcher's signal (OpenMPI sends SIGTERM, MPICH's Hydra
    forwards SIGINT), agree at the next multiple of 64 steps, and the directory is
    complete up to there with one line on stderr."""
    (tmp_path / "scene.toml").write_text(LONG)
    out = tmp_path / "run"
    env = clean_mpi_env()
    proc = subprocess.Popen([os.path.join(ROOT, "scripts", "mpirun.sh"), "-n", "2",
                             sys.executable, "-m", "impact_fenics", "run",
                             str(tmp_path / "scene.toml"), "--out", str(out), "--quiet"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env=env, cwd=ROOT, start_new_session=True)  # a terminal's group
    wait_for_loop(proc, out)
    os.killpg(proc.pid, signal.SIGINT)
    _, err = proc.communicate(timeout=120)
    sig = signal.Signals(launcher_ctrl_c_signal())
    lines = [ln for ln in err.splitlines() if ln.startswith(("stopped:", "error:"))]
    assert proc.returncode != 0
    assert len(lines) == 1 and f"interrupted by {sig.name}" in lines[0], err
    assert "Traceback" not in err
    s = _summary(str(out))
    assert s["status"] == f"interrupted by {sig.name}"
    assert s["stopped_at_step"] % 64 == 0 and 0 < s["stopped_at_step"] < s["n_steps"]
    assert not os.path.exists(str(out) + ".partial")


@serial_only
def test_signal_during_set_up_under_mpirun_ends_every_rank(tmp_path):
    """SIGTERM to every rank before the run (while rank 0 builds the scene: after its
    estimate line): every rank ends, the one line names the phase, nothing is written."""
    (tmp_path / "bar.toml").write_text(BAR)
    out = str(tmp_path / "run")
    tag = uuid.uuid4().hex
    proc = _mpirun(["run", tmp_path / "bar.toml", "--out", out], tag)
    _wait_for_line(proc, SET_UP_LINE)
    pids = _rank_pids(tag)
    assert sorted(pids) == [0, 1], pids
    for pid in pids.values():
        os.kill(pid, signal.SIGTERM)
    _, err = proc.communicate(timeout=DEADLINE)
    assert proc.returncode != 0
    assert any(f"stopped: interrupted by SIGTERM during {phase}; nothing was written" in err
               for phase in ("start-up", "set-up")), err
    assert "Traceback" not in err
    assert not os.path.exists(out) and not os.path.exists(out + ".partial")
