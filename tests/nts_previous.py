"""The node-to-segment set and methods before they joined the one contact front-end.

The previous code path, kept here while the move lands: ``tests/test_contact_nts.py``
compares every array of a run on it with the one front-end (``array_equal``). Its set,
``NodeToSegmentSet``, and its methods (``Penalty``, ``FILM``, ``DME`` on a banded S,
mapped from the node-pair family by ``as_node_to_segment``), verbatim but for the imports.
"""
from __future__ import annotations

import time

import numpy as np
from mpi4py import MPI
from numba import njit

from impact_fenics.contact import dme, film, penalty
from impact_fenics.contact.banded import (apply_multipliers, band_of_s, bandwidth, dense_s,
                                          gap_of, gershgorin_beta, lcp_bpp, lcp_dense)
from impact_fenics.contact.penalty import STABILITY_BOUND
from impact_fenics.contact.state import PhaseTimes, _take, owned_slots
from impact_fenics.errors import InputError


class _Workspace:
    """Scratch arrays of the complementarity solver (allocated once)."""

    def __init__(self, n: int, bw: int):
        self.lam = np.zeros(n)
        self.w = np.zeros(n)
        self.free = np.zeros(n, dtype=np.bool_)
        self.start = np.zeros(n, dtype=np.bool_)
        self.everywhere = np.ones(n, dtype=np.bool_)
        self.idx = np.zeros(n, dtype=np.int64)
        self.rhs = np.zeros(n)
        self.sol = np.zeros(n)
        self.L = np.zeros((n, bw + 1))
        self.factored = np.zeros(n + 1, dtype=np.bool_)  # the set L factors, valid flag


class _Pivoting:
    """Shared by FILM and DME: the multipliers of the position problem and their counts."""

    solver = "bpp"
    max_iter = 1000

    def setup(self, c) -> None:
        self.ws = _Workspace(c.n, c.bw)
        self.S = dense_s(c.band, c.bw) if self.solver == "dense" else None
        self.iterations = 0
        self.info.update({"bandwidth": int(c.bw), "iterations_max": 0, "iterations_total": 0})

    def _solver_calls(self, c) -> list:
        """(kernel, arguments) of the position problem's solver, for loading at set-up."""
        ws = self.ws
        if self.solver == "dense":
            return []  # lcp_dense is numpy and LAPACK: nothing to compile
        return [(lcp_bpp, (c.band, c.bw, c.gap, ws.lam, ws.w, ws.free, ws.idx, ws.rhs, ws.sol,
                           ws.L, self.max_iter, ws.factored, ws.everywhere))]

    def _solve(self, c) -> np.ndarray:
        ws = self.ws
        if self.solver == "dense":
            it = lcp_dense(self.S, c.gap, ws.lam, self.max_iter)
            np.greater(ws.lam, 0.0, out=ws.free)
        else:
            # warm start: last step's loaded set and every predicted penetration
            np.less(c.gap, 0.0, out=ws.start)
            np.logical_or(ws.free, ws.start, out=ws.free)
            it = lcp_bpp(c.band, c.bw, c.gap, ws.lam, ws.w, ws.free, ws.idx, ws.rhs, ws.sol, ws.L,
                         self.max_iter, ws.factored, ws.everywhere)
            if it < 0:
                raise RuntimeError(f"{self.name}: complementarity pivoting did not converge in "
                                   f"{self.max_iter} iterations ({c.n} constraints)")
        self.iterations = it
        info = self.info
        info["iterations_total"] += it
        if it > info["iterations_max"]:
            info["iterations_max"] = it
        return ws.lam


class FILM(_Pivoting):
    """Forward-increment Lagrange multipliers, node to segment; ``solver`` 'bpp' or 'dense'."""

    name = "film"
    jumps = False

    def __init__(self, solver: str = "bpp"):
        if solver not in ("bpp", "dense"):
            raise InputError(f"film solver = '{solver}': use 'bpp' or 'dense' (node to segment)")
        self.solver = solver
        self.info: dict = {"solver": solver}

    def kernel_calls(self, c) -> list:
        """(kernel, arguments) of every compiled call of :meth:`correct`."""
        return self._solver_calls(c) + [
            (apply_multipliers, (c.force, c.cs, c.cc, c.mass, c.free, c.dt, c.u, c.v))]

    def correct(self, c) -> None:
        lam = self._solve(c)
        c.force[:] = lam
        np.greater(lam, 0.0, out=c.active)
        c.apply_forces(c.force)


class DME(_Pivoting):
    """Direct manifold elimination of the normal gap, node to segment; restitution e in [0, 1]."""

    name = "dme"
    jumps = True

    def __init__(self, restitution: float = 0.0):
        if not 0.0 <= restitution <= 1.0:
            raise InputError(f"restitution = {restitution}: must lie in [0, 1]")
        self.e = float(restitution)
        self.solver = "bpp"  # the velocity projection reuses the band factor
        self.info: dict = {"restitution": self.e, "positions": "mass_weighted"}

    def setup(self, c) -> None:
        super().setup(c)
        self.phi = np.zeros(c.n)
        self.vgap = np.zeros(c.n)
        self.vfree = np.zeros(c.n, dtype=np.bool_)
        self.vw = np.zeros(c.n)

    def kernel_calls(self, c) -> list:
        """(kernel, arguments) of every compiled call of :meth:`correct`."""
        ws = self.ws
        return self._solver_calls(c) + [
            (_velocity_gaps, (ws.free, c.cs, c.cc, c.v_pred, self.e, c.dt, self.vgap, self.vfree)),
            (lcp_bpp, (c.band, c.bw, self.vgap, self.phi, self.vw, self.vfree, ws.idx, ws.rhs,
                       ws.sol, ws.L, self.max_iter, ws.factored, ws.free)),
            (_dme_update, (ws.lam, self.phi, ws.free, c.cs, c.cc, c.mass, c.free, c.dt, c.u,
                           c.v, c.force, c.active))]

    def correct(self, c) -> None:
        nu = self._solve(c)
        ws = self.ws
        _velocity_gaps(ws.free, c.cs, c.cc, c.v_pred, self.e, c.dt, self.vgap, self.vfree)
        it = lcp_bpp(c.band, c.bw, self.vgap, self.phi, self.vw, self.vfree, ws.idx, ws.rhs,
                     ws.sol, ws.L, self.max_iter, ws.factored, ws.free)
        if it < 0:
            raise RuntimeError(f"dme: velocity pivoting did not converge ({c.n} constraints)")
        _dme_update(nu, self.phi, ws.free, c.cs, c.cc, c.mass, c.free, c.dt, c.u, c.v,
                    c.force, c.active)


