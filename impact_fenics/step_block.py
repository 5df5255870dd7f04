"""A run's steps in compiled blocks (linear bodies), their outputs' numbers included.

A step of linear bodies is the predictor of paper eq. (1) (v <- A u + v by
MatMultAdd, A = -dt M^-1 K; u <- u + dt v by VecAXPY), the contact set's step and a
history row. The loop of :class:`~.simulation.Simulation` runs these in Python,
about 3 us a step around the PETSc calls: a third of a step on a mesh of ~1,000
dofs. Here :func:`run_steps` runs a block of steps in one call: PETSc's MatMultAdd
and VecAXPY by address on the same objects (:mod:`.native`), the contact set's
:func:`~.contact.fused.contact_step` (under MPI after its pack and MPI_Allgatherv,
also by address), the contact track, the history and per-pair rows, the divergence
check (its count reduced over the ranks) and the phase timers: each the operations
of the Python step in the same order on the same arrays, so the numbers are the
same bit for bit (tests/test_step_block.py, 1 and 2 ranks).

Outputs inside a block. An output step keeps u^n and v^n, and after it the block
sums its energies and momenta (energy._output_sums; MPI_SUM by address under MPI)
and records them with the contact work and the rigid body's speeds; the loop makes
the energy rows from these records after the block
(Simulation._row_from_record, which makes the Python step's rows from the same
record), and a step whose energy fails energy.energy_verdict ends its block so the
row raises at the same step. On one rank, when the cell fields are the stresses of
one isotropic kernel, a fields step computes its
frame straight into the writer's batch row (stresses, point vectors, the run's
peaks) and the loop hands the frames to the writer after the block (else a fields
step ends its block and the loop writes its frame). So a block ends where the
writer's batch goes to the file (full, or a flush due), when the history block is full, when a progress line may be due, at
the MPI ranks' agreement on signals, or after :data:`MAX_STEPS` steps or about
:data:`BLOCK_SECONDS` (on one rank the signal flag is looked at between blocks).
The MPI calls happen at the same steps on every rank, so blocks that end at
different steps on different ranks (a progress line, rank 0's per-pair block) only
wait for each other inside the next call. The kernel releases the GIL.

It applies (:meth:`StepBlock.for_run`) when every body is linear, no surface
load acts, and at most one contact set runs by the fused call, with or without a
rigid body (whose force functions are evaluated in Python for the block's steps
first). Otherwise, and where PETSc or MPI cannot be reached by address, the
Python step runs (``Settings(compiled_steps=False)`` asks for it).

The phase times of a compiled step: f_int the predictor (with an output step's
copy of u^n, v^n and its strain energy), contact_solve the whole contact step
(detection and update are inside it: 0), history the rows, output the output
step's sums and the frame.
"""
from __future__ import annotations

import math
import time

import numpy as np
from numba import njit

from . import native
from .contact.fused import contact_step
from .cell_fields import STRESS_NAMES, isotropic_stress_range, track_peaks
from .energy import (STABLE, _output_sums, copy_state, energy_verdict, half_dot,
                     strain_from_prediction)
from .contact.interface import ContactSet
from .contact.state import (B, FORCE, LEDGER, LO, MISC_SIZE, N_CONS, RIGID_MASS, RIGID_WORK,
                            STATS, U, U_NOW, UP, V, V_NOW, WAVES, _committed_gap, _pack)
from .output import _pair_row
from .probes import _record_at
from .timers import _book
from .xdmf import _point_vectors

MAX_STEPS = 256  # a block's steps at most (the signal flag is looked at between blocks)
BLOCK_SECONDS = 0.05  # ... and about this long at most, by the steps' time so far (s)
# where a step's phase times go in simulation.PHASES (detection, update: 0, inside solve)
F_INT, SOLVE, HISTORY, OUTPUT = 0, 2, 4, 5

