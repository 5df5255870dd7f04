"""Tiny scene files shared by the CLI tests, and a launcher for the command line."""
import os
import subprocess
import sys
import time

from conftest import clean_mpi_env

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), ".."))


# The two Q1 copper-size bars of the mixed-kinematics scenes (R = 3.2 mm, 12.8 mm long, h = R/4 on
# the striker and R/6 on the target: node-to-segment faces 4/6), their J2 copper, and the film
# node-to-segment contact with the 100 steps of 2^-24 s that both scenes run.
Q1_BARS_MESH = """[mesh]
generator = "coaxial_bars_sized"
radius = 3.2e-3
striker_length = 12.8e-3
target_length = 12.8e-3
h_striker = 8e-4
h_target = 5.333333333333333e-4
structured = true
quadrilaterals = true
"""

COPPER_J2 = """[materials.copper]
model = "j2"
E = 117e9
nu = 0.35
density = 8930.0
yield_stress = 400e6
hardening = 100e6
"""

FILM_SEGMENTS_100_STEPS = """[[contact]]
slave = "target_contact"
master = "striker_contact"
method = "film"
repair_every = 5

[time]
dt = 5.9604644775390625e-08     # s, 2^-24 (exact)
t_end = 5.9604644775390625e-06  # s, 100 steps
"""

# Two coaxial steel bars of radius 2 cm and length 4 cm (h = 1 cm): 3 pairs, a few dozen cells.
PAIR = """\
title = "tiny impact"

[mesh]
generator = "coaxial_bars"
radius = 0.02
striker_length = 0.04
target_length = 0.04
h = 0.01

[materials.steel]
E = 200e9
nu = 0.3
density = 7850.0

[bodies.striker]
material = "steel"
velocity = [0.0, 5.0]

[bodies.target]
material = "steel"

[[contact]]
lower = "striker_contact"
upper = "target_contact"
method = "film"

[[loads]]
facet = "target_end"
pulse = "trapezoid"
peak = 1e6
t_rise = 1e-6
t_fall = 2e-6
t_end = 3e-6

[time]
dt = 1e-7
n_steps = 20

[output]
output_every = 10

[[probes]]
name = "s"
point = [0.01, 0.02]
quantity = "sigma_zz"
"""

# A rigid punch of radius 0.1 m on a small block.
RIGID = """\
[mesh]
generator = "punch_block"
width = 0.3
depth = 0.1
h_surface = 0.02
grading = 0.3
h_max = 0.05
breaks = [[0.1, 5]]

[materials.steel]
E = 200e9
nu = 0.3
density = 7850.0

[bodies.block]
material = "steel"

[rigid.punch]
mass = 0.1

[[fixed]]
facet = "bottom"
components = ["z"]

[[contact]]
surface = "surface"
rigid = "punch"
radius = 0.1
method = "dme"

[[loads]]
rigid = "punch"
peak = 1e6
area = 0.0314
t_rise = 1e-6
t_fall = 2e-6
t_end = 3e-6

[time]
dt = 1e-7
n_steps = 20
"""

# A single bar of radius 2 cm and length 10 cm loaded on z = 0.
BAR = """\
[mesh]
generator = "bar"
radius = 0.02
length = 0.1
h = 0.01

[materials.steel]
E = 200e9
nu = 0.3
density = 7850.0

[bodies.bar]
material = "steel"

[[loads]]
facet = "loaded_end"
peak = 1e8
t_rise = 2e-6
t_fall = 1e-5
t_end = 1.2e-5

[time]
cfl = 0.9
n_steps = 100

[output]
output_every = 10

[[probes]]
name = "u_mid"
point = [0.01, 0.05]
quantity = "u_z"
"""


def replace(text: str, old: str, new: str) -> str:
    """``text`` with the one occurrence of ``old`` replaced (it must occur)."""
    assert text.count(old) == 1, old
    return text.replace(old, new)


def launch(args, timeout=120, **kwargs) -> subprocess.CompletedProcess:
    """Run ``python -m impact_fenics ARGS`` as a user would (a fresh process, no MPI)."""
    cmd = [sys.executable, "-m", "impact_fenics"] + [str(a) for a in args]
    return subprocess.run(cmd, capture_output=True, text=True, timeout=timeout,
                          env=clean_mpi_env(), cwd=ROOT, **kwargs)


