"""The Johnson-Cook return (Newton's iteration on ln x) against the regula falsi it replaced.

Both solve g(x) = q - 3 mu x - sigma_y(eps_bar + x, x / dt, T_n) = 0 for the increment
x = Delta eps_bar_p of a yielding point and stop by the same rule (materials/johnson_cook.py):
the residual |g| <= RESIDUAL_TOL q, or a bracket of the root narrower than BRACKET_TOL q / 3 mu.
As |g'| >= 3 mu, either rule leaves x within max(RESIDUAL_TOL, BRACKET_TOL) q / 3 mu of the
root, so the two x agree within twice that, plus g's own rounding (its terms are at most 2 q:
q, 3 mu x <= q and sigma_y <= q in the bracket; a power, a logarithm and about 16 roundings)
over 3 mu. The previous solver is kept here as the reference. Every check runs on single
points, the same on every rank.
"""
import math

import numpy as np
import pytest

from impact_fenics.materials.johnson_cook import (BRACKET_TOL, CHI, CP, POWER, RESIDUAL_TOL,
                                                  THERMAL, JohnsonCook, RHO, flow_stress,
                                                  return_increment, strain_hardening,
                                                  thermal_factor)
from roundoff import LIBM, rounding


def previous_return_increment(params, mu, q, eps_bar, dt, temperature):
    """The previous solver: Illinois regula falsi in [0, q / 3 mu], bisection safeguard."""
    lo, hi = 0.0, q / (3.0 * mu)
    g_lo = q - flow_stress(params, eps_bar, 0.0, temperature)
    g_hi = -flow_stress(params, eps_bar + hi, hi / dt, temperature)
    if g_hi >= 0.0:
        return hi
    side = 0
    x = lo
    for _ in range(200):
        x = (lo * g_hi - hi * g_lo) / (g_hi - g_lo)
        if not (lo < x < hi):
            x = 0.5 * (lo + hi)
        g = q - 3.0 * mu * x - flow_stress(params, eps_bar + x, x / dt, temperature)
        if g > 0.0:
            lo, g_lo = x, g
            if side == 1:
                g_hi *= 0.5
            side = 1
        else:
            hi, g_hi = x, g
            if side == -1:
                g_lo *= 0.5
            side = -1
        if hi - lo <= BRACKET_TOL * (q / (3.0 * mu)) or abs(g) <= RESIDUAL_TOL * q:
            break
    return x


def root_tolerance(q: float, mu: float) -> float:
    """|x_new - x_previous| allowed (-): see the module docstring."""
    return (2.0 * max(RESIDUAL_TOL, BRACKET_TOL) + 2.0 * rounding(16 + 2 * LIBM, 2.0)) * q / (3.0 * mu)


def new_return(m, q, eps_bar, dt, temperature):
    p = m.params()
    x, hard, visc, _ = return_increment(m.A, m.B, m.n, m.C, m.rate0, m.mu, q, eps_bar, dt,
                                        strain_hardening(p, eps_bar), thermal_factor(p, temperature))
    return x, hard, visc


MATERIALS = {
    "ofhc_copper": JohnsonCook(),
    "n_0.2_infinite_slope": JohnsonCook(n=0.2),
    "rate_independent": JohnsonCook(C=0.0),
    "perfectly_plastic": JohnsonCook(B=0.0),
    "strongly_rate_sensitive": JohnsonCook(C=0.5),
    "rate0_high": JohnsonCook(rate0=1e6),  # the root below the rate threshold dt rate0
    "n_above_1": JohnsonCook(n=1.5),
}
POINTS = [(eps, dt, T, over) for eps in (0.0, 1e-12, 1e-3, 0.3, 2.0) for dt in (1e-9, 1e-7, 1e-5)
          for T in (293.0, 700.0, 1350.0, 1356.0, 1400.0)
          for over in (0.0, 1e-9, 1e-4, 0.01, 0.3, 3.0)]


