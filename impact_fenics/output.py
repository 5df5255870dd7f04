"""Output: the run directory, CSV tables written in blocks and a JSON summary (fields: xdmf.py).

Files are written into a staging directory ``DIR.partial`` and renamed to DIR
when the run ends, so a directory named DIR always holds a finished (or
cleanly stopped) run; a crash leaves only ``DIR.partial``. The staging
directory is created atomically and is the run's lock; a run removes or
replaces only directories it wrote (see rundir.py). Rank 0 writes the
CSV and JSON files; every rank writes its piece of the fields.
"""
from __future__ import annotations

import json
import os
from typing import Sequence

import numpy as np
from mpi4py import MPI
from numba import njit

from . import float_text
from .errors import output_failed
from .worker import Worker, failure, write_all


def write_json(path: str, data: dict, comm: MPI.Comm) -> None:
    """Write ``data`` as indented, strict JSON from rank 0 (NaN and infinities become null)."""
    if comm.rank == 0:
        try:
            with open(path, "w") as f:
                json.dump(json_ready(data), f, indent=2, sort_keys=True, allow_nan=False)
                f.write("\n")
        except OSError as exc:  # (a full disk: the file named in the one line)
            output_failed(failure(exc, os.path.basename(path), "the summary"))


def json_ready(obj):
    """A JSON-ready copy of ``obj`` with numpy values as Python ones and non-finite floats as None."""
    if isinstance(obj, dict):
        return {k: json_ready(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple, np.ndarray)):
        return [json_ready(v) for v in obj]
    if isinstance(obj, np.generic):
        obj = obj.item()
    if isinstance(obj, float) and not np.isfinite(obj):
        return None
    return obj