# ints (int64) of a block: in
I_N, I_STOP, I_STEP, I_NEXT_HISTORY, I_EVERY, I_ROW, I_CAPACITY, I_WIDTH, I_OFFSET = range(9)
# ... flags: contact, rigid, penalty, probes, timed
I_CONTACT, I_RIGID, I_PENALTY, I_PROBES, I_TIMED = range(9, 14)
# ... handles: MatMultAdd, VecAXPY, clock_gettime, A, u, v
I_MULT_ADD, I_AXPY, I_CLOCK, I_A, I_U, I_V = range(14, 20)
# ... the divergence check (next step, every, the last step) and the per-pair rows (on,
# next step, every, rows filled, rows of the block)
I_NEXT_CHECK, I_CHECK_EVERY, I_LAST = range(20, 23)
I_PAIRS, I_NEXT_PAIRS, I_PAIRS_EVERY, I_PAIR_ROW, I_PAIR_CAPACITY = range(23, 28)
# ... hold the last step's phase times (its frame follows in Python: its time is added
# before booking them); the output steps (next, every)
I_HOLD, I_NEXT_OUTPUT, I_OUTPUT_EVERY = 28, 29, 30
# ... and out: the step reached, the PETSc error code, the step whose rigid body ran away,
# the step after which a speed exceeded the runaway limit (-1: none), the last step's
# times held in ``current`` (1) or booked (0), the output steps recorded, the output step
# whose energy failed energy_verdict (-1: none)
I_DONE, I_ERROR, I_RUNAWAY, I_DIVERGED, I_HELD, I_EVENTS, I_UNSOUND = range(31, 38)
# the frames written by the block (on: 1), the fields steps (next, every), the first cell of
# the stress kernel's range, the batch's next row (in and out), the frames of the block
# (out), the batch's row where it goes to the file (the block stops there)
I_FRAMES, I_NEXT_FIELDS, I_FIELDS_EVERY, I_STRESS_FIRST, I_FRAME_ROW, I_N_FRAMES = range(38, 44)
I_FRAME_END = 44
N_INTS = 45
# energy (floats): E_0 of the ledger (J, the initial state's), the growth limit
E_0, E_LIMIT = 0, 1
# the contact track (floats): lowest gap, first and last step in contact (-1: none),
# steps in contact, reversals, the penalty's last number active and last nonzero change
T_LOWEST, T_FIRST, T_LAST, T_STEPS, T_REVERSALS, T_ACTIVE, T_CHANGE = range(7)


@njit(cache=True)
def count_beyond(values, limit) -> int:
    """The number of entries with |value| > limit or NaN (a branch-free pass)."""
    count = 0
    for x in values:
        count += not (abs(x) <= limit)
    return count


@njit(cache=True)
def _next(k, every, last):
    """The step after k of a schedule (schedule.Schedule.due)."""
    return min(k + every, last) if k < last else last + 1


