"""Coulomb friction on node to segment (FILM, DME, penalty): the box problem of the stick
set, the Tresca iteration on a curved master, and the penalty's tangential spring.

Derived in docs/friction.md (sections 1.1, 2 and 3). Constraint i of a segment set has
the normal row G_i (the slave's (r, z) slots with n, the master nodes' with -N_a n and
-N_b n) and a tangential row T_i: the same slots with the unit tangent t = (n_z, -n_r)
in place of n, so w_t = t . (v_s - N_a v_a - N_b v_b) (m/s) and λ_t (N) acts along +t
on the slave, along -t on the master nodes (in proportion to N_a, N_b). On a face
normal to z (n = ±e_z) this is the force along +r on the upper side, the convention
of the node pairs.

After the set's normal step (λ_n: FILM's multipliers, DME's φ), with the cone radius
c_i = μ_i λ_n,i on the active rows, the tangential multipliers solve the box problem

    w = w~ + A λ_t,   A = h_n T M^-1 T' (m/(N s)),   |λ_t,i| <= c_i,
    |λ_t,i| < c_i  =>  w_i = 0 (stick),   λ_t,i = ±c_i  =>  ±w_i <= 0 (slip),

on the velocities the normal step left (w~ = T v~'), by a three-set block pivoting
(stick; slip at +c; slip at -c) on A's band with the safeguard of the normal pivoting
(:func:`.banded.lcp_bpp`): block exchanges while the number of infeasible rows falls,
three tries otherwise, then single exchanges on the last infeasible row. It starts
from the last step's sets. Then v += h_n M^-1 T' λ_t and u += h_{n+1/2} (that change):
no tangential position jump, for DME too (whose stick is this same velocity
projection, its momentum average).

Where the normal and tangential rows decouple (G M^-1 T' = 0: a straight master face)
this is one pass. Where they couple (a curved master face, a partly fixed slot under an
inclined normal; measured at set-up) each step iterates (the Tresca iteration,
:meth:`SegmentTangential._tresca`): the normal problem again with the tangential forces
in its prediction, then the box problem with the new radii, until the sets repeat and
the multipliers settle, the tangential problem last so that the cone holds exactly.

The ledger: the pass's forces sit on the set's own slots, so the set's one booking
holds them; the tangential work of the step, by linearity of T,
W_t = 1/2 h_n Σ λ_t,i (w_i^{n-1/2} + w_i^{n+1/2}), is returned so that the activation
loss takes the normal share only, and the slip work D = Σ h_n |λ_t| |w^{n+1/2}| and
L_t = -W_t - D are kept with the stats of :mod:`.friction` (same indices and columns).
Every rank holds the set's gathered slots and takes the same decisions.

A set re-paired in the loop (``ContactSet.set_repairing``; FILM and DME) tells the pass
after each re-pairing (:meth:`SegmentTangential.repaired`): T's rows, A's band and the
coupling are rebuilt in place from the new rows of G; the last step's sets are only the
pivoting's start (a stuck slave on a new segment is tested again against its tangent),
and a released slave (a zero row) gets λ_t = 0. The penalty's spring is carried
(docs/friction.md 4.1, :func:`carry_elastic_slip`): a slave kept on its segment keeps its
elastic slip s_e (the tangent turned with the segment), one paired to another segment
keeps its projection (t . t') s_e on the new tangent, a released one none; the stored
energy the projection drops is booked into the release loss at the re-pairing.

The penalty (docs/friction.md 4) solves nothing: each loaded row's spring k_t (N/m) on its
committed elastic slip s_e (m) gives the trial λ_tr = -k_t (s_e + h_{n+1/2} w~_t), which is
returned to the cone row by row, and the rows' forces are applied together. Its
recurrence is the normal penalty's with s_e in place of the gap and A in place of S, so it
is stable for beta_t = λ_max(h_{n+1/2} K^1/2 A K^1/2) < 4/3, bounded by Gershgorin's row
sums on A's band (``"scaled"`` puts that bound at 1). On a straight master the normal and
tangential rows decouple, so the two bounds hold apart; on a curved master (coupled rows)
the sequential update is (I - Θ)(I - N) in mass-scaled coordinates, stable under the same
rule where the normal bound is at most 1 (docs/friction.md 4.2): a normal penalty whose
bound passes 1 is refused there (and under re-pairing, which can make the rows couple)
unless forced. The penalty needs no Tresca iteration: both springs are explicit.
"""
from __future__ import annotations

import numpy as np
from numba import njit

from ..errors import InputError
from ..plausibility import warn
from .banded import apply_multipliers, band_factor, band_matvec, band_of_s, \
    band_of_s_steps, band_solve, bandwidth, bandwidth_of, gap_of, gershgorin_beta, \
    gershgorin_of, tolerance
