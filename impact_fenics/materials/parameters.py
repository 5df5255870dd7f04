"""A material's parameters, stated once: name, unit, meaning, admissible range, scene default.

Each material class lists its own parameters (besides the elastic constants E, nu
and density of :class:`.elastic.IsotropicConstants`) in ``parameters``; its
constructor checks them by :func:`check`, and a scene file takes them as the keys
of ``[materials.NAME]`` with the same names, units and ranges
(:mod:`impact_fenics.scene_keys` builds its key table from them). Conditions that
tie two parameters together (psi <= phi, t_melt > t_room) stay in the class.

A parameter's ``scene_default``: :data:`REQUIRED` (a scene must give it), a value
(the one that switches its effect off: no hardening, no viscosity), or
:data:`CLASS_DEFAULT` (the class computes it, ``default_text`` says how).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from ..errors import require

REQUIRED = "required"            # the scene key table's word for a key that must be given
CLASS_DEFAULT = "class default"  # absent from the scene: the class's own default


@dataclass(frozen=True)
class Parameter:
    """One parameter of a material: ``low``/``high`` bound its value (None: unbounded),
    ``low_open``/``high_open`` exclude the bound itself."""

    name: str
    unit: str  # SI; "-" dimensionless
    what: str  # its meaning, one line
    low: float | None = None
    high: float | None = None
    low_open: bool = False
    high_open: bool = False
    scene_default: Any = REQUIRED
    default_text: str = ""  # with CLASS_DEFAULT: the default in words
    choices: tuple[str, ...] = ()  # a word parameter: its admissible words (no range then)

    def admits(self, value: Any) -> bool:
        """Whether ``value`` is one of the choices (a word parameter), or a finite number
        within the range."""
        if self.choices:
            return isinstance(value, str) and value in self.choices
        if isinstance(value, str) or not math.isfinite(value):
            return False
        if self.low is not None and (value < self.low or (self.low_open and value == self.low)):
            return False
        if self.high is not None and (value > self.high or (self.high_open and value == self.high)):
            return False
        return True

    @property
    def range_text(self) -> str:
        """The range as a condition: '> 0', '>= 0', 'in [0, 90)', 'one of "a", "b"' ('' when
        unbounded)."""
        if self.choices:
            return "one of " + ", ".join(f'"{c}"' for c in self.choices)
        if self.low is not None and self.high is not None:
            return (f"in {'(' if self.low_open else '['}{self.low:g}, "
                    f"{self.high:g}{')' if self.high_open else ']'}")
        if self.low is not None:
            return f"{'>' if self.low_open else '>='} {self.low:g}"
        if self.high is not None:
            return f"{'<' if self.high_open else '<='} {self.high:g}"
        return ""

    @property
    def described(self) -> str:
        """Meaning, range and unit, as messages and the scene reference quote them."""
        rng = f", {self.range_text}" if self.range_text else ""
        unit = "" if self.unit in ("", "-") else f" ({self.unit})"
        return f"{self.what}{rng}{unit}"


def positive(name: str, unit: str, what: str, **kw) -> Parameter:
    """A parameter > 0."""
    return Parameter(name, unit, what, low=0.0, low_open=True, **kw)


def non_negative(name: str, unit: str, what: str, **kw) -> Parameter:
    """A parameter >= 0."""
    return Parameter(name, unit, what, low=0.0, **kw)


def word(name: str, what: str, choices: tuple[str, ...], default: str) -> Parameter:
    """A parameter that is one of the words ``choices``; ``default`` its scene default."""
    return Parameter(name, "-", what, choices=choices, scene_default=default)


def check(material) -> None:
    """Refuse, in one line, a parameter of ``material`` outside its range (or its words)."""
    for p in type(material).parameters:
        value = getattr(material, p.name)
        if value is None and p.scene_default == CLASS_DEFAULT:
            continue
        unit = "" if p.unit in ("", "-") else f" {p.unit}"
        require((isinstance(value, str) if p.choices else isinstance(value, (int, float)))
                and p.admits(value),
                f"material.{p.name} = {value!r}{unit}: must be {p.range_text} ({p.what})")
