"""A prescribed velocity of a rigid part along its axis of motion (z; y in plane strain).

The velocity is a constant V (m/s) or a table of points (t_k, v_k) (s, m/s), linear
between them, v_0 before the first and held after the last. A step from t^n to t^{n+1}
moves the part by the exact integral of v over the step,

    u^{n+1} = u^n + h_{n+1/2} v^{n+1/2},   v^{n+1/2} = (1 / h_{n+1/2}) int_{t^n}^{t^{n+1}} v dt,

so that u^n = int_0^{t^n} v dt at every step to round-off: the part's stroke is the
table's whatever the steps (docs/friction.md 12). A constant V gives v^{n+1/2} = V
exactly.
"""
from __future__ import annotations

import numpy as np

from ..errors import InputError


class PrescribedVelocity:
    """v(t) (m/s): a constant ``value`` or the table ``points`` ((t, v) pairs, s and m/s,
    times strictly increasing and >= 0)."""

    def __init__(self, name: str, value: float | None = None,
                 points: list[tuple[float, float]] | None = None):
        if (value is None) == (points is None):
            raise InputError(f"rigid body '{name}': a prescribed velocity is a constant or a "
                             "table of (t, v) points, one of them")
        if points is None:
            if not np.isfinite(value):
                raise InputError(f"rigid body '{name}': prescribed velocity {value} m/s is "
                                 "not finite")
            points = [(0.0, float(value))]
        t = np.array([p[0] for p in points], dtype=float)
        v = np.array([p[1] for p in points], dtype=float)
        if t.size == 0 or not (np.all(np.isfinite(t)) and np.all(np.isfinite(v))):
            raise InputError(f"rigid body '{name}': the prescribed velocity table needs finite "
                             "(t, v) points, at least one")
        if t[0] < 0.0 or np.any(np.diff(t) <= 0.0):
            raise InputError(f"rigid body '{name}': the prescribed velocity table's times must "
                             "start at t >= 0 s and increase strictly")
        self.t, self.v = t, v
        # the integral of v from 0 to each point (m): the trapezoids of the table, v_0 before
        # its first point
        self._u = np.empty(t.size)
        self._u[0] = t[0] * v[0]
        for k in range(1, t.size):
            self._u[k] = self._u[k - 1] + 0.5 * (t[k] - t[k - 1]) * (v[k - 1] + v[k])
        self.constant = t.size == 1

    def __call__(self, t: float) -> float:
        """v(t) (m/s)."""
        return float(self.v[0]) if self.constant else float(np.interp(t, self.t, self.v))

    def displacement(self, t: float) -> float:
        """int_0^t v dt (m): the trapezoid of the segment holding t, added to the sum of the
        points before it."""
        if self.constant:
            return float(self.v[0]) * t
        k = int(np.searchsorted(self.t, t, side="right")) - 1
        if k < 0:
            return float(self.v[0]) * t
        return float(self._u[k]) + 0.5 * (t - self.t[k]) * (self.v[k] + self(t))

    def mean(self, t0: float, h: float) -> float:
        """v^{n+1/2} = (1/h) int_{t0}^{t0+h} v dt (m/s); V itself for a constant. Within
        one segment of the table (v linear there) the mean of its two ends, so a held
        value is the value itself; across points the difference of the integrals."""
        if self.constant:
            return float(self.v[0])
        t1 = t0 + h
        t = self.t
        if np.searchsorted(t, t0, side="right") == np.searchsorted(t, t1, side="left"):
            return 0.5 * (self(t0) + self(t1))
        return (self.displacement(t1) - self.displacement(t0)) / h


def prescribed_velocity(name: str, velocity: float | list[tuple[float, float]]
                        ) -> PrescribedVelocity:
    """The law of rigid body ``name``: a constant ``velocity`` (m/s) or (t, v) points."""
    if isinstance(velocity, (int, float)):
        return PrescribedVelocity(name, value=float(velocity))
    return PrescribedVelocity(name, points=list(velocity))


def crosshead(name: str, speed: float, t_ramp: float) -> PrescribedVelocity:
    """A testing machine's crosshead for rigid body ``name``: v(t) ramped linearly from 0
    to -``speed`` (m/s, down the axis of motion) over ``t_ramp`` (s) and held after, the
    table [(0, 0), (t_ramp, -speed)]; its stroke is speed (t - t_ramp / 2) past the ramp."""
    if not (speed > 0.0 and t_ramp > 0.0):
        raise InputError(f"rigid body '{name}': a crosshead's speed ({speed} m/s) and ramp "
                         f"({t_ramp} s) must be > 0")
    return PrescribedVelocity(name, points=[(0.0, 0.0), (t_ramp, -speed)])