from .friction import HISTORY, N_SLIP, N_STICK, PENALTY_HISTORY, RELEASE_LOSS, SLIP_WORK, \
    STABILITY_BOUND, STORED, T_FORCE, T_LOSS, T_PEAK, FrictionFigures, FrictionLaw, \
    _coefficient, _return_to_cone

OFF, STICK, SLIP_UP, SLIP_DOWN = 0, 1, 2, 3  # a row's set: λ_t = 0, free, +c, -c
COUPLING_TOL = 1e-12  # |G M^-1 T'| against the largest |G M^-1 G'|: round-off of the normals
TRESCA_PASSES = 10  # at most, per step (docs/friction.md 2)


def tangent_rows(cc: np.ndarray) -> np.ndarray:
    """T's coefficients from G's: each slot's (r, z) pair (a n_r, a n_z) becomes
    (a n_z, -a n_r), i.e. t = (n_z, -n_r)."""
    ct = np.empty_like(cc)
    ct[:, 0::2] = cc[:, 1::2]
    ct[:, 1::2] = -cc[:, 0::2]
    return ct


def coupling(cs: np.ndarray, cc: np.ndarray, ct: np.ndarray, minv: np.ndarray) -> float:
    """max |(G M^-1 T')_ij| / max |(G M^-1 G')_ii| (-): 0 where normal and tangential
    rows decouple (docs/friction.md 1.1)."""
    n, ns = cs.shape[0], minv.size
    G = np.zeros((n, ns))
    T = np.zeros((n, ns))
    rows = np.repeat(np.arange(n), cs.shape[1])
    np.add.at(G, (rows, cs.ravel()), cc.ravel())
    np.add.at(T, (rows, cs.ravel()), ct.ravel())
    scale = float(np.max(np.einsum("ij,j,ij->i", G, minv, G), initial=0.0))
    cross = float(np.abs((G * minv) @ T.T).max(initial=0.0))
    return cross / scale if scale > 0.0 else 0.0


def tangent_rows_into(cc: np.ndarray, ct: np.ndarray) -> None:
    """:func:`tangent_rows` in place (``ct`` rewritten from ``cc``; no array made)."""
    ct[:, 0::2] = cc[:, 1::2]
    np.negative(cc[:, 0::2], out=ct[:, 1::2])


@njit(cache=True)
def coupling_of(cs, cc, ct, minv, bw):
    """:func:`coupling` compiled on the band ``bw`` of every row listing a free slot, without
    temporaries: max |(G M^-1 T')_ij| / max (G M^-1 G')_ii (-)."""
    n, m = cs.shape[0], cs.shape[1]
    scale = 0.0
    cross = 0.0
    for i in range(n):
        for j in range(max(0, i - bw), min(n, i + bw + 1)):
            g = 0.0
            t = 0.0
            for p in range(m):
                w = minv[cs[i, p]]
                if w == 0.0 or cc[i, p] == 0.0:
                    continue
                for q in range(m):
                    if cs[j, q] == cs[i, p]:
                        g += cc[i, p] * cc[j, q] * w
                        t += cc[i, p] * ct[j, q] * w
            if j == i:
                scale = max(scale, g)
            cross = max(cross, abs(t))
    return cross / scale if scale > 0.0 else 0.0


@njit(cache=True)
def _tangential_gaps(cs, ct, v, out):
    """w_i = T_i v (m/s)."""
    for i in range(cs.shape[0]):
        s = 0.0
        for k in range(cs.shape[1]):
            s += ct[i, k] * v[cs[i, k]]
        out[i] = s


