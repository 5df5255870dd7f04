"""Coulomb friction on the decoupled kinds: node pairs and a node on a rigid or fixed face.

The law and its discrete form are derived in docs/friction.md. A contact set with a
coefficient μ > 0 (or ``"stick"``) gets a :class:`Tangential` pass that runs after its
normal step; with μ = 0 nothing here is made and the set's step is unchanged.

On node pairs and a rigid face (the wall included) the normal and the tangential rows
decouple exactly (docs/friction.md 1.1): the normal multipliers λ_n (N) of the step do
not depend on the tangential ones, and the tangential operator A = h_n T M^-1 T' is
diagonal, A_ii = h_n (1/m_lo,r + 1/m_up,r) (m/(N s); 1/m = 0 on a fixed r dof and on a
rigid part, which has no r slot). So the pass is one loop over the constraints, after
the normal step, on the r components of the constraints' nodes (the *tangential slots*:
one per deformable slot of the set, in the same order, and one with zero inverse mass in
place of a rigid part's). In plane strain a moving rigid part slides along x under FILM
and DME: its slot gets 1/M and :func:`rigid_slide` solves the face's rows together
(A = D + (h_n/M) 1 1', docs/friction.md 11); under the penalty the spring's kernel runs
on the part's predicted V~ and :func:`slide_spring` gives the part the rows' sum.

With t = e_r, the relative tangential velocity of constraint i is
w_t = v_up,r - v_lo,r (m/s) and its multiplier λ_t (N) acts along +r on the upper side,
along -r on the lower side. Per active constraint with λ_n > 0 and the cone radius
c = μ λ_n (``"stick"``: no cone):

- FILM: λ* = -w~_t / A_ii, λ_t = clip(λ*, -c, c); velocities move by h_n λ_t / m,
  positions by h_{n+1/2} times that.
- DME: the merged r velocity v* = (m_lo v~_lo + m_up v~_up) / (m_lo + m_up) (the fixed
  side's velocity where one side is fixed), the reaction that sticking implies
  λ* = m_up (v* - v~_up) / h_n; inside the cone both r velocities become v*, outside it
  λ_t = ±c is applied; positions u^{n+1} = u^n + h_{n+1/2} v^{n+1/2} (no jump in r).
- penalty: a tangential spring k_t (N/m) on the committed elastic slip s_e (m), trial
  λ_tr = -k_t (s_e + h_{n+1/2} w~_t), returned to the cone where it lies outside it
  (plastic slip Δs_p), applied as FILM's; s_e += h_{n+1/2} w_t^{n+1/2} - Δs_p. k_t is
  "scaled" (beta_t = k_t h_{n+1/2} A_ii = 1: the penalty's stick is FILM's) or given;
  at a change of step a scaled k_t follows it and each spring keeps its force k_t s_e
  (:func:`rescale_springs`), a given one is checked against beta_t <= 4/3.

μ_i = μ_d + (μ_s - μ_d) exp(-d_c |w_t^{n-1/2}|) with the previous step's slip speed.

The ledger (docs/friction.md 5): the r slots carry only tangential forces, so the one
contact-work booking (:func:`.state._book`) on them gives the tangential work W_t of the
step, added to the set's contact work. The slip work D = Σ h_n |λ_t| |w_t^{n+1/2}| >= 0
(the penalty: Σ c |Δs_p|) and the tangential arrival loss L_t = -W_t - D (the penalty:
minus also the release loss R, the stored energy the springs give up without work at a
release or a change of step, and the change of the springs' stored energy 1/2 k_t s_e^2,
both kept; a return to the cone books D alone, docs/friction.md 5.1) are kept beside it,
with the stats of a history row: the total tangential force Σ λ_t (N, on the upper sides
along +r) and the numbers of sticking and slipping constraints.

Under MPI the r components are gathered once per step (one Allgatherv) in slot order;
every rank takes the decisions on the same gathered data and writes back what it owns.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from mpi4py import MPI
from numba import njit

from ..errors import InputError, UnstableRunError
from ..jit_watch import direct
from ..plausibility import warn
from .state import _book, _pack, _take, _unpack, gathered_order, owned_slots

# the pass's scalars (Tangential.stats): the total tangential force of the step (N), the
# numbers sticking and slipping, then the cumulative slip work and tangential arrival
# loss (J) (the history's five columns), the largest |total| so far (N), then the
# penalty's release loss so far and the stored energy 1/2 k_t s_e^2 now (J)
T_FORCE, N_STICK, N_SLIP, SLIP_WORK, T_LOSS, T_PEAK, RELEASE_LOSS, STORED = range(8)
# a set's history columns and the stats they read (the penalty adds its two energies)
HISTORY = (("tangential_force", T_FORCE), ("n_stick", N_STICK), ("n_slip", N_SLIP),
           ("slip_work", SLIP_WORK), ("tangential_loss", T_LOSS))
PENALTY_HISTORY = (("release_loss", RELEASE_LOSS), ("spring_energy", STORED))
STABILITY_BOUND = 4.0 / 3.0  # of beta_t = k_t h A_ii (penalty.py's derivation)
FILM_T, DME_T, PENALTY_T = 1, 2, 3  # the tangential kernels


@dataclass(frozen=True)
class FrictionLaw:
    """Coulomb's law: μ = μ_d + (μ_s - μ_d) exp(-d_c |w_t|) (``static`` μ_s, ``dynamic``
    μ_d, ``decay`` d_c in s/m, w_t the previous step's slip speed, m/s); ``stick``: no
    slip at all (no cone is evaluated)."""

    static: float = 0.0
    dynamic: float = 0.0
    decay: float = 0.0
    stick: bool = False

    @property
    def is_zero(self) -> bool:
        """μ = 0 everywhere: frictionless (today's path, nothing made)."""
        return not self.stick and self.static == 0.0 and self.dynamic == 0.0

    def text(self) -> str:
        if self.stick:
            return '"stick"'
        if self.static == self.dynamic:
            return f"{self.static:g}"
        return f"{{static = {self.static:g}, dynamic = {self.dynamic:g}, decay = {self.decay:g}}}"


def friction_law(value, where: str = "friction") -> FrictionLaw:
    """The law of a scene's or a caller's ``friction`` (``where``: how messages name it): a
    number μ >= 0, ``"stick"``, a :class:`FrictionLaw`, or a table {static, dynamic,
    decay} (decay in s/m, default 0; dynamic defaults to static). Refuses anything else
    in one line."""
    usage = 'give a coefficient >= 0, "stick" or {static, dynamic, decay}'
    if isinstance(value, FrictionLaw):
        law = value
    elif isinstance(value, str):
        if value != "stick":
            raise InputError(f'{where} = "{value}": {usage}')
        law = FrictionLaw(stick=True)
    elif isinstance(value, dict):
        extra = sorted(set(value) - {"static", "dynamic", "decay"})
        if extra or "static" not in value:
            problem = f"unknown key {', '.join(extra)}" if extra else "static is missing"
            raise InputError(f"{where}: {problem} ({usage})")
        s = value["static"]
        law = FrictionLaw(s, value.get("dynamic", s), value.get("decay", 0.0))
    elif isinstance(value, (int, float)) and not isinstance(value, bool):
        law = FrictionLaw(value, value)
    else:
        raise InputError(f"{where} = {value!r}: {usage}")
    for name in ("static", "dynamic", "decay"):
        x = getattr(law, name)
        if isinstance(x, bool) or not isinstance(x, (int, float)) or not (math.isfinite(x)
                                                                          and x >= 0):
            label = where if isinstance(value, (int, float)) else f"{where} {name}"
            raise InputError(f"{label} = {x!r}: must be a finite number >= 0")
    return FrictionLaw(float(law.static), float(law.dynamic), float(law.decay), law.stick)


# ----------------------------------------------------------------------------- kernels

@njit(cache=True)
def _coefficient(mu_s, mu_d, decay, w_prev):
    """μ of a constraint from its previous slip speed |w_prev| (m/s)."""
    if mu_s == mu_d:
        return mu_s
    return mu_d + (mu_s - mu_d) * math.exp(-decay * abs(w_prev))


@njit(cache=True)
def _return_to_cone(trial, cap):
    """Coulomb's return: the trial tangential force (N) where |trial| <= cap = μ λ_n (stick,
    state 1), else cap sign(trial) on the cone (slip, state 2)."""
    if abs(trial) <= cap:
        return trial, 1
    return (cap if trial > 0.0 else -cap), 2


@njit(cache=True)
def _apply_tangential(f, p, q, h_over_m, h, u, v):
    """Apply λ_t = ``f`` (N) along +r on slot ``q`` and -r on slot ``p``: v by h_n f / m
    (``h_over_m``), u by h_{n+1/2} (``h``) times that. A slot with h_n / m = 0 (a fixed r
    dof, a rigid part's slot) is not written: its move would be 0 (under a rigid face
    every constraint shares its slot, and a write there each would chain the loop's
    iterations through memory)."""
    if h_over_m[q] != 0.0:
        dv_q = f * h_over_m[q]
        v[q] += dv_q
        u[q] += h * dv_q
    if h_over_m[p] != 0.0:
        dv_p = f * h_over_m[p]
        v[p] -= dv_p
        u[p] -= h * dv_p


@njit(cache=True)
def film_tangential(lo, up, active, force, a_inv, h_over_m, h, mu_s, mu_d, decay, stick,
                    v_now, u, v, lam, state):
    """FILM's tangential pass on the predicted r state (u, v; m, m/s) of the tangential
    slots, after the normal step (``force``: λ_n (N), ``active``): per constraint the
    stick multiplier λ* = -w~_t / A_ii (``a_inv``: 1/A_ii, 0 where no slot is free),
    projected on the cone; u, v corrected in place (``h_over_m``: h_n / m per slot, 0 on
    a fixed r dof or a rigid part; ``h``: h_{n+1/2}). ``v_now``: v^{n-1/2} (the decaying
    coefficient's slip speed). Writes λ_t (N) into ``lam`` and 0 (none), 1 (stick) or 2
    (slip) into ``state``."""
    for i in range(lo.size):
        lam[i] = 0.0
        state[i] = 0
        fn = force[i]
        if not active[i] or not fn > 0.0 or a_inv[i] == 0.0:
            continue
        p, q = lo[i], up[i]
        lam_star = -(v[q] - v[p]) * a_inv[i]
        if stick:
            f = lam_star
            state[i] = 1
        else:
            c = _coefficient(mu_s, mu_d, decay, v_now[q] - v_now[p]) * fn
            f, state[i] = _return_to_cone(lam_star, c)
        lam[i] = f
        _apply_tangential(f, p, q, h_over_m, h, u, v)


@njit(cache=True)
def dme_tangential(lo, up, active, force, mass, m_over_h, h_over_m, h, mu_s, mu_d, decay,
                   stick, u_now, v_now, u, v, lam, state):
    """DME's tangential pass (see the module): the merged r velocity v* of each active
    constraint (``mass``: the r slots' masses, inf on a fixed r dof or a rigid part;
    ``m_over_h``: m / h_n, 0 there) and the reaction m_up (v* - v~_up) / h_n it implies,
    tested against the cone; stick merges, slip applies λ_t = ±μ λ_n. Positions
    u^{n+1} = u^n + h v^{n+1/2} (``u_now``: u^n) on the slots it moves."""
    for i in range(lo.size):
        lam[i] = 0.0
        state[i] = 0
        fn = force[i]
        if not active[i] or not fn > 0.0:
            continue
        p, q = lo[i], up[i]
        free_p, free_q = h_over_m[p] != 0.0, h_over_m[q] != 0.0
        if not (free_p or free_q):
            continue
        if not free_p:
            v_star = v[p]
        elif not free_q:
            v_star = v[q]
        else:
            v_star = (mass[p] * v[p] + mass[q] * v[q]) / (mass[p] + mass[q])
        lam_star = (m_over_h[q] * (v_star - v[q]) if free_q else
                    m_over_h[p] * (v[p] - v_star))
        f, st = lam_star, 1
        if not stick:
            f, st = _return_to_cone(lam_star,
                                    _coefficient(mu_s, mu_d, decay, v_now[q] - v_now[p]) * fn)
        lam[i] = f
        state[i] = st
        if st == 1:
            if free_p:
                v[p] = v_star
            if free_q:
                v[q] = v_star
        else:
            if free_q:
                v[q] += f * h_over_m[q]
            if free_p:
                v[p] -= f * h_over_m[p]
        if free_p:
            u[p] = u_now[p] + h * v[p]
        if free_q:
            u[q] = u_now[q] + h * v[q]


@njit(cache=True)
def _slide_force(k, vt, mass, v, c, h_avg):
    """F_i(V) = clip(m_k (v~_k - V) / h_n, -c, c) (N): the force on a sliding part along
    +x of a row on node slot ``k`` at the part's velocity ``vt`` (docs/friction.md 11)."""
    f = mass[k] * (v[k] - vt) / h_avg
    if f > c:
        return c
    if f < -c:
        return -c
    return f


@njit(cache=True)
def _slide_phi(vt, v_tilde, hm_body, lo, up, body, mass, v, cap, state, h_avg):
    """phi(V) = V - V~ - (h_n / M) sum_i F_i(V) (m/s) over the rows that take part
    (``state`` 3; c_i in ``cap``): continuous, strictly increasing."""
    total = 0.0
    for i in range(lo.size):
        if state[i] == 3:
            k = up[i] if lo[i] == body else lo[i]
            total += _slide_force(k, vt, mass, v, cap[i], h_avg)
    return vt - v_tilde - hm_body * total


@njit(cache=True)
def rigid_slide(lo, up, active, force, mass, h_over_m, h_avg, h, mu_s, mu_d, decay, stick,
                merge, u_now, v_now, u, v, lam, state, cap, brk):
    """The tangential pass of a rigid face whose part slides along x (its slot the last;
    docs/friction.md 11), FILM's (``merge`` False) or DME's (True), on the predicted x
    state (u, v; m, m/s) after the normal step (``force``: λ_n, N; ``active``). The
    part's V^{n+1/2} is the one root of phi(V) = V - V~ - (h_n/M) sum_i F_i(V),
    F_i(V) = clip(m_k (v~_k - V)/h_n, -c_i, c_i), found exactly: the rows' breakpoints
    v~_k -+ h_n c_i/m_k sorted in place in ``brk`` (2 n), a bisection over them for the
    piece that holds the root, on which the stick set S and the slip forces are fixed,
    and there the momentum average V = (M V~ + sum_S m_k v~_k + h_n sum_slip F_i) /
    (M + sum_S m_k) ("stick": every row in S). Each row then takes F_i(V) (N, on the
    part along +x; λ_t = s_i F_i into ``lam``, s_i = +1 where the part is the upper
    side): FILM applies -F_i to the node, DME merges a stuck node (v_k = V) and applies
    -F_i to a slipping one; u = u^n + h v on the moved slots (``h``: h_{n+1/2};
    ``h_avg``: h_n; ``h_over_m``: h_n/m). ``cap`` receives c_i (N), ``state`` 0 (none),
    1 (stick), 2 (slip)."""
    body = u.size - 1
    big_m = mass[body]
    hm_body = h_over_m[body]
    v_tilde = v[body]
    nb = 0
    n_part = 0
    for i in range(lo.size):
        lam[i] = 0.0
        state[i] = 0
        cap[i] = 0.0
        fn = force[i]
        if not active[i] or not fn > 0.0:
            continue
        state[i] = 3  # takes part (stick or slip decided below)
        n_part += 1
        if stick:
            cap[i] = math.inf
        else:
            k = up[i] if lo[i] == body else lo[i]
            c = _coefficient(mu_s, mu_d, decay, v_now[up[i]] - v_now[lo[i]]) * fn
            cap[i] = c
            half = h_avg * c / mass[k]
            brk[nb] = v[k] - half
            brk[nb + 1] = v[k] + half
            nb += 2
    # the piece (low, high) of phi that holds its root: between two sorted breakpoints
    low, high = -math.inf, math.inf
    if nb > 0:
        b = brk[:nb]
        b.sort()
        a, z = -1, nb  # phi(b[a]) < 0 <= phi(b[z]), with phi(-inf) < 0 < phi(inf)
        while z - a > 1:
            mid = (a + z) // 2
            if _slide_phi(b[mid], v_tilde, hm_body, lo, up, body, mass, v, cap, state,
                          h_avg) < 0.0:
                a = mid
            else:
                z = mid
        if a >= 0:
            low = b[a]
        if z < nb:
            high = b[z]
    # on it each row sticks (its two breakpoints around the piece) or slips at +-c_i
    num = big_m * v_tilde
    den = big_m
    slip = 0.0
    for i in range(lo.size):
        if state[i] != 3:
            continue
        k = up[i] if lo[i] == body else lo[i]
        c = cap[i]
        half = h_avg * c / mass[k]
        if not stick and high <= v[k] - half:  # V below both: the node drags it up
            slip += c
        elif not stick and low >= v[k] + half:
            slip -= c
        else:
            num += mass[k] * v[k]
            den += mass[k]
    v_part = (num + h_avg * slip) / den
    for i in range(lo.size):
        if state[i] != 3:
            continue
        node_up = lo[i] == body
        k = up[i] if node_up else lo[i]
        f = _slide_force(k, v_part, mass, v, cap[i], h_avg)
        stuck = stick or abs(mass[k] * (v[k] - v_part) / h_avg) <= cap[i]
        state[i] = 1 if stuck else 2
        lam[i] = -f if node_up else f  # s_i F_i: s_i = -1 where the part is below
        if merge and stuck:
            v[k] = v_part
        else:
            v[k] -= f * h_over_m[k]
        u[k] = u_now[k] + h * v[k]
    v[body] = v_part
    u[body] = u_now[body] + h * v_part


@njit(cache=True)
def penalty_tangential(lo, up, active, force, k_t, h_over_m, h, mu_s, mu_d, decay, stick,
                       v_now, u, v, lam, state, s_e, d_slip, stats):
    """The penalty's tangential spring with a return to the cone (docs/friction.md 4) on
    the predicted r state: per active constraint the trial λ_tr = -k_t (s_e + h w~_t)
    (``k_t``: N/m, ``s_e``: the committed elastic slip, m), stick inside the cone, else
    λ_t = ±c and the plastic slip Δs_p = -(|λ_tr| - c) sign(λ_tr) / k_t; u, v corrected
    as FILM's, then s_e += h w_t^{n+1/2} - Δs_p. A constraint without a compressive λ_n
    is released: λ_t = 0, s_e = 0, its stored 1/2 k_t s_e^2 into the release loss (a
    return to the cone books nothing there: its loss is D, docs/friction.md 5.1).
    ``d_slip`` receives c |Δs_p| (J) per constraint; the release loss and the stored
    energy (J) in ``stats`` are updated."""
    released = 0.0
    stored = 0.0
    for i in range(lo.size):
        lam[i] = 0.0
        state[i] = 0
        d_slip[i] = 0.0
        fn = force[i]
        p, q = lo[i], up[i]
        if not active[i] or not fn > 0.0 or k_t[i] == 0.0:
            if s_e[i] != 0.0:  # released: the spring's stored energy is lost
                released += 0.5 * k_t[i] * s_e[i] * s_e[i]
                s_e[i] = 0.0
            continue
        trial = -k_t[i] * (s_e[i] + h * (v[q] - v[p]))
        dsp = 0.0
        if stick:
            f = trial
            state[i] = 1
        else:
            c = _coefficient(mu_s, mu_d, decay, v_now[q] - v_now[p]) * fn
            f, state[i] = _return_to_cone(trial, c)
            if state[i] == 2:
                dsp = (f - trial) / k_t[i]  # -(|trial| - c) sign(trial) / k_t
                d_slip[i] = c * abs(dsp)
        lam[i] = f
        _apply_tangential(f, p, q, h_over_m, h, u, v)
        s_e[i] += h * (v[q] - v[p]) - dsp
        stored += 0.5 * k_t[i] * s_e[i] * s_e[i]
    stats[RELEASE_LOSS] += released
    stats[STORED] = stored


@njit(cache=True)
def slide_spring(lo, up, state, h_over_m, h, u, v, k_t, s_e, lam, stats, hm_part):
    """The penalty's springs on a sliding part (docs/friction.md 11), after
    :func:`penalty_tangential` ran on its slot held (the trials on V~): the part takes
    the rows' sum, V^{n+1/2} = V~ + (h_n/M) sum_i F_i (``hm_part``: h_n/M; F_i = s_i λ_t,i,
    N, s_i = +1 where the part is the upper side), U by h_{n+1/2} (``h``) times that,
    and each loaded row's s_e (m) is committed with the corrected slip rate: shifted by
    h s_i (V^{n+1/2} - V~); the stored energy 1/2 k_t s_e^2 (J) in ``stats`` follows."""
    body = u.size - 1
    total = 0.0
    for i in range(lo.size):
        total += lam[i] if up[i] == body else -lam[i]
    dv = hm_part * total
    v[body] += dv
    u[body] += h * dv
    stored = 0.0
    for i in range(lo.size):
        if state[i] != 0:
            s_e[i] += h * dv if up[i] == body else -h * dv
        stored += 0.5 * k_t[i] * s_e[i] * s_e[i]
    stats[STORED] = stored


@njit(cache=True)
def rescale_springs(a_inv, h, scaled, given, k_t, s_e):
    """The penalty's springs at a new step (docs/friction.md 4.3): k_t' = 1 / (h A_ii)
    (``scaled``; ``a_inv`` = 1/A_ii, 1/(m/(N s)), ``h`` = h_{n+1/2}, s) or ``given`` (N/m)
    where A_ii > 0, else 0; each spring keeps its force, s_e' = k_t s_e / k_t' (m), in
    place. Returns (E_s - E_s', E_s') (J): the stored energy given up (signed: >= 0 where
    k_t grows) and the stored energy 1/2 k_t' s_e'^2 after. A spring whose k_t is
    unchanged is left as it is (bit for bit)."""
    released = 0.0
    stored = 0.0
    for i in range(k_t.size):
        k_new = 0.0
        if a_inv[i] > 0.0:
            k_new = a_inv[i] / h if scaled else given
        k_old = k_t[i]
        if k_new != k_old:
            before = 0.5 * k_old * s_e[i] * s_e[i]
            s_e[i] = k_old * s_e[i] / k_new if k_new > 0.0 else 0.0
            k_t[i] = k_new
            released += before - 0.5 * k_new * s_e[i] * s_e[i]
        stored += 0.5 * k_t[i] * s_e[i] * s_e[i]
    return released, stored


@njit(cache=True)
def _commit_tangential(local, pos, dst_u, dst_v, h, h_avg, m_over_h, u, v, v_pred, u_now,
                       v_now, f_prev, ku_prev, jump, lo, up, lam, state, stats, slip_limit,
                       penalty, d_slip, spring_change):
    """Write the corrected r state back to the owned dofs, book the tangential work by
    the one contact-work booking (:func:`.state._book`, no jump) and roll the r slots
    to n+1; slip work D = Σ h_n |λ_t| |w_t^{n+1/2}| (the ``penalty``: Σ ``d_slip``,
    c |Δs_p|) and L_t = -W_t - D (the penalty: minus also ``spring_change``, the step's
    release loss and change of stored energy, J) into ``stats`` (cumulative), with the
    step's total tangential force, its largest magnitude so far and the stick/slip
    counts. Returns (W_t (J), the first constraint whose relative
    tangential displacement u_up,r - u_lo,r exceeds its ``slip_limit`` (m), or -1);
    ``slip_limit`` may be empty (no finite limit: a rigid face)."""
    for k in range(local.size):
        dst_u[local[k]] = u[pos[k]]
        dst_v[local[k]] = v[pos[k]]
    total = 0.0
    n_stick = 0
    n_slip = 0
    slip = 0.0
    for i in range(lam.size):
        f = lam[i]
        total += f
        if state[i] == 1:
            n_stick += 1
        elif state[i] == 2:
            n_slip += 1
        if penalty:
            slip += d_slip[i]
        elif f != 0.0:
            slip += h_avg * abs(f) * abs(v[up[i]] - v[lo[i]])
    w_t, _ = _book(h_avg, 0, m_over_h, u, v, v_pred, u_now, v_now, f_prev, ku_prev, jump,
                   jump[:0], False, False)  # no jump (u = u^n + h v): no slot books one
    stats[0] = total
    stats[1] = n_stick
    stats[2] = n_slip
    stats[3] += slip
    stats[4] += -w_t - slip - spring_change
    stats[5] = max(stats[5], abs(total))
    for i in range(slip_limit.size):  # (empty where no constraint has a finite limit)
        if abs(u_now[up[i]] - u_now[lo[i]]) > slip_limit[i]:
            return w_t, i
    return w_t, -1


# the rows of Tangential.slots (per tangential slot), of .rows (per constraint) and the
# entries of .scalars, packed so that the step's pass is one compiled call of few arguments
(S_U, S_V, S_U_PRED, S_V_PRED, S_U_NOW, S_V_NOW, S_F_PREV, S_KU_PREV, S_JUMP, S_MASS,
 S_H_OVER_M, S_M_OVER_H) = range(12)
R_LAM, R_A_INV, R_K_T, R_S_E, R_D_SLIP, R_SLIP_LIMIT, R_CAP, R_BREAKS = range(8)  # (2 rows)
X_DT, X_H_AVG, X_MU_S, X_MU_D, X_DECAY, X_STICK, X_KERNEL, X_GATHERED, X_LIMITED, X_SLIDES = (
    range(10))


@njit(cache=True)
def _tangential_pass(src_u, src_v, own, recv, unpack, slots, rows, pairs, active, force,
                     state, stats, x):
    """The tangential pass of a step as one call: take the predicted r state of the slots
    (``own``: the owned dofs' local indices and slots; or, where ``x[X_GATHERED]``, unpack
    the Allgatherv's ``recv`` with ``unpack``: its u and v positions and the slots), run
    the method's kernel (``x[X_KERNEL]``) and :func:`_commit_tangential`. The arrays are
    the packed rows above (``pairs``: lo, up; the slip limits checked where
    ``x[X_LIMITED]``). Returns what the commit returns."""
    u, v, u_pred, v_pred = slots[S_U], slots[S_V], slots[S_U_PRED], slots[S_V_PRED]
    u_now, v_now, mass = slots[S_U_NOW], slots[S_V_NOW], slots[S_MASS]
    h_over_m, m_over_h = slots[S_H_OVER_M], slots[S_M_OVER_H]
    lo, up = pairs[0], pairs[1]
    lam, d_slip = rows[R_LAM], rows[R_D_SLIP]
    if x[X_GATHERED] != 0.0:
        _unpack(recv, unpack[0], unpack[1], unpack[2], u_pred, v_pred)
    else:
        _take(src_u, src_v, own[0], own[1], u_pred, v_pred)
    for k in range(u.size):
        u[k] = u_pred[k]
        v[k] = v_pred[k]
    h = x[X_DT]
    mu_s, mu_d, decay, stick = x[X_MU_S], x[X_MU_D], x[X_DECAY], x[X_STICK] != 0.0
    kernel = int(x[X_KERNEL])
    before = stats[RELEASE_LOSS] + stats[STORED]  # (0 but for the penalty)
    slide = x[X_SLIDES] != 0.0
    hm_part = h_over_m[u.size - 1]
    if slide and kernel == PENALTY_T:  # the rows' trials on V~: the part's slot held
        h_over_m[u.size - 1] = 0.0     # in the spring's pass (docs/friction.md 11)
    if slide and kernel != PENALTY_T:  # a rigid part that slides along x (FILM, DME)
        rigid_slide(lo, up, active, force, mass, h_over_m, x[X_H_AVG], h, mu_s, mu_d, decay,
                    stick, kernel == DME_T, u_now, v_now, u, v, lam, state, rows[R_CAP],
                    rows[R_BREAKS:R_BREAKS + 2].reshape(2 * lo.size))
    elif kernel == FILM_T:
        film_tangential(lo, up, active, force, rows[R_A_INV], h_over_m, h, mu_s, mu_d, decay,
                        stick, v_now, u, v, lam, state)
    elif kernel == DME_T:
        dme_tangential(lo, up, active, force, mass, m_over_h, h_over_m, h, mu_s, mu_d, decay,
                       stick, u_now, v_now, u, v, lam, state)
    else:
        penalty_tangential(lo, up, active, force, rows[R_K_T], h_over_m, h, mu_s, mu_d, decay,
                           stick, v_now, u, v, lam, state, rows[R_S_E], d_slip, stats)
        h_over_m[u.size - 1] = hm_part
    if slide and kernel == PENALTY_T:  # the part takes the rows' sum
        slide_spring(lo, up, state, h_over_m, h, u, v, rows[R_K_T], rows[R_S_E], lam, stats,
                     hm_part)
    change = stats[RELEASE_LOSS] + stats[STORED] - before
    return _commit_tangential(own[0], own[1], src_u, src_v, h, x[X_H_AVG], m_over_h, u, v,
                              v_pred, u_now, v_now, slots[S_F_PREV], slots[S_KU_PREV],
                              slots[S_JUMP], lo, up, lam, state, stats,
                              rows[R_SLIP_LIMIT][:lo.size if x[X_LIMITED] != 0.0 else 0],
                              kernel == PENALTY_T, d_slip, change)



# ----------------------------------------------------------------------------- the pass

class FrictionFigures:
    """What a tangential pass reports from its ``stats`` and ``law``: D, L_t and the peak
    tangential force (the node-pair and the segment passes alike)."""

    stats: np.ndarray
    law: FrictionLaw

    @property
    def slip_work(self) -> float:
        """D (J) so far: Σ h_n |λ_t| |w_t^{n+1/2}| >= 0."""
        return float(self.stats[SLIP_WORK])

    @property
    def tangential_loss(self) -> float:
        """L_t (J) so far: -W_t - D, the tangential arrival loss."""
        return float(self.stats[T_LOSS])

    def figures(self) -> dict:
        """The law, D and L_t (J), the peak |Σ λ_t| (N)."""
        return {"friction": self.law.text().strip('"'), "slip_work": self.slip_work,
                "tangential_loss": self.tangential_loss,
                "peak_tangential_force": float(self.stats[T_PEAK])}

class Tangential(FrictionFigures):
    """The tangential slots and pass of a node-pair or rigid-face contact set ``c``
    (:class:`~.interface.ContactSet`) with friction ``law`` (a :class:`FrictionLaw`, not
    zero); ``kernel`` FILM_T, DME_T or PENALTY_T, the last with the tangential
    stiffness ``stiffness`` (N/m, or ``"scaled"``: beta_t = 1 per row, k_t = m_red /
    (h_{n+1/2} h_n)). Made by ``ContactSet.set_friction``."""

    def __init__(self, c, law: FrictionLaw, kernel: int, stiffness: float | str = "scaled",
                 force: bool = False):
        self.c, self.law, self.kernel = c, law, kernel
        self.stiffness = stiffness
        # a given k_t whose beta_t passes 4/3 at a change of step in the run stops it
        # unless forced (``force``, as ContactSet.set_friction was given; at set-up it is
        # refused there)
        self.forced = force
        # the set's one compiled call of a step runs this pass too
        # (:func:`.fused.contact_step_friction`); False: the set calls :meth:`step`, the
        # pass as a call of its own (the tests compare the two paths)
        self.folds = True
        integ = c.integrator
        model = integ.model
        nd, ns = c.n_deformable, c.n_slots
        z_dofs = self._z_dofs(c)
        r_dofs = z_dofs - 1  # (r, z) pairs: each node's r dof precedes its z dof
        local, pos, all_pos, self._counts, self._displs = owned_slots(model, r_dofs, c.comm)
        self._local, self._pos, self._all_pos = local, pos, all_pos
        self._recv_u, self._recv_v = gathered_order(self._counts, self._displs)
        self._send = np.empty(2 * local.size)
        self._recv = np.empty(2 * nd)
        self._own = np.vstack([local, pos]).astype(np.int64)
        self._unpack = np.vstack([self._recv_u, self._recv_v, all_pos]).astype(np.int64)
        # per tangential slot (a rigid part's: zero inverse mass, never moved)
        self.slots = np.zeros((12, ns))
        (self.u, self.v, self.u_pred, self.v_pred, self.u_now, self.v_now, self.f_prev,
         self.ku_prev, self.jump, self.mass, self.h_over_m, self.m_over_h) = self.slots
        free_owned = np.ones(model.n_owned)
        free_owned[np.asarray(getattr(integ, "fixed", []), dtype=np.int64)] = 0.0
        free = np.zeros(ns)
        self._gather(integ.mass, free_owned, self.mass[:nd], free[:nd])
        self.free = free > 0.5
        # a moving rigid part of a plane-strain face slides along x under every method
        # (its slot gets 1/M); a fixed part, the axisymmetric axis and a face with a held
        # x node keep it held (docs/friction.md 11)
        rigid = c.rigid
        self.slides = bool(rigid is not None and not rigid.fixed and model.geometry.plane
                           and self.free[:nd].all())
        if self.slides:
            self.free[nd] = True
            self.mass[nd] = rigid.mass
        self.mass[~self.free] = np.inf
        self.pairs = np.vstack([c.lo, c.up]).astype(np.int64)
        self.lo, self.up = self.pairs
        self.state = np.zeros(c.n, dtype=np.int8)  # 0 none, 1 stick, 2 slip
        self.stats = np.zeros(8)
        # per constraint: λ_t (N) of the last step, 1/A_ii, the penalty's tangential
        # stiffness k_t (N/m), committed elastic slip s_e (m) and c |Δs_p| of the step (J)
        # (then a sliding part's c_i and its 2 n breakpoints, docs/friction.md 11)
        self.rows = np.zeros((9, c.n))
        self.lam, self.a_inv, self.k_t, self.s_e, self.d_slip, self.slip_limit = self.rows[:6]
        # a node pair keeps its partner (docs/friction.md 6): past half the smaller facet
        # at the pair the slave is nearer another master node, and the run says so once
        self.slip_limit[:] = np.inf
        if c.rigid is None and c.n > 1:
            r = np.asarray(c.r, dtype=float)
            order = np.argsort(r, kind="stable")
            gaps = np.diff(r[order])
            near = np.minimum(np.r_[np.inf, gaps], np.r_[gaps, np.inf])
            self.slip_limit[order] = 0.5 * near
        self.warned = False
        self.set_step()

    @staticmethod
    def _z_dofs(c) -> np.ndarray:
        k = c.constraints
        if c.rigid is None:
            return np.concatenate([k.lower, k.upper]).astype(np.int64)
        return np.asarray(k.upper if k.lower is None else k.lower, dtype=np.int64)

    def _gather(self, src_u, src_v, u_out, v_out) -> None:
        if self.c.comm.size == 1:
            _take(src_u, src_v, self._local, self._pos, u_out, v_out)
            return
        _pack(src_u, src_v, self._local, self._send)
        self.c.comm.Allgatherv(self._send, [self._recv, self._counts, self._displs, MPI.DOUBLE])
        _unpack(self._recv, self._recv_u, self._recv_v, self._all_pos, u_out, v_out)

    def set_step(self) -> None:
        """h_n / m, m / h_n and 1/A_ii = 1 / (h_n (1/m_lo + 1/m_up)) at the set's steps (0
        where no slot of a row is free)."""
        h_avg = self.c.h_avg
        free = self.free
        self.h_over_m[:] = 0.0
        self.m_over_h[:] = 0.0
        self.h_over_m[free] = h_avg / self.mass[free]
        self.m_over_h[free] = self.mass[free] / h_avg
        a = self.h_over_m[self.lo] + self.h_over_m[self.up]
        if self.slides and self.kernel == PENALTY_T:  # Gershgorin's row sum over the
            a += (self.lo.size - 1) * self.h_over_m[-1]  # part's coupling: 1/m_k + n/M
        self.a_inv[:] = 0.0
        np.divide(1.0, a, out=self.a_inv, where=a > 0.0)
        if self.kernel == PENALTY_T:  # beta_t = k_t h A_ii
            scaled = isinstance(self.stiffness, str)
            given = 0.0 if scaled else float(self.stiffness)
            released, stored = rescale_springs(self.a_inv, self.c.dt, scaled, given, self.k_t,
                                               self.s_e)
            # the springs' force k_t s_e kept: the stored energy's change booked into the
            # release loss (signed, docs/friction.md 4.3), the stored column at its new value
            self.stats[RELEASE_LOSS] += released
            self.stats[STORED] = stored
            self.beta_max = float((self.k_t * self.c.dt * a).max(initial=0.0))
            if not scaled and self.beta_max > STABILITY_BOUND and not self.forced \
                    and hasattr(self, "scalars"):  # a change of step in the run
                raise UnstableRunError(
                    f"tangential_penalty = {self.stiffness!r} N/m: beta_t = "
                    f"{self.beta_max:.3g} passes the stable bound 4/3 (k_t h h_n (1/m_lo + "
                    f"1/m_up), + n/M on a sliding part) at the re-estimated dt = "
                    f"{self.c.dt:.4g} s: the run stops; "
                    "lower it, use 'scaled' or force")
        self._bind()

    def initialize(self) -> None:
        """Read u_r^0 and v_r^0 (the first step's v^{n-1/2})."""
        integ = self.c.integrator
        nd = self.c.n_deformable
        self._gather(integ.u_owned, integ.v_owned, self.u_now[:nd], self.v_now[:nd])
        if self.slides:
            self.u_now[nd], self.v_now[nd] = self.c.rigid.u_x, self.c.rigid.v_x

    def predict_rigid(self, t: float) -> None:
        """A sliding part's x prediction (U~, V~) at t^n into its slot (before the pass)."""
        c = self.c
        nd = c.n_deformable
        self.u_pred[nd], self.v_pred[nd] = c.rigid.predict_x(t, c.dt, c.h_avg)

    def commit_rigid(self) -> None:
        """A sliding part's U^{n+1}, V^{n+1/2} from its slot (after the pass)."""
        nd = self.c.n_deformable
        rigid = self.c.rigid
        rigid.u_x, rigid.v_x = float(self.u[nd]), float(self.v[nd])

    def _bind(self) -> None:
        """The step's one compiled call: its scalars (the steps, the law, the kernel)
        rewritten in place at each change of the step; its arguments, the same arrays for
        the run, bound to its compiled entry once."""
        law, c = self.law, self.c
        if not hasattr(self, "scalars"):
            self.scalars = np.zeros(10)
            integ = c.integrator
            self._args = (integ.u_owned, integ.v_owned, self._own, self._recv, self._unpack,
                          self.slots, self.rows, self.pairs, c.active, c.force, self.state,
                          self.stats, self.scalars)
            self._pass = direct(_tangential_pass, *self._args)
        x = self.scalars
        x[X_DT], x[X_H_AVG] = c.dt, c.h_avg
        x[X_MU_S], x[X_MU_D], x[X_DECAY], x[X_STICK] = (law.static, law.dynamic, law.decay,
                                                        float(law.stick))
        x[X_KERNEL], x[X_GATHERED] = float(self.kernel), float(c.comm.size > 1)
        x[X_LIMITED] = float(np.isfinite(self.slip_limit).any())
        x[X_SLIDES] = float(self.slides)

    @property
    def fused_args(self) -> tuple:
        """The pass's arrays, in :func:`.fused.contact_step_friction`'s order (the same
        for the run; its scalars rewritten in place by :meth:`set_step`)."""
        return (self._own, self._recv, self._unpack, self.slots, self.rows, self.pairs,
                self.state, self.stats, self.scalars)

    def exchange(self) -> None:
        """Under MPI, the Allgatherv of the predicted r state of the slots (into the pass's
        receive buffer); nothing in serial. Before the pass: the set's normal step does
        not write r dofs, so before or after it reads the same values."""
        if self.c.comm.size > 1:
            integ = self.c.integrator
            _pack(integ.u_owned, integ.v_owned, self._local, self._send)
            self.c.comm.Allgatherv(self._send,
                                   [self._recv, self._counts, self._displs, MPI.DOUBLE])

    def step(self) -> float:
        """The tangential pass of the step as a call of its own, after the set's normal
        step: gather the predicted r state, correct, write back, book (one compiled call,
        after the Allgatherv under MPI). Returns W_t (J). (The normal step's own call runs
        it instead where it :attr:`folds`.)"""
        self.exchange()
        w_t, far = self._pass(*self._args)
        self.check_slip(far)
        return w_t

    def check_slip(self, far: int) -> None:
        """Warn once if constraint ``far`` (>= 0; -1: none) slipped past its limit."""
        if far >= 0 and not self.warned:
            self.warned = True
            c = self.c
            s = self.u_now[self.up[far]] - self.u_now[self.lo[far]]
            first = c.integrator.model.geometry.axes[0]  # r, or x in plane strain
            warn(f"contact {'/'.join(c.constraints.names)}: the node pair at {first} = "
                 f"{c.r[far]:.6g} "
                 f"m has slipped {s:.3g} m, past half its facet ({self.slip_limit[far]:.3g} m): "
                 "node pairs keep their partner, so the force acts at the wrong place; use "
                 "node to segment (slave/master) for faces that slide", c.comm)

    # outputs
    @property
    def history_columns(self) -> tuple:
        """(name, index into ``stats``) of the set's history columns."""
        return HISTORY + (PENALTY_HISTORY if self.kernel == PENALTY_T else ())

    def summary(self) -> dict:
        """The run's friction figures: the law, D and L_t (J), the peak |Σ λ_t| (N)."""
        out = self.figures()
        if self.kernel == PENALTY_T:
            out.update(release_loss=float(self.stats[RELEASE_LOSS]),
                       spring_energy=float(self.stats[STORED]), beta_t_max=self.beta_max,
                       tangential_penalty=self.stiffness)
        return out
