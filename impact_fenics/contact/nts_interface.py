"""The node-to-segment contact set: gathered (u_r, u_z) of slave and master nodes, one method.

It stands beside the node-to-node :class:`~impact_fenics.contact.ContactSet`
with the same outward API the simulation uses (``step``, ``times``, ``force``,
``active``, ``committed_gap``, ``min_gap``, ``any_active``, ``contact_work``,
``activation_loss``, ``initialize``). Each step:

1. *detection*: one Allgatherv brings the predicted displacement and velocity
   of every contact dof (both components of slave and master nodes) to every
   rank in global slot order; the predicted gaps g~ = g0 + G u~ follow;
2. *solve*: the method corrects the slot state (only free dofs: a dof fixed
   by the axis or a support never moves);
3. *update*: the owned dofs are written back and the contact work booked in
   the ledger's discrete form (as the node-to-node set does).

Slots: slave node k has slots (2k, 2k+1) = (r, z); master node k has
(2(n_s + k), 2(n_s + k) + 1). Constraint i is row i of G: six (slot,
coefficient) entries ``cs[i]``, ``cc[i]``. The contact force ``force`` (N) is
the normal multiplier, compressive-positive: it pushes the slave along n and
the master nodes along -n in proportion to N_a, N_b.
"""
from __future__ import annotations

import time

import numpy as np
from mpi4py import MPI
from numba import njit

from ..errors import InputError
from .banded import apply_multipliers, band_of_s, bandwidth, gap_of
from .nts_methods import as_node_to_segment
from .segments import SegmentConstraints
from .state import PhaseTimes, _take, owned_slots


# ----------------------------------------------------------------------------- kernels

@njit(cache=True)
def _pack_pairs(src_u, src_v, local, send):
    for k in range(local.size):
        send[2 * k] = src_u[local[k]]
        send[2 * k + 1] = src_v[local[k]]


@njit(cache=True)
def _unpack_pairs(recv, pos, u_out, v_out):
    for k in range(pos.size):
        u_out[pos[k]] = recv[2 * k]
        v_out[pos[k]] = recv[2 * k + 1]


@njit(cache=True)
def _predict(u_pred, v_pred, u, v, g0, cs, cc, gap, active, was_active):
    for k in range(u.size):
        u[k] = u_pred[k]
        v[k] = v_pred[k]
    gap_of(g0, cs, cc, u_pred, gap)
    for i in range(gap.size):
        was_active[i] = active[i]


@njit(cache=True)
def _book(dt, first, mass, u, v, u_pred, v_pred, u_now, v_now, f_prev, ku_prev, jump, jumps,
          jumped, active, was_active, g0, cs, cc, gap_buf):
    """Contact work increment of step n in the ledger's discrete form (as the
    node-to-node set books it): F^n = m (v^{n+1} - v~^{n+1}) / dt per slot adds
    1/2 dt v^n . (F^{n-1} + F^n); a jump j = u^{n+1} - u^n - dt v^{n+1} adds
    1/2 j . K (u^n + u^{n+1}) a step later (K u^n = -m (v~^{n+1} - v^n) / dt).
    Rolls the state to n+1; returns (J, jumped, grew, any active, min gap in m)."""
    inc = 0.0
    jumped_now = False
    grew = False
    any_active = False
    for i in range(active.size):
        if active[i]:
            any_active = True
            if not was_active[i]:
                grew = True
    gap_of(g0, cs, cc, u, gap_buf)
    min_gap = np.inf
    for i in range(gap_buf.size):
        min_gap = min(min_gap, gap_buf[i])
    for k in range(mass.size):
        f = mass[k] * (v[k] - v_pred[k]) / dt
        if not first:
            inc += 0.5 * dt * v_now[k] * (f_prev[k] + f)
        f_prev[k] = f
    if jumps:
        for k in range(mass.size):
            ku = -mass[k] * (v_pred[k] - v_now[k]) / dt
            if jumped:
                inc += 0.5 * jump[k] * (ku_prev[k] + ku)
            ku_prev[k] = ku
            jump[k] = u[k] - u_now[k] - dt * v[k]
            if jump[k] != 0.0:
                jumped_now = True
    for k in range(mass.size):
        u_now[k] = u[k]
        v_now[k] = v[k]
    return inc, jumped_now, grew, any_active, min_gap