@njit(cache=True)
def box_bpp(band, bw, wt, cap, lam, w, state, idx, rhs, sol, L, factored, max_iter):
    """The box problem w = wt + A λ, |λ_i| <= cap_i (A: ``band``, its lower band of
    bandwidth ``bw``), on the rows whose ``state`` is not OFF on entry (their start:
    STICK, SLIP_UP or SLIP_DOWN; ``cap`` inf: no cone). Writes λ and w, the sets into
    ``state``; ``factored`` (n + 1): the stick set whose band factor L holds and its
    validity. Returns the iterations (band solves), -1 if none converged."""
    n = wt.size
    scale = 0.0
    for i in range(n):
        if state[i] != OFF:
            scale = max(scale, abs(wt[i]))
    tol_w = tolerance(scale)
    best = n + 1
    budget = 3
    for it in range(1, max_iter + 1):
        for i in range(n):
            lam[i] = 0.0
            if state[i] == SLIP_UP:
                lam[i] = cap[i]
            elif state[i] == SLIP_DOWN:
                lam[i] = -cap[i]
        band_matvec(band, bw, lam, w)  # A λ_slip
        m = 0
        for i in range(n):
            if state[i] == STICK:
                idx[m] = i
                rhs[m] = -(wt[i] + w[i])
                m += 1
        if m > 0:
            same = factored[n]
            if same:
                for i in range(n):
                    if factored[i] != (state[i] == STICK):
                        same = False
                        break
            if not same:
                if not band_factor(band, bw, idx, m, L):
                    factored[n] = False
                    return -1
                for i in range(n):
                    factored[i] = state[i] == STICK
                factored[n] = True
            band_solve(L, bw, m, rhs, sol)
            for p in range(m):
                lam[idx[p]] = sol[p]
        band_matvec(band, bw, lam, w)
        lam_max = 0.0
        for i in range(n):
            w[i] += wt[i]
            lam_max = max(lam_max, abs(lam[i]))
        tol_lam = tolerance(lam_max)
        count = 0
        last = -1
        for i in range(n):
            s = state[i]
            if ((s == STICK and abs(lam[i]) > cap[i] + tol_lam) or
                    (s == SLIP_UP and w[i] > tol_w) or (s == SLIP_DOWN and w[i] < -tol_w)):
                count += 1
                last = i
        if count == 0:
            for i in range(n):
                if state[i] == STICK:  # within the tolerance: on the cone, exactly
                    w[i] = 0.0
                    lam[i] = min(max(lam[i], -cap[i]), cap[i])
            return it
        if count < best:
            best = count
            budget = 3
        elif budget > 0:
            budget -= 1
        else:  # a single exchange of the last infeasible row
            count = 1
        for i in range(n):
            s = state[i]
            if count == 1 and i != last:
                continue
            if s == STICK and abs(lam[i]) > cap[i] + tol_lam:
                state[i] = SLIP_UP if lam[i] > 0.0 else SLIP_DOWN
            elif (s == SLIP_UP and w[i] > tol_w) or (s == SLIP_DOWN and w[i] < -tol_w):
                state[i] = STICK
    return -1


@njit(cache=True)
def _caps(active, force, no_free, mu_s, mu_d, decay, stick, w_prev, cap, state):
    """Cone radii c_i = μ_i λ_n,i (inf under "stick") on the active rows with a
    compressive λ_n and a free slot; the others OFF. A row newly in the problem starts
    STICK, the others keep the last step's set."""
    for i in range(force.size):
        if not active[i] or not force[i] > 0.0 or no_free[i]:
            state[i] = OFF
            cap[i] = 0.0
            continue
        if state[i] == OFF:
            state[i] = STICK
        if stick:
            cap[i] = np.inf
        else:
            cap[i] = _coefficient(mu_s, mu_d, decay, w_prev[i]) * force[i]


@njit(cache=True)
def _settled(lam, lam_last, force, force_last, state, state_last, active, active_last):
    """The Tresca iteration has settled: the sets repeat and λ_t, λ_n (N) changed by at most
    1e-13 of the largest |λ| of the pass."""
    scale = 0.0
    for i in range(lam.size):
        scale = max(scale, abs(lam[i]), abs(force[i]))
    tol = tolerance(scale)
    for i in range(lam.size):
        if (state[i] != state_last[i] or active[i] != active_last[i]
                or abs(lam[i] - lam_last[i]) > tol or abs(force[i] - force_last[i]) > tol):
            return False
    return True


@njit(cache=True)
def _apply_and_book(lam, state, cs, ct, mass, free, h, h_avg, u, v, v_now, w_prev, w_next,
                    stats, apply):
    """With ``apply``, v += h_n M^-1 T' λ and u += h_{n+1/2} (that change)
    (``banded.apply_multipliers``); then the stats of the step (Σ λ_t, counts, D and L_t
    cumulative, the peak) on λ and the corrected v. Returns W_t (J)."""
    if apply:
        apply_multipliers(lam, cs, ct, mass, free, h_avg, u, v, h)
    _tangential_gaps(cs, ct, v_now, w_prev)
    _tangential_gaps(cs, ct, v, w_next)
    total = 0.0
    work = 0.0
    slip = 0.0
    n_stick = 0
    n_slip = 0
    for i in range(lam.size):
        f = lam[i]
        total += f
        work += 0.5 * h_avg * f * (w_prev[i] + w_next[i])
        slip += h_avg * abs(f) * abs(w_next[i])
        if state[i] == STICK:
            n_stick += 1
        elif state[i] != OFF:
            n_slip += 1
    stats[T_FORCE] = total
    stats[N_STICK] = n_stick
    stats[N_SLIP] = n_slip
    stats[SLIP_WORK] += slip
    stats[T_LOSS] += -work - slip
    stats[T_PEAK] = max(stats[T_PEAK], abs(total))
    return work


