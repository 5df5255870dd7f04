"""J2 (von Mises) plasticity with linear isotropic hardening and optional overstress viscosity.

Small strain, additive split eps = eps_e + eps_p, isotropic elasticity
sigma = C : (eps - eps_p). Yield function and flow rule (associative):

    f(sigma, eps_bar_p) = sigma_eq - sigma_y(eps_bar_p),   sigma_eq = sqrt(3/2 s : s),
    sigma_y(eps_bar_p) = sigma_y0 + H eps_bar_p,            (H = d sigma_y / d eps_bar_p, Pa)
    d eps_p = d eps_bar_p * 3/2 s / sigma_eq,    (so d eps_bar_p = sqrt(2/3 d eps_p : d eps_p))

Rate-independent (eta = 0): f <= 0. Viscoplastic (eta > 0, Pa s): the linear
overstress law of Perzyna type

    d eps_bar_p / dt = <f> / eta       (<x> = max(x, 0)).

Radial return (Simo & Hughes 1998, box 3.1; de Souza Neto et al. 2008, box 7.3):
with the trial state sigma_tr = C : (eps_{n+1} - eps_p,n), f_tr = f(sigma_tr,
eps_bar_p,n), backward Euler on the flow rule gives, in closed form,

    Delta eps_bar_p = f_tr / (3 mu + H + eta / dt),
    s_{n+1} = (1 - 3 mu Delta eps_bar_p / sigma_eq,tr) s_tr,
    eps_p,{n+1} = eps_p,n + Delta eps_bar_p * 3/2 s_tr / sigma_eq,tr,

and then sigma_eq,{n+1} = sigma_y(eps_bar_p,{n+1}) + eta Delta eps_bar_p / dt:
the rate-independent return (eta = 0) is consistent exactly, and the
viscoplastic one tends to it as eta / dt -> 0.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from numba import njit

from .elastic import IsotropicConstants
from .parameters import Parameter, check, non_negative, positive

YIELD = positive("yield_stress", "Pa", "initial yield stress sigma_y0")
LINEAR_HARDENING = non_negative("hardening", "Pa", "hardening modulus H = d sigma_y / d eps_bar_p "
                                "(no softening: it would make the solution mesh-dependent)",
                                scene_default=0.0)

# layout of the parameter array given to :func:`update`
LAMBDA, MU, YIELD_STRESS, HARDENING, VISCOSITY = range(5)


@njit(cache=True, error_model="numpy")
def screen(e0, e1, e2, e3, p0, p1, p2, p3, state, k, params):
    """The trial stress sigma_tr = C : (eps - eps_p,n) (Pa) and whether it is elastic
    (f_tr <= 0), on scalars: (elastic, s0, s1, s2, s3). Arguments as :func:`point`'s.

    The exact test, without a square root: sigma_eq,tr^2 <= sigma_y^2 (sigma_y > 0).
    Small and without calls, so that a cell loop inlines it and runs it at several
    points side by side before it updates any; :func:`point` begins with it."""
    lmbda, mu = params[LAMBDA], params[MU]
    x0, x1, x2, x3 = e0 - p0, e1 - p1, e2 - p2, e3 - p3
    lt = lmbda * (x0 + x1 + x2)
    s0, s1, s2, s3 = lt + 2.0 * mu * x0, lt + 2.0 * mu * x1, lt + 2.0 * mu * x2, 2.0 * mu * x3
    m = (s0 + s1 + s2) / 3.0
    d0, d1, d2 = s0 - m, s1 - m, s2 - m
    q2_tr = 1.5 * (d0 * d0 + d1 * d1 + d2 * d2 + 2.0 * s3 * s3)  # sigma_eq,tr^2
    sy = params[YIELD_STRESS] + params[HARDENING] * state[k]
    return q2_tr <= sy * sy, s0, s1, s2, s3


@njit(cache=True, error_model="numpy")
def point(e0, e1, e2, e3, p0, p1, p2, p3, state, k, params, dt):
    """Radial return for J2 at one point, on scalars (the scalar seam of :mod:`.axisym`).

    (e0..e3) the strain at t_{n+1}, (p0..p3) the plastic strain at t_n; ``state[k]`` the
    equivalent plastic strain eps_bar_p, updated in place. Returns the stress (Pa) and
    the plastic strain at t_{n+1}, eight floats. Units: Pa, Pa s, s.

    Compiled with numpy's error model: no division here is by zero (dt > 0, and
    sigma_eq,tr > sigma_y > 0 where it divides by it), and without a zero test and an
    exception path at each division numba drops the reference counts of the arrays, so
    that a cell loop inlines this function instead of calling it."""
    elastic, s0, s1, s2, s3 = screen(e0, e1, e2, e3, p0, p1, p2, p3, state, k, params)
    if elastic:  # f_tr <= 0: no square root needed
        return s0, s1, s2, s3, p0, p1, p2, p3
    mu, hardening = params[MU], params[HARDENING]
    # the deviator and sigma_eq,tr^2 again, as the screen forms them
    m = (s0 + s1 + s2) / 3.0
    d0, d1, d2 = s0 - m, s1 - m, s2 - m
    q_tr = math.sqrt(1.5 * (d0 * d0 + d1 * d1 + d2 * d2 + 2.0 * s3 * s3))
    f_tr = q_tr - (params[YIELD_STRESS] + hardening * state[k])
    viscous = params[VISCOSITY] / dt if params[VISCOSITY] > 0.0 else 0.0
    dg = f_tr / (3.0 * mu + hardening + viscous)  # Delta eps_bar_p
    kp = 1.5 * dg / q_tr  # Delta eps_p = kp s_tr
    state[k] += dg
    c = 2.0 * mu * kp  # sigma = sigma_tr - 2 mu Delta eps_p
    return (s0 - c * d0, s1 - c * d1, s2 - c * d2, s3 - c * s3,
            p0 + kp * d0, p1 + kp * d1, p2 + kp * d2, p3 + kp * s3)


@njit(cache=True, error_model="numpy")
def update(eps, eps_p, state, params, dt, sigma) -> None:
    """Radial return for J2 at one point (the array seam of :mod:`.axisym`): :func:`point`.

    ``state[0]`` is the equivalent plastic strain eps_bar_p. Units: Pa, Pa s, s."""
    (sigma[0], sigma[1], sigma[2], sigma[3], eps_p[0], eps_p[1], eps_p[2], eps_p[3]) = point(
        eps[0], eps[1], eps[2], eps[3], eps_p[0], eps_p[1], eps_p[2], eps_p[3], state, 0,
        params, dt)


@dataclass(frozen=True)
class J2(IsotropicConstants):
    """Von Mises plasticity, linear isotropic hardening, optional overstress viscosity.

    E, yield_stress (initial sigma_y0), hardening (H = d sigma_y / d eps_bar_p) in Pa;
    nu dimensionless; density kg/m^3; viscosity eta in Pa s (0: rate-independent)."""

    E: float = 200e9
    nu: float = 0.3
    density: float = 7850.0
    yield_stress: float = 250e6
    hardening: float = 0.0
    viscosity: float = 0.0
    linear: bool = False
    n_state: int = 1
    strain: ClassVar[str] = "small"
    # the triangles' cell kernel runs the exact :func:`screen` at a cell's three points
    # before it updates any, and a cell found elastic skips the point loop
    # (:func:`..internal_force.quadrature.kernels`)
    screen_ahead: ClassVar[bool] = True
    parameters: ClassVar[tuple[Parameter, ...]] = (
        YIELD, LINEAR_HARDENING,
        non_negative("viscosity", "Pa s", "overstress viscosity eta, d eps_bar_p / dt = "
                     "<sigma_eq - sigma_y> / eta (0: rate-independent)", scene_default=0.0))

    def __post_init__(self) -> None:
        self.check_elastic()
        check(self)

    def params(self) -> np.ndarray:
        """The float64 parameter array of :func:`update`."""
        p = np.zeros(5)
        p[LAMBDA], p[MU], p[YIELD_STRESS] = self.lmbda, self.mu, self.yield_stress
        p[HARDENING], p[VISCOSITY] = self.hardening, self.viscosity
        return p

    @property
    def update(self):
        """The compiled point update (radial return)."""
        return update

    @property
    def screen(self):
        """The compiled elastic test and trial stress on scalars (exact: :func:`screen`)."""
        return screen

    @property
    def point(self):
        """The compiled point update on scalars (the same radial return)."""
        return point
