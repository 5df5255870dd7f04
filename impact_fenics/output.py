"""Output: XDMF time series of fields, CSV histories and a JSON summary.

Files are written into a staging directory ``DIR.partial`` and renamed to DIR
when the run ends, so a directory named DIR always holds a finished (or
cleanly stopped) run; a crash leaves only ``DIR.partial``. The staging
directory is created atomically and is the run's lock; a run removes or
replaces only directories it wrote (see rundir.py). Rank 0 writes the
CSV and JSON files; the XDMF file is written collectively.
"""
from __future__ import annotations

import csv
import json
import os
from typing import Sequence

import numpy as np
from mpi4py import MPI
from dolfinx import fem, io

# the output directory rules and the lock live in rundir.py (no dolfinx import there)
from .rundir import abandon_directory, finalize_directory, prepare_directory  # noqa: F401

# beyond this many XDMF snapshots a run warns: each write rewrites the whole .xdmf
MANY_SNAPSHOTS = 500


def write_json(path: str, data: dict, comm: MPI.Comm) -> None:
    """Write ``data`` as indented, strict JSON from rank 0 (NaN and infinities become null)."""
    if comm.rank == 0:
        with open(path, "w") as f:
            json.dump(json_ready(data), f, indent=2, sort_keys=True, allow_nan=False)
            f.write("\n")


def json_ready(obj):
    """A JSON-ready copy of ``obj`` with numpy values as Python ones and non-finite floats as None."""
    if isinstance(obj, dict):
        return {k: json_ready(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple, np.ndarray)):
        return [json_ready(v) for v in obj]
    if isinstance(obj, np.generic):
        obj = obj.item()
    if isinstance(obj, float) and not np.isfinite(obj):
        return None
    return obj


class Table:
    """A CSV history filled row by row into a preallocated buffer.

    With ``path`` the rows are appended to the file on :meth:`flush` (rank 0);
    with ``keep`` every row also stays in memory (:meth:`data`). The buffer
    grows by doubling when ``keep`` is set, so rows cost no allocation once
    warm."""

    def __init__(self, path: str | None, columns: Sequence[str], comm: MPI.Comm,
                 capacity: int = 4096, keep: bool = False):
        self.path = path
        self.columns = list(columns)
        self.comm = comm
        self.keep = keep
        self._buf = np.full((max(1, capacity), len(self.columns)), np.nan)
        self._n = 0
        self._written = 0
        if path and comm.rank == 0:
            with open(path, "w", newline="") as f:
                csv.writer(f).writerow(self.columns)

    def row(self) -> np.ndarray:
        """The next row to fill (a view)."""
        if self._n == self._buf.shape[0]:
            if self.keep:
                grown = np.full((2 * self._n, self._buf.shape[1]), np.nan)
                grown[: self._n] = self._buf
                self._buf = grown
            else:
                self.flush()
        r = self._buf[self._n]
        self._n += 1
        return r

    def rows(self, k: int) -> np.ndarray:
        """The next ``k`` rows to fill (a view; ``keep=False`` tables only)."""
        if self._n + k > self._buf.shape[0]:
            self.flush()
        if k > self._buf.shape[0]:
            self._buf = np.full((k, self._buf.shape[1]), np.nan)
        block = self._buf[self._n: self._n + k]
        self._n += k
        return block

    def flush(self) -> None:
        """Append the rows not yet written to the file."""
        if self.path and self._n > self._written and self.comm.rank == 0:
            with open(self.path, "a") as f:
                np.savetxt(f, self._buf[self._written: self._n], delimiter=",", fmt="%.12g")
        if self.keep:
            self._written = self._n
        else:
            self._buf[: self._n] = np.nan
            self._n = self._written = 0

    def data(self) -> dict[str, np.ndarray]:
        """All kept rows, by column (``keep=True`` only)."""
        return {c: self._buf[: self._n, k].copy() for k, c in enumerate(self.columns)}


class FieldWriter:
    """XDMF time series of displacement, velocity and DG0 stress components.

    ``stresses(u)`` maps an output name to a list of (UFL expression of u, cells)
    pieces (one per body), evaluated at cell midpoints."""

    def __init__(self, path: str, V: fem.FunctionSpace, stresses):
        mesh = V.mesh
        self.n_owned = V.dofmap.index_map.size_local * V.dofmap.index_map_bs
        self.xdmf = io.XDMFFile(mesh.comm, path, "w")
        self.xdmf.write_mesh(mesh)
        self.u = fem.Function(V, name="displacement")
        self.v = fem.Function(V, name="velocity")
        Q = fem.FunctionSpace(mesh, ("DG", 0))
        points = Q.element.interpolation_points()
        self._stress = []
        for name, pieces in stresses(self.u).items():
            f = fem.Function(Q, name=name)
            exprs = [(fem.Expression(expr, points), cells) for expr, cells in pieces]
            self._stress.append((f, exprs))

    def set_state(self, u: np.ndarray, v: np.ndarray) -> None:
        """Copy owned u (m) and v (m/s) into the fields and update the ghosts."""
        for f, values in ((self.u, u), (self.v, v)):
            f.x.array[: self.n_owned] = values
            f.x.scatter_forward()

    def write(self, t: float) -> None:
        """Write u, v and the stresses at time t (s); call :meth:`set_state` first."""
        self.xdmf.write_function(self.u, t)
        self.xdmf.write_function(self.v, t)
        for f, exprs in self._stress:
            for expr, cells in exprs:
                f.interpolate(expr, cells)
            self.xdmf.write_function(f, t)

    def close(self) -> None:
        self.xdmf.close()
