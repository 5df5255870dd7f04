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
step), and the set's state is packed so that the call unboxes ten arrays:

- ``slots`` (12 x slots): u, v, u_pred, v_pred, u_now, v_now, mass, f_prev,
  dt/m, m/dt, ku_prev, jump (the last two over the deformable slots);
- ``cons`` (6 x constraints): b, gap, force, d, 1/d, p;
- ``ints`` (lo, up, work), ``flags`` (active, was_active);
- ``misc``: the ledger, the stats, the rigid body's work and waves, the
  constants (layout: interface.LEDGER ... INCIDENT);
- ``mine`` (local, pos: the owned contact dofs and their slots) and, under MPI,
  ``recv`` and ``gath`` (recv_u, recv_v, all_pos: where each slot's gathered u
  and v are).

The attributes of the set are views of these rows.
"""
from __future__ import annotations

from numba import njit

from .dme import _cluster, _pairs
from .film import _film_fast
from .interface import (CODE, DT, IMPEDANCE, INCIDENT, JUMPS, KAPPA, LEDGER, MASS_WEIGHTED,
                        N_DEFORMABLE, RESTITUTION, RIGID, RIGID_F_PREV, RIGID_MASS, RIGID_WORK,
                        STATS, WAVES, _commit, _predicted_gaps, _take, _unpack)
from .penalty import _penalty

# the methods the fused call runs (ContactSet.method_code); 0: the method's own correct()
PENALTY, FILM_FAST, DME_PAIRS, DME_CLUSTER = 1, 2, 3, 4


@njit(cache=True)
def contact_step(src_u, src_v, mine, recv, gath, slots, cons, ints, flags, misc, first, f_ext,
                 f_in):
    """Step n -> n+1 of a contact set: predict the rigid body, detect, correct with the
    method ``misc[CODE]``, write back, book, commit the rigid body.

    ``src_u``, ``src_v``: the owned displacement (m) and velocity (m/s), read at the
    contact dofs (serial) and written back there; under MPI (``recv`` not empty) the
    prediction comes from the Allgatherv buffer ``recv``. ``first``: the step n = 0.
    ``f_ext``: the rigid body's external force f(t^n) (N, z), ``f_in`` its rod's
    incident wave F_i(t^n) (N, compressive > 0; 0 without). Returns the rigid body's
    (u^{n+1}, v^{n+1}) (m, m/s; zeros without one)."""
    u, v, u_pred, v_pred = slots[0], slots[1], slots[2], slots[3]
    u_now, v_now, mass, f_prev = slots[4], slots[5], slots[6], slots[7]
    dt_over_m, m_over_dt, ku_prev, jump = slots[8], slots[9], slots[10], slots[11]
    b, gap, force, d, d_inv, p = cons[0], cons[1], cons[2], cons[3], cons[4], cons[5]
    lo, up, work = ints[0], ints[1], ints[2]
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
    if recv.size > 0:
        _unpack(recv, gath[0], gath[1], gath[2], u_pred, v_pred)
    else:
        _take(src_u, src_v, mine[0], mine[1], u_pred, v_pred)
    _predicted_gaps(u_pred, v_pred, u, v, b, lo, up, gap, active, was_active)
    if code == PENALTY:
        _penalty(gap, p, force, active, lo, up, dt_over_m, dt, u, v)
    elif code == FILM_FAST:
        _film_fast(gap, d, d_inv, misc[KAPPA], force, active, lo, up, dt_over_m, dt, u, v, work)
    elif code == DME_PAIRS:
        _pairs(gap, b, lo, up, mass, dt, misc[RESTITUTION], misc[MASS_WEIGHTED] != 0.0, u, v,
               force, active)
    else:
        _cluster(gap, b, lo, up[0], mass, m_over_dt, dt, u_now, u, v, force, active, work)
    ledger = misc[LEDGER:LEDGER + 4]
    inc, jumped, grew = _commit(mine[0], mine[1], src_u, src_v, dt, first,
                                int(misc[N_DEFORMABLE]), m_over_dt, u, v, u_pred, v_pred, u_now,
                                v_now, f_prev, ku_prev, jump, misc[JUMPS] != 0.0,
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