@njit(cache=True)
def carry_elastic_slip(seg, cs, cc, ct_old, k_t, s_e, stats):
    """The penalty's elastic slips across a re-pairing (docs/friction.md 4.1), the rows of
    G rewritten (``cs``, ``cc``) and T's not yet (``ct_old``: the old tangents, the slave's
    entries t = (n_z, -n_r)). ``seg``: per row the slots of the master nodes a, b it had
    (rewritten here to the new ones). A row on the same segment keeps s_e (m; carried with
    the segment); on another segment s_e' = (t . t') s_e; a released row (zero
    coefficients, t' = 0) s_e' = 0. The drop of stored energy 1/2 k_t (s_e^2 - s_e'^2) (J)
    goes into the release loss and out of the stored energy in ``stats``."""
    drop = 0.0
    for i in range(s_e.shape[0]):
        a, b = cs[i, 2], cs[i, 4]
        released = cc[i, 0] == 0.0 and cc[i, 1] == 0.0
        if s_e[i] != 0.0 and (released or a != seg[i, 0] or b != seg[i, 1]):
            s = (ct_old[i, 0] * cc[i, 1] - ct_old[i, 1] * cc[i, 0]) * s_e[i]
            drop += 0.5 * k_t[i] * (s_e[i] * s_e[i] - s * s)
            s_e[i] = s
        seg[i, 0] = a
        seg[i, 1] = b
    stats[RELEASE_LOSS] += drop
    stats[STORED] -= drop


@njit(cache=True)
def _penalty_pass(active, force, no_free, k_t, mu_s, mu_d, decay, stick, cs, ct, mass, free,
                  h, h_avg, u, v, v_now, w_prev, wt, w_next, lam, state, cap, s_e, dsp,
                  stats):
    """The penalty's tangential spring on node to segment (docs/friction.md 4), on the
    velocities the normal penalty left (``wt`` = T v, m/s): per loaded row the trial
    λ_tr = -k_t (s_e + h w~_t) (``k_t``: N/m; ``s_e``: the committed elastic slip, m),
    returned to the cone c = μ λ_n where it lies outside it (the plastic slip
    Δs_p = (λ_t - λ_tr) / k_t into ``dsp``); a row without a compressive λ_n is released
    (λ_t = 0, s_e = 0, its stored 1/2 k_t s_e^2 booked as release loss). The rows' forces
    are then applied together, v += h_n M^-1 T' λ_t and u += h (that change), and
    s_e += h w_t^{n+1/2} - Δs_p with the corrected w (``w_next``). Books the step's stats
    (D = Σ c |Δs_p|, the release loss, the stored energy Σ 1/2 k_t s_e^2, L_t = -W_t - D
    - the change of those two; a return to the cone books D alone, docs/friction.md 5.1)
    and returns W_t (J)."""
    n = force.size
    released = 0.0
    slip = 0.0
    for i in range(n):
        lam[i] = 0.0
        dsp[i] = 0.0
        if not active[i] or not force[i] > 0.0 or no_free[i] or k_t[i] == 0.0:
            state[i] = OFF
            cap[i] = 0.0
            if s_e[i] != 0.0:  # released: the spring's stored energy is lost
                released += 0.5 * k_t[i] * s_e[i] * s_e[i]
                s_e[i] = 0.0
            continue
        trial = -k_t[i] * (s_e[i] + h * wt[i])
        if stick:
            cap[i] = np.inf
            f, st = trial, 1
        else:
            cap[i] = _coefficient(mu_s, mu_d, decay, w_prev[i]) * force[i]
            f, st = _return_to_cone(trial, cap[i])
        if st == 1:
            state[i] = STICK
        else:
            state[i] = SLIP_UP if f > 0.0 else SLIP_DOWN
            d = (f - trial) / k_t[i]  # -(|trial| - c) sign(trial) / k_t
            dsp[i] = d
            slip += cap[i] * abs(d)
        lam[i] = f
    apply_multipliers(lam, cs, ct, mass, free, h_avg, u, v, h)
    _tangential_gaps(cs, ct, v, w_next)
    total = 0.0
    work = 0.0
    stored = 0.0
    n_stick = 0
    n_slip = 0
    for i in range(n):
        if state[i] == OFF:
            continue
        f = lam[i]
        total += f
        work += 0.5 * h_avg * f * (w_prev[i] + w_next[i])
        s_e[i] += h * w_next[i] - dsp[i]
        stored += 0.5 * k_t[i] * s_e[i] * s_e[i]
        if state[i] == STICK:
            n_stick += 1
        else:
            n_slip += 1
    change = released + stored - stats[STORED]
    stats[T_FORCE] = total
    stats[N_STICK] = n_stick
    stats[N_SLIP] = n_slip
    stats[SLIP_WORK] += slip
    stats[RELEASE_LOSS] += released
    stats[STORED] = stored
    stats[T_LOSS] += -work - slip - change
    stats[T_PEAK] = max(stats[T_PEAK], abs(total))
    return work


