"""A thread that writes output while the loop's thread steps.

The compiled blocks of steps (:mod:`.step_block`) release the GIL, so a second thread
can put a run's output on disk meanwhile: the field writer's batches of frames
(:mod:`.xdmf`, os.pwrite of their bytes) and the history table's blocks
(:mod:`.output`, formatted by a compiled call that releases the GIL too, then
os.write). A :class:`Worker` runs the jobs one writer submits, in order, and hands
each job's outcome back to the submitting thread, so an I/O error (disk full) stops
the run there with its message and is never lost. A job should release the GIL for
most of its time; between its calls it holds the GIL for microseconds only.
"""
from __future__ import annotations

import os
import queue
import threading

from .errors import OutputError


def spare_core(comm) -> bool:
    """Is a core free for a writer thread beside this rank (collective)? Only if this
    process may run on more than one core (Open MPI binds each rank to one) and the
    machine has more cores than the ranks on it: a thread that takes a rank's core costs
    that rank more than the writes it saves (2 ranks on 2 cores, measured: punch 1.28-1.30
    x steps x median step with the writes on the ranks' threads, 1.30-1.42 with threads)."""
    from mpi4py import MPI

    node = comm.Split_type(MPI.COMM_TYPE_SHARED)
    ranks = node.size
    node.Free()
    try:
        own = len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        own = os.cpu_count() or 1
    return bool(comm.allreduce(int(own > 1 and (os.cpu_count() or 1) > ranks), op=MPI.MIN))


class Worker:
    """A daemon thread running submitted jobs (a function and its arguments) in order.
    :meth:`wait` takes their outcomes (None, or the exception that stopped the job) on the
    submitting thread; the first failure is kept in :attr:`error`. It holds no reference
    to its owner."""

    def __init__(self, name: str):
        self.submitted = 0  # jobs submitted, and jobs whose outcome was taken (by wait)
        self.taken = 0
        self.error: BaseException | None = None  # the first failure taken
        self._jobs: queue.SimpleQueue = queue.SimpleQueue()
        self._done: queue.SimpleQueue = queue.SimpleQueue()
        self._thread = threading.Thread(target=self._run, args=(self._jobs, self._done),
                                        name=name, daemon=True)
        self._thread.start()

    @staticmethod
    def _run(jobs: queue.SimpleQueue, done: queue.SimpleQueue) -> None:
        while True:
            job = jobs.get()
            if job is None:
                return
            outcome = None
            try:
                job[0](*job[1:])
            except BaseException as exc:  # (never lost: handed to the submitting thread)
                outcome = exc
            done.put(outcome)

    def submit(self, fn, *args) -> int:
        """Queue the job fn(*args); its number (for :meth:`wait`)."""
        self._jobs.put((fn, *args))
        self.submitted += 1
        return self.submitted

    def wait(self, job: int | None = None, block: bool = True) -> None:
        """Take the outcomes of the jobs up to number ``job`` (all submitted if None),
        waiting for them if ``block`` (else only those already done)."""
        job = self.submitted if job is None else job
        while self.taken < job:
            if not block and self._done.empty():
                return
            outcome = self._done.get()
            self.taken += 1
            if outcome is not None and self.error is None:
                self.error = outcome

    def stop(self) -> None:
        """Take every outcome and end the thread."""
        self.wait()
        self._jobs.put(None)
        self._thread.join()


def pwrite_all(fd: int, data, offset: int) -> None:
    """Write ``data`` (bytes-like) into ``fd`` at byte ``offset`` (os.pwrite, on from where a
    short write stopped)."""
    while data:
        n = os.pwrite(fd, data, offset)
        if n <= 0:
            raise OSError(5, "pwrite wrote nothing")
        data, offset = data[n:], offset + n


def write_all(fd: int, data) -> None:
    """Write ``data`` (bytes-like) at the end of ``fd`` (opened to append; os.write, on from
    where a short write stopped)."""
    while data:
        n = os.write(fd, data)
        if n <= 0:
            raise OSError(5, "write wrote nothing")
        data = data[n:]


def failure(exc: BaseException, name: str, what: str) -> OutputError:
    """A worker's failure ``exc`` as one line: 'writing <what> to <name> failed: ...'."""
    errno = getattr(exc, "errno", None)
    detail = exc.strerror if isinstance(exc, OSError) and exc.strerror else str(exc)
    message = f"writing {what} to {name} failed: {detail}"
    return OutputError(errno, message) if errno else OutputError(message)
