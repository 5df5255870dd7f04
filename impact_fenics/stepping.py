"""The step policy: which step h_{n+1/2} (s) the explicit loop takes next.

Every body shares the step (no subcycling). Two rules:

* :class:`ConstantStep`, scenes without a finite-strain body: h from ``dt`` or from
  ``cfl`` x the smallest body's stable limit (the element bound on 2 / omega_max),
  refused above that limit unless forced; t^n = n h; ``n_steps``, or t_end by
  ceil(t_end / h) steps.
* :class:`StepSequence`, steps given one by one (a run whose step changes where one
  chooses: the varying-step ledger's scenes), each at most the stable limit unless forced.
* :class:`FollowingStep`, a finite-strain body (its cells flatten, so its limit falls):
  every ``interval`` steps the limit is re-estimated from the current cells and
  h = ``safety`` x limit; or ``dt`` is fixed and the run stops (UnstableRunError, exit
  3) once the current limit falls below it. t accumulates; the last step is clipped
  to t_end.

A policy gives ``first()``, the first step h_{1/2} (s) (the one the operators are built
for), and ``next(n, t)``, h_{n+1/2} (s), called once per step in order.

With h_{n-1/2} the step before (h_{-1/2} := h_{1/2}), the velocity increment takes
h_n = 1/2 (h_{n-1/2} + h_{n+1/2}): under a constant step h_n = h.
"""
from __future__ import annotations

import math
from typing import Callable

from .errors import InputError, UnstableRunError, require


def count_steps(dt: float | None, n_steps: int | None, t_end: float | None) -> int:
    """Steps of a constant dt (s): ``n_steps``, or ceil(t_end / dt) (to 1e-9 of a step)."""
    require(dt is not None and dt > 0, f"dt = {dt} s: must be > 0")
    if n_steps is None:
        require(t_end is not None and t_end > 0, "give t_end > 0 (s) or n_steps")
        require(t_end >= dt * (1 - 1e-9), f"t_end = {t_end:.4g} s is shorter "
                                          f"than one step dt = {dt:.4g} s")
        return int(math.ceil(t_end / dt - 1e-9))
    require(n_steps > 0, f"n_steps = {n_steps}: must be > 0")
    return int(n_steps)


class ConstantStep:
    """h = ``dt``, or ``cfl`` x ``limit`` (s, the smallest body's element bound; its body
    ``limiting`` named in the refusal); ``n_steps`` steps, or t_end / h rounded up. A dt
    above the limit is bad input unless ``force``."""

    def __init__(self, dt: float | None, cfl: float | None, limit: float,
                 n_steps: int | None = None, t_end: float | None = None, force: bool = False,
                 limiting: str = ""):
        if cfl is not None:
            require(cfl > 0, f"cfl = {cfl}: must be > 0")
            dt = cfl * limit
        self.n_steps = count_steps(dt, n_steps, t_end)
        if dt > limit and not force:
            raise InputError(f"dt = {dt:.4g} s is above the stable limit {limit:.4g} s "
                             f"(element bound on 2/omega_max, body '{limiting}'); lower dt "
                             "or force it")
        self.h = float(dt)
        self.limit = limit

    def first(self) -> float:
        """h_{1/2} (s): the one step."""
        return self.h

    def next(self, n: int, t: float) -> float:
        """h_{n+1/2} (s): the one step."""
        return self.h


class StepSequence:
    """h_{n+1/2} = ``steps[n]`` (s), n = 0 .. len(steps) - 1: ``n_steps`` steps; a step above
    ``limit`` (s, the smallest body's element bound, its body ``limiting``) is bad input
    unless ``force``. t^n is the sum of the steps taken."""

    def __init__(self, steps, limit: float = math.inf, force: bool = False,
                 limiting: str = ""):
        self.steps = [float(h) for h in steps]
        require(len(self.steps) > 0, "a step sequence needs at least one step")
        bad = [h for h in self.steps if not h > 0.0]
        require(not bad, f"dt = {bad[0] if bad else 0} s in the step sequence: must be > 0")
        self.limit = limit
        self.check(limit, force, limiting)
        self.n_steps = len(self.steps)

    def check(self, limit: float, force: bool = False, limiting: str = "") -> None:
        """Refuse a step above ``limit`` (s) unless ``force`` (bad input, one line)."""
        largest = max(self.steps)
        if largest > limit and not force:
            raise InputError(f"dt = {largest:.4g} s in the step sequence is above the stable "
                             f"limit {limit:.4g} s (element bound on 2/omega_max, body "
                             f"'{limiting}'); lower it or force it")

    def first(self) -> float:
        """h_{1/2} (s)."""
        return self.steps[0]

    def next(self, n: int, t: float) -> float:
        """h_{n+1/2} (s)."""
        return self.steps[n]


