"""The slot state of a contact set: its packed layout, the gather, the write-back and the booking.

A node-pair or rigid-face set (:class:`~impact_fenics.contact.interface.ContactSet`)
keeps its state in *slots*: one per contact dof (the lower nodes first, then the
upper nodes of node pairs) and one more for a rigid upper body; constraint i ties
slot ``lo[i]`` to slot ``up[i]``. The slot and constraint rows live in a few packed
arrays whose layout is given here by row and entry names, so that the set, the
fused step (:mod:`.fused`) and the compiled blocks read the same rows.

The kernels here are what every method and both step paths share: the forces of
a method applied to the slots (:func:`apply_forces`), the detection (take or
unpack the predicted contact dofs, form the predicted gaps
g~_i = b_i + u~[up_i] - u~[lo_i], or g0 + G u~ for node to segment) and the commit
(write back the owned dofs, then the one booking of every kind, :func:`_book`: the
contact work, the state rolled to n+1). :func:`owned_slots` gives which slots a
rank owns for the gather. Nothing here imports a method or the set: the methods
and the set import it.

Signs: the contact force ``force`` (N) is compressive-positive; it pushes the
upper side up (+z) and the lower side down.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from mpi4py import MPI
from numba import njit

from ..errors import InputError
from .banded import gap_of

# a set's kind of geometry (its ``kind``), which fixes the structure of
# S = h_{n+1/2} h_n G M^-1 G': node pairs diagonal, a rigid face diagonal + kappa 1 1',
# node to segment banded (contact.banded); each method has a kernel per structure
PAIRS, RIGID_FACE, SEGMENTS = "pairs", "rigid", "segments"

# the set's scalars in one float array (ContactSet._misc), read and written by the fused
# call: the contact-work ledger (work, activation loss, jumped, grew), the stats of a
# history row, the rigid body's external work and last force, its rod's wave energies,
# then the run's constants: DT is the position step h_{n+1/2}, H_AVG the velocity step
# h_n = (h_{n-1/2} + h_{n+1/2}) / 2 (equal under a constant step); RIGID_MASS is inf for
# a fixed part (zero inverse mass)
LEDGER, STATS, RIGID_WORK, RIGID_F_PREV, WAVES = 0, 4, 7, 8, 9
CODE, DT, KAPPA, RESTITUTION, MASS_WEIGHTED, JUMPS, N_DEFORMABLE = 12, 13, 14, 15, 16, 17, 18
RIGID, RIGID_MASS, IMPEDANCE, INCIDENT, N_CONS, N_LOCAL, H_AVG = 19, 20, 21, 22, 23, 24, 25
MISC_SIZE = 26
# the rows of ContactSet._floats: per slot, then per constraint (their first n entries);
# DT_OVER_M is h_n / m and M_OVER_DT m / h_n (0 at a fixed part's slot), D the diagonal
# of S = h_{n+1/2} h_n G M^-1 G' (m/N)
U, V, U_PRED, V_PRED, U_NOW, V_NOW, MASS, F_PREV, DT_OVER_M, M_OVER_DT, KU_PREV, JUMP = range(12)
B, GAP, FORCE, D, D_INV, P = range(12, 18)
# and one more slot row: 1 where the slot's dof belongs to a body whose stored energy is
# booked from its positions (its jumps are work, _book), else 0
JUMP_BOOK = 18
# the rows of ContactSet._ints (int32): per constraint lo, up and a scratch row; per
# slot where its u and v are in the Allgatherv buffer and its slot (recv_u, recv_v,
# all_pos: in gathered order), where its predicted u and v are read and the owned dof it
# is written back to (from_u, from_v, to: in slot order); the owned contact dofs and
# their slots (local, pos)
LO, UP, WORK, RECV_U, RECV_V, ALL_POS, FROM_U, FROM_V, TO, LOCAL, POS = range(11)


def is_banded(c) -> bool:
    """Is S of the set ``c`` banded (its ``kind`` is node to segment)? A set without a
    ``kind`` holds node pairs or a rigid face."""
    return getattr(c, "kind", PAIRS) == SEGMENTS


@dataclass
class PhaseTimes:
    """CPU time (s) of the last step's contact phases."""

    detection: float = 0.0
    solve: float = 0.0
    update: float = 0.0


# ----------------------------------------------------------------------------- kernels

