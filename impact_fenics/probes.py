"""Point probes: a field's value in the cell that contains a point (DG0, as CST gives it)."""
from __future__ import annotations

import numpy as np
from mpi4py import MPI
from dolfinx import fem

from .compat import colliding_cells, eval_expression
from .errors import InputError


def locate_cell(mesh, point: tuple[float, float]) -> tuple[int, bool]:
    """Local index of the cell holding ``point`` (r, z) in m, and whether this rank owns it.

    A point on a cell boundary belongs to the touching cell whose midpoint is
    smallest in (r, z): the same choice for every partition."""
    x = np.array([[point[0], point[1], 0.0]])
    n_owned = mesh.topology.index_map(mesh.topology.dim).size_local
    cells = colliding_cells(mesh, x).links(0)
    cells = np.asarray([c for c in cells if c < n_owned], dtype=np.int32)
    best = (np.inf, np.inf)
    if cells.size:
        mids = _midpoints(mesh, cells)
        k = int(np.lexsort((mids[:, 1], mids[:, 0]))[0])
        best = (float(mids[k, 0]), float(mids[k, 1]))
        cell = int(cells[k])
    winner = min(mesh.comm.allgather(best))
    if not np.isfinite(winner[0]):
        raise InputError(f"probe point (r={point[0]}, z={point[1]}) m lies outside the mesh")
    mine = cells.size > 0 and best == winner
    return (cell if mine else -1), mine


def _midpoints(mesh, cells: np.ndarray) -> np.ndarray:
    from dolfinx.mesh import compute_midpoints

    return compute_midpoints(mesh, mesh.topology.dim, cells)[:, :2]


_CENTROID = np.array([[1.0 / 3.0, 1.0 / 3.0]])


class Probes:
    """Scalar UFL expressions of the displacement, each evaluated at the midpoint of the
    cell that holds its point (the DG0 value of that cell)."""

    def __init__(self, u: fem.Function, probes: list[tuple[str, tuple[float, float], object]]):
        self.names = [name for name, _, _ in probes]
        self.points = [pt for _, pt, _ in probes]
        self.u = u
        mesh = self.mesh = u.function_space.mesh
        self.comm = mesh.comm
        self._local = np.zeros(len(probes))
        self._values = np.zeros(len(probes))
        self._evals = []
        self.midpoints = np.zeros((len(probes), 2))  # (r, z) in m of each probe's cell
        for k, (name, point, expr) in enumerate(probes):
            cell, mine = locate_cell(mesh, point)
            compiled = fem.Expression(expr, _CENTROID)  # JIT is collective: every rank
            if mine:
                self.midpoints[k] = _midpoints(mesh, np.array([cell], dtype=np.int32))[0]
                self._evals.append((k, compiled, np.array([cell], dtype=np.int32)))
        self.midpoints = self.comm.allreduce(self.midpoints, op=MPI.SUM)

    def evaluate(self) -> np.ndarray:
        """Probe values (shared by all ranks); u must be current, ghosts included."""
        self._local[:] = 0.0
        for k, expr, cells in self._evals:
            self._local[k] = eval_expression(expr, self.mesh, cells)[0, 0]
        self.comm.Allreduce(self._local, self._values)
        return self._values


def arrival_time(t: np.ndarray, y: np.ndarray, level: float) -> float:
    """First time (s) at which the history y(t) reaches ``level``, linearly interpolated
    (NaN if it never does or starts there)."""
    k = int(np.argmax(y >= level))
    if k == 0:
        return float("nan")
    return float(t[k - 1] + (level - y[k - 1]) * (t[k] - t[k - 1]) / (y[k] - y[k - 1]))
