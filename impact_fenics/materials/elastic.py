"""Materials: parameters in SI units and the stress as a UFL function of the strain.

A material is anything with ``density`` (kg/m^3), ``stress(eps)`` returning the
3x3 Cauchy stress (Pa) for the 3x3 axisymmetric strain tensor in (r, theta, z)
order, ``linear`` (True when the stress is linear in the strain, so that the
stiffness is assembled once) and ``wave_speed()`` (m/s, the fastest
dilatational speed, used only for progress estimates and sizing, never for the
stability check).

A new material is a new class with a new ``stress``; nothing else changes.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import ufl

from ..errors import require


class IsotropicConstants:
    """Isotropic elastic constants of a material with ``E`` (Pa), ``nu`` and ``density``
    (kg/m^3): their checks, the Lame constants and the dilatational wave speed."""

    E: float
    nu: float
    density: float

    def check_elastic(self) -> None:
        require(self.E > 0, f"material.E = {self.E} Pa: Young's modulus must be > 0")
        require(self.density > 0, f"material.density = {self.density} kg/m^3: must be > 0")
        require(-1.0 < self.nu < 0.5,
                f"material.nu = {self.nu}: Poisson's ratio must lie in (-1, 0.5); "
                "nu >= 0.5 is incompressible and has no explicit stable time step")

    @property
    def mu(self) -> float:
        """Shear modulus (Pa)."""
        return self.E / (2.0 * (1.0 + self.nu))

    @property
    def lmbda(self) -> float:
        """Lame's first parameter (Pa)."""
        return self.E * self.nu / ((1.0 + self.nu) * (1.0 - 2.0 * self.nu))

    @property
    def bulk(self) -> float:
        """Bulk modulus K = lambda + 2 mu / 3 (Pa)."""
        return self.lmbda + 2.0 * self.mu / 3.0

    def wave_speed(self) -> float:
        """Dilatational wave speed c1 = sqrt((lambda + 2 mu)/rho) in m/s."""
        return math.sqrt((self.lmbda + 2.0 * self.mu) / self.density)


@dataclass(frozen=True)
class LinearElastic(IsotropicConstants):
    """Isotropic linear elasticity. E in Pa, nu dimensionless, density in kg/m^3."""

    E: float = 200e9
    nu: float = 0.3
    density: float = 7850.0
    linear: bool = True
    strain: ClassVar[str] = "small"
    parameters: ClassVar[tuple] = ()  # E, nu and density only

    def __post_init__(self) -> None:
        self.check_elastic()

    def stress(self, eps: ufl.core.expr.Expr) -> ufl.core.expr.Expr:
        """Cauchy stress (Pa) of the 3x3 strain tensor."""
        return self.lmbda * ufl.tr(eps) * ufl.Identity(3) + 2.0 * self.mu * eps

    def bar_wave_speed(self) -> float:
        """One-dimensional bar speed c0 = sqrt(E/rho) in m/s."""
        return math.sqrt(self.E / self.density)


STEEL = LinearElastic(E=200e9, nu=0.3, density=7850.0)