def run_on_ranks(scene, outs: dict, timeout: float = 300.0) -> None:
    """Run ``impact-fenics run SCENE --out OUT --quiet`` under ``scripts/mpirun.sh -n N``
    for every (N, OUT) of ``outs``, all launched at once (their start-up overlaps), each
    expected to succeed (its stderr's tail in the failure); ``timeout`` (s) only keeps a
    broken run from hanging the suite."""
    procs = {n: subprocess.Popen([os.path.join(ROOT, "scripts", "mpirun.sh"), "-n", str(n),
                                  sys.executable, "-m", "impact_fenics", "run", str(scene),
                                  "--out", str(out), "--quiet"],
                                 stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                                 env=clean_mpi_env(), cwd=ROOT) for n, out in outs.items()}
    for n, proc in procs.items():
        try:
            _, err = proc.communicate(timeout=timeout)
        except subprocess.TimeoutExpired:
            for p in procs.values():
                p.kill()
            raise
        assert proc.returncode == 0, f"{n} ranks: {err[-2000:]}"


def scene_on_every_rank(tmp_path_factory, name: str, text: str) -> tuple[str, str]:
    """(a directory every rank shares, the scene ``text`` written there as NAME.toml by
    rank 0), for a test that runs it in-process and under mpirun."""
    from mpi4py import MPI

    comm = MPI.COMM_WORLD
    base = comm.bcast(str(tmp_path_factory.mktemp(name)) if comm.rank == 0 else None, root=0)
    scene = os.path.join(base, f"{name}.toml")
    if comm.rank == 0:
        with open(scene, "w") as f:
            f.write(text)
    comm.barrier()
    return base, scene


def read_history(out) -> dict:
    """A run's history.csv as {column: values}."""
    import numpy as np

    h = np.genfromtxt(os.path.join(out, "history.csv"), delimiter=",", names=True)
    return {k: h[k] for k in h.dtype.names}


def assert_ranks_agree(scene, base: str, serial: dict, columns, unit: str = "") -> None:
    """The scene run on 2 and 3 ranks (launched, into BASE/n2 and BASE/n3) gives each of
    ``columns`` within 1e-10 of its largest value in ``serial`` (the serial run's history):
    the partitions reorder the sums of each step, round-off that an undamped wave does not
    amplify beyond it."""
    import numpy as np

    run_on_ranks(scene, {n: os.path.join(base, f"n{n}") for n in (2, 3)})
    for n in (2, 3):
        hn = read_history(os.path.join(base, f"n{n}"))
        for col in columns:
            scale = float(np.max(np.abs(serial[col])))
            diff = float(np.max(np.abs(hn[col] - serial[col])))
            print(f"{n} ranks, {col}: largest difference {diff:.3g} of {scale:.3g} {unit}")
            assert diff <= 1e-10 * scale


def assert_refused(args, expected: str, out) -> None:
    """``impact-fenics ARGS`` run as a user runs it is refused as bad input: exit 2, one line
    on stderr beginning with ``expected``, no traceback, nothing written at ``out`` (nor its
    staging directory)."""
    proc = launch(args)
    lines = [ln for ln in proc.stderr.splitlines() if ln.strip()]
    assert proc.returncode == 2, proc.stderr
    assert len(lines) == 1 and lines[0].startswith(expected), proc.stderr
    assert "Traceback" not in proc.stderr + proc.stdout
    assert not os.path.exists(str(out)) and not os.path.exists(f"{out}.partial")


def wait_for_loop(proc, out, timeout=300.0) -> None:
    """Wait until the run is in its loop: the first output row is in the staging directory
    (a state the run reports, checked again and again; ``timeout`` (s) only keeps a broken
    run from hanging the suite: a first run compiles its kernels for tens of seconds)."""
    energy = os.path.join(str(out) + ".partial", "energy.csv")
    deadline = time.monotonic() + timeout
    while True:
        try:
            with open(energy) as f:
                if len(f.read().splitlines()) >= 2:
                    return
        except OSError:
            pass
        assert proc.poll() is None and time.monotonic() < deadline, proc.communicate()
        time.sleep(0.01)
