"""One compiled call per contact step: the rigid body, detection, the method and the commit.

For penalty, FILM (solver "fast") and DME the whole step of a
:class:`~impact_fenics.contact.interface.ContactSet` after the free prediction
is one call of :func:`contact_step`: predict the rigid body from its external
force at t^n, take (or, under MPI, unpack after the Allgatherv) the predicted
contact dofs and form the gaps g~_i = b_i + u~[up_i] - u~[lo_i], correct them
with the method's kernel, write the corrected state back to the owned dofs,
book the contact work (_ContactWork's discrete form, impact_fenics/energy.py)
and commit the rigid body (RigidBody.advance: its rod's waves and the work of
its external force). The kernels called are the ones the separate calls run, in
the same order on the same arrays, and the rigid body's arithmetic is
RigidBody.predict/advance's, so the numbers are the same bit for bit.

What it costs is set by memory and the call, not by arithmetic: masses, 1/d and
the penalty stiffnesses are set-up constants (dt/m, m/dt, 1/d: no division in a
step); a rigid face (the punch, the bit) runs in two passes over its nodes
(:func:`_face_step`, compiled per method); and the set's state is packed so that
the call unboxes seven arrays:

- ``floats`` (18 x slots): the slot rows u, v, u_pred, v_pred, u_now, v_now,
  mass, f_prev, dt/m, m/dt, ku_prev, jump (the last two over the deformable
  slots), then the constraint rows b, gap, force, d, 1/d, p (their first n
  entries, n <= slots);
- ``ints`` (int32, 11 x deformable slots; layout state.LO ... POS): lo, up
  and a scratch row per constraint, the slot maps of the gather and write-back;
- ``flags`` (active, was_active);
- ``misc``: the ledger, the stats, the rigid body's work and waves, the
  constants (layout: state.LEDGER ... N_LOCAL);
- ``recv``: under MPI the Allgatherv buffer (empty in serial), and the owned
  displacement and velocity.

The attributes of the set are views of these rows.
"""
from __future__ import annotations

import numpy as np
from numba import njit

from .dme import _cluster, _pairs
from .film import _film_fast
from .friction import _tangential_pass
from .penalty import _penalty
from .state import (ALL_POS, B, CODE, D_INV, DT, DT_OVER_M, F_PREV, FORCE, FROM_U, FROM_V, GAP,
                    H_AVG, IMPEDANCE, INCIDENT, JUMP, JUMP_BOOK, JUMPS, KAPPA, KU_PREV, LEDGER, LO,
                    LOCAL, M_OVER_DT, MASS, MASS_WEIGHTED, N_CONS, N_DEFORMABLE, N_LOCAL, P, POS,
                    RECV_U, RECV_V, RESTITUTION, RIGID, RIGID_F_PREV, RIGID_MASS, RIGID_WORK, STATS,
                    TO, U, U_NOW, U_PRED, UP, V, V_NOW, V_PRED, WAVES, WORK, _commit,
                    _predicted_gaps, _take, _unpack)

# the methods the fused call runs (misc[CODE]); another method runs its own correct()
PENALTY, FILM_FAST, DME_PAIRS, DME_CLUSTER = 1, 2, 3, 4