@njit(cache=True)
def apply_forces(force, lo, up, dt_over_m, dt, u, v):
    """Compressive forces (N) move each lower slot down and each upper slot up:
    velocities by dt F/m, positions by dt^2 F/m (a rigid slot sums its forces).
    ``dt_over_m``: dt / m of each slot (s/kg), a set-up constant."""
    for i in range(force.size):
        f = force[i]
        if f != 0.0:
            a, b = lo[i], up[i]
            dv_a = f * dt_over_m[a]
            dv_b = f * dt_over_m[b]
            v[a] -= dv_a
            u[a] -= dt * dv_a
            v[b] += dv_b
            u[b] += dt * dv_b


@njit(cache=True)
def _take(src_u, src_v, local, pos, u_out, v_out):
    for k in range(local.size):
        u_out[pos[k]] = src_u[local[k]]
        v_out[pos[k]] = src_v[local[k]]


@njit(cache=True)
def _pack(src_u, src_v, local, send):
    m = local.size
    for k in range(m):
        send[k] = src_u[local[k]]
        send[m + k] = src_v[local[k]]


@njit(cache=True)
def _unpack(recv, recv_u, recv_v, pos, u_out, v_out):
    for k in range(pos.size):
        u_out[pos[k]] = recv[recv_u[k]]
        v_out[pos[k]] = recv[recv_v[k]]


@njit(cache=True)
def _predicted_gaps(u_pred, v_pred, u, v, b, lo, up, gap, active, was_active):
    for k in range(u.size):
        u[k] = u_pred[k]
        v[k] = v_pred[k]
    for i in range(b.size):
        gap[i] = b[i] + u_pred[up[i]] - u_pred[lo[i]]
        was_active[i] = active[i]


@njit(cache=True)
def _detect_local(src_u, src_v, local, pos, u_pred, v_pred, u, v, b, lo, up, gap, active,
                  was_active):
    """Detection on one rank: take the predicted contact dofs, form the gaps (one call)."""
    _take(src_u, src_v, local, pos, u_pred, v_pred)
    _predicted_gaps(u_pred, v_pred, u, v, b, lo, up, gap, active, was_active)


@njit(cache=True)
def _detect_gathered(recv, recv_u, recv_v, all_pos, u_pred, v_pred, u, v, b, lo, up, gap,
                     active, was_active):
    """Detection after the Allgatherv: unpack in slot order, form the gaps (one call)."""
    _unpack(recv, recv_u, recv_v, all_pos, u_pred, v_pred)
    _predicted_gaps(u_pred, v_pred, u, v, b, lo, up, gap, active, was_active)


@njit(cache=True)
def _committed_gap(b, u_now, lo, up, out):
    for i in range(b.size):
        out[i] = b[i] + u_now[up[i]] - u_now[lo[i]]


@njit(cache=True)
def _book(h_n, n_deformable, m_over_dt, u, v, v_pred, u_now, v_now, f_prev, ku_prev, jump,
          books, jumps, jumped, h=0.0):
    """Book the contact work increment of step n by the kinetic identity of the half-step
    scheme (see impact_fenics.energy) and roll the slots' state to n+1: every kind's
    booking.

    Slot k's contact force is its momentum change over the step,
    F_k^n = (m_k / h_n) (v_k^{n+1/2} - v~_k^{n+1/2}) (``m_over_dt``: m / h_n, kg/s; 0 at a
    fixed part's slot; ``h_n``: the velocity step (h_{n-1/2} + h_{n+1/2}) / 2, s); the step
    adds 1/2 h_n (v^{n-1/2} + v^{n+1/2}) . F^n (``v_now`` holds v^{n-1/2}: v^0 at the first
    step), exact under any sequence of steps. A set whose method ``jumps`` (positions
    apart from u^n + h v^{n+1/2}, ``h`` the position step h_{n+1/2}, s) adds, over its
    ``n_deformable`` deformable slots, the previous step's jump j (``jumped``: was any
    nonzero) times 1/2 K (u^{n-1} + u^n), K u^n = -(m / h_n) (v~^{n+1/2} - v^{n-1/2}) on a
    contact dof, and records this step's jump u^{n+1} - u^n - h v^{n+1/2}: the work of
    the jumps on a body whose stored energy is booked from its positions (a small-strain
    path-dependent body; a linear body under a constant step), on the slots where
    ``books`` is not 0 (a finite-strain body's work is its kinetic share, which no jump
    enters). ``f_prev`` keeps F^n.
    Returns (the increment (J), whether this step jumped)."""
    inc = 0.0  # the work of the slots' forces,
    inc_jump = 0.0  # and of the jumps (summed apart: the fused rigid-face pass sums both at once)
    jumped_now = False
    for k in range(m_over_dt.size):
        f = m_over_dt[k] * (v[k] - v_pred[k])
        inc += 0.5 * h_n * (v_now[k] + v[k]) * f
        f_prev[k] = f
    rolled = 0  # slots already rolled to n+1 (in the jump loop, after their last read)
    if jumps:
        for k in range(n_deformable):
            ku = -m_over_dt[k] * (v_pred[k] - v_now[k])  # K u^n on this dof
            if jumped and books[k] != 0.0:
                inc_jump += 0.5 * jump[k] * (ku_prev[k] + ku)
            ku_prev[k] = ku
            jump[k] = u[k] - u_now[k] - h * v[k]
            if jump[k] != 0.0:
                jumped_now = True
            u_now[k] = u[k]
            v_now[k] = v[k]
        rolled = n_deformable
    for k in range(rolled, m_over_dt.size):
        u_now[k] = u[k]
        v_now[k] = v[k]
    return inc + inc_jump, jumped_now


