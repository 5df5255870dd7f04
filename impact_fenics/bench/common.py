"""What every part shares: the sizes of a run (Mode), the timer, the run context and
child processes."""
from __future__ import annotations

import json
import os
import subprocess
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from mpi4py import MPI

from ..compat import LAUNCHER_ENV_PREFIXES
from .bar import bar_mesh
from .tables import format_table

ROOT = Path(__file__).resolve().parents[2]
MPI_ENV = LAUNCHER_ENV_PREFIXES  # a launcher's variables


@dataclass(frozen=True)
class Mode:
    """Sizes and repeats of one kind of run."""

    name: str
    step_dofs: int            # mesh of the step, format and matfree parts
    sim_steps: int            # steps of the Simulation loop
    repeats: int              # repeats of each timed block
    target: float             # seconds per timed block
    sizes: tuple[int, ...]    # dofs of the scaling part
    rank_sizes: tuple[int, ...]  # dofs of the 1-vs-2 ranks comparison
    contact_ns: tuple[int, ...]  # numbers of constraints
    dense_cap: int            # FILM dense runs up to this many constraints (O(n^3))
    contact_steps: int
    dense_steps: int
    stream_n: int             # entries of the STREAM vectors (global)
    solver_ns: tuple[int, ...]
    akantu_dofs: int
    akantu_steps: int


MODES = {
    "smoke": Mode("smoke", step_dofs=4_000, sim_steps=20, repeats=3, target=0.005,
                  sizes=(4_000,), rank_sizes=(4_000,), contact_ns=(40,), dense_cap=40,
                  contact_steps=8, dense_steps=4, stream_n=1 << 20, solver_ns=(40,),
                  akantu_dofs=4_000, akantu_steps=5),
    "quick": Mode("quick", step_dofs=50_000, sim_steps=200, repeats=5, target=0.04,
                  sizes=(20_000, 100_000, 200_000), rank_sizes=(200_000,),
                  contact_ns=(100, 1000), dense_cap=1000, contact_steps=40, dense_steps=5,
                  stream_n=1 << 23, solver_ns=(100, 1000), akantu_dofs=20_000,
                  akantu_steps=20),
    "full": Mode("full", step_dofs=200_000, sim_steps=400, repeats=7, target=0.15,
                 sizes=(20_000, 50_000, 100_000, 200_000, 500_000, 1_000_000),
                 rank_sizes=(200_000, 500_000, 1_000_000),
                 contact_ns=(100, 300, 1000, 2000, 5000, 10_000), dense_cap=2000,
                 contact_steps=100, dense_steps=5, stream_n=1 << 25,
                 solver_ns=(100, 300, 1000, 2000, 5000, 10_000), akantu_dofs=200_000,
                 akantu_steps=30),
}


def timeit(fn, comm: MPI.Comm, repeats: int, target: float, min_inner: int = 1) -> dict:
    """Median seconds per call of ``fn`` over ``repeats`` blocks of calls lasting ~``target`` s.

    One call first (warm-up and calibration); under MPI every block starts at a
    barrier and the slowest rank's time counts."""
    clock = time.perf_counter
    comm.Barrier()
    t = clock()
    fn()
    first = comm.allreduce(clock() - t, op=MPI.MAX)
    inner = max(min_inner, int(target / max(first, 1e-9)))
    samples = []
    for _ in range(repeats):
        comm.Barrier()
        t = clock()
        for _ in range(inner):
            fn()
        samples.append(comm.allreduce((clock() - t) / inner, op=MPI.MAX))
    return {"median": float(np.median(samples)), "min": float(min(samples)),
            "max": float(max(samples)), "calls_per_repeat": inner, "repeats": repeats}


def ns_per_dof(seconds: float, n_dofs: int) -> float:
    return 1e9 * seconds / n_dofs


def per_dof(times: dict, n_dofs: int) -> dict:
    """ns per dof of each entry of ``times`` (s)."""
    return {k: ns_per_dof(v, n_dofs) for k, v in times.items()}


class Context:
    """What the parts share in one run: communicator, mode, options, results so far,
    meshes kept for reuse, and the printing (rank 0, unless quiet)."""

    def __init__(self, comm: MPI.Comm, mode: Mode, args, parts: list[str]):
        self.comm = comm
        self.mode = mode
        self.args = args
        self.parts = parts
        self.results: dict = {}
        self.quiet = args.quiet or args.child
        self.rank0 = comm.rank == 0
        self._meshes: dict = {}

    def log(self, *msg) -> None:
        if self.rank0 and not self.quiet:
            print(*msg, flush=True)

    def table(self, title: str, headers: list, rows: list) -> None:
        self.log(format_table(title, headers, rows))

    def timeit(self, fn, target: float | None = None, repeats: int | None = None) -> dict:
        """:func:`timeit` with the mode's repeats and block length (or these)."""
        return timeit(fn, self.comm, repeats or self.mode.repeats,
                      self.mode.target if target is None else target)

    def median(self, fn, target: float | None = None, repeats: int | None = None) -> float:
        return self.timeit(fn, target, repeats)["median"]

    def mesh(self, dofs: int, keep: bool = True):
        """(mesh, h) of the bar with about ``dofs`` dofs; kept for the next part if ``keep``."""
        if dofs in self._meshes:
            return self._meshes[dofs]
        m = bar_mesh(self.comm, dofs)
        if keep:
            self._meshes[dofs] = m
        return m

    def forget_meshes(self) -> None:
        self._meshes.clear()


def child_env(*drop: str, **set_vars: str) -> dict:
    """This environment without a launcher's variables (nor those starting with ``drop``):
    a child started from a rank must not take itself for a rank of this job."""
    env = {k: v for k, v in os.environ.items() if not k.startswith(MPI_ENV + drop)}
    env.update(set_vars)
    return env


def run_json(cmd: list[str], out: str, env: dict, cwd: str, timeout: float) -> dict:
    """Run ``cmd`` and read the JSON it writes to ``out``; RuntimeError on a non-zero exit."""
    p = subprocess.run(cmd, env=env, cwd=cwd, capture_output=True, text=True, timeout=timeout)
    if p.returncode != 0:
        raise RuntimeError(f"exit {p.returncode}: {p.stderr[-2000:]}")
    with open(out) as f:
        return json.load(f)
