"""J2 plasticity at finite strain with linear isotropic hardening (multiplicative, Hencky).

F = F_e F_p; the elastic response is hyperelastic in the logarithmic elastic
strains, psi_e = mu |dev eps_e|^2 + K/2 (tr eps_e)^2, so the Kirchhoff stress is
tau = lambda tr(eps_e) I + 2 mu eps_e (principal axes of b_e). Von Mises yield in
the Kirchhoff stress, sqrt(3/2 dev tau : dev tau) <= sigma_y0 + H eps_bar_p;
associative flow integrated by the exponential map, which makes the return a
radial return on the principal log strains (Simo 1992, CMAME 99, 61-112; Simo &
Hughes 1998, box 9.1; de Souza Neto et al. 2008, box 14.3):

    Delta eps_bar_p = f_trial / (3 mu + H),   dev tau = (1 - 3 mu Delta eps_bar_p / q_trial) dev tau_trial.

At small strain it is the small-strain radial return of :mod:`.j2`. It is a
stored-energy model (not a hypoelastic rate), so the ledger splits the internal
work into the stored psi_e and the plastic work

    Delta W_p = Delta eps_bar_p (sigma_y(eps_bar_p,n) + sigma_y(eps_bar_p,n+1)) / 2   (J/m^3),

exact for linear hardening. State: [eps_bar_p, a_rr, a_zz, a_rz, a_tt] with
a = C_p^-1 (see :mod:`.hencky`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from numba import njit

from .elastic import IsotropicConstants
from .j2 import LINEAR_HARDENING, YIELD
from .parameters import Parameter, check
from . import hencky

LAMBDA, MU, YIELD_STRESS, HARDENING = range(4)


@njit(cache=True, error_model="numpy", inline="always")
def update(F, state, params, dt, tau, work) -> float:
    """Exponential-map radial return at one point; returns the plastic work increment (J/m^3)."""
    lmbda, mu, sy0, hard = params[LAMBDA], params[MU], params[YIELD_STRESS], params[HARDENING]
    em, g, e3, h, s, dd, det_b = hencky.log_strains(F, state)
    tau_m, tau_d, tau_tt, q2 = hencky.stresses(lmbda, mu, em, g, e3, dd)
    sy = sy0 + hard * state[0]
    if q2 > sy * sy:  # q > sigma_y without the square root at an elastic point
        # 1 / (3 mu + H) and 1 / q^2 alongside the square root (independent of it): then the
        # flow factor k = 1 - 3 mu dg / q, 1 / q = q / q^2, waits on no division after it
        inv_h = 1.0 / (3.0 * mu + hard)
        inv_q2 = 1.0 / q2
        q = math.sqrt(q2)
        f = q - sy
        if f > 0.0:
            dg = f * inv_h
            k = 1.0 - 3.0 * mu * dg * (q * inv_q2)
            em, g, e3, tau_m, tau_d, tau_tt = hencky.scale_deviator(mu, k, em, g, e3, tau_m,
                                                                    tau_d, tau_tt)
            wp = dg * (sy + 0.5 * hard * dg)
            state[0] += dg
            hencky.set_returned_state(F, state, em, g, dd, det_b, h, s)
            hencky.set_kirchhoff(tau, tau_m, tau_d, tau_tt, h, s)
            return wp
    # (tau written in each branch: written once after them, where they join, it keeps numba
    # from pruning the reference counts of the kernel's views of state and tau, a call and
    # an atomic operation each, six a point)
    hencky.set_kirchhoff(tau, tau_m, tau_d, tau_tt, h, s)
    return 0.0


@dataclass(frozen=True)
class FiniteJ2(IsotropicConstants):
    """E, yield_stress (sigma_y0), hardening (H >= 0) in Pa; nu (-); density (kg/m^3,
    reference). Rate-independent."""

    E: float = 117e9
    nu: float = 0.35
    density: float = 8930.0
    yield_stress: float = 400e6
    hardening: float = 100e6
    linear: bool = False
    finite: bool = True
    n_state: int = 5
    strain: ClassVar[str] = "finite"
    parameters: ClassVar[tuple[Parameter, ...]] = (YIELD, LINEAR_HARDENING)  # those of J2

    def __post_init__(self) -> None:
        self.check_elastic()
        check(self)

    def params(self) -> np.ndarray:
        return np.array([self.lmbda, self.mu, self.yield_stress, self.hardening])

    def initial_state(self) -> np.ndarray:
        """[eps_bar_p, a_rr, a_zz, a_rz, a_tt] = [0, 1, 1, 0, 1] (a = C_p^-1 = I)."""
        return np.array([0.0, 1.0, 1.0, 0.0, 1.0])

    update = staticmethod(update)
    energy = staticmethod(hencky.stored_energy)