@njit(cache=True)
def shared_jump_work(jump, pos, local, f, f_prev):
    """The work of the previous step's position jumps j (m) on the slots ``pos`` whose dofs
    (``local``, owned) two bonded bodies share, one booked from its positions and one by
    the kinetic identity: 1/2 j . (f^{n-1} + f^n) with f (N) the first body's force alone
    (``f``: a small-strain force's owned array at u^n; ``f_prev`` keeps f^{n-1} per slot),
    :func:`_book`'s term on that body's share (one_loop.md 4.7). Called after the
    prediction, before the set's commit overwrites j. Returns the work (J, this rank)."""
    work = 0.0
    for i in range(pos.size):
        fk = f[local[i]]
        work += 0.5 * jump[pos[i]] * (f_prev[i] + fk)
        f_prev[i] = fk
    return work


@njit(cache=True)
def _commit(local, pos, dst_u, dst_v, dt, h_n, n_deformable, m_over_dt, u, v, u_pred, v_pred,
            u_now, v_now, f_prev, ku_prev, jump, books, jumps, jumped, active, was_active, b, lo,
            up, force, stats):
    """The commit of node pairs and a rigid face: write the corrected state back to the
    owned dofs, then book step n and roll the state to n+1 (:func:`_book`; one call; ``dt``
    and ``h_n`` the position and velocity steps h_{n+1/2}, h_n, s).
    Returns the increment (J), whether this step jumped and whether the active set grew;
    ``stats`` receives (number active, total force (N), smallest committed gap (m))."""
    for k in range(local.size):
        dst_u[local[k]] = u[pos[k]]
        dst_v[local[k]] = v[pos[k]]
    n_active = 0
    total = 0.0
    grew = False
    min_gap = np.inf
    for i in range(active.size):
        total += force[i]
        if active[i]:
            n_active += 1
            if not was_active[i]:
                grew = True
        min_gap = min(min_gap, (b[i] - u[lo[i]]) + u[up[i]])
    inc, jumped_now = _book(h_n, n_deformable, m_over_dt, u, v, v_pred, u_now, v_now,
                            f_prev, ku_prev, jump, books, jumps, jumped, dt)
    stats[0] = n_active
    stats[1] = total
    stats[2] = min_gap
    return inc, jumped_now, grew


@njit(cache=True)
def _detect_segments(u_pred, v_pred, u, v, g0, cs, cc, gap, active, was_active):
    """Detection of node to segment after the gather: the predicted gaps
    g~ = g0 + G u~ (G: six (slot ``cs``, coefficient ``cc``) entries a row)."""
    for k in range(u.size):
        u[k] = u_pred[k]
        v[k] = v_pred[k]
    gap_of(g0, cs, cc, u_pred, gap)
    for i in range(gap.size):
        was_active[i] = active[i]