def _make_face_step(code: int):
    """The rigid-face step of method ``code``, compiled for it alone (``code`` is a
    constant of the closure: no branch on the method inside the loops). Each method's
    closure has a name of its own: a cached kernel that calls it holds it under that
    name, and one name for the three would let a process that loads two caches made by
    two processes link one method's step to another's (kernel_cache)."""

    def _face_step(src_u, src_v, recv, F, ints, flags, misc):
        """The step of a rigid face (constraint i ties node slot i to the body's slot) for
        penalty, FILM fast and DME's cluster in two passes over the nodes: A takes the
        prediction, forms the gaps and the method's sums; B corrects each node, writes it
        back, books its work and rolls it. The same operations in the same order as
        detection, the method's kernel and _commit, so the same numbers bit for bit.
        Returns (work increment (J), jumped, grew, done); not done (FILM with candidates
        left unloaded, DME with a node that would pull: the rare sorted cases) leaves
        u_pred, v_pred set for the general path, nothing else changed. The step's scratch
        rows of the nodes (u, v, gap, was_active) are not written: the committed state is
        u_now, v_now (and u, v at the body's slot).

        The packed arrays are indexed in place (F[U_NOW, i]): a row view would cost a
        reference count (an atomic operation) each."""
        n = int(misc[N_CONS])
        dt = misc[DT]
        h_n = misc[H_AVG]  # the velocity step, the booking's (dt under a constant step)
        kappa = misc[KAPPA]
        body = n
        # +1: the body above its nodes (g = b + u_body - u_node), -1: below (g = b + u_node -
        # u_body); a node's correction moves it by -side dv, the body's by +side dv. A fixed
        # body (infinite mass) has h/m = 0 and m/h = 0 at its slot.
        side = -1.0 if ints[LO, 0] == body else 1.0
        fixed = F[MASS, body] == np.inf
        gathered = recv.size > 0
        ut_b, vt_b = F[U_PRED, body], F[V_PRED, body]
        u_b, v_b = ut_b, vt_b  # the body's corrected state (penalty: summed in A; FILM: in B)
        dvb = F[DT_OVER_M, body]
        # pass A: the prediction, the gaps and the sums of the method
        n_cand = 0
        a = 0.0
        w = 0.0
        g_max = -np.inf
        g_sum = 0.0
        g_0 = 0.0
        s_0 = 0.0
        momentum = 0.0 if fixed else F[MASS, body] * vt_b
        total_mass = F[MASS, body]
        v_min = np.inf  # of side x v
        for i in range(n):
            if gathered:
                ut = recv[ints[FROM_U, i]]
                vt = recv[ints[FROM_V, i]]
            else:
                k = ints[TO, i]
                ut = src_u[k]
                vt = src_v[k]
            F[U_PRED, i] = ut
            F[V_PRED, i] = vt
            g = F[B, i] + ut_b - ut if side > 0.0 else F[B, i] + ut - ut_b
            if code == PENALTY:
                f = -F[P, i] * g if g < 0.0 else 0.0
                F[FORCE, i] = f
                if f != 0.0:
                    dv = side * (f * dvb)
                    v_b += dv
                    u_b += dt * dv
            elif g < 0.0:
                n_cand += 1
                if code == FILM_FAST:
                    if n_cand == 1:
                        g_0 = g
                    a -= g * F[D_INV, i]
                    w += F[D_INV, i]
                    g_max = max(g_max, g)
                    g_sum += g
                    s_0 += (g - g_0) * F[D_INV, i]
                else:
                    if not fixed:
                        momentum += F[MASS, i] * vt
                        total_mass += F[MASS, i]
                    v_min = min(v_min, side * vt)
        g_ref = 0.0
        base = 0.0
        v_c = 0.0
        if code == FILM_FAST and n_cand > 0:
            if not g_max + kappa * a / (1.0 + kappa * w) <= 0.0:
                return 0.0, False, False, False
            g_ref = g_sum / n_cand  # film._loaded, its sums taken in A
            s = s_0 + (g_0 - g_ref) * w
            base = (g_ref - kappa * s) / (1.0 + kappa * w)
        elif code == DME_CLUSTER:
            v_c = vt_b if fixed else momentum / total_mass
            if not v_min >= side * v_c:
                return 0.0, False, False, False
            u_b = F[U_NOW, body] + dt * v_c
            v_b = v_c
        # pass B: correct, write back, book and roll each node
        jumps = code == DME_CLUSTER and misc[JUMPS] != 0.0
        jumped = misc[LEDGER + 2] != 0.0
        inc = 0.0
        inc_jump = 0.0
        n_active = 0
        total = 0.0
        min_gap = np.inf
        jumped_now = False
        grew = False
        for i in range(n):
            ut, vt = F[U_PRED, i], F[V_PRED, i]
            bi = F[B, i]
            g = bi + ut_b - ut if side > 0.0 else bi + ut - ut_b
            ui, vi = ut, vt
            if code == PENALTY:
                f = F[FORCE, i]
                act = g < 0.0
                if f != 0.0:
                    dv = side * (f * F[DT_OVER_M, i])
                    vi = vt - dv
                    ui = ut - dt * dv
            elif code == FILM_FAST:
                if kappa == 0.0:  # film._solve_fast's diagonal answer
                    f = -g * F[D_INV, i] if g < 0.0 else 0.0
                else:
                    f = max(-(g - g_ref + base) * F[D_INV, i], 0.0) if g < 0.0 else 0.0
                act = f > 0.0
                if f != 0.0:
                    dv = side * (f * F[DT_OVER_M, i])
                    vi = vt - dv
                    ui = ut - dt * dv
                    dv = side * (f * dvb)
                    v_b += dv
                    u_b += dt * dv
            else:
                act = g < 0.0
                f = 0.0
                if act:
                    f = F[M_OVER_DT, i] * (side * (vt - v_c))
                    vi = v_c
                    ui = u_b + side * bi
            F[FORCE, i] = f
            was = flags[0, i]
            flags[0, i] = act
            total += f
            if act:
                n_active += 1
                if not was:
                    grew = True
            k = ints[TO, i]
            if k >= 0:
                src_u[k] = ui
                src_v[k] = vi
            fb = F[M_OVER_DT, i] * (vi - vt)
            inc += 0.5 * h_n * (F[V_NOW, i] + vi) * fb
            F[F_PREV, i] = fb
            if jumps:
                ku = -F[M_OVER_DT, i] * (vt - F[V_NOW, i])
                if jumped and F[JUMP_BOOK, i] != 0.0:
                    inc_jump += 0.5 * F[JUMP, i] * (F[KU_PREV, i] + ku)
                F[KU_PREV, i] = ku
                j = ui - F[U_NOW, i] - dt * vi
                F[JUMP, i] = j
                if j != 0.0:
                    jumped_now = True
            F[U_NOW, i] = ui
            F[V_NOW, i] = vi
            if side > 0.0:
                min_gap = min(min_gap, bi - ui)  # + u_b after the loop: rounding is monotonic
            else:
                min_gap = min(min_gap, (bi - u_b) + ui)  # _commit's (b - u[lo]) + u[up]
        if side > 0.0:
            min_gap += u_b
        # the body's slot, last, as in _commit
        F[U, body] = u_b
        F[V, body] = v_b
        fb = F[M_OVER_DT, body] * (v_b - vt_b)
        inc += 0.5 * h_n * (F[V_NOW, body] + v_b) * fb
        F[F_PREV, body] = fb
        F[U_NOW, body] = u_b
        F[V_NOW, body] = v_b
        misc[STATS] = n_active
        misc[STATS + 1] = total
        misc[STATS + 2] = min_gap
        return inc + inc_jump, jumped_now, grew, True

    name = {PENALTY: "penalty", FILM_FAST: "film_fast", DME_CLUSTER: "dme_cluster"}[code]
    _face_step.__name__ = _face_step.__qualname__ = f"_face_step_{name}"
    return njit(cache=True)(_face_step)