@njit(cache=True, nogil=True)  # (the GIL is free for a writer thread while it runs)
def run_steps(ints, dt, limit, src_u, src_v, recv, F, c_ints, flags, misc, f_ext, f_in, track,
              history, probe_index, pair_clock, pair_state, gap, current, totals, sample, state,
              timespec, mpi, local, send, counts, displs, reduce, u_n, v_n, minus_m_over_dt,
              f_n, mass, body_dofs, body_start, sums_local, sums_total, events, event_steps,
              energy, frame_points, frame_cells, nodes, s_dofs, s_g, lame, no_plastic,
              s_peaks, peak_state, frame_t, frame_step) -> None:
    """Steps ints[I_N] .. ints[I_STOP] - 1 of the loop (integrator step ints[I_STEP] for the
    first), each as the Python step does it: predictor, contact step, track, history row
    (when the step is ints[I_NEXT_HISTORY]: then the next is ``ints[I_EVERY]`` on), phase
    times booked. ``f_ext``, ``f_in``: the rigid body's forces (N) at each step's t^n.
    Stops early after a step that fills the history block (ints[I_ROW] == capacity), a
    PETSc error (ints[I_ERROR]) or a rigid body moving at a non-finite speed
    (ints[I_RUNAWAY] = that step). The divergence check at its steps (a speed of v above
    ``limit``, m/s, or NaN: stops with ints[I_DIVERGED] = that step) and the per-pair
    rows at theirs (a full block of them stops the block too). ints[I_DONE]: the loop's
    next step. Under MPI (``recv`` not empty: the contact set's Allgatherv buffer) the
    contact dofs are packed (``local`` -> ``send``) and gathered (``counts``, ``displs``)
    before the contact step, and the check's count is reduced (``reduce``: 2 doubles),
    by the MPI library itself (``mpi``: native.mpi_addresses), as the Python step does
    through mpi4py; every rank calls them at the same steps.

    An output step (ints[I_NEXT_OUTPUT], then every ints[I_OUTPUT_EVERY]) keeps u^n, v^n
    (``u_n``, ``v_n``; the internal force f_int(u^n) from the prediction into ``f_n``),
    has a history row whether or not one is due, and after it its
    record (simulation.event_record_size's layout) goes to the next row of ``events``
    (its loop step to ``event_steps``; ints[I_EVENTS] rows in all): the output sums
    (energy._output_sums of M = ``mass``, the stored energy 1/2 (u^n + dt v^{n+1/2})' K u^n
    from the prediction, summed over the ranks into ``sums_total`` by MPI_SUM under MPI), the
    contact set's work and activation loss, the rigid body's v^n, v^{n+1} and external
    work, and whether contact was made and nothing is active. The loop makes the energy
    rows from them after the block. If the step's energy fails energy_verdict (E_0 and the
    growth limit in ``energy``) the block stops after it (ints[I_UNSOUND] = that step):
    the loop's row of it raises. A full ``events`` stops the block too.

    With ints[I_FRAMES] (one rank, the stresses of one isotropic kernel), a fields step
    (ints[I_NEXT_FIELDS], then every ints[I_FIELDS_EVERY]) writes the frame of the state
    after it into the writer's batch row ints[I_FRAME_ROW] (``frame_points``,
    ``frame_cells``: xdmf.FieldWriter.batch_rows): the point vectors of ``nodes``, the
    stresses (cell_fields.isotropic_stress_range of ``s_dofs``, ``s_g``, ``lame``, from
    cell ints[I_STRESS_FIRST], their peaks into ``s_peaks``) and the run's peaks
    (``peak_state``, cell_fields.track_peaks), its time and step into ``frame_t``,
    ``frame_step`` (ints[I_N_FRAMES] frames): the loop then hands them to the writer
    (FieldWriter.written). The block stops at row ints[I_FRAME_END], where the batch goes
    to the file (FieldWriter.batch_rows)."""
    n0, stop, step0 = ints[I_N], ints[I_STOP], ints[I_STEP]
    contact, rigid = ints[I_CONTACT] != 0, ints[I_RIGID] != 0
    penalty, probes, timed = ints[I_PENALTY] != 0, ints[I_PROBES] != 0, ints[I_TIMED] != 0
    mult_add, axpy, clock = ints[I_MULT_ADD], ints[I_AXPY], ints[I_CLOCK]
    A, u, v = ints[I_A], ints[I_U], ints[I_V]
    width, offset, capacity = ints[I_WIDTH], ints[I_OFFSET], ints[I_CAPACITY]
    row, next_history, every = ints[I_ROW], ints[I_NEXT_HISTORY], ints[I_EVERY]
    last, next_check, check_every = ints[I_LAST], ints[I_NEXT_CHECK], ints[I_CHECK_EVERY]
    pairs, next_pairs, pairs_every = ints[I_PAIRS] != 0, ints[I_NEXT_PAIRS], ints[I_PAIRS_EVERY]
    pair_row, pair_capacity = ints[I_PAIR_ROW], ints[I_PAIR_CAPACITY]
    next_output, output_every = ints[I_NEXT_OUTPUT], ints[I_OUTPUT_EVERY]
    frames, next_fields, fields_every = ints[I_FRAMES] != 0, ints[I_NEXT_FIELDS], ints[I_FIELDS_EVERY]
    frame_row, frame_end, n_frames = ints[I_FRAME_ROW], ints[I_FRAME_END], 0
    ints[I_ERROR] = 0
    ints[I_RUNAWAY] = -1
    ints[I_DIVERGED] = -1
    ints[I_HELD] = 0
    ints[I_UNSOUND] = -1
    n_events = 0
    body = F.shape[1] - 1
    gathered = recv.size > 0
    parallel = mpi[native.M_ALLREDUCE] != 0
    n = int(misc[N_CONS])
    b, u_now, lo, up = F[B, :n], F[U_NOW], c_ints[LO, :n], c_ints[UP, :n]
    force, active_flags = F[FORCE, :n], flags[0, :n]
    n_sums = sums_local.size
    sums = sums_total if parallel else sums_local
    strain = v_rigid = 0.0
    k = n0
    while k < stop:
        step = step0 + k - n0
        output = k == next_output
        t0 = native.now(clock, timespec)
        if output:  # u^n, v^n (simulation._pre_output)
            copy_state(src_u, src_v, u_n, v_n)
            if rigid:
                v_rigid = F[V_NOW, body]  # committed v^n (F[V] is set by a first step)
        err = native.mat_mult_add(mult_add, A, u, v, v)
        if err == 0:
            err = native.vec_axpy(axpy, u, dt, v)
        if err != 0:
            ints[I_ERROR] = err
            break
        if output:
            strain = strain_from_prediction(u_n, src_v, v_n, minus_m_over_dt, f_n)
        t1 = native.now(clock, timespec)
        t2 = t1
        u_r = v_r = 0.0
        if contact:
            if gathered:  # ContactSet.step under MPI: pack, Allgatherv
                _pack(src_u, src_v, local, send)
                err = native.allgatherv(mpi, send, recv, counts, displs)
                if err != 0:
                    ints[I_ERROR] = err
                    break
            u_r, v_r = contact_step(src_u, src_v, recv, F, c_ints, flags, misc,
                                    f_ext[k - n0], f_in[k - n0])
            t2 = native.now(clock, timespec)
            # the track (checks.ContactTrack.step) of this step k
            active = misc[STATS]
            if misc[STATS + 2] < track[T_LOWEST]:
                track[T_LOWEST] = misc[STATS + 2]
            if active > 0.0:
                if track[T_FIRST] < 0.0:
                    track[T_FIRST] = k
                track[T_LAST] = k
                track[T_STEPS] += 1.0
            if penalty:
                d = active - track[T_ACTIVE]
                if d * track[T_CHANGE] < 0.0:
                    track[T_REVERSALS] += 1.0
                track[T_ACTIVE] = active
                if d != 0.0:
                    track[T_CHANGE] = d
        t3 = native.now(clock, timespec)
        k += 1
        due = k - 1 == next_history
        if due:
            next_history += every
        if due or output:  # the state after the step
            j = row * width
            row += 1
            if probes:
                _record_at(src_u, probe_index, history, j)
            c = j + offset
            history[c] = float(step + 1)
            history[c + 1] = (step + 1) * dt
            history[c + 2] = dt
            if contact:
                history[c + 3] = misc[STATS]
                history[c + 4] = misc[STATS + 1]
                history[c + 5] = misc[STATS + 2]
                if rigid:
                    history[c + 6] = u_r
                    history[c + 7] = v_r
                    c += 2
                history[c + 6] = 0.0
                history[c + 7] = t2 - t1
                history[c + 8] = 0.0
        if pairs and k - 1 == next_pairs:  # outputs.record_pairs of the state after the step
            next_pairs = _next(k - 1, pairs_every, last)
            _committed_gap(b, u_now, lo, up, gap)
            _pair_row(pair_clock, pair_state, pair_row, step + 1, (step + 1) * dt, gap, force,
                      active_flags)
            pair_row += 1
        t4 = native.now(clock, timespec)
        if rigid and not math.isfinite(F[V, body]):
            ints[I_RUNAWAY] = k - 1
            break
        if k - 1 == next_check:
            next_check = _next(k - 1, check_every, last)
            count = count_beyond(src_v, limit)
            if parallel:  # the largest count of the ranks (checks.OwnedVec.exceeds)
                reduce[0] = count
                native.allreduce(mpi, reduce[0:1], reduce[1:2], native.M_MAX)
                count = reduce[1]
            if count > 0:
                ints[I_DIVERGED] = k - 1
                break
        unsound = False
        if output:  # its record (simulation._post_output), the energy's verdict
            next_output = _next(k - 1, output_every, last)
            _output_sums(mass, src_v, body_dofs, body_start, sums_local)
            sums_local[1] = strain + dt * half_dot(src_v, f_n)
            sums_local[3 + body_start.size - 1:] = 0.0  # (no loads: their work is 0)
            if parallel:
                err = native.allreduce(mpi, sums_local, sums_total, native.M_SUM)
                if err != 0:
                    ints[I_ERROR] = err
                    break
            rec = events[n_events]
            event_steps[n_events] = k - 1
            n_events += 1
            rec[:n_sums] = sums
            kinetic, ext, work = sums[0], sums[3 + body_start.size - 1], 0.0
            m = n_sums
            if contact:
                work = misc[LEDGER]
                rec[m] = work
                rec[m + 1] = misc[LEDGER + 1]
                m += 2
                if rigid:
                    rec[m] = v_rigid
                    rec[m + 1] = F[V, body]
                    rec[m + 2] = misc[RIGID_WORK]
                    m += 3
                    kinetic += 0.5 * misc[RIGID_MASS] * F[V, body] * F[V, body]
                    ext += misc[RIGID_WORK]
            rec[m] = 1.0 if track[T_FIRST] >= 0.0 and misc[STATS] <= 0.0 else 0.0
            total = kinetic + sums[1] + 0.0  # (energy.Ledger.record's E_n)
            unsound = energy_verdict(kinetic, sums[1], ext, work, total, energy[E_0],
                                     energy[E_LIMIT]) != STABLE
        if frames and k - 1 == next_fields and not unsound:  # the frame of the state after it
            next_fields = _next(k - 1, fields_every, last)
            isotropic_stress_range(s_dofs, s_g, src_u, lame[0], lame[1], no_plastic,
                                   ints[I_STRESS_FIRST], frame_cells[frame_row], s_peaks)
            _point_vectors(src_u, src_v, nodes, frame_points[frame_row])
            t_frame = (step + 1) * dt
            track_peaks(s_peaks, t_frame, peak_state)
            frame_t[n_frames] = t_frame
            frame_step[n_frames] = step + 1
            n_frames += 1
            frame_row += 1
        t5 = native.now(clock, timespec)
        if timed:
            current[F_INT] = t1 - t0
            current[SOLVE] = t2 - t1
            current[HISTORY] = t4 - t3
            current[OUTPUT] = t5 - t4
        if k == stop and ints[I_HOLD] != 0:  # (with or without timers: the caller's output)
            ints[I_HELD] = 1
        elif timed:
            _book(current, totals, sample, state)
        if unsound:
            ints[I_UNSOUND] = k - 1
            break
        if (row == capacity or pair_row == pair_capacity or n_events == events.shape[0]
                or (frames and frame_row == frame_end)):
            break
    ints[I_DONE] = k
    ints[I_ROW] = row
    ints[I_NEXT_HISTORY] = next_history
    ints[I_NEXT_CHECK] = next_check
    ints[I_NEXT_PAIRS] = next_pairs
    ints[I_NEXT_OUTPUT] = next_output
    ints[I_PAIR_ROW] = pair_row
    ints[I_EVENTS] = n_events
    ints[I_NEXT_FIELDS] = next_fields
    ints[I_FRAME_ROW] = frame_row
    ints[I_N_FRAMES] = n_frames




