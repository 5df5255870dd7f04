"""Point probes: a field's value in the cell that contains a point (DG0, as CST gives it).

A probe reads the six displacement dofs of its cell's three nodes, nothing else:
each rank copies the ones it owns into the history row (one compiled call for
all probes, no communication), the rows are summed over the ranks once per
block of rows, and the values follow from the dofs by
:func:`~impact_fenics.cell_fields.triangle_strain` and the material's constant
stiffness D, the value a UFL Expression of the stress gives at the cell's
midpoint, to round-off. u_r and u_z probes are the cell means of the nodal values.
"""
from __future__ import annotations

import numpy as np
from mpi4py import MPI
from numba import njit
from dolfinx import geometry

from .cell_fields import STRESS_NAMES, stiffness_matrix, stress_outputs, triangle_strain
from .errors import InputError

QUANTITIES = STRESS_NAMES + ("u_r", "u_z")


def locate_cell(mesh, point: tuple[float, float]) -> tuple[int, bool]:
    """Local index of the cell holding ``point`` (r, z) in m, and whether this rank owns it.

    A point on a cell boundary belongs to the touching cell whose midpoint is
    smallest in (r, z): the same choice for every partition."""
    x = np.array([[point[0], point[1], 0.0]])
    tdim = mesh.topology.dim
    n_owned = mesh.topology.index_map(tdim).size_local
    tree = geometry.BoundingBoxTree(mesh, tdim)
    candidates = geometry.compute_collisions(tree, x)
    cells = geometry.compute_colliding_cells(mesh, candidates, x).links(0)
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


@njit(cache=True)
def _record(u_owned, index, row) -> None:
    """row[k] = u_owned[index[k]] for the dofs this rank owns (index >= 0)."""
    for k in range(index.size):
        if index[k] >= 0:
            row[k] = u_owned[index[k]]


@njit(cache=True)
def _values(raw, xy, D, code, out) -> None:
    """Probe values of each row of ``raw`` (rows x 6 per probe: ur, uz of nodes 1-3)."""
    for i in range(raw.shape[0]):
        for p in range(code.size):
            q = raw[i, 6 * p: 6 * p + 6]
            c = code[p]
            if c == 5 or c == 6:
                out[i, p] = (q[c - 5] + q[c - 3] + q[c - 1]) / 3.0
                continue
            e = triangle_strain(xy[p, 0, 0], xy[p, 0, 1], xy[p, 1, 0], xy[p, 1, 1],
                                xy[p, 2, 0], xy[p, 2, 1], q[0], q[1], q[2], q[3], q[4], q[5])
            out[i, p] = stress_outputs(D[p], e[0], e[1], e[2], e[3])[c]


class Probes:
    """Cell values at points: ``quantity`` in QUANTITIES (stresses in Pa, u_r, u_z in m)
    of the cell holding each point (r, z) in m."""

    def __init__(self, model, probes: list[tuple[str, tuple[float, float], str]]):
        self.names = [name for name, _, _ in probes]
        self.points = [pt for _, pt, _ in probes]
        self.comm: MPI.Comm = model.comm
        mesh = model.mesh
        n = len(probes)
        self.n_raw = 6 * n
        self.xy = np.zeros((n, 3, 2))
        self.D = np.zeros((n, 4, 4))
        self.code = np.zeros(n, dtype=np.int64)
        self.midpoints = np.zeros((n, 2))  # (r, z) in m of each probe's cell
        dofs = np.zeros(self.n_raw, dtype=np.int64)  # global unrolled dofs
        imap = model.V.dofmap.index_map
        cell_nodes = model.V.dofmap.list.array.reshape(-1, 3)
        bodies = list(model.bodies.values())
        which = np.full(n, -1, dtype=np.int64)  # body of each probe cell
        for k, (name, point, quantity) in enumerate(probes):
            if quantity not in QUANTITIES:
                raise InputError(f"probe '{name}': unknown quantity '{quantity}' "
                                 f"(use {', '.join(QUANTITIES)})")
            self.code[k] = QUANTITIES.index(quantity)
            cell, mine = locate_cell(mesh, point)
            if mine:
                nodes = cell_nodes[cell].astype(np.int32)
                glob = imap.local_to_global(nodes)
                dofs[6 * k: 6 * k + 6] = np.column_stack([2 * glob, 2 * glob + 1]).ravel()
                self.xy[k] = model.node_xy[nodes]
                self.midpoints[k] = self.xy[k].mean(axis=0)
                which[k] = next(b for b, body in enumerate(bodies)
                                if cell in model.tmesh.cells(body.name))
        for arr in (dofs, self.xy, self.midpoints):
            self.comm.Allreduce(MPI.IN_PLACE, arr, op=MPI.SUM)
        self.comm.Allreduce(MPI.IN_PLACE, which, op=MPI.MAX)
        for k, (name, _, quantity) in enumerate(probes):
            if self.code[k] < len(STRESS_NAMES):
                D = stiffness_matrix(bodies[which[k]].material)
                if D is None:
                    raise InputError(f"probe '{name}': {quantity} of body '{bodies[which[k]].name}' "
                                     "needs a linear material with a constant stiffness")
                self.D[k] = D
        owned = (dofs >= model.offset) & (dofs < model.offset + model.n_owned)
        self._index = np.where(owned, dofs - model.offset, -1).astype(np.int64)
        # load the compiled calls now, not in the first timed step
        self.record(np.zeros(model.n_owned), np.zeros(self.n_raw))
        self.values(np.zeros((1, self.n_raw)))

    def record(self, u_owned: np.ndarray, row: np.ndarray) -> None:
        """Copy the probe dofs this rank owns (m) into ``row`` (n_raw entries, zero elsewhere)."""
        _record(u_owned, self._index, row)

    def values(self, raw: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        """Probe values (rows x probes) of summed raw rows (rows x n_raw)."""
        if out is None:
            out = np.empty((raw.shape[0], self.code.size))
        _values(np.ascontiguousarray(raw), self.xy, self.D, self.code, out)
        return out


def arrival_time(t: np.ndarray, y: np.ndarray, level: float) -> float:
    """First time (s) at which the history y(t) reaches ``level``, linearly interpolated
    (NaN if it never does or starts there)."""
    k = int(np.argmax(y >= level))
    if k == 0:
        return float("nan")
    return float(t[k - 1] + (level - y[k - 1]) * (t[k] - t[k - 1]) / (y[k] - y[k - 1]))