_FACE_STEP = {code: _make_face_step(code) for code in (PENALTY, FILM_FAST, DME_CLUSTER)}
_face_penalty, _face_film, _face_cluster = _FACE_STEP[PENALTY], _FACE_STEP[FILM_FAST], \
    _FACE_STEP[DME_CLUSTER]


@njit(cache=True)
def _general_step(code, src_u, src_v, recv, F, ints, flags, misc):
    """Detection, the method's kernel and the commit on row views of the packed arrays:
    node pairs, and a rigid face's rare sorted cases. Returns (work increment (J),
    jumped, grew)."""
    n = int(misc[N_CONS])
    u, v, u_pred, v_pred, u_now, v_now = F[U], F[V], F[U_PRED], F[V_PRED], F[U_NOW], F[V_NOW]
    mass, dt_over_m, m_over_dt = F[MASS], F[DT_OVER_M], F[M_OVER_DT]
    b, gap, force, d_inv, p = F[B][:n], F[GAP][:n], F[FORCE][:n], F[D_INV][:n], F[P][:n]
    lo, up, work = ints[LO][:n], ints[UP][:n], ints[WORK][:n]
    n_local = int(misc[N_LOCAL])
    local, pos = ints[LOCAL][:n_local], ints[POS][:n_local]
    active, was_active = flags[0], flags[1]
    dt = misc[DT]
    if misc[RIGID] == 0.0:  # a rigid face has its prediction taken already
        if recv.size > 0:
            _unpack(recv, ints[RECV_U], ints[RECV_V], ints[ALL_POS], u_pred, v_pred)
        else:
            _take(src_u, src_v, local, pos, u_pred, v_pred)
    _predicted_gaps(u_pred, v_pred, u, v, b, lo, up, gap, active, was_active)
    if code == PENALTY:
        _penalty(gap, p, force, active, lo, up, dt_over_m, dt, u, v)
    elif code == FILM_FAST:
        _film_fast(gap, d_inv, misc[KAPPA], force, active, lo, up, dt_over_m, dt, u, v, work)
    elif code == DME_PAIRS:
        _pairs(gap, b, lo, up, mass, misc[H_AVG], misc[RESTITUTION], misc[MASS_WEIGHTED] != 0.0,
               u, v, force, active)
    elif lo[0] == F.shape[1] - 1:  # a body below its nodes
        _cluster(gap, b, up, lo[0], -1.0, mass, m_over_dt, dt, u_now, u, v, force, active, work)
    else:
        _cluster(gap, b, lo, up[0], 1.0, mass, m_over_dt, dt, u_now, u, v, force, active, work)
    return _commit(local, pos, src_u, src_v, dt, misc[H_AVG], int(misc[N_DEFORMABLE]), m_over_dt, u,
                   v, u_pred, v_pred, u_now, v_now, F[F_PREV], F[KU_PREV], F[JUMP],
                   F[JUMP_BOOK], misc[JUMPS] != 0.0, misc[LEDGER + 2] != 0.0, active,
                   was_active, b, lo, up, force, misc[STATS:STATS + 3])


