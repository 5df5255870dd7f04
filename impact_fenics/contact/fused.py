"""One compiled call per contact step: detection, the method and the commit fused.

For penalty, FILM (solver "fast") and DME the whole step of a
:class:`~impact_fenics.contact.interface.ContactSet` after the free prediction
is one call of :func:`contact_step`: take (or, under MPI, unpack after the
Allgatherv) the predicted contact dofs and form the gaps g~_i = b_i + u~[up_i]
- u~[lo_i], correct them with the method's kernel, write the corrected state
back to the owned dofs and book the contact work (_ContactWork's discrete form,
impact_fenics/energy.py). The kernels called are the ones the separate calls
ran, in the same order on the same arrays, so the numbers are the same bit for
bit; what goes is the Python between them and the unboxing of ~50 arguments
(about 80 ns each) in three calls.

The set's state is packed so that the call takes few arguments: ``slots``
(8 x slots: u, v, u_pred, v_pred, u_now, v_now, mass, f_prev), ``cons``
(4 x constraints: b, gap, force, d), ``ints`` (lo, up, work), ``flags``
(active, was_active), ``jumps_state`` (ku_prev, jump over the deformable slots)
and ``ledger`` (work (J), activation loss (J), jumped last step, active set grew
last step). The attributes of the set are views of these rows.
"""
from __future__ import annotations

from numba import njit

from .dme import _cluster, _pairs
from .film import _film_fast
from .interface import _commit, _predicted_gaps, _take, _unpack
from .penalty import _penalty

# the methods the fused call runs (ContactSet.method_code); 0: the method's own correct()
PENALTY, FILM_FAST, DME_PAIRS, DME_CLUSTER = 1, 2, 3, 4


@njit(cache=True)
def contact_step(code, gathered, src_u, src_v, local, pos, recv, recv_u, recv_v, all_pos,
                 slots, cons, ints, flags, jumps_state, p, stats, ledger, dt, kappa, e,
                 mass_weighted, first, n_deformable, jumps):
    """Detect, correct with method ``code``, write back and book, for step n -> n+1.

    ``src_u``, ``src_v``: the owned displacement (m) and velocity (m/s), read at the
    contact dofs (``gathered`` False) and written back there; with ``gathered`` the
    prediction comes from the Allgatherv buffer ``recv``. ``p``: the penalty
    stiffnesses (N/m; any float array for the other methods), ``e`` DME's restitution,
    ``kappa`` = dt^2 / m_rigid (m/N). ``stats`` receives (number active, total force
    (N), smallest committed gap (m))."""
    u, v, u_pred, v_pred = slots[0], slots[1], slots[2], slots[3]
    u_now, v_now, mass, f_prev = slots[4], slots[5], slots[6], slots[7]
    b, gap, force, d = cons[0], cons[1], cons[2], cons[3]
    lo, up, work = ints[0], ints[1], ints[2]
    active, was_active = flags[0], flags[1]
    if gathered:
        _unpack(recv, recv_u, recv_v, all_pos, u_pred, v_pred)
    else:
        _take(src_u, src_v, local, pos, u_pred, v_pred)
    _predicted_gaps(u_pred, v_pred, u, v, b, lo, up, gap, active, was_active)
    if code == PENALTY:
        _penalty(gap, p, force, active, lo, up, mass, dt, u, v)
    elif code == FILM_FAST:
        _film_fast(gap, d, kappa, force, active, lo, up, mass, dt, u, v, work)
    elif code == DME_PAIRS:
        _pairs(gap, b, lo, up, mass, dt, e, mass_weighted, u, v, force, active)
    else:
        _cluster(gap, b, lo, up[0], mass, dt, u_now, u, v, force, active, work)
    inc, jumped, grew = _commit(local, pos, src_u, src_v, dt, first, n_deformable, mass, u, v,
                                u_pred, v_pred, u_now, v_now, f_prev, jumps_state[0],
                                jumps_state[1], jumps, ledger[2] != 0.0, active, was_active, b,
                                lo, up, force, stats)
    ledger[0] += inc
    if grew or ledger[3] != 0.0:
        ledger[1] -= inc
    ledger[2] = 1.0 if jumped else 0.0
    ledger[3] = 1.0 if grew else 0.0