class Table:
    """A CSV table filled row by row into a preallocated block, written a block at a time.

    Rows cost no allocation: :meth:`row` hands out a view of the next row of the
    block, or, cheaper for a per-step row, :meth:`next_row` the offset of the next
    row in :attr:`cells` (a flat memoryview of the block: a float stored there costs
    ~40 ns, a numpy element ~100 ns). A full block is appended to the file (rank 0,
    one compiled formatting call per block, :mod:`.float_text`: 17 significant
    digits that read back to the identical float64, ~0.1 us a value against ~0.45
    us for '%.17g') and reused, so memory does not grow with the number of rows.
    :meth:`data` reads the rows back from the file (on every rank); a table without
    a file keeps its rows in memory instead.

    ``summed``: the number of leading raw columns ("raw" block, see ``finish``)
    that each rank fills with its own share (zero elsewhere); they are summed
    over the ranks once per block, so a row never communicates. ``finish(raw)``
    turns a full raw block (rows x raw columns) into the output rows (rows x
    ``columns``); without it the raw columns are the columns.

    ``asynchronous``: rank 0 formats and appends a block on a worker thread
    (:mod:`.worker`; the formatter releases the GIL) while the loop goes on: the
    block's finished rows are copied for it (two copies, each reused once its job is
    done); an I/O error raises at the next flush or at close. For the history
    table, whose blocks fill inside the loop: 256 rows cost ~0.2 ms to format."""

    def __init__(self, path: str | None, columns: Sequence[str], comm: MPI.Comm,
                 capacity: int = 256, raw_columns: int | None = None, summed: int = 0,
                 finish=None, asynchronous: bool = False):
        self.path = path
        self.columns = list(columns)
        self.comm = comm
        n_raw = len(self.columns) if raw_columns is None else raw_columns
        self._buf = np.zeros((max(1, capacity), n_raw))
        self.width = n_raw
        self.flat = self._buf.reshape(-1)  # the block, row after row (a view)
        self.cells = memoryview(self.flat)
        self._n = 0
        self._summed = summed
        self._sum_buf = np.zeros((self._buf.shape[0], summed))
        self._finish = finish
        self._text = None  # the bytes of a formatted block (rank 0 of a table with a file)
        self._kept: list[np.ndarray] = []  # finished blocks, only without a file
        self.n_rows = 0
        self._worker: Worker | None = None
        if path and comm.rank == 0:
            self._text = float_text.buffer_for(self._buf.shape[0], len(self.columns))
            float_text.load()
            with open(path, "w", newline="") as f:
                f.write(",".join(self.columns) + "\n")
            if asynchronous:  # the finished rows' two copies, the job that reads each
                self._copies = [np.empty((self._buf.shape[0], len(self.columns)))
                                for _ in range(2)]
                self._copy_job = [0, 0]
                self._next_copy = 0
                self._fd = os.open(path, os.O_WRONLY | os.O_APPEND)
                self._worker = Worker(f"table-{os.path.basename(path)}")

    def row(self) -> np.ndarray:
        """The next (raw) row to fill (a view)."""
        if self._n == self._buf.shape[0]:
            self.flush()
        r = self._buf[self._n]
        self._n += 1
        return r

    def next_row(self) -> int:
        """Offset in :attr:`cells` of the next (raw) row to fill (``width`` floats)."""
        n = self._n
        if n == self._buf.shape[0]:
            self.flush()
            n = 0
        self._n = n + 1
        return n * self.width

    @property
    def capacity(self) -> int:
        """Rows of the block."""
        return self._buf.shape[0]

    def room(self) -> int:
        """The number of rows filled in the block, after writing it out if it was full:
        for a compiled caller that fills rows itself from there (:meth:`filled` after)."""
        if self._n == self._buf.shape[0]:
            self.flush()
        return self._n

    def filled(self, n: int) -> None:
        """The block holds ``n`` filled rows (a compiled caller filled them)."""
        self._n = n

    def flush(self) -> None:
        """Finish the rows of the block and append them to the file (collective when
        ``summed`` columns exist: call it on every rank)."""
        n = self._n
        if n == 0:
            return
        block = self._buf[:n]
        if self._summed and self.comm.size > 1:
            part = self._sum_buf[:n]
            part[:] = block[:, : self._summed]
            self.comm.Allreduce(MPI.IN_PLACE, part)
            block[:, : self._summed] = part
        out = self._finish(block) if self._finish is not None else block
        if self.path:
            if self._worker is not None:
                k = self._next_copy
                self._take(self._copy_job[k])  # that copy free (and a failure raised)
                rows = self._copies[k][:n]
                rows[:] = out
                self._copy_job[k] = self._worker.submit(self._append, rows)
                self._next_copy = 1 - k
            elif self.comm.rank == 0:
                text = float_text.format_rows(out, self._text)
                try:
                    with open(self.path, "ab") as f:
                        f.write(text)
                except OSError as exc:
                    output_failed(failure(exc, os.path.basename(self.path), "the table"))
        else:
            self._kept.append(np.array(out, dtype=float))
        self.n_rows += n
        self._n = 0
        if self._summed:
            self._buf[:n, : self._summed] = 0.0

    def _append(self, rows: np.ndarray) -> None:
        """The worker's job: ``rows`` formatted and appended to the file."""
        write_all(self._fd, float_text.format_rows(rows, self._text))

    def _take(self, job: int | None = None) -> None:
        """Wait for the worker's jobs up to ``job`` (all if None); raise its failure."""
        worker = self._worker
        worker.wait(job)
        if worker.error is not None:
            exc, worker.error = worker.error, None
            output_failed(failure(exc, os.path.basename(self.path), "the table"))

    def close(self) -> None:
        """Write what is left (collective, like :meth:`flush`); with the worker, wait for it
        and end it (an I/O error of its raises here)."""
        try:
            self.flush()
        finally:
            if self._worker is not None:
                worker, self._worker = self._worker, None
                try:
                    worker.wait()
                    error = worker.error
                finally:
                    worker.stop()
                    os.close(self._fd)
                if error is not None:
                    output_failed(failure(error, os.path.basename(self.path), "the table"))

    def moved(self, directory: str) -> None:
        """The file now lives in ``directory`` (the run directory was published)."""
        if self.path:
            self.path = os.path.join(directory, os.path.basename(self.path))

    def data(self) -> dict[str, np.ndarray]:
        """Every row written so far, by column: read back from the file (after the run, when
        every rank has flushed), or the rows kept in memory by a table without a file."""
        if not self.path:
            self.flush()
        if self._worker is not None:
            self._take()
        if self.path:
            raw = np.loadtxt(self.path, delimiter=",", skiprows=1, ndmin=2)
            raw = raw.reshape(-1, len(self.columns))
        elif self._kept:
            raw = np.concatenate(self._kept)
        else:
            raw = np.zeros((0, len(self.columns)))
        return {c: raw[:, k].copy() for k, c in enumerate(self.columns)}


@njit(cache=True)
def _pair_row(clock, state, k, step, t, gap, force, active) -> None:
    """Row k of the per-pair block: (step, time) and the gaps, forces and active flags."""
    clock[k, 0] = step
    clock[k, 1] = t
    for i in range(gap.size):
        state[k, 0, i] = gap[i]
        state[k, 1, i] = force[i]
        state[k, 2, i] = 1.0 if active[i] else 0.0


@njit(cache=True)
def _pair_row_tangential(state, k, lam_t, slip_state) -> None:
    """Row k's friction fields: the tangential force λ_t (N) and 0 (none), 1 (stick) or 2
    (slip) from a tangential pass's sets (a segment set's slip at -c, 3, is slip)."""
    for i in range(lam_t.size):
        state[k, 3, i] = lam_t[i]
        state[k, 4, i] = float(min(slip_state[i], 2))