class FollowingStep:
    """h follows the limit ``limit()`` (s, collective: the current cells' min L / c):
    re-estimated at every step n with n % ``interval`` == 0 (n = 0 at set-up), h =
    ``safety`` x the limit, or the fixed ``dt`` checked against it; the last step clipped
    to ``t_end`` (s). ``limit`` may be given later by :meth:`bind` (the loop that holds
    the forces binds it); ``others`` (s) is the fixed limit of the bodies whose cells do
    not move (their element bound), so the limit is min(limit(), others).

    After :meth:`next`: ``limit`` the current estimate (s), ``smallest`` the smallest one
    so far, ``h_range`` [smallest, largest] h before clipping (the clipped last step left
    out), ``h_avg`` the increment's step h_n (s), ``renewed`` whether it re-estimated."""

    def __init__(self, limit: Callable[[], float] | None, t_end: float,
                 dt: float | None = None, safety: float = 0.5, interval: int = 10,
                 others: float = math.inf):
        self.t_end, self.dt, self.others = t_end, dt, others
        self.safety, self.interval = safety, interval
        self._estimate: Callable[[], float] | None = None
        if limit is not None:
            self.bind(limit)
        self.h_range = [math.inf, 0.0]
        self.h_prev: float | None = None
        self.h_avg: float | None = None
        self.renewed = False  # whether the last next() re-estimated the limit

    @property
    def bound(self) -> bool:
        """Whether the limit's estimate is given."""
        return self._estimate is not None

    def bind(self, limit: Callable[[], float]) -> None:
        """Estimate the limit (s) with ``limit()`` (collective), now and every interval."""
        self._estimate = limit
        self.limit = self.start = self.smallest = self._limit()

    def _limit(self) -> float:
        return min(self._estimate(), self.others)

    def first(self) -> float:
        """The first step h_{1/2} (s) as :meth:`next` will take it (the set-up's checks)."""
        return min(self.dt if self.dt is not None else self.safety * self.limit, self.t_end)

    def fixed_steps(self) -> list[float]:
        """With a fixed ``dt``: the steps (s) it takes to t_end, the last clipped, t summed
        as the loop sums it (t += h, up to t_end to 1e-12 relative, no sliver step after).
        :meth:`next` returns these steps unless it stops the run first."""
        require(self.dt is not None and self.dt > 0, f"dt = {self.dt} s: a fixed step must be > 0")
        steps, t = [], 0.0
        while t < self.t_end * (1.0 - 1e-12):
            steps.append(min(self.dt, self.t_end - t))
            t += steps[-1]
        return steps

    def next(self, n: int, t: float) -> float:
        """h_{n+1/2} (s) from step n at time t (s); raises UnstableRunError when a fixed dt
        is above the current limit. Call once per step, in order."""
        self.renewed = n % self.interval == 0 and n > 0
        if self.renewed:
            self.limit = self._limit()
            if self.limit < self.smallest:
                self.smallest = self.limit
        if self.dt is None:
            h = self.safety * self.limit
        else:
            h = self.dt
            if h > self.limit:
                raise UnstableRunError(
                    f"run stopped at step {n} (t = {t:.6g} s): the fixed dt = {h:.4g} s is "
                    f"above the current stable limit {self.limit:.4g} s (elements flattened); "
                    "use the adaptive step (dt = None) or a smaller dt")
        if h < self.t_end - t:  # the range of h leaves out the last, clipped step
            self.h_range[0], self.h_range[1] = min(self.h_range[0], h), max(self.h_range[1], h)
        h = min(h, self.t_end - t)
        self.h_avg = h if self.h_prev is None else 0.5 * (self.h_prev + h)
        self.h_prev = h
        return h
