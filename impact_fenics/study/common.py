"""Shared pieces of the study: runs that record failure instead of raising, errors,
the Pareto front, and the figure/JSON writer.

Every function here is collective (call it on every rank); files are written by
rank 0 only. Timings are per rank; where one number is reported it is the
largest over the ranks (the step waits for the slowest rank).
"""
from __future__ import annotations

import dataclasses
import json
import math
import os
import shutil
import tempfile
import time

import numpy as np
from mpi4py import MPI

from ..compat import trapezoid
from ..errors import UnstableRunError
from ..simulation import Settings

# material of every scene (scenes.STEEL, nu = 0.3): c1 = sqrt((lambda + 2 mu) / rho)
E, NU, RHO = 200e9, 0.3, 7850.0
LAMBDA = E * NU / ((1 + NU) * (1 - 2 * NU))
MU = E / (2 * (1 + NU))
C1 = math.sqrt((LAMBDA + 2 * MU) / RHO)
C0 = math.sqrt(E / RHO)
TWO_PI = 2.0 * math.pi
BETA_BOUND = 4.0 / 3.0


def settings(**kw) -> Settings:
    """Settings for a study run: quiet, no XDMF fields, no per-run plots (when the
    installed Simulation knows that option)."""
    names = {f.name for f in dataclasses.fields(Settings)}
    # unstable penalties on purpose; per-pair rows every step (the bars study reads them)
    base = dict(quiet=True, fields=False, plots=False, force=True, pairs_every=1)
    base.update(kw)
    return Settings(**{k: v for k, v in base.items() if k in names})


def run_recorded(sim, extra=None) -> dict:
    """Run ``sim``; a diverging run is recorded (status, step) instead of raised.

    Returns a dict with the summary, the history and energy tables (in memory),
    and the wall time (s, max over ranks)."""
    t0 = time.perf_counter()
    try:
        summary = sim.run(extra=extra)
    except UnstableRunError as exc:
        summary = dict(sim.summary)
        summary["failure"] = str(exc)
    wall = sim.comm.allreduce(time.perf_counter() - t0, op=MPI.MAX)
    hist = sim.history.data()
    for key in [k for k in hist if k.endswith(("cpu_detection", "cpu_solve", "cpu_update"))]:
        col = np.ascontiguousarray(hist[key])
        sim.comm.Allreduce(MPI.IN_PLACE, col, op=MPI.MAX)
        hist[key] = col
    summary["wall_time"] = sim.comm.allreduce(float(summary.get("wall_time", 0.0)), op=MPI.MAX)
    return {"summary": summary, "history": hist, "energy": sim.energy.data(),
            "status": summary["status"], "stopped_at": summary["stopped_at_step"],
            "wall": wall}


def coupling(c) -> float:
    """kappa = dt^2 / m_rigid (m/N) of a contact set, 0 for node pairs."""
    if hasattr(c, "kappa"):
        return float(c.kappa)
    return float(c.s_coupling())


def contact_cpu(hist: dict, prefix: str = "") -> np.ndarray:
    """Contact CPU time (s) of each recorded step: detection + solve + update."""
    return (hist[f"{prefix}cpu_detection"] + hist[f"{prefix}cpu_solve"]
            + hist[f"{prefix}cpu_update"])


def rel_l2(t: np.ndarray, y: np.ndarray, t_ref: np.ndarray, y_ref: np.ndarray,
           window: tuple[float, float]) -> float:
    """Relative L2 distance of a history y(t) from y_ref(t_ref) on a time window (s).

    Both are interpolated linearly on the union of their sample times inside the
    window; a history that stopped early (a diverged run) or holds non-finite
    values counts as infinitely far."""
    lo, hi = window
    if t.size == 0 or t[-1] < hi - 1e-12 * max(hi, 1e-30) or not np.all(np.isfinite(y)):
        return float("inf")
    grid = np.union1d(t[(t >= lo) & (t <= hi)], t_ref[(t_ref >= lo) & (t_ref <= hi)])
    a = np.interp(grid, t, y)
    b = np.interp(grid, t_ref, y_ref)
    den = math.sqrt(trapezoid(b * b, grid))
    return float(math.sqrt(trapezoid((a - b) ** 2, grid)) / den) if den > 0 else float("inf")