def scaled_stiffness(band: np.ndarray, bw: int, h: float) -> np.ndarray:
    """The penalty's ``"scaled"`` tangential stiffnesses (N/m) on A's band (``band``:
    A = h_n T M^-1 T', m/(N s); ``h``: h_{n+1/2}, s): k_t,i = c / (h A_ii) with c from
    Gershgorin's row sums of h K^1/2 A K^1/2, so that its bound is 1 (the normal
    penalty's choice on S); 0 on a row moving no free slot."""
    a = band[:, 0]
    k = np.zeros(a.size)
    np.divide(1.0, h * a, out=k, where=a > 0.0)
    bound = gershgorin_beta(band, bw, h * k)
    if bound > 0.0:
        k /= bound
    return k


class SegmentTangential(FrictionFigures):
    """The tangential pass of a node-to-segment set ``c`` (FILM or DME) with friction
    ``law`` (not zero). Made by ``ContactSet.set_friction``; :meth:`step` runs between
    the method's normal correction and the set's commit. With ``stiffness`` (N/m, or
    ``"scaled"``) the pass is the penalty's tangential spring (:func:`_penalty_pass`), its
    stability bound ``beta_max`` (Gershgorin's, of h K^1/2 A K^1/2) checked by the caller
    against 4/3 (:meth:`bound_problem`); ``force``: accept the bounds past it."""

    max_iter = 1000

    def __init__(self, c, law: FrictionLaw, what: str, stiffness: float | str | None = None,
                 force: bool = False):
        self.c, self.law, self.forced = c, law, force
        self._local = c._local  # the owned dofs it moves, the set's (D of a varying step)
        self.penalty, self.stiffness = stiffness is not None, stiffness
        self.ct = tangent_rows(c.cc)
        # normal and tangential rows couple (a curved master face): the Tresca iteration
        self.coupled = coupling(c.cs, c.cc, self.ct, c.minv) > COUPLING_TOL
        if self.coupled and getattr(c.method, "e", 0.0) > 0.0:
            raise InputError(f"{what}: friction on a curved master face with restitution "
                             "e > 0 is not built yet (e = 0 is)")
        n = c.n
        self.bw = bandwidth(c.cs, self.ct, c.minv)
        self.band = np.empty((n, self.bw + 1))
        self.lam = np.zeros(n)  # λ_t (N) of the last step
        self.state = np.zeros(n, dtype=np.int8)
        self.cap = np.zeros(n)
        (self.wt, self.w, self.w_prev, self.w_next, self.rhs, self.sol) = np.zeros((6, n))
        self.idx = np.zeros(n, dtype=np.int64)
        self.L = np.zeros((n, self.bw + 1))
        self.factored = np.zeros(n + 1, dtype=np.bool_)
        self.stats = np.zeros(8)
        self.iterations = 0
        self.info = {"tangential_bandwidth": int(self.bw), "tangential_iterations_max": 0,
                     "coupled": bool(self.coupled), "tresca_passes_max": 0,
                     "tresca_passes_total": 0, "tresca_unsettled": 0}
        # the Tresca iteration's state: λ_t applied so far, the last pass's λ_t, λ_n, sets
        (self.applied, self.delta, self.lam_last, self.force_last, self.aw) = np.zeros((5, n))
        self.state_last = np.zeros(n, dtype=np.int8)
        self.active_last = np.zeros(n, dtype=np.bool_)
        self.passes = 0
        self._v_pred_saved = np.zeros(c.n_slots)
        # the penalty's springs: k_t (N/m), the committed elastic slips s_e and the step's
        # plastic slips Δs_p (m)
        self.k_t, self.s_e, self.dsp, self._hk = np.zeros((4, n))
        self.seg = np.ascontiguousarray(c.cs[:, 2::2])  # the master nodes' r slots, a and b
        self._k_setup, self._hh_setup = self.k_t.copy(), 0.0  # a re-paired set's k_t
        self.beta_max = 0.0
        self.no_free = np.zeros(n, dtype=np.bool_)
        self.repairing = False  # start_repairing: the set re-pairs in the loop
        self.set_step()

    def bound_problem(self) -> str | None:
        """What of the penalty's bounds (docs/friction.md 4.2) passes its limit, unless
        ``force``: k_t's Gershgorin bound past 4/3; where the rows couple or re-pair, the
        normal penalty's past 1. None if nothing (or not the penalty)."""
        if not self.penalty or self.forced:
            return None
        if self.beta_max > STABILITY_BOUND:
            return (f"tangential_penalty = {self.stiffness!r} N/m: beta_t <= "
                    f"{self.beta_max:.3g} (Gershgorin bound on h h_n K^1/2 T M^-1 T' K^1/2) "
                    "passes the stable bound 4/3; lower it, use 'scaled' or force")
        beta_n = float(getattr(self.c.method, "info", {}).get("beta_max", 0.0))
        if (self.coupled or self.repairing) and beta_n > 1.0 + 1e-12:
            return (f"penalty: beta_max <= {beta_n:.4g} passes 1, the bound under which the "
                    "penalty's friction is stable where normal and tangential rows couple (a "
                    "curved master, re-pairing); lower p, use 'scaled' or force")
        return None

    def refuse_repairing(self, what: str) -> None:
        """Refuse re-pairing where it is not built: restitution e > 0 (a re-pairing can
        make the rows couple, where e > 0 is not built)."""
        if getattr(self.c.method, "e", 0.0) > 0.0:
            raise InputError(f"{what}: friction with re-pairing and restitution e > 0 is not "
                             "built (a re-pairing can make the rows couple); e = 0 is")

    def start_repairing(self, what: str) -> None:
        """The set re-pairs (``ContactSet.set_repairing``): from now on :meth:`repaired`
        follows each re-pairing. Refused for e > 0 (:meth:`refuse_repairing`). Its scratch
        and the bound of A's band storage are made here; the penalty's k_t is chosen for
        every row a re-pairing can make and kept (docs/friction.md 4.2), its bounds
        checked (:meth:`bound_problem`)."""
        self.refuse_repairing(what)
        c = self.c
        self.repairing = True
        if self.penalty:
            self._repairing_stiffness()
        self._first = np.empty(c.n_slots, np.int64)
        # the band of rows that list a common free slot, whatever their coefficients (it
        # holds both G M^-1 G' and G M^-1 T'): bandwidth_of on coefficients of one
        self._every_entry = np.ones(c.cs.shape)
        bw_slots = bandwidth_of(c.cs, self._every_entry, c.minv, self._first)
        self.coupled = coupling_of(c.cs, c.cc, self.ct, c.minv, bw_slots) > COUPLING_TOL
        self.info["coupled"] = bool(self.coupled)
        self.initialize()  # the re-pairing's kernels loaded now
        problem = self.bound_problem()
        if problem:
            raise InputError(problem)

    def _repairing_stiffness(self) -> None:
        """A re-paired set's k_t (N/m), kept for the run: ``"scaled"`` from the largest
        A_ii a slave's row can have, h_n (1/m_s + 1/m_min) (m_min the lightest free master
        component, N_a^2 + N_b^2 <= 1), scaled by Gershgorin's bound of A at set-up (the
        normal penalty's choice of p, penalty.py); a given k_t on every row."""
        c = self.c
        if isinstance(self.stiffness, str):
            n_slave = c.constraints.slave_xy.shape[0]
            worst = float(c.minv[2 * n_slave:].max(initial=0.0))
            slave = np.maximum(c.minv[0:2 * n_slave:2], c.minv[1:2 * n_slave:2])
            k = 1.0 / (c.dt * c.h_avg * (slave + worst))
            bound = gershgorin_beta(self.band, self.bw, c.dt * k)
            self._k_setup[:] = k / bound if bound > 0.0 else k
        else:
            self._k_setup[:] = float(self.stiffness)
        self._hh_setup = c.dt * c.h_avg
        self.k_t[:] = self._k_setup
        self.beta_max = gershgorin_beta(self.band, self.bw, c.dt * self.k_t)

    def repaired(self) -> None:
        """After a re-pairing (the set's rows of G rewritten in place): T's rows, A's band
        (its storage grows only past its widest so far, as S's), the rows moving no free
        slot (a released slave: no row, so λ_t = 0), the coupling (the Tresca iteration
        from this step on where the new rows couple) and the kept factor dropped. The sets
        of the last step stay as the pivoting's start: a stuck slave on a new segment is
        tested again against the new tangent; FILM and DME keep no elastic slip, so
        nothing else is carried; the penalty's elastic slips are carried
        (:func:`carry_elastic_slip`, before T's rows are rewritten). Nothing is allocated
        but a wider band."""
        c = self.c
        if self.penalty:
            carry_elastic_slip(self.seg, c.cs, c.cc, self.ct, self.k_t, self.s_e, self.stats)
        tangent_rows_into(c.cc, self.ct)
        bw = bandwidth_of(c.cs, self.ct, c.minv, self._first)
        rebind = bw != self.bw
        if bw + 1 > self.band.shape[1]:
            self.band = np.empty((c.n, bw + 1))
            self.L = np.zeros((c.n, bw + 1))
        self.bw = bw
        self.info["tangential_bandwidth"] = max(self.info["tangential_bandwidth"], int(bw))
        bw_slots = bandwidth_of(c.cs, self._every_entry, c.minv, self._first)
        self.coupled = coupling_of(c.cs, c.cc, self.ct, c.minv, bw_slots) > COUPLING_TOL
        self.info["coupled"] = self.info["coupled"] or bool(self.coupled)
        self._rebuild(rebind)

    def set_step(self) -> None:
        """A's band, h_n T M^-1 T' (band_of_s with sqrt(h_n) for its dt^2); the penalty's
        k_t at this step and its bound beta_max = Gershgorin's row sums of
        h_{n+1/2} K^1/2 A K^1/2 (on matched faces A is diagonal and this is the node
        pairs' beta_t = k_t h h_n (1/m_s + 1/m_m) exactly)."""
        self._rebuild(True)

    def _rebuild(self, rebind: bool) -> None:
        """A's band at the set's steps and rows, in place; ``rebind``: the kernels'
        argument tuples again (a new step, a new bandwidth)."""
        c = self.c
        band_of_s(c.cs, self.ct, c.minv, np.sqrt(c.h_avg), self.bw, self.band)
        np.less_equal(self.band[:, 0], 0.0, out=self.no_free)  # no free slot: λ_t = 0
        self.factored[-1] = False
        if self.penalty and self.repairing:  # k_t kept; a scaled one follows 1 / (h h_n)
            hh = c.dt * c.h_avg
            if isinstance(self.stiffness, str) and hh != self._hh_setup:
                np.multiply(self._k_setup, self._hh_setup / hh, out=self.k_t)
            np.multiply(self.k_t, c.dt, out=self._hk)
            self.beta_max = max(self.beta_max, gershgorin_of(self.band, self.bw, self._hk))
        if not rebind:
            return
        if self.penalty and not self.repairing:
            if isinstance(self.stiffness, str):
                self.k_t[:] = scaled_stiffness(self.band, self.bw, c.dt)
            else:
                self.k_t[:] = np.where(self.no_free, 0.0, float(self.stiffness))
            self.beta_max = gershgorin_beta(self.band, self.bw, c.dt * self.k_t)
        self._bind()

    def _bind(self) -> None:
        """The kernels' argument tuples, made once per step size (none in the loop)."""
        self._caps_call, self._box_call = self._caps_args(), self._box_args()
        self._apply_call = self._apply_args()
        self._penalty_call = self._penalty_args()

    def _penalty_args(self) -> tuple:
        c, law = self.c, self.law
        return (c.active, c.force, self.no_free, self.k_t, law.static, law.dynamic, law.decay,
                law.stick, c.cs, self.ct, c.mass, c.free, c.dt, c.h_avg, c.u, c.v, c.v_now,
                self.w_prev, self.wt, self.w_next, self.lam, self.state, self.cap, self.s_e,
                self.dsp, self.stats)

    def initialize(self) -> None:
        from ..jit_watch import load

        c = self.c
        load(_tangential_gaps, c.cs, self.ct, c.v_now, self.w_prev)
        if self.penalty:
            load(_penalty_pass, *self._penalty_args())
            if self.repairing:  # a re-pairing's calls
                load(carry_elastic_slip, self.seg, c.cs, c.cc, self.ct, self.k_t, self.s_e,
                     self.stats)
                load(bandwidth_of, c.cs, self.ct, c.minv, self._first)
                load(coupling_of, c.cs, c.cc, self.ct, c.minv, self.bw)
                load(band_of_s_steps, c.cs, self.ct, c.minv, c.h_avg, c.h_avg, self.bw,
                     self.band)
                load(gershgorin_of, self.band, self.bw, self._hk)
            self._bind()
            return
        load(_caps, *self._caps_args())
        load(box_bpp, *self._box_args())
        load(_apply_and_book, *self._apply_args(), True)
        load(apply_multipliers, self.lam, c.cs, self.ct, c.mass, c.free, c.h_avg, c.u, c.v, c.dt)
        load(_settled, self.lam, self.lam_last, c.force, self.force_last, self.state,
             self.state_last, c.active, self.active_last)
        if self.repairing:  # a re-pairing's calls, and the Tresca iteration's it may need
            load(bandwidth_of, c.cs, self.ct, c.minv, self._first)
            load(coupling_of, c.cs, c.cc, self.ct, c.minv, self.bw)
            load(band_of_s_steps, c.cs, self.ct, c.minv, c.h_avg, c.h_avg, self.bw, self.band)
            load(band_matvec, self.band, self.bw, self.applied, self.aw)
            load(gap_of, c.g0, c.cs, c.cc, c.u, c.gap)
        self._bind()

    def _caps_args(self) -> tuple:
        c, law = self.c, self.law
        return (c.active, c.force, self.no_free, law.static, law.dynamic, law.decay, law.stick,
                self.w_prev, self.cap, self.state)

    def _box_args(self) -> tuple:
        return (self.band, self.bw, self.wt, self.cap, self.lam, self.w, self.state, self.idx,
                self.rhs, self.sol, self.L, self.factored, self.max_iter)

    def _apply_args(self) -> tuple:
        c = self.c
        return (self.lam, self.state, c.cs, self.ct, c.mass, c.free, c.dt, c.h_avg, c.u, c.v,
                c.v_now, self.w_prev, self.w_next, self.stats)

    def _box(self) -> None:
        """The box problem on the caps of c.force and self.wt: λ_t into self.lam."""
        c = self.c
        _caps(*self._caps_call)
        if np.any(self.state):
            it = box_bpp(*self._box_call)
            if it < 0:
                raise RuntimeError(f"friction: the stick-set pivoting did not converge in "
                                   f"{self.max_iter} iterations ({c.n} constraints)")
        else:
            it = 0
            self.lam[:] = 0.0
        self.iterations = it
        self.info["tangential_iterations_max"] = max(self.info["tangential_iterations_max"], it)

    def step(self) -> float:
        """The pass on the set's corrected predicted state (c.u, c.v) before its commit,
        the method's normal correction made. Where the rows couple, the Tresca iteration
        (docs/friction.md 2, 3): the normal problem again with the tangential forces in
        its prediction, then the tangential one with the new radii, until the sets repeat
        and λ_n, λ_t change by at most 1e-13 of the largest; the tangential problem last.
        Returns W_t (J)."""
        c = self.c
        _tangential_gaps(c.cs, self.ct, c.v_now, self.w_prev)  # the decaying μ's speed
        if self.penalty:
            _tangential_gaps(c.cs, self.ct, c.v, self.wt)
            return _penalty_pass(*self._penalty_call)
        if not self.coupled:
            _tangential_gaps(c.cs, self.ct, c.v, self.wt)
            self._box()
            return _apply_and_book(*self._apply_call, True)
        return self._tresca()

    def _tresca(self) -> float:
        c = self.c
        applied, delta = self.applied, self.delta
        applied[:] = 0.0
        passes, settled = 0, False
        while True:
            passes += 1
            # w~' = T v - A λ_applied: the velocities of the normal step alone
            _tangential_gaps(c.cs, self.ct, c.v, self.wt)
            band_matvec(self.band, self.bw, applied, self.aw)
            self.wt -= self.aw
            self._box()
            np.subtract(self.lam, applied, out=delta)
            apply_multipliers(delta, c.cs, self.ct, c.mass, c.free, c.h_avg, c.u, c.v, c.dt)
            applied[:] = self.lam
            if passes > 1:
                settled = _settled(self.lam, self.lam_last, c.force, self.force_last,
                                   self.state, self.state_last, c.active, self.active_last)
            if settled or passes == TRESCA_PASSES or not np.any(self.lam):
                break
            self.lam_last[:] = self.lam
            self.state_last[:] = self.state
            self.force_last[:] = c.force
            self.active_last[:] = c.active
            # the normal problem again, the tangential forces in its prediction
            c.u[:] = c.u_pred
            c.v[:] = c.v_pred
            apply_multipliers(applied, c.cs, self.ct, c.mass, c.free, c.h_avg, c.u, c.v, c.dt)
            gap_of(c.g0, c.cs, c.cc, c.u, c.gap)
            self._v_pred_saved[:] = c.v_pred
            c.v_pred[:] = c.v  # DME's velocity problem reads its prediction here
            try:
                c.method.correct(c)
            finally:
                c.v_pred[:] = self._v_pred_saved
        info = self.info
        self.passes = passes
        info["tresca_passes_max"] = max(info["tresca_passes_max"], passes)
        info["tresca_passes_total"] += passes
        if not (settled or not np.any(self.lam)):
            info["tresca_unsettled"] += 1
            if info["tresca_unsettled"] == 1:
                gap = gap_of(c.g0, c.cs, c.cc, c.u, self.aw).min(initial=0.0)
                warn(f"contact {'/'.join(c.constraints.names)}: friction on the curved master "
                     f"did not settle in {TRESCA_PASSES} passes at step {c.integrator.n} "
                     f"(residual penetration {max(-gap, 0.0):.3g} m); counted in the summary",
                     c.comm)
        return _apply_and_book(*self._apply_call, False)

    # outputs (as friction.Tangential's)
    @property
    def history_columns(self) -> tuple:
        """(name, index into ``stats``) of the set's history columns."""
        return HISTORY + (PENALTY_HISTORY if self.penalty else ())

    def summary(self) -> dict:
        """The law, D and L_t (J), the peak |Σ λ_t| (N), the pivoting's largest count (the
        penalty: its release loss, stored energy, beta_t bound and stiffness instead)."""
        out = self.figures()
        if self.penalty:
            out.update(release_loss=float(self.stats[RELEASE_LOSS]),
                       spring_energy=float(self.stats[STORED]), beta_t_max=self.beta_max,
                       tangential_penalty=self.stiffness)
            return out
        out["tangential_iterations_max"] = int(self.info["tangential_iterations_max"])
        if self.coupled:
            out.update({k: int(self.info[k]) for k in ("tresca_passes_max",
                                                        "tresca_passes_total",
                                                        "tresca_unsettled")})
        return out