class StepBlock:
    """The compiled steps of one run (see the module docstring); build it by :meth:`for_run`.

    ``schedules``: the loop's (output, check, pairs) schedules (schedule.Schedule:
    their ``next`` advances with the block's steps); ``pairs``: the contact set's
    per-pair table (output.PairHistory) or None; ``limit``: the runaway speed (m/s);
    ``last``: the run's last step; ``track``: the contact track's counters (layout T_*);
    ``sums``: the run's energy.OutputSums; ``record``: the floats of an output step's
    record; ``growth_limit``: Settings.energy_growth_limit; ``frames``: (the field writer,
    its CellStress, the fields steps' schedule, the run's peaks: cell_fields.track_peaks'
    state) where the blocks write the frames, else None."""

    def __init__(self, integ, contact, table, times, probes, every: int, addresses,
                 schedules, pairs, limit: float, last: int, track: np.ndarray,
                 mpi: np.ndarray | None, state_n: tuple, sums, record: int,
                 growth_limit: float, frames: tuple | None = None):
        self.integ, self.contact, self.table, self.times = integ, contact, table, times
        self.rigid = contact.rigid if contact is not None else None
        self.output_at, self.check_at, self.pairs_at = schedules
        self.writer = self.fields_at = None
        self.pairs = pairs
        ints = np.zeros(N_INTS, dtype=np.int64)
        ints[I_MULT_ADD:I_CLOCK + 1] = addresses
        ints[I_A], ints[I_U], ints[I_V] = integ.A.handle, integ.u_vec.handle, integ._v.handle
        ints[I_EVERY], ints[I_WIDTH], ints[I_CAPACITY] = every, table.width, table.capacity
        ints[I_OFFSET] = probes.n_raw if probes is not None else 0
        ints[I_PROBES] = probes is not None
        ints[I_TIMED] = times is not None
        ints[I_CONTACT] = contact is not None
        ints[I_RIGID] = self.rigid is not None
        ints[I_PENALTY] = contact is not None and contact.method.name == "penalty"
        ints[I_CHECK_EVERY], ints[I_LAST] = self.check_at.every, last
        ints[I_PAIRS] = pairs is not None
        ints[I_PAIRS_EVERY] = self.pairs_at.every
        ints[I_OUTPUT_EVERY] = self.output_at.every
        self.ints = ints
        self._f_ext, self._f_in = np.zeros(MAX_STEPS), np.zeros(MAX_STEPS)
        self.max_steps = 8  # the first block's, then by the rate (run)
        if contact is not None:
            call = contact._fused_call
        else:  # arrays of the same types (one compiled version serves both)
            call = (integ.u_owned, integ.v_owned, np.empty(0), np.zeros((18, 1)),
                    np.zeros((11, 1), dtype=np.int32), np.zeros((2, 1), dtype=np.bool_),
                    np.zeros(MISC_SIZE))
        index = probes._index if probes is not None else np.empty(0, dtype=np.int64)
        if pairs is not None:
            ints[I_PAIR_CAPACITY] = pairs.capacity
            pair_arrays = (*pairs.block(), np.empty(contact.n))
        else:  # (never filled)
            ints[I_PAIR_CAPACITY] = -1
            pair_arrays = (np.zeros((1, 2)), np.zeros((1, 3, 1)), np.zeros(1))
        self.track = track  # checks.ContactTrack.state: the block updates it too
        if times is not None:
            clocks = times.booking()
        else:
            clocks = (np.zeros(6), np.zeros(6), np.zeros((2, 6)), np.array([0, 0, 1]))
        if mpi is not None:  # the contact set's pack and Allgatherv, the check's reduction
            comm = (np.zeros(0, dtype=np.int32), np.zeros(0), np.zeros(0, dtype=np.int32),
                    np.zeros(0, dtype=np.int32))
            if contact is not None:
                comm = (contact._local, contact._send, contact._counts.astype(np.int32),
                        contact._displs.astype(np.int32))
            comm = (mpi, *comm, np.zeros(2))
        else:  # (never used)
            comm = (np.zeros(7, dtype=np.int64), np.zeros(0, dtype=np.int32), np.zeros(0),
                    np.zeros(0, dtype=np.int32), np.zeros(0, dtype=np.int32), np.zeros(2))
        # the records of the block's output steps (at most one a step) and their loop steps
        self.events = np.zeros((MAX_STEPS, record))
        self.event_steps = np.zeros(MAX_STEPS, dtype=np.int64)
        self._event_views = [memoryview(r) for r in self.events]
        self.energy = np.array([math.nan, growth_limit])  # layout E_*
        if frames is not None:  # the writer's batch, the stress kernel's arrays
            self.writer, stress, self.fields_at, peak_state = frames
            _, s_dofs, s_g, _, lame, (first, _) = stress._kernel[0]
            points, cells, _, _ = self.writer.batch_rows()
            frame_arrays = (points, cells, self.writer._nodes, s_dofs, s_g, np.array(lame),
                            stress._no_plastic, stress.peaks, peak_state)
            ints[I_FRAMES], ints[I_FIELDS_EVERY], ints[I_STRESS_FIRST] = 1, self.fields_at.every, first
            n_frames = points.shape[0]
        else:  # (never used)
            frame_arrays = (np.zeros((1, 2, 1, 3)), np.zeros((1, 5, 1)), np.zeros(1, dtype=np.int64),
                            np.zeros((1, 3), dtype=np.uint32), np.zeros((1, 5)), np.zeros(2),
                            np.zeros((0, 4)), np.zeros(3), np.zeros(7))
            n_frames = 1
        self.frame_t = np.zeros(n_frames)
        self.frame_step = np.zeros(n_frames, dtype=np.int64)
        head = (ints, integ.dt, float(limit), *call, self._f_ext, self._f_in, self.track,
                table.flat, index, *pair_arrays, *clocks, np.zeros(2, dtype=np.int64),
                *comm, *state_n, sums.mass, sums._dofs, sums._start, sums._local,
                sums._total, self.events, self.event_steps, self.energy)
        self._batch = len(head)  # where the batch's two arrays are in _args
        self._args = (*head, *frame_arrays, self.frame_t, self.frame_step)
        from .jit_watch import direct

        self._run = direct(run_steps, *self._args)

    @classmethod
    def for_run(cls, sim, table, times, probes, schedules, pair_tables, limit: float,
                last: int, track: np.ndarray, state_n: tuple, writer=None,
                fields_at=None) -> "StepBlock | None":
        """The block of ``sim``'s run, or None where the Python step must run. ``state_n``:
        (u^n, v^n buffers of an output step, -M/dt, the f_int(u^n) buffer) as
        simulation.run keeps them;
        ``writer``: the run's FieldWriter (or None), ``fields_at`` its schedule: the
        blocks write the frames on one rank when the cell fields are the stresses of one
        isotropic kernel (else the loop writes them)."""
        integ = sim.integrator
        if integ.A is None or integ.nonlinear or integ.loads or len(sim.contacts) > 1:
            return None
        contact = sim.contacts[0] if sim.contacts else None
        if contact is not None and (type(contact) is not ContactSet or contact._fused is None
                                    or (contact.rigid is not None and (contact.rigid.fixed
                                                                       or contact.rigid.slides))
                                    or contact.friction is not None):
            return None  # (a fixed or sliding part, a wall, friction's tangential pass: the Python step)
        if probes is not None and probes._plastic:
            return None
        addresses = native.addresses()
        mpi = native.mpi_addresses(sim.comm) if sim.comm.size > 1 else None
        if addresses is None or (sim.comm.size > 1 and mpi is None):
            return None
        pairs = pair_tables[0][1] if pair_tables else None
        frames = None
        if (writer is not None and sim.comm.size == 1
                and writer.cell_fields == list(STRESS_NAMES) and not sim._cell_field_providers
                and sim._cell_stress._single):
            frames = (writer, sim._cell_stress, fields_at, sim._peaks)
        return cls(integ, contact, table, times, probes, sim.settings.history_every, addresses,
                   schedules, pairs, limit, last, track, mpi, state_n, sim._output_sums,
                   sim.event_record_size(), sim.settings.energy_growth_limit, frames)

    def run(self, n: int, stop: int, next_history: int, hold: bool = False,
            E0: float = 0.0) -> tuple[int, int]:
        """Run the loop's steps n .. stop - 1 (or fewer: see :func:`run_steps`); returns (the
        loop's next step, the next history step). Raises RuntimeError on a PETSc or MPI
        error; a runaway is left for the caller in :attr:`runaway` and :attr:`diverged`
        (the step after which it was seen, or -1). ``hold``: if step stop - 1 is reached,
        its phase times are not booked: :meth:`book_held` books them with the time of
        what the caller does after it (:attr:`held`). The output steps' records are then
        :meth:`event` 0 .. :attr:`n_events` - 1, for the energy rows; ``E0``: the
        ledger's E_0 (J), the initial state's energy."""
        ints, integ, rigid = self.ints, self.integ, self.rigid
        if stop > n + self.max_steps:
            stop, hold = n + self.max_steps, False
        ints[I_HOLD] = hold
        self.energy[E_0] = E0
        if rigid is not None:  # its force functions at each step's t^n, in Python
            dt, step0 = integ.dt, integ.n
            f_ext, f_in, incident = self._f_ext, self._f_in, rigid.incident
            for i in range(stop - n):
                t = (step0 + i) * dt
                f_ext[i] = float(rigid.force(t))
                if incident is not None:
                    f_in[i] = float(incident(t))
        ints[I_N], ints[I_STOP], ints[I_STEP] = n, stop, integ.n
        ints[I_NEXT_HISTORY], ints[I_ROW] = next_history, self.table.room()
        ints[I_NEXT_CHECK], ints[I_NEXT_PAIRS] = self.check_at.next, self.pairs_at.next
        ints[I_NEXT_OUTPUT] = self.output_at.next
        if self.writer is not None:  # the batch's arrays (the writer may change them)
            points, cells, ints[I_FRAME_ROW], ints[I_FRAME_END] = self.writer.batch_rows()
            b = self._batch
            if points is not self._args[b] or cells is not self._args[b + 1]:
                self._args = (*self._args[:b], points, cells, *self._args[b + 2:])
            ints[I_NEXT_FIELDS] = self.fields_at.next
        if self.pairs is not None:
            ints[I_PAIR_ROW] = self.pairs.room()
        t = time.perf_counter()
        self._run(*self._args)
        done = int(ints[I_DONE])
        if done == n and not (ints[I_ERROR] or ints[I_RUNAWAY] >= 0 or ints[I_DIVERGED] >= 0):
            raise RuntimeError(f"a block of steps from step {n} to {stop} made no step")
        if done > n:  # a block of at most BLOCK_SECONDS at the rate so far
            per_step = (time.perf_counter() - t) / (done - n)
            self.max_steps = max(1, min(MAX_STEPS, int(BLOCK_SECONDS / max(per_step, 1e-9))))
        integ.n += done - n
        self.table.filled(int(ints[I_ROW]))
        self.check_at.next, self.pairs_at.next = int(ints[I_NEXT_CHECK]), int(ints[I_NEXT_PAIRS])
        self.output_at.next = int(ints[I_NEXT_OUTPUT])
        if self.writer is not None:
            self.fields_at.next = int(ints[I_NEXT_FIELDS])
        if self.pairs is not None:
            self.pairs.filled(int(ints[I_PAIR_ROW]))
        if rigid is not None and done > n:
            c = self.contact
            body = c._floats.shape[1] - 1
            rigid.u, rigid.v = float(c._floats[U, body]), float(c._floats[V, body])
            if rigid.impedance > 0.0:
                misc = c._misc
                rigid.wave_incident, rigid.wave_reflected, rigid.wave_delivered = (
                    float(misc[WAVES]), float(misc[WAVES + 1]), float(misc[WAVES + 2]))
        if ints[I_ERROR]:
            raise RuntimeError(f"PETSc or MPI error {int(ints[I_ERROR])} in the step "
                               f"{integ.n} -> {integ.n + 1}")
        return done, int(ints[I_NEXT_HISTORY])

    @property
    def n_events(self) -> int:
        """The output steps of the last block."""
        return int(self.ints[I_EVENTS])

    def event(self, i: int) -> tuple[memoryview, int]:
        """(record, loop step) of the last block's output step i."""
        return self._event_views[i], int(self.event_steps[i])

    @property
    def n_frames(self) -> int:
        """The frames the last block wrote into the writer's batch."""
        return int(self.ints[I_N_FRAMES])

    def frame(self, i: int) -> tuple[float, int]:
        """(time in s, step) of the last block's frame i."""
        return float(self.frame_t[i]), int(self.frame_step[i])

    @property
    def held(self) -> bool:
        """Did the last block reach its last step with ``hold`` (its times not booked)?"""
        return self.ints[I_HELD] != 0

    def book_held(self, output: float) -> None:
        """Book the held step's phase times with ``output`` (s) added to its output phase."""
        if self.times is not None:
            self.times.current[OUTPUT] += output
            self.times.record()

    @property
    def runaway(self) -> int:
        """The loop step after which the rigid body moved at a non-finite speed, or -1."""
        return int(self.ints[I_RUNAWAY])

    @property
    def diverged(self) -> int:
        """The loop step after which a speed exceeded the runaway limit (or was NaN), or -1."""
        return int(self.ints[I_DIVERGED])
