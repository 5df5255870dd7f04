"""Isotropic elastic constants of the finite-strain materials: Lame parameters and checks.

A material dataclass with fields ``E`` (Pa), ``nu`` (-) and ``density`` (kg/m^3)
inherits ``mu``, ``lmbda``, ``wave_speed()`` and ``check_elastic()`` from
:class:`LameConstants`.
"""
from __future__ import annotations

import math

from ..errors import require


class LameConstants:
    """mu = E / (2 (1 + nu)), lambda = E nu / ((1 + nu)(1 - 2 nu)) (Pa)."""

    E: float
    nu: float
    density: float

    def check_elastic(self) -> None:
        """Refuse E <= 0, density <= 0 or nu outside (-1, 0.5) (one-line InputError)."""
        require(self.E > 0, f"material.E = {self.E} Pa: Young's modulus must be > 0")
        require(self.density > 0, f"material.density = {self.density} kg/m^3: must be > 0")
        require(-1.0 < self.nu < 0.5, f"material.nu = {self.nu}: Poisson's ratio must lie in (-1, 0.5)")

    @property
    def mu(self) -> float:
        """Shear modulus (Pa)."""
        return self.E / (2.0 * (1.0 + self.nu))

    @property
    def lmbda(self) -> float:
        """Lame's first parameter (Pa)."""
        return self.E * self.nu / ((1.0 + self.nu) * (1.0 - 2.0 * self.nu))

    def wave_speed(self) -> float:
        """Small-strain dilatational speed sqrt((lambda + 2 mu) / rho) (m/s), reference density."""
        return math.sqrt((self.lmbda + 2.0 * self.mu) / self.density)
