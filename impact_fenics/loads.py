"""Loads: time functions (dimensionless or in Pa) and surface loads on tagged facets."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from .bodies import DeformableModel
from .errors import require
from .forms import traction_form
from .operators import assemble_owned


@dataclass(frozen=True)
class Trapezoid:
    """0 -> peak linearly over [0, t_rise], held, back to 0 linearly over [t_fall, t_end].

    Times in s; ``peak`` in the unit of the load (Pa for a pressure)."""

    peak: float
    t_rise: float
    t_fall: float
    t_end: float

    def __post_init__(self) -> None:
        require(0.0 <= self.t_rise <= self.t_fall <= self.t_end,
                "trapezoid pulse: need 0 <= t_rise <= t_fall <= t_end (s)")

    def __call__(self, t: float) -> float:
        if t <= 0.0 or t >= self.t_end:
            return 0.0
        if t < self.t_rise:
            return self.peak * t / self.t_rise
        if t <= self.t_fall:
            return self.peak
        return self.peak * (self.t_end - t) / (self.t_end - self.t_fall)

    def impulse(self) -> float:
        """Integral of the pulse over time (unit * s)."""
        return self.peak * 0.5 * (self.t_fall + self.t_end - self.t_rise)


@dataclass(frozen=True)
class Constant:
    """A load held at ``value`` for all t >= 0."""

    value: float

    def __call__(self, t: float) -> float:
        return self.value


TimeFunction = Callable[[float], float]


class SurfaceLoad:
    """A pressure (or traction) on a facet group, scaled in time by ``history`` (Pa).

    ``dofs`` are the owned dofs it loads and ``force`` (N per Pa) their nodal forces,
    so that the nodal force at time t is ``history(t) * force``.
    """

    def __init__(self, model: DeformableModel, facet_name: str, history: TimeFunction,
                 traction: tuple[float, float] | None = None):
        tag = model.tmesh.facet_tag(facet_name)
        unit = assemble_owned(model, traction_form(model.V, model.tmesh.facet_tags, tag, model.geometry,
                                                   traction))
        self.dofs = np.flatnonzero(unit != 0.0).astype(np.int32)
        self.force = unit[self.dofs].copy()
        self.history = history
        self.name = facet_name
        total = model.comm.allreduce(float(np.abs(self.force).sum()))
        require(total > 0.0, f"load on facet group '{facet_name}' produces no nodal force")