@pytest.mark.parametrize("name", MATERIALS)
def test_newton_and_regula_falsi_find_the_same_root(name):
    """Over plastic strains from 0 to 2, steps 1 ns-10 us, temperatures up to and beyond
    melting, and trial stresses from 1e-9 to 3 times over the yield stress: the Newton root
    is the regula falsi's within their common stopping tolerance (:func:`root_tolerance`);
    and the flow stress returned with it is sigma_y at that x, bit for bit (the same
    expressions in the same order: the plastic work and the heating book exactly it).
    The trial stresses include four ulp above the yield stress, where the hardening's
    upper bound of the root can be lost in rounding."""
    m = MATERIALS[name]
    p = m.params()
    worst = 0.0
    for eps, dt, T, over in POINTS:
        sy = flow_stress(p, eps, 0.0, T)
        q = sy * (1.0 + over) if sy > 0.0 else 1e8 * (1.0 + over)  # T >= T_melt: sigma_y = 0
        if over == 0.0 and sy > 0.0:  # four ulp above the yield stress
            q = sy
            for _ in range(4):
                q = np.nextafter(q, np.inf)
        x_old = previous_return_increment(p, m.mu, q, eps, dt, T)
        x, hard, visc = new_return(m, q, eps, dt, T)
        assert 0.0 < x <= q / (3.0 * m.mu)
        assert abs(x - x_old) <= root_tolerance(q, m.mu), (eps, dt, T, over, x, x_old)
        assert hard * visc * thermal_factor(p, T) == flow_stress(p, eps + x, x / dt, T)
        worst = max(worst, abs(x - x_old) / root_tolerance(q, m.mu))
    print(f"{name}: largest |x_new - x_old| {worst:.2g} of the tolerance")


def test_the_return_lands_on_the_yield_surface():
    """A point of the Taylor bar's kind (copper, 1e5 1/s over 10 ns, heated to 500 K, at
    eps_bar_p = 0.5): q_trial - 3 mu x equals sigma_y(eps_bar + x, x / dt, T) to the
    residual rule RESIDUAL_TOL q and g's rounding (terms of 2 q, 16 roundings, a power and
    a logarithm), the consistency condition of the backward-Euler return."""
    m = JohnsonCook()
    p = m.params()
    eps, dt, T = 0.5, 1e-8, 500.0
    x_target = 1e5 * dt
    q = 3.0 * m.mu * x_target + flow_stress(p, eps + x_target, 1e5, T)
    x, _, _ = new_return(m, q, eps, dt, T)
    residual = q - 3.0 * m.mu * x - flow_stress(p, eps + x, x / dt, T)
    assert abs(residual) <= RESIDUAL_TOL * q + rounding(16 + 2 * LIBM, 2.0 * q)
    assert x == pytest.approx(x_target, rel=2 * root_tolerance(q, m.mu) / x_target)


def test_update_books_the_trapezoid_of_flow_stress():
    """The point update's plastic work is x (sigma_y(eps_n) + sigma_y(eps_n + x)) / 2 at the
    step's rate x / dt and T_n, and its heating chi times that over rho c_p, with the sigma_y
    of flow_stress bit for bit (the same expressions in the same order). From eps_n = 0 the
    state's new eps_bar_p is x itself, unrounded, so the check is exact."""
    m = JohnsonCook()
    p = m.params()
    state = m.initial_state().copy()
    state[5] = 400.0
    state[THERMAL] = thermal_factor(p, 400.0)  # a state keeps the factor of its T
    dt = 1e-8
    F = np.array([math.exp(-0.01), 0.0, 0.0, math.exp(0.02), math.exp(-0.01)])
    wp = m.update(F, state, p, dt, np.zeros(4), np.zeros(16))
    x = state[0]
    assert x > 0.0
    sy_n = flow_stress(p, 0.0, x / dt, 400.0)
    sy_x = flow_stress(p, x, x / dt, 400.0)
    assert wp == 0.5 * x * (sy_n + sy_x)
    assert state[5] == 400.0 + p[CHI] * wp / (p[RHO] * p[CP])


def test_the_state_keeps_the_power_of_its_plastic_strain():
    """Along a straining path with heating (the update's own returns, elastic and plastic
    steps), the state's B eps_bar_p^n is the power of its eps_bar_p bit for bit: the return
    computes it at eps_bar_p + x rounded as the state's sum is, with the same expression."""
    m = JohnsonCook(n=0.2)
    p = m.params()
    state = m.initial_state().copy()
    tau, work = np.zeros(4), np.zeros(16)
    flowed = 0
    for k in range(1, 200):
        e = 0.004 * math.sin(0.05 * k) + 1e-4 * k  # loading, unloading, reloading
        before = state[0]
        m.update(np.array([math.exp(-e / 2), 0.0, 0.0, math.exp(e), math.exp(-e / 2)]), state, p,
                 1e-8, tau, work)
        flowed += state[0] > before
        assert state[POWER] == strain_hardening(p, state[0])
    assert 20 < flowed < 199 and state[5] > m.t_room