def pareto_front(points: list[tuple[float, float]]) -> list[int]:
    """Indices of the non-dominated points when both coordinates are minimised.

    A point is dominated if another is no worse in both and better in one;
    equal points are all kept. Sorted by the first coordinate."""
    idx = sorted(range(len(points)), key=lambda i: (points[i][0], points[i][1]))
    front, best = [], math.inf
    k = 0
    while k < len(idx):
        # points with the same x: only those with the smallest y can be on the front
        j = k
        while j < len(idx) and points[idx[j]][0] == points[idx[k]][0]:
            j += 1
        group = idx[k:j]
        y_min = min(points[i][1] for i in group)
        if y_min < best:
            front += [i for i in group if points[i][1] == y_min]
            best = y_min
        k = j
    return front


def dominated(points, i) -> bool:
    """Whether point i is dominated by another point (both coordinates minimised)."""
    x, y = points[i]
    return any((a <= x and b <= y) and (a < x or b < y) for a, b in points)


def flips(active_count: np.ndarray) -> int:
    """Changes of the number of active constraints, summed over steps."""
    a = np.asarray(active_count, dtype=float)
    a = a[np.isfinite(a)]
    return int(np.abs(np.diff(a)).sum()) if a.size > 1 else 0


class Writer:
    """Figures (PNG) and their numbers (JSON, same basename) in one folder; rank 0 writes."""

    def __init__(self, folder: str, comm: MPI.Comm = MPI.COMM_WORLD):
        self.folder = folder
        self.comm = comm
        if comm.rank == 0:
            os.makedirs(folder, exist_ok=True)
        comm.barrier()

    def json(self, name: str, data: dict) -> None:
        if self.comm.rank == 0:
            with open(os.path.join(self.folder, f"{name}.json"), "w") as f:
                json.dump(_clean(data), f, indent=1, sort_keys=True)
                f.write("\n")

    def figure(self, name: str, fig) -> None:
        if self.comm.rank == 0:
            fig.savefig(os.path.join(self.folder, f"{name}.png"), dpi=110, bbox_inches="tight")
        import matplotlib.pyplot as plt

        plt.close(fig)


def _clean(obj):
    """JSON-ready copy: arrays to lists, non-finite floats to None, numbers rounded to 6
    significant digits in long series (the figures' data, not the report's numbers)."""
    if isinstance(obj, dict):
        return {str(k): _clean(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_clean(v) for v in obj]
    if isinstance(obj, np.ndarray):
        if obj.dtype.kind in "fc" and obj.size > 16:
            return [None if not np.isfinite(v) else float(f"{v:.6g}") for v in obj.ravel()]
        return _clean(obj.tolist())
    if isinstance(obj, (np.floating, float)):
        v = float(obj)
        return v if math.isfinite(v) else None
    if isinstance(obj, np.integer):
        return int(obj)
    if isinstance(obj, np.bool_):
        return bool(obj)
    return obj


def pyplot():
    """matplotlib.pyplot on the Agg backend."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


class Scratch:
    """A scratch folder shared by all ranks (for runs whose per-pair CSV we read back)."""

    def __init__(self, comm: MPI.Comm = MPI.COMM_WORLD):
        self.comm = comm
        path = tempfile.mkdtemp(prefix="impact_study_") if comm.rank == 0 else None
        self.path = comm.bcast(path, root=0)

    def sub(self, name: str) -> str:
        return os.path.join(self.path, name)

    def close(self) -> None:
        self.comm.barrier()
        if self.comm.rank == 0:
            shutil.rmtree(self.path, ignore_errors=True)


def read_pairs(path: str, comm: MPI.Comm = MPI.COMM_WORLD) -> dict:
    """contact_pairs.h5 of a run as arrays (steps x pairs): time, r, gap (m), force (N), active."""
    from ..output import read_pairs as read

    return comm.bcast(read(path) if comm.rank == 0 else None, root=0)


def log(msg: str, comm: MPI.Comm = MPI.COMM_WORLD) -> None:
    if comm.rank == 0:
        print(msg, flush=True)
