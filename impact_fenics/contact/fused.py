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
- ``ints`` (int32, 11 x deformable slots; layout interface.LO ... POS): lo, up
  and a scratch row per constraint, the slot maps of the gather and write-back;
- ``flags`` (active, was_active);
- ``misc``: the ledger, the stats, the rigid body's work and waves, the
  constants (layout: interface.LEDGER ... N_LOCAL);
- ``recv``: under MPI the Allgatherv buffer (empty in serial), and the owned
  displacement and velocity.

The attributes of the set are views of these rows.
"""
from __future__ import annotations

import numpy as np
from numba import njit

from .dme import _cluster, _pairs
from .film import _film_fast
from .interface import (ALL_POS, CODE, DT, FROM_U, FROM_V, IMPEDANCE, INCIDENT, JUMPS, KAPPA,
                        LEDGER, LO, LOCAL, MASS_WEIGHTED, N_CONS, N_DEFORMABLE, N_LOCAL, POS,
                        RECV_U, RECV_V, RESTITUTION, RIGID, RIGID_F_PREV, RIGID_MASS, RIGID_WORK,
                        STATS, TO, UP, WAVES, WORK, _commit, _predicted_gaps, _take, _unpack)
from .penalty import _penalty

# the methods the fused call runs (ContactSet.method_code); 0: the method's own correct()
PENALTY, FILM_FAST, DME_PAIRS, DME_CLUSTER = 1, 2, 3, 4


@njit(cache=True)
def _slot_rows(floats):
    """The 12 slot rows of the packed floats: u, v, u_pred, v_pred, u_now, v_now, mass,
    f_prev, dt/m, m/dt, ku_prev, jump."""
    return (floats[0], floats[1], floats[2], floats[3], floats[4], floats[5], floats[6],
            floats[7], floats[8], floats[9], floats[10], floats[11])


@njit(cache=True)
def _constraint_rows(floats, n):
    """The 6 constraint rows of the packed floats (their first n entries): b, gap, force,
    d, 1/d, p."""
    return (floats[12][:n], floats[13][:n], floats[14][:n], floats[15][:n], floats[16][:n],
            floats[17][:n])


def _make_face_step(code: int):
    """The rigid-face step of method ``code``, compiled for it alone (``code`` is a
    constant of the closure: no branch on the method inside the loops)."""

    @njit(cache=True)
    def _face_step(first, src_u, src_v, recv, floats, ints, flags, misc):
        """The step of a rigid face (constraint i ties node slot i to the body's slot) for
        penalty, FILM fast and DME's cluster in two passes over the nodes (and a third for
        FILM's reference gap): A takes the prediction, forms
        the gaps and the method's sums; B corrects each node, writes it back, books its work
        and rolls it. The same operations in the same order as detection, the method's
        kernel and _commit, so the same numbers bit for bit. Returns (work increment (J),
        jumped, grew, done); not done (FILM with candidates left unloaded, DME with a node
        that would pull: the rare sorted cases) leaves u_pred, v_pred set for the general
        path, nothing else changed. The step's scratch rows of the nodes (u, v, gap,
        was_active) are not written: the committed state is u_now, v_now (and u, v at the
        body's slot)."""
        u, v, u_pred, v_pred, u_now, v_now, mass, f_prev, dt_over_m, m_over_dt, ku_prev, jump \
            = _slot_rows(floats)
        n = int(misc[N_CONS])
        b, gap, force, d, d_inv, p = _constraint_rows(floats, n)
        active = flags[0]
        dt = misc[DT]
        kappa = misc[KAPPA]
        body = n
        iu, iv, to = ints[FROM_U], ints[FROM_V], ints[TO]
        gathered = recv.size > 0
        ut_b, vt_b = u_pred[body], v_pred[body]
        u_b, v_b = ut_b, vt_b  # the body's corrected state (penalty: summed in A; FILM: in B)
        dvb = dt_over_m[body]
        # pass A: the prediction, the gaps and the sums of the method
        n_cand = 0
        a = 0.0
        w = 0.0
        g_max = -np.inf
        g_sum = 0.0
        momentum = mass[body] * vt_b
        total_mass = mass[body]
        v_min = np.inf
        for i in range(n):
            if gathered:
                ut = recv[iu[i]]
                vt = recv[iv[i]]
            else:
                k = to[i]
                ut = src_u[k]
                vt = src_v[k]
            u_pred[i] = ut
            v_pred[i] = vt
            g = b[i] + ut_b - ut
            if code == PENALTY:
                f = -p[i] * g if g < 0.0 else 0.0
                force[i] = f
                if f != 0.0:
                    dv = f * dvb
                    v_b += dv
                    u_b += dt * dv
            elif g < 0.0:
                n_cand += 1
                if code == FILM_FAST:
                    a -= g * d_inv[i]
                    w += d_inv[i]
                    g_max = max(g_max, g)
                    g_sum += g
                else:
                    momentum += mass[i] * vt
                    total_mass += mass[i]
                    v_min = min(v_min, vt)
        g_ref = 0.0
        base = 0.0
        v_c = 0.0
        if code == FILM_FAST and n_cand > 0:
            if not g_max + kappa * a / (1.0 + kappa * w) <= 0.0:
                return 0.0, False, False, False
            g_ref = g_sum / n_cand
            s = 0.0
            for i in range(n):
                g = b[i] + ut_b - u_pred[i]
                if g < 0.0:
                    s += (g - g_ref) * d_inv[i]
            base = (g_ref - kappa * s) / (1.0 + kappa * w)
        elif code == DME_CLUSTER:
            if not v_min >= momentum / total_mass:
                return 0.0, False, False, False
            v_c = momentum / total_mass
            u_b = u_now[body] + dt * v_c
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
            ut, vt = u_pred[i], v_pred[i]
            bi = b[i]
            g = bi + ut_b - ut
            ui, vi = ut, vt
            if code == PENALTY:
                f = force[i]
                act = g < 0.0
                if f != 0.0:
                    dv = f * dt_over_m[i]
                    vi = vt - dv
                    ui = ut - dt * dv
            elif code == FILM_FAST:
                f = max(-(g - g_ref + base) * d_inv[i], 0.0) if g < 0.0 else 0.0
                act = f > 0.0
                if f != 0.0:
                    dv = f * dt_over_m[i]
                    vi = vt - dv
                    ui = ut - dt * dv
                    dv = f * dvb
                    v_b += dv
                    u_b += dt * dv
            else:
                act = g < 0.0
                f = 0.0
                if act:
                    f = m_over_dt[i] * (vt - v_c)
                    vi = v_c
                    ui = u_b + bi
            force[i] = f
            was = active[i]
            active[i] = act
            total += f
            if act:
                n_active += 1
                if not was:
                    grew = True
            k = to[i]
            if k >= 0:
                src_u[k] = ui
                src_v[k] = vi
            fb = m_over_dt[i] * (vi - vt)
            if not first:
                inc += 0.5 * dt * v_now[i] * (f_prev[i] + fb)
            f_prev[i] = fb
            if jumps:
                ku = -m_over_dt[i] * (vt - v_now[i])
                if jumped:
                    inc_jump += 0.5 * jump[i] * (ku_prev[i] + ku)
                ku_prev[i] = ku
                jump[i] = ui - u_now[i] - dt * vi
                if jump[i] != 0.0:
                    jumped_now = True
            u_now[i] = ui
            v_now[i] = vi
            min_gap = min(min_gap, bi - ui)  # + u_b after the loop: rounding is monotonic
        min_gap += u_b
        # the body's slot, last, as in _commit
        u[body] = u_b
        v[body] = v_b
        fb = m_over_dt[body] * (v_b - vt_b)
        if not first:
            inc += 0.5 * dt * v_now[body] * (f_prev[body] + fb)
        f_prev[body] = fb
        u_now[body] = u_b
        v_now[body] = v_b
        stats = misc[STATS:STATS + 3]
        stats[0] = n_active
        stats[1] = total
        stats[2] = min_gap
        return inc + inc_jump, jumped_now, grew, True

    return _face_step


_FACE_STEP = {code: _make_face_step(code) for code in (PENALTY, FILM_FAST, DME_CLUSTER)}
_face_penalty, _face_film, _face_cluster = _FACE_STEP[PENALTY], _FACE_STEP[FILM_FAST], \
    _FACE_STEP[DME_CLUSTER]


@njit(cache=True)
def contact_step(src_u, src_v, recv, floats, ints, flags, misc, first, f_ext, f_in):
    """Step n -> n+1 of a contact set: predict the rigid body, detect, correct with the
    method ``misc[CODE]``, write back, book, commit the rigid body.

    ``src_u``, ``src_v``: the owned displacement (m) and velocity (m/s), read at the
    contact dofs (serial) and written back there; under MPI (``recv`` not empty) the
    prediction comes from the Allgatherv buffer ``recv``. ``first``: the step n = 0.
    ``f_ext``: the rigid body's external force f(t^n) (N, z), ``f_in`` its rod's
    incident wave F_i(t^n) (N, compressive > 0; 0 without). Returns the rigid body's
    (u^{n+1}, v^{n+1}) (m, m/s; zeros without one)."""
    u, v, u_pred, v_pred, u_now, v_now, mass, f_prev, dt_over_m, m_over_dt, ku_prev, jump = \
        _slot_rows(floats)
    n = int(misc[N_CONS])
    b, gap, force, d, d_inv, p = _constraint_rows(floats, n)
    lo, up, work = ints[LO][:n], ints[UP][:n], ints[WORK][:n]
    n_local = int(misc[N_LOCAL])
    local, pos = ints[LOCAL][:n_local], ints[POS][:n_local]
    active, was_active = flags[0], flags[1]
    code = int(misc[CODE])
    dt = misc[DT]
    rigid = misc[RIGID] != 0.0
    body = mass.size - 1
    v_n = 0.0
    drive = 0.0
    if rigid:  # RigidBody.predict: its state without contact at t^n+1
        drive = f_ext - (2.0 * f_in if misc[INCIDENT] != 0.0 else 0.0)
        m_r, z = misc[RIGID_MASS], misc[IMPEDANCE]
        v_n = v_now[body]
        if z == 0.0:
            v_tilde = v_n + dt * drive / m_r
        else:
            half = 0.5 * z * dt
            v_tilde = ((m_r - half) * v_n + dt * drive) / (m_r + half)
        u_pred[body] = u_now[body] + dt * v_tilde
        v_pred[body] = v_tilde
    ledger = misc[LEDGER:LEDGER + 4]
    done = False
    if rigid:  # a rigid face: two passes (its rare sorted cases go on below)
        if code == PENALTY:
            inc, jumped, grew, done = _face_penalty(first, src_u, src_v, recv, floats, ints,
                                                    flags, misc)
        elif code == FILM_FAST:
            inc, jumped, grew, done = _face_film(first, src_u, src_v, recv, floats, ints, flags,
                                                 misc)
        else:
            inc, jumped, grew, done = _face_cluster(first, src_u, src_v, recv, floats, ints,
                                                    flags, misc)
    elif recv.size > 0:
        _unpack(recv, ints[RECV_U], ints[RECV_V], ints[ALL_POS], u_pred, v_pred)
    else:
        _take(src_u, src_v, local, pos, u_pred, v_pred)
    if not done:
        _predicted_gaps(u_pred, v_pred, u, v, b, lo, up, gap, active, was_active)
        if code == PENALTY:
            _penalty(gap, p, force, active, lo, up, dt_over_m, dt, u, v)
        elif code == FILM_FAST:
            _film_fast(gap, d, d_inv, misc[KAPPA], force, active, lo, up, dt_over_m, dt, u, v,
                       work)
        elif code == DME_PAIRS:
            _pairs(gap, b, lo, up, mass, dt, misc[RESTITUTION], misc[MASS_WEIGHTED] != 0.0, u, v,
                   force, active)
        else:
            _cluster(gap, b, lo, up[0], mass, m_over_dt, dt, u_now, u, v, force, active, work)
        inc, jumped, grew = _commit(local, pos, src_u, src_v, dt, first,
                                    int(misc[N_DEFORMABLE]), m_over_dt, u, v, u_pred, v_pred,
                                    u_now, v_now, f_prev, ku_prev, jump, misc[JUMPS] != 0.0,
                                    ledger[2] != 0.0, active, was_active, b, lo, up, force,
                                    misc[STATS:STATS + 3])
    ledger[0] += inc
    if grew or ledger[3] != 0.0:
        ledger[1] -= inc
    ledger[2] = 1.0 if jumped else 0.0
    ledger[3] = 1.0 if grew else 0.0
    if not rigid:
        return 0.0, 0.0
    # RigidBody.advance and _ContactWork.book_rigid: the rod's waves, the external work
    v_next = v[body]
    f = drive
    z = misc[IMPEDANCE]
    if z > 0.0:
        w = -0.5 * (v_n + v_next)
        rod = 2.0 * f_in - z * w
        f_r = f_in - z * w
        misc[WAVES] += dt * f_in * f_in / z
        misc[WAVES + 1] += dt * f_r * f_r / z
        misc[WAVES + 2] += dt * rod * w
        f = f_ext - rod
    if not first:
        misc[RIGID_WORK] += 0.5 * dt * v_n * (misc[RIGID_F_PREV] + f)
    misc[RIGID_F_PREV] = f
    return u[body], v_next
