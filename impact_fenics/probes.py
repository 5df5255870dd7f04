"""Point probes: a field's value in the cell that contains a point (DG0, as CST gives it).

A probe reads the six displacement dofs of its cell's three nodes, nothing else:
each rank copies the ones it owns into the history row (one compiled call for
all probes, no communication), the rows are summed over the ranks once per
block of rows, and the values follow from the dofs by
:func:`~impact_fenics.cell_fields.triangle_strain` and the material's constant
stiffness D, the value a UFL Expression of the stress gives at the cell's
midpoint, to round-off. u_r and u_z probes are the cell means of the nodal values.
In the cell of a path-dependent body the row also holds the cell means of its
plastic strain, equivalent plastic strain and yielded flag (from the quadrature
state, :class:`~impact_fenics.internal_force.QuadratureForce`), and the stress is
D (eps - eps_p) with the elastic D.
"""
from __future__ import annotations

import functools

import numpy as np
from mpi4py import MPI
from numba import njit

from .cell_fields import (STRESS_NAMES, isotropic_stiffness, stiffness_matrix, stress_outputs,
                          triangle_strain)
from .compat import cell_dofs, colliding_cells
from .errors import InputError
from .jit_watch import direct

PLASTIC_QUANTITIES = ("eps_p_eq", "yielded")
QUANTITIES = STRESS_NAMES + ("u_r", "u_z") + PLASTIC_QUANTITIES
# raw history entries per probe: u_r, u_z of the cell's three nodes, then the cell means
# of the plastic strain (rr, tt, zz, rz), of eps_bar_p and the yielded flag (0 in the
# cells of linear bodies)
RAW = 12


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


@njit(cache=True)
def _record_at(u_owned, index, block, offset) -> None:
    """block[offset + k] = u_owned[index[k]] for the dofs this rank owns (index >= 0)."""
    for k in range(index.size):
        if index[k] >= 0:
            block[offset + k] = u_owned[index[k]]


@njit(cache=True)
def _record_plastic(eps_p, state, pos, row, start) -> None:
    """Cell means of eps_p (4), eps_bar_p and yielded (any point with eps_bar_p > 0) of
    the quadrature cell ``pos`` into row[start:start + 6]."""
    for i in range(4):
        row[start + i] = (eps_p[pos, 0, i] + eps_p[pos, 1, i] + eps_p[pos, 2, i]) / 3.0
    row[start + 4] = (state[pos, 0, 0] + state[pos, 1, 0] + state[pos, 2, 0]) / 3.0
    yielded = 0.0
    for q in range(3):
        if state[pos, q, 0] > 0.0:
            yielded = 1.0
    row[start + 5] = yielded


@njit(cache=True)
def _values(raw, xy, D, code, out) -> None:
    """Probe values of each row of ``raw`` (rows x RAW per probe, see RAW)."""
    for i in range(raw.shape[0]):
        for p in range(code.size):
            q = raw[i, 12 * p: 12 * p + 12]
            c = code[p]
            if c == 5 or c == 6:
                out[i, p] = (q[c - 5] + q[c - 3] + q[c - 1]) / 3.0
                continue
            if c == 7 or c == 8:
                out[i, p] = q[c + 3]
                continue
            e = triangle_strain(xy[p, 0, 0], xy[p, 0, 1], xy[p, 1, 0], xy[p, 1, 1],
                                xy[p, 2, 0], xy[p, 2, 1], q[0], q[1], q[2], q[3], q[4], q[5])
            out[i, p] = stress_outputs(D[p], e[0] - q[6], e[1] - q[7], e[2] - q[8],
                                       e[3] - q[9])[c]


class Probes:
    """Cell values at points: ``quantity`` in QUANTITIES (stresses in Pa, u_r, u_z in m)
    of the cell holding each point (r, z) in m."""

    def __init__(self, model, probes: list[tuple[str, tuple[float, float], str]],
                 plastic_forces=()):
        self.names = [name for name, _, _ in probes]
        self.points = [pt for _, pt, _ in probes]
        self.comm: MPI.Comm = model.comm
        mesh = model.mesh
        n = len(probes)
        self.n_raw = RAW * n
        self.xy = np.zeros((n, 3, 2))
        self.D = np.zeros((n, 4, 4))
        self.code = np.zeros(n, dtype=np.int64)
        self.midpoints = np.zeros((n, 2))  # (r, z) in m of each probe's cell
        dofs = np.zeros(6 * n, dtype=np.int64)  # global unrolled dofs
        imap = model.V.dofmap.index_map
        cell_nodes = cell_dofs(model.V)
        forces = {f.body: f for f in plastic_forces}
        self._plastic = []  # (force, position of the cell in force.cells, row offset)
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
                force = forces.get(bodies[which[k]].name)
                if force is not None:
                    pos = int(np.searchsorted(force.cells, cell))
                    self._plastic.append((force.qs, pos, RAW * k + 6))
        for arr in (dofs, self.xy, self.midpoints):
            self.comm.Allreduce(MPI.IN_PLACE, arr, op=MPI.SUM)
        self.comm.Allreduce(MPI.IN_PLACE, which, op=MPI.MAX)
        for k, (name, _, quantity) in enumerate(probes):
            material = bodies[which[k]].material
            if self.code[k] < len(STRESS_NAMES):
                D = stiffness_matrix(material)
                if D is None and not material.linear:  # stress = C : (eps - eps_p)
                    D = isotropic_stiffness(material.lmbda, material.mu)
                if D is None:
                    raise InputError(f"probe '{name}': {quantity} of body '{bodies[which[k]].name}' "
                                     "needs a material with a constant (elastic) stiffness")
                self.D[k] = D
            if quantity in PLASTIC_QUANTITIES and not plastic_forces:
                raise InputError(f"probe '{name}': {quantity} needs a path-dependent body in "
                                 "the run (it reads 0 in the cells of linear bodies)")
        owned = (dofs >= model.offset) & (dofs < model.offset + model.n_owned)
        index = np.full((n, RAW), -1, dtype=np.int64)
        index[:, :6] = np.where(owned, dofs - model.offset, -1).reshape(n, 6)
        self._index = index.ravel()
        # load the compiled calls now, not in the first timed step
        self.recorder(np.zeros(model.n_owned), np.zeros(self.n_raw))(0)
        self.values(np.zeros((1, self.n_raw)))
        # and with ``out`` a column slice of a wider block, as a history table passes it
        # (two rows and a column either side: a view numpy does not call contiguous)
        self.values(np.zeros((2, self.n_raw)), np.zeros((2, n + 2))[:, 1: n + 1])

    def recorder(self, u_owned: np.ndarray, block: np.ndarray):
        """``record(offset)``: the probe dofs this rank owns (m), and the plastic state of
        the probe cells it owns, into block[offset: offset + n_raw] (a flat block of rows,
        zero elsewhere; ``offset`` a Python int), for the u_owned of the run; one compiled call
        without plastic probe cells (~0.25 us)."""
        fill = functools.partial(direct(_record_at, u_owned, self._index, block, 0),
                                 u_owned, self._index, block)
        if not self._plastic:
            return fill
        plastic = self._plastic

        def record(offset: int) -> None:
            fill(offset)
            for qs, pos, start in plastic:
                _record_plastic(qs.eps_p, qs.state, pos, block, offset + start)
        return record

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
