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

is monotone decreasing with g(0) > 0 (yielding) and g(q_trial / 3 mu) = -sigma_y <= 0,
so it is solved in that bracket (Illinois regula falsi, bisection safeguard): with
n < 1 the hardening slope is infinite at eps_bar_p = 0, where a Newton step fails.
The plastic work (J/m^3) is booked as Delta W_p = x (sigma_y(eps_bar_p,n) +
sigma_y(eps_bar_p,n+1)) / 2 at the step's rate and T_n (the trapezoid of sigma_y over the
increment, exact for linear hardening), and the heating uses the same sigma_y:
T_{n+1} = T_n + chi Delta W_p / (rho_0 c_p), so the heat in the body is chi times the
plastic work in the ledger, to round-off. State: [eps_bar_p, a_rr, a_zz, a_rz, a_tt, T (K)].
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


@njit(cache=True)
def flow_stress(params, eps_bar, rate, temperature) -> float:
    """sigma_y(eps_bar_p, eps_dot_p, T) (Pa)."""
    hard = params[A_] + (params[B_] * eps_bar ** params[N_] if eps_bar > 0.0 else 0.0)
    ratio = rate / params[RATE0]
    visc = 1.0 + params[C_] * math.log(ratio) if ratio > 1.0 else 1.0
    ts = (temperature - params[T_ROOM]) / (params[T_MELT] - params[T_ROOM])
    ts = min(max(ts, 0.0), 1.0)
    return hard * visc * (1.0 - ts ** params[M_])


@njit(cache=True)
def return_increment(params, mu, q, eps_bar, dt, temperature) -> float:
    """The root x in [0, q / 3 mu] of g(x) = q - 3 mu x - sigma_y(eps_bar + x, x / dt, T)."""
    lo, hi = 0.0, q / (3.0 * mu)
    g_lo = q - flow_stress(params, eps_bar, 0.0, temperature)
    g_hi = -flow_stress(params, eps_bar + hi, hi / dt, temperature)
    if g_hi >= 0.0:
        return hi
    side = 0
    x = lo
    for _ in range(200):
        x = (lo * g_hi - hi * g_lo) / (g_hi - g_lo)  # regula falsi
        if not (lo < x < hi):
            x = 0.5 * (lo + hi)
        g = q - 3.0 * mu * x - flow_stress(params, eps_bar + x, x / dt, temperature)
        if g > 0.0:
            lo, g_lo = x, g
            if side == 1:
                g_hi *= 0.5  # Illinois: halve the stale end
            side = 1
        else:
            hi, g_hi = x, g
            if side == -1:
                g_lo *= 0.5
            side = -1
        if hi - lo <= 1e-15 * (q / (3.0 * mu)) or abs(g) <= 1e-13 * q:
            break
    return x


@njit(cache=True, error_model="numpy", inline="always")
def update(F, state, params, dt, tau, work) -> float:
    """Johnson-Cook return at one point; returns the plastic work increment (J/m^3)."""
    lmbda, mu = params[LAMBDA], params[MU]
    principal = work[8:11]
    hencky.trial_log_strains(F, state, work)
    q = hencky.principal_kirchhoff(lmbda, mu, work, principal)
    temperature = state[TEMPERATURE]
    wp = 0.0
    if q > flow_stress(params, state[0], 0.0, temperature):
        x = return_increment(params, mu, q, state[0], dt, temperature)
        if x > 0.0:
            rate = x / dt
            hencky.radial_return(mu, x, q, principal, work)
            wp = 0.5 * x * (flow_stress(params, state[0], rate, temperature)
                            + flow_stress(params, state[0] + x, rate, temperature))
            state[0] += x
            state[TEMPERATURE] = temperature + params[CHI] * wp / (params[RHO] * params[CP])
            hencky.finish(F, principal, work, state, tau)
            return wp
    hencky.kirchhoff(principal, work, tau)
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
    n_state: int = 6
    temperature_index: int = TEMPERATURE
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
        """[eps_bar_p, C_p^-1 = I, T = t_room]."""
        return np.array([0.0, 1.0, 1.0, 0.0, 1.0, self.t_room])

    update = staticmethod(update)
    energy = staticmethod(hencky.stored_energy)