@njit(cache=True)
def _velocity_gaps(held, cs, cc, v_pred, e, dt, vgap, vfree):
    """The velocity problem on the held set: w = (1 + e) dt G v~ + S phi >= 0, phi >= 0,
    phi . w = 0 (G v >= -e G v~: Newton's law where the constraint pushes). Zero off
    the held set; the held set is the start."""
    for i in range(held.size):
        vgap[i] = 0.0
        vfree[i] = held[i]
        if held[i]:
            gv = 0.0
            for k in range(cs.shape[1]):
                gv += cc[i, k] * v_pred[cs[i, k]]
            vgap[i] = (1.0 + e) * dt * gv


@njit(cache=True)
def _dme_update(nu, phi, held, cs, cc, mass, slot_free, dt, u, v, force, active):
    """Positions u~ + dt^2 M^-1 G' nu, velocities v~ + dt M^-1 G' phi; force = phi (N)."""
    for i in range(nu.size):
        active[i] = held[i]
        force[i] = phi[i]
        if not held[i]:
            continue
        for k in range(cs.shape[1]):
            s = cs[i, k]
            if slot_free[s] and cc[i, k] != 0.0:
                v[s] += dt * (cc[i, k] * phi[i]) / mass[s]
                u[s] += dt * dt * (cc[i, k] * nu[i]) / mass[s]


class Penalty:
    """Penalty springs on the normal gap, node to segment. ``p``: N/m, 'scaled' or 'auto'
    (the mean of 1/S_ii, the paper's rule in its first reading); ``force`` accepts a
    Gershgorin bound above 4/3."""

    name = "penalty"
    jumps = False

    def __init__(self, p: float | str = "scaled", beta_target: float = 1.0, force: bool = False):
        node = penalty.Penalty(p, beta_target=beta_target)  # the same checks of p and beta_target
        self.choice, self.beta_target, self.forced = node.choice, node.beta_target, force
        self.info: dict = {}

    def setup(self, c) -> None:
        d = c.band[:, 0]
        if self.choice == "scaled":
            self.p = 1.0 / d
            self.p *= self.beta_target / gershgorin_beta(c.band, c.bw, self.p)
        elif self.choice == "auto":
            self.p = np.full(c.n, float(np.mean(1.0 / d)))
        else:
            self.p = np.full(c.n, float(self.choice))
        beta = gershgorin_beta(c.band, c.bw, self.p)
        if beta > STABILITY_BOUND * (1 + 1e-12) and not self.forced:
            raise InputError(f"penalty: beta_max <= {beta:.4g} (Gershgorin bound on "
                             f"dt^2 P^1/2 G M^-1 G' P^1/2) exceeds the stability limit 4/3: "
                             "lower p, use 'scaled', or force it")
        self.info = {"p_choice": str(self.choice), "p_min": float(self.p.min()),
                     "p_max": float(self.p.max()), "beta_max": beta,
                     "beta_bound": STABILITY_BOUND}

    def kernel_calls(self, c) -> list:
        """(kernel, arguments) of every compiled call of :meth:`correct`."""
        return [(_penalty, (c.gap, self.p, c.force, c.active, c.cs, c.cc, c.mass, c.free, c.dt,
                            c.u, c.v))]

    def correct(self, c) -> None:
        _penalty(c.gap, self.p, c.force, c.active, c.cs, c.cc, c.mass, c.free, c.dt, c.u, c.v)


@njit(cache=True)
def _penalty(gap, p, force, active, cs, cc, mass, free, dt, u, v):
    for i in range(gap.size):
        active[i] = gap[i] < 0.0
        force[i] = -p[i] * gap[i] if active[i] else 0.0
    apply_multipliers(force, cs, cc, mass, free, dt, u, v)


def as_node_to_segment(method):
    """The node-to-segment counterpart of a method object (node-to-node ones are mapped
    with their settings: penalty p and beta_target, FILM's solver, DME's restitution)."""
    if isinstance(method, (Penalty, FILM, DME)):
        return method
    if isinstance(method, penalty.Penalty):
        return Penalty(method.choice, beta_target=method.beta_target)
    if isinstance(method, film.FILM):
        return FILM("dense" if method.solver == "dense" else "bpp")
    if isinstance(method, dme.DME):
        if method.positions != "mass_weighted":
            raise InputError("dme positions = 'paper' has no node-to-segment form: "
                             "use 'mass_weighted'")
        return DME(method.e)
    raise InputError(f"contact method {method!r} has no node-to-segment form")


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

    def __init__(self, constraints, integrator, method):
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
        from impact_fenics.jit_watch import load

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
