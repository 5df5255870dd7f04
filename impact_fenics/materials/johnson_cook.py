"""Johnson-Cook thermo-viscoplasticity at finite strain (multiplicative, Hencky elasticity).

Flow stress (Johnson & Cook 1983), Pa:

    sigma_y = (A + B eps_bar_p^n) (1 + C ln eps_dot*) (1 - T*^m),
    eps_dot* = max(eps_dot_p / eps_dot_0, 1),   T* = (T - T_room) / (T_melt - T_room) clipped to [0, 1],

with adiabatic heating from the plastic work, Delta T = chi sigma_y Delta eps_bar_p / (rho_0 c_p)
(chi the Taylor-Quinney factor, c_p in J/(kg K), rho_0 the reference density).

Kinematics and elasticity as :mod:`.finite_j2` (the exponential-map return on
the principal log strains, :mod:`.hencky`). The return is backward Euler in
eps_bar_p and its rate (eps_dot_p = Delta eps_bar_p / dt) with the temperature
of t_n (staggered, explicit in T): the scalar equation

    g(x) = q_trial - 3 mu x - sigma_y(eps_bar_p,n + x, x / dt, T_n) = 0,   x = Delta eps_bar_p,

is monotone decreasing with g(0) > 0 (yielding), and concave in ln x: it is solved by
Newton's iteration on ln x from an upper bound of the root, which converges from above
without overshooting, also where Newton on x fails (with n < 1 the hardening slope is
infinite at eps_bar_p = 0, and the rate term's is C sigma_y / x), in a few iterations
(:func:`return_increment`; a bracket of the root's signs and bisection guard it).
The plastic work (J/m^3) is booked as Delta W_p = x (sigma_y(eps_bar_p,n) +
sigma_y(eps_bar_p,n+1)) / 2 at the step's rate and T_n (the trapezoid of sigma_y over the
increment, exact for linear hardening), and the heating uses the same sigma_y:
T_{n+1} = T_n + chi Delta W_p / (rho_0 c_p), so the heat in the body is chi times the
plastic work in the ledger, to round-off. State: [eps_bar_p, a_rr, a_zz, a_rz, a_tt, T (K),
B eps_bar_p^n (Pa), 1 - T*^m (-)]: the last two are the hardening of eps_bar_p and the thermal
factor of T, each kept from the return that made its variable (bit for bit the power of the
stored eps_bar_p, and :func:`thermal_factor` of the stored T: the temperature changes only
where a point flows) so that an elastic point computes no power.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from numba import njit

from ..errors import require
from .elastic import IsotropicConstants
from .parameters import Parameter, check, non_negative, positive
from . import hencky

(LAMBDA, MU, A_, B_, N_, C_, RATE0, M_, T_ROOM, T_MELT, CHI, RHO, CP) = range(13)
TEMPERATURE = 5  # index of T in the state
POWER = 6  # index of B eps_bar_p^n in the state
THERMAL = 7  # index of 1 - T*^m in the state


@njit(cache=True, error_model="numpy", inline="always")
def strain_hardening(params, eps_bar) -> float:
    """B eps_bar_p^n (Pa); 0 at eps_bar_p = 0."""
    return params[B_] * eps_bar ** params[N_] if eps_bar > 0.0 else 0.0


@njit(cache=True, error_model="numpy", inline="always")
def rate_factor(params, rate) -> float:
    """1 + C ln eps_dot* (-), eps_dot* = max(rate / rate0, 1)."""
    ratio = rate / params[RATE0]
    return 1.0 + params[C_] * math.log(ratio) if ratio > 1.0 else 1.0


@njit(cache=True, error_model="numpy", inline="always")
def thermal_factor(params, temperature) -> float:
    """1 - T*^m (-), T* = (T - T_room) / (T_melt - T_room) clipped to [0, 1]."""
    ts = (temperature - params[T_ROOM]) / (params[T_MELT] - params[T_ROOM])
    if ts <= 0.0:
        return 1.0  # 1 - 0^m, without the power
    return 1.0 - min(ts, 1.0) ** params[M_]


@njit(cache=True)
def flow_stress(params, eps_bar, rate, temperature) -> float:
    """sigma_y(eps_bar_p, eps_dot_p, T) (Pa)."""
    return ((params[A_] + strain_hardening(params, eps_bar)) * rate_factor(params, rate)
            * thermal_factor(params, temperature))


RESIDUAL_TOL = 1e-13  # |g(x)| <= RESIDUAL_TOL q_trial stops the return (Pa / Pa)
BRACKET_TOL = 1e-15   # or a bracket narrower than BRACKET_TOL q_trial / 3 mu (-)
MAX_ITERATIONS = 100  # bisection alone narrows [0, q / 3 mu] to BRACKET_TOL in 50
LINEAR_STEP = 1e-2    # |ln x step| below which exp(t) is taken as 1 + t (the last steps)


@njit(cache=True, error_model="numpy", inline="always")
def return_increment(a, b, n, c, rate0, mu, q, eps_bar, dt, power_n, thermal
                     ) -> tuple[float, float, float, float]:
    """The root x = Delta eps_bar_p of g(x) = q - 3 mu x - sigma_y(eps_bar + x, x / dt, T_n)
    for a yielding point (g(0) > 0), with the parameters A, B (Pa), n, C (-), rate0 (1/s) and
    mu (Pa); ``power_n`` = B eps_bar^n (Pa) and ``thermal`` = 1 - T*^m (-), constant over the
    return. Scalars only: an array read in the branch that holds this loop keeps numba
    from pruning the reference counts of the kernel's array views (an atomic pair per
    view and point, elastic points too). Returns the last x at which g was evaluated, with its
    A + B e^n (Pa), rate factor (-) (they give its sigma_y) and B e^n (Pa), e = eps_bar + x
    rounded as the state's eps_bar_p + x is.

    Newton's iteration on ln x: as a function of y = ln x, g is decreasing and concave
    (-3 mu e^y is; A + B (eps_bar + e^y)^n is convex and increasing in y for every n > 0, the
    rate factor 1 + C (y - ln(dt rate0)) linear and non-decreasing, with a concave kink at
    rate0), so Newton's steps x <- x exp(g / (x |g'|)) from above the root move down to it
    without overshooting. The start is the smallest of three upper bounds of the root,
    each where g <= 0 from one term of sigma_y alone (f = g(0)):
    f / 3 mu (elasticity), dt rate0 exp(f / (Theta (A + B eps_bar^n) C)) (the rate factor)
    and (eps_bar^n + f / (Theta B))^(1/n) - eps_bar (the hardening). Close to the root
    (|step| < LINEAR_STEP) exp(t) is taken as 1 + t (Newton on x), and a step that leaves
    the bracket [lo, hi] of the iterates' signs of g bisects it. Stops at
    |g| <= RESIDUAL_TOL q or a bracket narrower than BRACKET_TOL q / 3 mu (the regula falsi
    this replaced stopped by the same rule: the two roots are within 2 RESIDUAL_TOL q / 3 mu
    of each other, as |g'| >= 3 mu)."""
    three_mu = 3.0 * mu
    hard_n = a + power_n
    f = q - hard_n * thermal
    lo, hi = 0.0, f / three_mu
    x = hi
    rate_scale = dt * rate0  # x / rate_scale = eps_dot_p / rate0
    viscous = thermal * hard_n * c
    if viscous > 0.0:
        x = min(x, rate_scale * math.exp(f / viscous))
    if b > 0.0 and thermal > 0.0:
        x_hard = (power_n / b + f / (thermal * b)) ** (1.0 / n) - eps_bar
        if 0.0 < x_hard < x:  # (not where f / Theta B is lost in the rounding of the sum)
            x = x_hard
    g_tol, x_tol = RESIDUAL_TOL * q, BRACKET_TOL * (q / three_mu)
    x_done = x
    hard = visc = power = 0.0
    for _ in range(MAX_ITERATIONS):
        x_done = x
        e = eps_bar + x
        power = b * e ** n
        hard = a + power
        ratio = x / dt / rate0  # the rate of flow_stress, eps_dot_p / rate0
        if ratio > 1.0:
            visc = 1.0 + c * math.log(ratio)
            dvisc = c / x
        else:
            visc, dvisc = 1.0, 0.0
        g = q - three_mu * x - hard * visc * thermal
        if g > 0.0:
            lo = x
        else:
            hi = x
        if abs(g) <= g_tol or hi - lo <= x_tol:
            break
        slope = three_mu + thermal * (n * power / e * visc + hard * dvisc)  # -g'(x) > 0
        t = g / (x * slope)  # the Newton step in ln x
        x_next = x + x * t if abs(t) < LINEAR_STEP else x * math.exp(t)
        x = x_next if lo < x_next < hi else 0.5 * (lo + hi)
    return x_done, hard, visc, power


@njit(cache=True, error_model="numpy", inline="always")
def update(F, state, params, dt, tau, work) -> float:
    """Johnson-Cook return at one point; returns the plastic work increment (J/m^3)."""
    # every array read before the branch of the return (see return_increment)
    lmbda, mu, a = params[LAMBDA], params[MU], params[A_]
    b, n, c, rate0 = params[B_], params[N_], params[C_], params[RATE0]
    chi, rho_cp = params[CHI], params[RHO] * params[CP]
    eps_bar, power_n, temperature = state[0], state[POWER], state[TEMPERATURE]
    thermal = state[THERMAL]  # thermal_factor(params, temperature), kept
    em, g, e3, h, s, dd, det_b = hencky.log_strains(F, state)
    tau_m, tau_d, tau_tt, q2 = hencky.stresses(lmbda, mu, em, g, e3, dd)
    wp = 0.0
    hard_n = a + power_n  # A + B eps_bar_p^n
    x = hard = visc = power = q = 0.0
    y0 = hard_n * thermal  # sigma_y at the rate 0 (rate factor 1)
    if q2 > y0 * y0:  # q > y0; no array in this branch
        q = math.sqrt(q2)
        x, hard, visc, power = return_increment(a, b, n, c, rate0, mu, q, eps_bar, dt, power_n,
                                                thermal)
    if x > 0.0:
        em, g, e3, tau_m, tau_d, tau_tt = hencky.flow(mu, x, q, em, g, e3, tau_m, tau_d, tau_tt)
        # the trapezoid of sigma_y over the increment at the step's rate and T_n
        wp = 0.5 * x * (hard_n * visc * thermal + hard * visc * thermal)
        state[0] = eps_bar + x
        state[POWER] = power
        temperature = temperature + chi * wp / rho_cp
        state[TEMPERATURE] = temperature
        state[THERMAL] = thermal_factor(params, temperature)  # T changes only here
        hencky.set_returned_state(F, state, em, g, dd, det_b, h, s)
    hencky.set_kirchhoff(tau, tau_m, tau_d, tau_tt, h, s)
    return wp


@dataclass(frozen=True)
class JohnsonCook(IsotropicConstants):
    """E (Pa), nu (-), density (kg/m^3); A, B (Pa), n (-), C (-), rate0 (1/s), m (-);
    t_room, t_melt (K); chi (-), c_p (J/(kg K)). Defaults: OFHC copper (Johnson & Cook 1983)."""

    E: float = 124e9
    nu: float = 0.34
    density: float = 8960.0
    A: float = 90e6
    B: float = 292e6
    n: float = 0.31
    C: float = 0.025
    rate0: float = 1.0
    m: float = 1.09
    t_room: float = 293.0
    t_melt: float = 1356.0
    chi: float = 0.9
    c_p: float = 383.0
    linear: bool = False
    finite: bool = True
    n_state: int = 8
    temperature_index: int = TEMPERATURE
    # the force kernel runs the update on a copy of the point's state and stress: around
    # the return's loop numba keeps the reference counts of array views (internal_force.finite)
    point_copy: ClassVar[bool] = True
    strain: ClassVar[str] = "finite"
    parameters: ClassVar[tuple[Parameter, ...]] = (
        positive("A", "Pa", "yield stress at zero plastic strain"),
        non_negative("B", "Pa", "strain-hardening coefficient"),
        positive("n", "-", "strain-hardening exponent"),
        non_negative("C", "-", "strain-rate coefficient (0: rate-independent)"),
        positive("rate0", "1/s", "reference plastic strain rate eps_dot_0"),
        positive("m", "-", "thermal-softening exponent"),
        positive("t_room", "K", "room temperature: the initial temperature and T* = 0"),
        positive("t_melt", "K", "melting temperature (T* = 1; above t_room)"),
        Parameter("chi", "-", "Taylor-Quinney factor: the share of the plastic work that "
                  "heats", low=0.0, high=1.0),
        positive("c_p", "J/(kg K)", "specific heat"),
    )

    def __post_init__(self) -> None:
        self.check_elastic()
        check(self)
        require(self.t_melt > self.t_room,
                f"material.t_melt = {self.t_melt} K: must exceed t_room = {self.t_room} K")

    def params(self) -> np.ndarray:
        return np.array([self.lmbda, self.mu, self.A, self.B, self.n, self.C, self.rate0, self.m,
                         self.t_room, self.t_melt, self.chi, self.density, self.c_p])

    def initial_state(self) -> np.ndarray:
        """[eps_bar_p, C_p^-1 = I, T = t_room, B eps_bar_p^n = 0, 1 - T*^m = 1]."""
        return np.array([0.0, 1.0, 1.0, 0.0, 1.0, self.t_room, 0.0, 1.0])

    update = staticmethod(update)
    energy = staticmethod(hencky.stored_energy)