@njit(cache=True)
def _commit_segments(local, pos, dst_u, dst_v, dt, h_n, m_over_dt, u, v, v_pred, u_now, v_now,
                     f_prev, ku_prev, jump, books, jumps, jumped, active, was_active, g0, cs,
                     cc, gap_buf):
    """The commit of node to segment: write the corrected state back to the owned dofs,
    then book step n and roll the state to n+1 (:func:`_book`, every slot deformable;
    one call). Returns (the increment (J), jumped, grew, the smallest committed gap
    g0 + G u (m))."""
    for k in range(local.size):
        dst_u[local[k]] = u[pos[k]]
        dst_v[local[k]] = v[pos[k]]
    grew = False
    for i in range(active.size):
        if active[i] and not was_active[i]:
            grew = True
    gap_of(g0, cs, cc, u, gap_buf)
    min_gap = np.inf
    for i in range(gap_buf.size):
        min_gap = min(min_gap, gap_buf[i])
    inc, jumped_now = _book(h_n, m_over_dt.size, m_over_dt, u, v, v_pred, u_now, v_now,
                            f_prev, ku_prev, jump, books, jumps, jumped, dt)
    return inc, jumped_now, grew, min_gap


@njit(cache=True)
def kinetic_share(local, pos, f_int, h_avg, mass, u_pred, v_pred, v_now, b, lo, up, p, active):
    """The contact's share of the kinetic identity of the half-step scheme on this rank's
    owned slots (``local``: their owned dofs, ``pos``: their slots), after a step's
    commit; ``f_int`` the internal force of the step (N, owned dofs) and ``h_avg`` the
    velocity step h_n (s). With v~ the prediction (``v_pred``), v the committed velocity
    (``v_now``) and v^- = v~ + h_n f_int / m the velocity before the step, a slot's
    kinetic energy changes by 1/2 (v^- + v) m (v - v^-): the internal force's
    h_n 1/2 (v^- + v) (-f_int) and the contact's 1/2 (v^- + v) m (v - v~).

    Returns (the energy the contact took from the body, -sum 1/2 (v^- + v) m (v - v~) (J);
    the internal work's correction h_n 1/2 (v - v~) f_int (J) for a pass that booked it
    with v~; the number of active constraints; the contact force sum m (v - v~) / h_n (N);
    the springs' energy 1/2 p g~^2 of the active constraints (J, penalty; p = 0 else)).
    Constraint i belongs to slot i (a rigid face's node slots come first)."""
    taken = 0.0
    w_fix = 0.0
    spring = 0.0
    total = 0.0
    n_active = 0
    for k in range(local.size):
        i = pos[k]
        f = f_int[local[k]]
        m = mass[i]
        vt = v_pred[i]
        v = v_now[i]
        v_old = vt + h_avg * f / m
        taken -= 0.5 * (v_old + v) * m * (v - vt)
        w_fix += 0.5 * h_avg * (v - vt) * f
        total += m * (v - vt) / h_avg
        if i < active.size and active[i]:
            n_active += 1
            g = b[i] + u_pred[up[i]] - u_pred[lo[i]]
            spring += 0.5 * p[i] * g * g
    return taken, w_fix, n_active, total, spring


# ----------------------------------------------------------------------------- the gather

def owned_slots(model, dofs: np.ndarray, comm: MPI.Comm) -> tuple:
    """The contact slots (global z dofs ``dofs``) this rank owns, for the gather of
    (u, v) pairs: (local owned indices, their slot positions, every rank's positions
    in rank order, Allgatherv counts and displacements in doubles). Refuses dofs not
    owned exactly once over the ranks."""
    lo_dof, hi_dof = model.offset, model.offset + model.n_owned
    mine = np.flatnonzero((dofs >= lo_dof) & (dofs < hi_dof))
    counts = np.array(comm.allgather(mine.size))
    positions = np.concatenate(comm.allgather(mine)).astype(np.int64)
    if not np.array_equal(np.sort(positions), np.arange(dofs.size)):
        raise InputError("contact dofs are not all owned exactly once: "
                         "each contact node must belong to one body")
    displs = np.concatenate([[0], np.cumsum(2 * counts)[:-1]])
    return ((dofs[mine] - lo_dof).astype(np.int64), mine.astype(np.int64), positions,
            2 * counts, displs)


def gathered_order(counts: np.ndarray, displs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Where each gathered slot's u and v are in the Allgatherv buffer (in gathered order):
    each rank sends the u of its slots, then their v (``counts``, ``displs`` in doubles,
    from :func:`owned_slots`)."""
    per_rank = counts // 2
    recv_u = np.concatenate([s + np.arange(c) for s, c in zip(displs, per_rank)])
    recv_v = np.concatenate([s + c + np.arange(c) for s, c in zip(displs, per_rank)])
    return recv_u, recv_v