class PairHistory:
    """Per-pair gap (m), contact force (N) and active flag at every history row, in HDF5
    (``contact_pairs.h5``: ``clock`` (rows x 2: step, time in s), ``r`` (pairs, m; ``x``
    in plane strain, the name ``axis``) and
    ``state`` (rows x 3 x pairs: gap, force, active as 0/1; with ``tangential``, a set
    with friction, rows x 5 x pairs: then the tangential force λ_t (N) and 0/1/2 for
    none, stick, slip)), written by rank 0 in blocks of rows, two dataset writes a
    block; the contact state is the same on every rank, so nothing is gathered.
    :func:`read_pairs` reads it back."""

    def __init__(self, path: str, r: np.ndarray, comm: MPI.Comm, capacity: int = 256,
                 rows: int = 1024, tangential: bool = False, axis: str = "r"):
        self.path = path
        self.comm = comm
        n = r.size
        self._n = 0
        self._f = None
        self._rows = 0
        if comm.rank == 0:
            import h5py

            self._clock = np.zeros((capacity, 2))
            self._state = np.zeros((capacity, 5 if tangential else 3, n))
            self._alloc = max(rows, capacity)  # rows the datasets hold (grown if exceeded)
            self._f = h5py.File(path, "w")
            self._f.create_dataset(axis, data=r)
            self._ds = [self._f.create_dataset(name, shape=(self._alloc,) + arr.shape[1:],
                                               maxshape=(None,) + arr.shape[1:], dtype=np.float64,
                                               chunks=(min(capacity, 64),) + arr.shape[1:])
                        for name, arr in (("clock", self._clock), ("state", self._state))]

    def prepare(self, gap: np.ndarray, force: np.ndarray, active: np.ndarray,
                lam_t: np.ndarray | None = None, slip_state: np.ndarray | None = None) -> None:
        """Load the compiled row copy for these arrays' types now (set-up), not in a step;
        it writes nothing that a first :meth:`record` does not overwrite."""
        if self._f is not None:
            _pair_row(self._clock, self._state, 0, 0, 0.0, gap, force, active)
            if lam_t is not None and self._state.shape[1] == 5:
                _pair_row_tangential(self._state, 0, lam_t, slip_state)

    def record(self, step: int, t: float, gap: np.ndarray, force: np.ndarray,
               active: np.ndarray, lam_t: np.ndarray | None = None,
               slip_state: np.ndarray | None = None) -> None:
        """One row: the committed gaps (m), forces (N) and active flags of step ``step``;
        with friction its tangential forces (N) and sets (``slip_state``)."""
        if self._f is None:
            return
        _pair_row(self._clock, self._state, self._n, step, t, gap, force, active)
        if lam_t is not None and self._state.shape[1] == 5:
            _pair_row_tangential(self._state, self._n, lam_t, slip_state)
        self._n += 1
        if self._n == self._clock.shape[0]:
            self.flush()

    @property
    def capacity(self) -> int:
        """Rows of the block (0 on ranks that write nothing)."""
        return self._clock.shape[0] if self._f is not None else 0

    def block(self) -> tuple[np.ndarray, np.ndarray]:
        """(clock, state): the block's arrays, for a compiled caller that fills rows itself
        (from :meth:`room` on, then :meth:`filled`); rank 0 only."""
        return self._clock, self._state

    def room(self) -> int:
        """The rows filled in the block (never full: a full block is written at once)."""
        return self._n

    def filled(self, n: int) -> None:
        """The block holds ``n`` rows (a compiled caller filled them); written if full."""
        self._n = n
        if self._f is not None and n == self._clock.shape[0]:
            self.flush()

    def flush(self) -> None:
        if self._f is None or self._n == 0:
            return
        n, start = self._n, self._rows
        if start + n > self._alloc:
            self._alloc = 2 * (start + n)
            for ds in self._ds:
                ds.resize(self._alloc, axis=0)
        for ds, arr in zip(self._ds, (self._clock, self._state)):
            ds[start: start + n] = arr[:n]
        self._rows += n
        self._n = 0

    def moved(self, directory: str) -> None:
        self.path = os.path.join(directory, os.path.basename(self.path))

    def close(self) -> None:
        """Write what is left and trim the datasets to the rows written."""
        self.flush()
        if self._f is not None:
            for ds in self._ds:
                ds.resize(self._rows, axis=0)
            self._f.close()
            self._f = None


def read_pairs(path: str) -> dict[str, np.ndarray]:
    """contact_pairs.h5 as arrays: step, time (rows), r (pairs, m; x in plane strain),
    gap (m), force (N), active (rows x pairs); with friction also tangential_force (N)
    and slip_state (0 none, 1 stick, 2 slip)."""
    import h5py

    with h5py.File(path, "r") as f:
        axis = "x" if "x" in f else "r"
        clock, state, r = f["clock"][...], f["state"][...], f[axis][...]
    out = {"step": clock[:, 0].astype(np.int64), "time": clock[:, 1], axis: r,
           "gap": state[:, 0], "force": state[:, 1], "active": state[:, 2] > 0.5}
    if state.shape[1] == 5:
        out.update(tangential_force=state[:, 3], slip_state=state[:, 4].astype(np.int8))
    return out
