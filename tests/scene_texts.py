"""Tiny scene files shared by the CLI tests, and a launcher for the command line."""
import os
import subprocess
import sys
import time

from conftest import clean_mpi_env

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), ".."))

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