# ----------------------------------------------------------------------------- the set

class NodeToSegmentSet:
    """Node-to-segment constraints, their gathered state and one method, on every rank.

    Slot arrays (length ``n_slots``): ``u``, ``v`` (m, m/s; the prediction on entry
    to the method, corrected by it), ``u_pred``, ``v_pred``, ``mass`` (kg),
    ``free`` (False on fixed dofs). Constraint arrays (length n): ``gap`` the
    predicted gaps (m), ``force`` (N), ``active``. ``band``/``bw``: S = dt^2 G M^-1 G'
    (m/N) as a lower band.
    """

    rigid = None

    def __init__(self, constraints: SegmentConstraints, integrator, method):
        model = integrator.model
        self.comm: MPI.Comm = model.comm
        self.constraints = constraints
        self.integrator = integrator
        self.method = as_node_to_segment(method)
        self.dt = integrator.dt
        self.n = n = constraints.n
        self.r = constraints.r
        dofs = constraints.dofs.astype(np.int64)
        self.n_slots = ns = dofs.size
        n_slave = constraints.slave_xy.shape[0]
        # which slots this rank owns, and where the gathered values go
        (self._local, self._pos_mine, self._pos, self._counts,
         self._displs) = owned_slots(model, dofs, self.comm)
        self._send = np.empty(2 * self._local.size)
        self._recv = np.empty(2 * ns)
        # slot state
        self.u, self.v = np.zeros(ns), np.zeros(ns)
        self.u_pred, self.v_pred = np.zeros(ns), np.zeros(ns)
        self.u_now, self.v_now = np.zeros(ns), np.zeros(ns)
        self.mass = np.empty(ns)
        self._gather(integrator.mass, integrator.mass, self.mass, np.empty(ns))
        free_owned = np.ones(model.n_owned)
        free_owned[integrator.fixed] = 0.0
        free = np.empty(ns)
        self._gather(free_owned, free_owned, free, np.empty(ns))
        self.free = free > 0.5
        self.minv = np.where(self.free, 1.0 / self.mass, 0.0)
        # G: six (slot, coefficient) entries per constraint
        c = constraints
        s = np.arange(n)
        self.cs = np.stack([2 * s, 2 * s + 1, 2 * (n_slave + c.a), 2 * (n_slave + c.a) + 1,
                            2 * (n_slave + c.b), 2 * (n_slave + c.b) + 1], axis=1).astype(np.int64)
        na, nb = 1.0 - c.xi, c.xi
        nr, nz = c.normal[:, 0], c.normal[:, 1]
        self.cc = np.stack([nr, nz, -na * nr, -na * nz, -nb * nr, -nb * nz], axis=1)
        self.g0 = c.g0.copy()
        self.bw = bandwidth(self.cs, self.cc, self.minv)
        self.band = np.empty((n, self.bw + 1))
        band_of_s(self.cs, self.cc, self.minv, self.dt, self.bw, self.band)
        if np.any(self.band[:, 0] <= 0.0):
            k = int(np.flatnonzero(self.band[:, 0] <= 0.0)[0])
            raise InputError(f"contact: the constraint of '{c.names[0]}' node at "
                             f"(r={c.slave_xy[k, 0]:.6g}, z={c.slave_xy[k, 1]:.6g}) moves no free dof")
        self.gap = np.empty(n)
        self._gap_buf = np.empty(n)
        self.force = np.zeros(n)
        self.active = np.zeros(n, dtype=np.bool_)
        self.was_active = np.zeros(n, dtype=np.bool_)
        self.times = PhaseTimes()
        self.any_active = False
        self.min_gap = np.inf
        self.stats = np.array([0.0, 0.0, np.inf])  # (number active, total force (N), min gap (m))
        self.jumps = bool(getattr(self.method, "jumps", False))
        self._f_prev = np.zeros(ns)
        self._ku_prev = np.zeros(ns)
        self._jump = np.zeros(ns)
        self._jumped = False
        self._grew_last = False
        self._work = 0.0
        self._activation_loss = 0.0
        self.method.setup(self)
        self._load_kernels()

    def _load_kernels(self) -> None:
        """Compile (or load from the cache) every compiled call of a step for its argument
        types now, at set-up, without running it: none loads inside the timed loop."""
        from ..jit_watch import load

        integ = self.integrator
        calls = [(_predict, (self.u_pred, self.v_pred, self.u, self.v, self.g0, self.cs,
                             self.cc, self.gap, self.active, self.was_active)),
                 (_take, (self.u, self.v, self._pos_mine, self._local, integ.u_owned,
                          integ.v_owned)),
                 (_book, (self.dt, True, self.mass, self.u, self.v, self.u_pred, self.v_pred,
                          self.u_now, self.v_now, self._f_prev, self._ku_prev, self._jump,
                          self.jumps, self._jumped, self.active, self.was_active, self.g0,
                          self.cs, self.cc, self._gap_buf))]
        if self.comm.size == 1:
            calls.append((_take, (integ.u_owned, integ.v_owned, self._local, self._pos_mine,
                                  self.u_pred, self.v_pred)))
        else:
            calls += [(_pack_pairs, (integ.u_owned, integ.v_owned, self._local, self._send)),
                      (_unpack_pairs, (self._recv, self._pos, self.u_pred, self.v_pred))]
        for fn, args in calls + self.method.kernel_calls(self):
            load(fn, *args)

    # ------------------------------------------------------------ gather
    def _gather(self, src_u, src_v, u_out, v_out) -> None:
        """src_u, src_v (owned arrays) on the contact dofs, into slot order on every rank."""
        if self.comm.size == 1:
            _take(src_u, src_v, self._local, self._pos_mine, u_out, v_out)
            return
        _pack_pairs(src_u, src_v, self._local, self._send)
        self.comm.Allgatherv(self._send, [self._recv, self._counts, self._displs, MPI.DOUBLE])
        _unpack_pairs(self._recv, self._pos, u_out, v_out)

    def initialize(self) -> None:
        """Read u^0 and v^0 of the contact dofs (after the integrator's set_initial)."""
        integ = self.integrator
        self._gather(integ.u_owned, integ.v_owned, self.u_now, self.v_now)

    # ------------------------------------------------------------ for methods
    def apply_forces(self, lam: np.ndarray) -> None:
        """Apply normal forces lam (N, compressive-positive) to the predicted state."""
        apply_multipliers(lam, self.cs, self.cc, self.mass, self.free, self.dt, self.u, self.v)

    # ------------------------------------------------------------ the step
    def step(self) -> None:
        """Detect, solve and update for the step n -> n+1 (after the integrator's predict)."""
        integ = self.integrator
        clock = time.perf_counter
        t0 = clock()
        self._gather(integ.u_owned, integ.v_owned, self.u_pred, self.v_pred)
        _predict(self.u_pred, self.v_pred, self.u, self.v, self.g0, self.cs, self.cc, self.gap,
                 self.active, self.was_active)
        t1 = clock()
        self.method.correct(self)
        t2 = clock()
        _take(self.u, self.v, self._pos_mine, self._local, integ.u_owned, integ.v_owned)
        inc, self._jumped, grew, self.any_active, self.min_gap = _book(
            self.dt, integ.n == 0, self.mass, self.u, self.v, self.u_pred, self.v_pred,
            self.u_now, self.v_now, self._f_prev, self._ku_prev, self._jump, self.jumps,
            self._jumped, self.active, self.was_active, self.g0, self.cs, self.cc, self._gap_buf)
        self._work += inc
        if grew or self._grew_last:
            self._activation_loss -= inc
        self._grew_last = grew
        st = self.stats
        st[0], st[1], st[2] = np.count_nonzero(self.active), self.force.sum(), self.min_gap
        t3 = clock()
        self.times.detection, self.times.solve, self.times.update = t1 - t0, t2 - t1, t3 - t2

    # ------------------------------------------------------------ outputs
    @property
    def contact_work(self) -> float:
        """Work (J) of the contact forces so far, jumps included."""
        return self._work

    @property
    def activation_loss(self) -> float:
        """Energy (J) lost in the steps where constraints became active (and the step after)."""
        return self._activation_loss

    def committed_gap(self) -> np.ndarray:
        """Gap (m) of the committed state, in global constraint order."""
        return gap_of(self.g0, self.cs, self.cc, self.u_now, np.empty(self.n))