@njit(cache=True)
def contact_step(src_u, src_v, recv, F, ints, flags, misc, f_ext, f_in):
    """Step n -> n+1 of a contact set: predict the rigid body, detect, correct with the
    method ``misc[CODE]``, write back, book, commit the rigid body.

    ``src_u``, ``src_v``: the owned displacement (m) and velocity (m/s), read at the
    contact dofs (serial) and written back there; under MPI (``recv`` not empty) the
    prediction comes from the Allgatherv buffer ``recv``.
    ``f_ext``: the rigid body's external force f(t^n) (N, z), ``f_in`` its rod's
    incident wave F_i(t^n) (N, compressive > 0; 0 without). Returns the rigid body's
    (u^{n+1}, v^{n+1}) (m, m/s; zeros without one). Positions move by the step
    h_{n+1/2} (misc[DT]), velocities by h_n (misc[H_AVG] and the slots' h_n / m), equal
    under a constant step; the contact and rigid-body work here, and the rod's wave
    energies, are booked by the kinetic identity with h_n, exact under any steps."""
    code = int(misc[CODE])
    dt = misc[DT]
    rigid = misc[RIGID] != 0.0
    body = F.shape[1] - 1
    v_n = 0.0
    drive = 0.0
    h_avg = misc[H_AVG]  # the velocity step h_n (dt under a constant step)
    if rigid:  # RigidBody.predict: its state without contact at t^n+1
        drive = f_ext - (2.0 * f_in if misc[INCIDENT] != 0.0 else 0.0)
        m_r, z = misc[RIGID_MASS], misc[IMPEDANCE]
        v_n = F[V_NOW, body]
        if z == 0.0:
            v_tilde = v_n + h_avg * drive / m_r  # a fixed part (m_r = inf): v_n
        else:
            half = 0.5 * z * h_avg
            v_tilde = ((m_r - half) * v_n + h_avg * drive) / (m_r + half)
        F[U_PRED, body] = F[U_NOW, body] + dt * v_tilde
        F[V_PRED, body] = v_tilde
    done = False
    if rigid:  # a rigid face: two passes (its rare sorted cases go on below)
        if code == PENALTY:
            inc, jumped, grew, done = _face_penalty(src_u, src_v, recv, F, ints, flags,
                                                    misc)
        elif code == FILM_FAST:
            inc, jumped, grew, done = _face_film(src_u, src_v, recv, F, ints, flags, misc)
        else:
            inc, jumped, grew, done = _face_cluster(src_u, src_v, recv, F, ints, flags,
                                                    misc)
    if not done:
        inc, jumped, grew = _general_step(code, src_u, src_v, recv, F, ints, flags, misc)
    misc[LEDGER] += inc
    if grew or misc[LEDGER + 3] != 0.0:
        misc[LEDGER + 1] -= inc
    misc[LEDGER + 2] = 1.0 if jumped else 0.0
    misc[LEDGER + 3] = 1.0 if grew else 0.0
    if not rigid:
        return 0.0, 0.0
    # RigidBody.advance and _ContactWork.book_rigid: the rod's waves, the external work
    v_next = F[V, body]
    f = drive
    z = misc[IMPEDANCE]
    if z > 0.0:
        w = -0.5 * (v_n + v_next)
        rod = 2.0 * f_in - z * w
        f_r = f_in - z * w
        misc[WAVES] += h_avg * f_in * f_in / z
        misc[WAVES + 1] += h_avg * f_r * f_r / z
        misc[WAVES + 2] += h_avg * rod * w
        f = f_ext - rod
    misc[RIGID_WORK] += 0.5 * h_avg * (v_n + v_next) * f
    misc[RIGID_F_PREV] = f
    return F[U, body], v_next


