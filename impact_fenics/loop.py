"""The half steps of the explicit loop: h_{n+1/2} from the step policy, h_n, and t^n.

With h_{n+1/2} the step from t^n to t^{n+1} and h_n = 1/2 (h_{n-1/2} + h_{n+1/2})
(h_{-1/2} := h_{1/2}):

    v^{n+1/2} = v^{n-1/2} + h_n M^-1 (f_ext^n - f_int(u^n) + f_c^n)
    u^{n+1}   = u^n + h_{n+1/2} v^{n+1/2}

:class:`HalfStep` is the step bookkeeping of that loop: each step it asks the policy
(:mod:`.stepping`) for h_{n+1/2}, forms h_n, and only when the pair (h_{n+1/2}, h_n)
differs from the one its forces and contact sets hold calls their ``set_step``. Under a
constant step the pair never changes (h_n = h exactly): nothing is rescaled, and every
force, load and contact set keeps the arithmetic it was built with, so the loop is the
modified Euler scheme operation for operation. t^n is n h under a constant step (a
compiled block that advances n itself keeps it), else the accumulated sum of the h.
"""
from __future__ import annotations

from typing import Protocol

from .stepping import ConstantStep


class Stepped(Protocol):
    """Anything that holds the step in its constants: forces, loads, contact sets."""

    def set_step(self, h: float, h_avg: float) -> None:
        """Take h = h_{n+1/2} (s) and h_avg = h_n (s) from now on."""


class HalfStep:
    """The loop's steps from ``policy`` (``next(n, t)`` gives h_{n+1/2} in s); ``h`` (s)
    the step everything in ``stepped`` was built for (h_{n+1/2} = h_n = h at set-up).

    After :meth:`begin`: ``h`` = h_{n+1/2} and ``h_avg`` = h_n (s) of the step taken."""

    def __init__(self, policy, h: float, stepped: list[Stepped] | None = None):
        self.policy = policy
        self.constant = isinstance(policy, ConstantStep)
        self.stepped: list[Stepped] = list(stepped or [])
        self.h = self.h_avg = float(h)  # the pair every stepped object holds
        self.h_prev: float | None = None  # h_{n-1/2} (s); None before the first step
        self._t = 0.0  # t^n (s) accumulated (a varying step)
        self.ahead: float | None = None  # h_{n+1/2} (s) taken by peek, before begin

    def add(self, obj: Stepped) -> None:
        """Keep ``obj``'s step current too (a contact set added after set-up)."""
        self.stepped.append(obj)

    def time(self, n: int) -> float:
        """t^n (s): n h under a constant step, else the sum of the steps taken."""
        return n * self.policy.h if self.constant else self._t

    def peek(self, n: int) -> float:
        """h_{n+1/2} (s) of step n, asked of the policy before the step (which then takes
        it): a loop that must know whether the step ends the run."""
        self.ahead = self.policy.next(n, self.time(n))
        return self.ahead

    def begin(self, n: int) -> tuple[float, float]:
        """(h_{n+1/2}, h_n) (s) of step n; ``set_step`` on every stepped object when the
        pair changes."""
        if self.ahead is None:
            h = self.policy.next(n, self.time(n))
        else:
            h, self.ahead = self.ahead, None
        h_avg = h if self.h_prev is None else 0.5 * (self.h_prev + h)
        if h != self.h or h_avg != self.h_avg:
            for obj in self.stepped:
                obj.set_step(h, h_avg)
            self.h, self.h_avg = h, h_avg
        return h, h_avg

    def end(self) -> None:
        """The step taken: t^{n+1} = t^n + h_{n+1/2}, and h_{n+1/2} becomes h_{n-1/2}."""
        self._t += self.h
        self.h_prev = self.h

    def restart(self) -> None:
        """Back to t = 0, before the first step (new initial conditions)."""
        self._t, self.h_prev, self.ahead = 0.0, None, None
