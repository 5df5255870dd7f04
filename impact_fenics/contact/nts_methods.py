"""Penalty, FILM and DME on node-to-segment constraints (one-pass, frictionless).

All three act on the predicted state of a
:class:`~impact_fenics.contact.nts_interface.NodeToSegmentSet` through
S = dt^2 G M^-1 G' (m/N), symmetric positive definite but, with positive
off-diagonal entries where slaves share a master node, not an M-matrix.

* **Penalty**: lam_i = p_i max(0, -g~_i). ``p="scaled"`` puts every constraint at
  p_i = c / S_ii with c from Gershgorin's bound so that beta_max =
  lambda_max(P^1/2 S P^1/2) <= ``beta_target``; a number (N/m) is refused when its
  Gershgorin bound exceeds the stability limit 4/3 (contact.penalty) unless forced.
* **FILM**: the complementarity problem w = g~ + S lam >= 0, lam >= 0, lam . w = 0
  by block principal pivoting on the band of S (``solver="bpp"``, O(n) per
  iteration; started from the last step's loaded set joined with g~ < 0, whose
  band factor is kept) or with dense factors (``solver="dense"``, for
  comparison, started from g~ < 0); then
  v += dt M^-1 G' lam, u += dt^2 M^-1 G' lam. Iterations are counted.
* **DME**: the normal relative displacement is eliminated. Positions: the
  M-orthogonal projection of u~ onto the active manifold g = 0 (the mass-weighted
  position; centre of mass kept), u = u~ + dt^2 M^-1 G' nu with nu >= 0 the
  solution of the same complementarity problem (with coupled constraints the
  set that can hold is found by the same pivoting; uncoupled it is g~ < 0, the
  paper's eq. 7). Velocities: the M-orthogonal projection of v~ onto
  G v = -e G v~ on that set (Newton's restitution on the normal relative
  velocity), v = v~ + dt M^-1 G' phi with S phi = -(1 + e) dt G v~ where phi
  pushes; where coupling would make some phi pull, the same pivoting solves
  S phi + (1 + e) dt G v~ >= 0, phi >= 0 on the set instead (it reuses the band
  factor, so the usual case costs one band solve). For one slave over a
  segment this is m_eff = (1/m_s + sum N_i^2 / m_i)^-1. The
  reported force is phi (N, the momentum change over dt). At an activation the
  position jump (u != u^n + dt v) is booked by the set's ledger. With e = 0 and
  a constraint closed at step n, nu = phi and DME equals FILM exactly.
"""
from __future__ import annotations

import numpy as np
from numba import njit

from ..errors import InputError
from . import dme, film, penalty
from .banded import apply_multipliers, dense_s, gershgorin_beta, lcp_bpp, lcp_dense
from .penalty import STABILITY_BOUND


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