@njit(cache=True)
def contact_step_friction(src_u, src_v, recv, F, ints, flags, misc, t_own, t_recv, t_unpack,
                          t_slots, t_rows, t_pairs, t_state, t_stats, t_x, f_ext, f_in):
    """Step n -> n+1 of a contact set with Coulomb friction (node pairs, a rigid or fixed
    face) as one call: :func:`contact_step` (the normal step), then the set's tangential
    pass (friction._tangential_pass: take the predicted r state of its slots, the
    method's tangential kernel, write back, book), its work W_t (J) added to the set's
    contact work. The same two kernels the two separate calls ran, in the same order on
    the same arrays, so the same numbers bit for bit; one call saves the second call's
    Python and argument unboxing. The normal step writes only normal (z) dofs, so under
    MPI both Allgathervs (``recv``, ``t_recv``) come before the call.

    The arguments: :func:`contact_step`'s, then the pass's
    (:attr:`.friction.Tangential.fused_args`), then the rigid body's forces. Returns the
    rigid body's (u^{n+1}, v^{n+1}) (m, m/s; zeros without one) and the first constraint
    past its slip limit (-1: none)."""
    u_r, v_r = contact_step(src_u, src_v, recv, F, ints, flags, misc, f_ext, f_in)
    n = int(misc[N_CONS])
    w_t, far = _tangential_pass(src_u, src_v, t_own, t_recv, t_unpack, t_slots, t_rows,
                                t_pairs, flags[0, :n], F[FORCE, :n], t_state, t_stats, t_x)
    misc[LEDGER] += w_t
    return u_r, v_r, far

