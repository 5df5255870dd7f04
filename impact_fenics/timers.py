"""Per-phase step timers whose memory does not grow with the number of steps.

Totals (s) are exact sums over every recorded step. Medians come from a
deterministic, evenly spaced sample of at most ``capacity`` steps: every step
is kept until the buffer is full, then every second sample is dropped and
only every second later step is kept (the stride doubles), so the sample
always spans the whole run. A run of 10^9 steps costs the same memory as one
of 10^3.

The sample keeps the steps n with (n + 1) a multiple of the stride, the last step of
each stride, not its first: the loop's periodic events fall on multiples of a power of
two (a history block of 256 rows is written out at the step after its last row), and a
sample of the multiples of a stride >= that period would hold nothing but those events'
steps, so its median would be the events' cost, not a step's.
"""
from __future__ import annotations

from typing import Sequence

import numpy as np
from mpi4py import MPI
from numba import njit


@njit(cache=True)
def _book(current, totals, sample, state) -> None:
    """Book ``current`` (one step's phase times, s) into the totals and the bounded sample,
    then zero it; ``state`` = (steps recorded, samples kept, stride)."""
    for i in range(current.size):
        totals[i] += current[i]
    n, stride = state[0], state[2]
    if (n + 1) % stride == 0:
        m = state[1]
        if m == sample.shape[0]:  # full: keep every second sample, double the stride
            half = m // 2  # (the kept ones, n + 1 a multiple of 2 stride, are the odd ones)
            for j in range(half):
                sample[j, :] = sample[2 * j + 1, :]
            m = half
            stride *= 2
            state[1], state[2] = m, stride
        if (n + 1) % stride == 0:
            sample[m, :] = current
            state[1] = m + 1
    state[0] = n + 1
    for i in range(current.size):
        current[i] = 0.0


@njit(cache=True)
def _record(current, totals, sample, state) -> None:
    """One step (``current``) booked by :func:`_book`: one compiled call, ~0.3 us."""
    _book(current, totals, sample, state)


@njit(cache=True)
def _record_rows(rows, count, totals, sample, state) -> None:
    """The first ``count`` rows of ``rows`` (one step each, in order) booked by :func:`_book`."""
    for r in range(count):
        _book(rows[r], totals, sample, state)


class PhaseTimers:
    """Wall time (s) per phase and step: exact totals, medians over a bounded sample."""

    def __init__(self, phases: Sequence[str], capacity: int = 4096, block: int = 64):
        if capacity < 2 or capacity % 2:
            raise ValueError("capacity must be an even number >= 2")
        self.phases = tuple(phases)
        self.current = np.zeros(len(self.phases))  # fill this step's times here, then record()
        self.totals = np.zeros(len(self.phases))
        self._sample = np.zeros((capacity, len(self.phases)))
        self._state = np.array([0, 0, 1], dtype=np.int64)  # steps, samples kept, stride
        # a block of steps filled through a flat memoryview (a float stored there costs
        # ~40 ns, against ~100 ns into a numpy array and ~0.3 us a compiled call per
        # step): the loop writes step k's phase times at rows[k * len(phases) + i] and
        # books the block with book() once it holds ``block`` steps (and at the end)
        self._rows = np.zeros((block, len(self.phases)))
        self.rows = memoryview(self._rows.reshape(-1))
        self.rows_end = self._rows.size  # rows filled completely at this offset
        for fn, args in ((_record, (np.zeros_like(self.current),)),  # load them now
                         (_record_rows, (np.zeros_like(self._rows), 1))):
            fn(*args, np.zeros_like(self.totals), np.zeros_like(self._sample),
               np.array([1, 0, 1], dtype=np.int64))

    @property
    def n_steps(self) -> int:
        """Number of steps recorded."""
        return int(self._state[0])

    @property
    def _n_sample(self) -> int:
        return int(self._state[1])

    @property
    def _stride(self) -> int:
        return int(self._state[2])

    def record(self) -> None:
        """Book ``current`` as one step's phase times, then zero it."""
        _record(self.current, self.totals, self._sample, self._state)

    def booking(self) -> tuple:
        """(current, totals, sample, state): the arrays that :func:`_book` books a step into,
        for a compiled caller that books its steps itself."""
        return self.current, self.totals, self._sample, self._state

    def book(self, filled: int) -> None:
        """Book the steps written into :attr:`rows` up to offset ``filled`` (whole rows, in
        step order); the rows are zeroed for the next block."""
        count = filled // len(self.phases)
        if count:
            _record_rows(self._rows, count, self.totals, self._sample, self._state)

    def medians(self, comm: MPI.Comm | None = None) -> dict[str, float]:
        """Median time (s) of each phase over the sampled steps (the slowest rank's)."""
        med = (np.median(self._sample[: self._n_sample], axis=0) if self._n_sample
               else np.zeros(len(self.phases)))
        if comm is not None:
            comm.Allreduce(MPI.IN_PLACE, med, op=MPI.MAX)
        return {k: float(v) for k, v in zip(self.phases, med)}

    def median_of_sum(self, phases: Sequence[str] | None = None,
                      comm: MPI.Comm | None = None) -> float:
        """Median over the sampled steps of the summed time (s) of ``phases`` (all if None)."""
        cols = [self.phases.index(p) for p in (phases or self.phases)]
        value = (float(np.median(self._sample[: self._n_sample][:, cols].sum(axis=1)))
                 if self._n_sample else 0.0)
        return comm.allreduce(value, op=MPI.MAX) if comm is not None else value

    def total(self, comm: MPI.Comm | None = None) -> dict[str, float]:
        """Total time (s) of each phase over every recorded step (the slowest rank's)."""
        tot = self.totals.copy()
        if comm is not None:
            comm.Allreduce(MPI.IN_PLACE, tot, op=MPI.MAX)
        return {k: float(v) for k, v in zip(self.phases, tot)}

    def summary(self, comm: MPI.Comm, wall: float) -> dict:
        """The summary entries of a loop of ``wall`` s (the slowest rank's): per phase the
        median and total (s) and the share of the loop, the median step (s) and the loop's
        wall time over steps x median step."""
        medians, totals = self.medians(comm), self.total(comm)
        step = self.median_of_sum(comm=comm)
        mean = np.append(self.totals, wall)
        comm.Allreduce(MPI.IN_PLACE, mean)
        mean /= comm.size
        share = {k: (float(mean[i] / mean[-1]) if mean[-1] > 0 else 0.0)
                 for i, k in enumerate(self.phases)}
        return {"time_per_step_median": medians, "time_per_step_total": totals,
                "step_time_median": step,
                "timing": {"phases": {k: {"total": totals[k], "median": medians[k],
                                          "share": share[k]} for k in totals},
                           "rest_share": max(0.0, 1.0 - sum(share.values())),
                           "loop_over_steps_median": (wall / (self.n_steps * step) if step > 0
                                                      else None),
                           "definition": "total and median: the slowest rank's (s); share: the "
                                         "phase's total over the loop's wall time, both "
                                         "averaged over the ranks; rest: the loop's own Python, "
                                         "progress and signal checks"}}
