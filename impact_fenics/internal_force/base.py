"""The protocol every internal force of the explicit loop follows.

The step with the velocity at half steps, h_{n+1/2} the step from t^n to t^{n+1} and
h_n = 1/2 (h_{n-1/2} + h_{n+1/2}) (h_{-1/2} := h_{1/2}):

    v^{n+1/2} = v^{n-1/2} + h_n M^-1 (f_ext^n - f_int(u^n)),   u^{n+1} = u^n + h_{n+1/2} v^{n+1/2}.

Each force owns the cells of its bodies (the forces of one run act on disjoint cells)
and adds its share of -h_n M^-1 f_int(u^n) into v. A force keeps the arithmetic of
its own kernel: the linear force's A = -h M^-1 K, the small-strain force's
coef = -h / m, the finite-strain force's h_n (-1 / m) f differ in the last bit and
are not unified (each family's runs stay bit for bit what they were).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np


@dataclass
class Booking:
    """What a force has booked on this rank (J): ``work`` the deformation work
    sum 1/2 (f^{n-1} + f^n) . (u^n - u^{n-1}) (None where the force books none: the
    linear force, whose work is the change of its stored energy), ``stored`` the energy
    its cells hold now, ``dissipated`` the plastic work (0 for an elastic force)."""

    work: float | None
    stored: float
    dissipated: float


class Force(Protocol):
    """An internal force of the loop (see the module docstring)."""

    def set_step(self, h: float, h_avg: float) -> None:
        """Take the step h = h_{n+1/2} (s) and the increment's h_avg = h_n (s) from now on."""

    def velocity_increment(self, u: np.ndarray, v: np.ndarray, h_avg: float) -> None:
        """v += h_avg M^-1 (-f_int(u^n)) on the free owned dofs of its cells (m/s): ``u``
        (m) and ``v`` (m/s) the owned entries the loop steps; u's ghosts current."""

    def stable_dt(self) -> float:
        """This force's own stable step now (s): its cells' limit (collective)."""

    def book(self) -> Booking:
        """Its work, stored energy and dissipation (J, this rank)."""
