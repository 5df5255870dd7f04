"""When the loop does what: event schedules as step counters, the progress line, the
signal flag.

A schedule is the next step of an event (an energy row, a frame, the per-pair rows, a
divergence check, the ranks' agreement on a signal), so the common step compares one
integer instead of testing n % every. Time in s.
"""
from __future__ import annotations

import sys
import time

from mpi4py import MPI

from . import console, interrupts


class StopFlag:
    """SIGINT/SIGTERM set a flag (interrupts.deferred) while this object lives; the loop
    reads it and the ranks agree on it collectively."""

    def __init__(self):
        interrupts.clear()
        self._guard = interrupts.deferred()
        self._guard.__enter__()
        self._open = True
        self.signum = 0
        self.name = None

    def collective(self, comm: MPI.Comm) -> bool:
        """True on every rank once any rank has caught a signal; all then name the same one."""
        self.signum = interrupts.agree(comm)
        if self.signum:
            self.name = interrupts.name(self.signum)
        return bool(self.signum)

    def restore(self) -> None:
        if self._open:
            self._open = False
            self._guard.__exit__(None, None, None)


# a log redirected to a file (a batch job): a whole line this often (s), none in a short run
LOG_INTERVAL = 30.0


class Progress:
    """Step, simulated time, steps/s and ETA on rank 0: on a terminal one line rewritten
    every 0.5 s; into a file (a batch job's log) a whole line every LOG_INTERVAL s.

    The loop calls :meth:`update` only at step :attr:`due` (which it returns anew): the
    next look is about 0.1 s of steps ahead at the rate so far (5 s into a file); never
    when disabled (due past the last step)."""

    def __init__(self, n_steps: int, dt: float, quiet: bool, t_end: float | None = None,
                 time_of=None):
        """A run whose steps follow a limit gives ``t_end`` (s) and ``time_of()``, the time
        reached (s): its line shows the time of t_end and an ETA by the time left."""
        self.n_steps, self.dt = n_steps, dt
        self.t_end, self.time_of = t_end, time_of
        self.enabled = not quiet
        self.terminal = self.enabled and console.on_terminal()
        self.interval, self.ahead = (0.5, 0.1) if self.terminal else (LOG_INTERVAL, 5.0)
        self.t0 = time.perf_counter()
        self.last = self.t0
        self.due = 1 if self.enabled else n_steps + 1

    def update(self, n: int) -> int:
        """Print the line of step ``n`` if one is due; return the step to look again."""
        if not self.enabled:
            return self.n_steps + 1
        now = time.perf_counter()
        rate = n / max(now - self.t0, 1e-9)
        if self.t_end is not None:  # (the count of steps is not known: the time is)
            self.due = n + max(1, int(self.ahead * rate))
            t = self.time_of()
            last = t >= self.t_end * (1.0 - 1e-12)
            if now - self.last >= self.interval or (last and self.terminal):  # the last always
                self.last = now
                self._line(n, t, rate, now)
            return self.due
        self.due = min(self.n_steps, n + max(1, int(self.ahead * rate)))
        if now - self.last < self.interval and (n < self.n_steps or not self.terminal):
            return self.due
        self.last = now
        eta = (self.n_steps - n) / max(rate, 1e-9)
        self._write(f"step {n}/{self.n_steps}  t = {n * self.dt:.4e} s  "
                    f"{rate:,.0f} steps/s  ETA {eta:,.0f} s")
        return self.due

    def _line(self, n: int, t: float, rate: float, now: float) -> None:
        frac = t / self.t_end
        eta = (now - self.t0) * (1.0 - frac) / max(frac, 1e-12)
        self._write(f"t = {t:.4e} of {self.t_end:.4e} s  step {n}  "
                    f"{rate:,.0f} steps/s  ETA {eta:,.0f} s")

    def _write(self, text: str) -> None:
        """On a terminal the line rewritten in place; into a file a line of its own."""
        sys.stdout.write(f"\r{text}   " if self.terminal else f"progress: {text}\n")
        sys.stdout.flush()

    def done(self, n: int | None = None) -> None:
        """End the line; a run that follows the time shows its last step's (``n``)."""
        if self.terminal:
            if self.t_end is not None and n is not None:
                now = time.perf_counter()
                self._line(n, self.time_of(), n / max(now - self.t0, 1e-9), now)
            sys.stdout.write("\n")
            sys.stdout.flush()


class Schedule:
    """The steps offset, offset + every, offset + 2 every, ... and the last step, as a
    counter: :attr:`next` is the next of them; :meth:`due` says whether step n is one
    (call it at every step that may be one, in order)."""

    __slots__ = ("next", "every", "last")

    def __init__(self, offset: int, every: int, last: int):
        self.every, self.last = every, last
        self.next = min(offset, last)

    @classmethod
    def never(cls, last: int) -> "Schedule":
        sched = cls(0, 1, last)
        sched.next = last + 1
        return sched

    def end_at(self, n: int) -> None:
        """Step n is the last (found as the run goes: a run to t_end under a step that
        follows a limit): due there too, unless the schedule is never due."""
        never = self.next > self.last
        self.last = n
        self.next = n + 1 if never else min(self.next, n)

    def due(self, n: int) -> bool:
        if n != self.next:
            return False
        self.next = min(n + self.every, self.last) if n < self.last else self.last + 1
        return True
