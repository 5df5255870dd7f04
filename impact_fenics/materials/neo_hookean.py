"""Compressible neo-Hookean hyperelasticity (finite strain).

Stored energy per unit reference volume (J/m^3), Lame constants lambda, mu (Pa):

    psi(F) = mu/2 (tr b - 3 - 2 ln J) + lambda/2 (ln J)^2,      b = F F',  J = det F,

Kirchhoff stress tau = J sigma = 2 (d psi / d b) b (Pa):

    tau = mu (b - I) + lambda ln J I                 (Simo & Hughes 1998, eq. 9.2.7 family;
                                                     Bonet & Wood 2008, eq. 6.28).

At small strain tau -> lambda tr(eps) I + 2 mu eps: linear elasticity with the same
constants. The point update of the finite-strain seam (see :mod:`.hencky`):

    update(F, state, params, dt, tau, work) -> plastic work increment (J/m^3, 0 here)
    energy(F, state, params, work) -> psi (J/m^3)

with F = (F_rr, F_rz, F_zr, F_zz, F_tt) and tau in the (rr, tt, zz, rz) notation.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from numba import njit

from .elastic import IsotropicConstants


@njit(cache=True, error_model="numpy", inline="always")
def update(F, state, params, dt, tau, work) -> float:
    """tau = mu (b - I) + lambda ln J I (Pa); no internal variables."""
    lmbda, mu = params[0], params[1]
    frr, frz, fzr, fzz, ftt = F[0], F[1], F[2], F[3], F[4]
    lnj = math.log((frr * fzz - frz * fzr) * ftt)
    vol = lmbda * lnj
    tau[0] = mu * (frr * frr + frz * frz - 1.0) + vol
    tau[1] = mu * (ftt * ftt - 1.0) + vol
    tau[2] = mu * (fzr * fzr + fzz * fzz - 1.0) + vol
    tau[3] = mu * (frr * fzr + frz * fzz)
    return 0.0


@njit(cache=True)
def energy(F, state, params, work) -> float:
    """psi(F) (J/m^3)."""
    lmbda, mu = params[0], params[1]
    frr, frz, fzr, fzz, ftt = F[0], F[1], F[2], F[3], F[4]
    lnj = math.log((frr * fzz - frz * fzr) * ftt)
    tr_b = frr * frr + frz * frz + fzr * fzr + fzz * fzz + ftt * ftt
    return 0.5 * mu * (tr_b - 3.0 - 2.0 * lnj) + 0.5 * lmbda * lnj * lnj


@dataclass(frozen=True)
class NeoHookean(IsotropicConstants):
    """Compressible neo-Hookean solid: E (Pa), nu (-) the small-strain constants, density
    (kg/m^3) in the reference configuration."""

    E: float = 117e9
    nu: float = 0.35
    density: float = 8930.0
    linear: bool = False
    finite: bool = True
    n_state: int = 0
    strain: ClassVar[str] = "finite"
    parameters: ClassVar[tuple] = ()  # E, nu and density only

    def __post_init__(self) -> None:
        self.check_elastic()

    def params(self) -> np.ndarray:
        return np.array([self.lmbda, self.mu])

    def initial_state(self) -> np.ndarray:
        return np.zeros(1)

    update = staticmethod(update)
    energy = staticmethod(energy)

