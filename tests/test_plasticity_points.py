"""J2 return mapping at one point, against closed forms and an independent integration.

Oracles: uniaxial strain and pure shear with linear hardening have closed-form
responses, and along these radial paths the radial return is exact (the flow
direction never turns), so they must match to round-off at any step size; the
consistency condition and the sign of the dissipation are exact properties of
the return; the viscoplastic (linear overstress) response under a constant
strain rate solves a linear ODE in closed form, which backward Euler must
approach at first order in dt, and which tends to the rate-independent
response as the viscosity vanishes.

Round-off (tests/roundoff.py): a point update takes under 128 roundings on the stress
scale (ROUND: the trial stress, its deviator and norm with a sqrt, the return, the
stress); the elastic strain eps - eps_p is a difference of accumulated strains, so the
elastic law carries (3 lambda + 2 mu) max|eps| roundings of its own.
"""
import math

import numpy as np
import pytest

from impact_fenics.materials.axisym import contract, von_mises
from impact_fenics.materials.j2 import J2
from roundoff import rounding

STEEL_J2 = J2(E=200e9, nu=0.3, density=7850.0, yield_stress=250e6, hardening=2e9)
ROUND = rounding(128)  # of the stress scale: a point update (module docstring)


def _path(mat, strains, dt=1e-6):
    """Drive one point through the strain states ``strains`` (n, 4); returns sigma (n, 4),
    eps_bar_p (n,) and the dissipation sigma_{n+1} : d eps_p of each step."""
    eps_p, state, sigma = np.zeros(4), np.zeros(1), np.zeros(4)
    params = mat.params()
    out_s, out_e, diss = [], [], []
    for eps in strains:
        old = eps_p.copy()
        mat.update(np.asarray(eps, dtype=float), eps_p, state, params, dt, sigma)
        out_s.append(sigma.copy())
        out_e.append(state[0])
        diss.append(contract(sigma, eps_p - old))
    return np.array(out_s), np.array(out_e), np.array(diss)


def test_uniaxial_strain_closed_form():
    """eps = e e_z e_z: elastic until 2 mu e = sigma_y0, then
    eps_bar_p = (2 mu e - sigma_y0) / (3 mu + H), sigma_zz = K e + 2/3 (sigma_y0 + H eps_bar_p),
    sigma_rr = sigma_tt = K e - 1/3 (sigma_y0 + H eps_bar_p)."""
    m = STEEL_J2
    e = np.linspace(0.0, 0.02, 57)[1:]
    sigma, ebar, _ = _path(m, [(0, 0, x, 0) for x in e])
    ebar_exact = np.maximum(2 * m.mu * e - m.yield_stress, 0.0) / (3 * m.mu + m.hardening)
    sy = m.yield_stress + m.hardening * ebar_exact
    elastic = 2 * m.mu * e <= m.yield_stress
    szz = np.where(elastic, (m.lmbda + 2 * m.mu) * e, m.bulk * e + 2 / 3 * sy)
    srr = np.where(elastic, m.lmbda * e, m.bulk * e - sy / 3)
    scale = np.abs(szz).max()
    assert np.abs(sigma[:, 2] - szz).max() <= ROUND * scale
    assert np.abs(sigma[:, 0] - srr).max() <= ROUND * scale
    assert np.abs(sigma[:, 1] - srr).max() <= ROUND * scale
    assert np.abs(ebar - ebar_exact).max() <= ROUND * ebar_exact.max()
    assert (~elastic).sum() > 40  # most of the path is plastic


def test_pure_shear_closed_form():
    """eps_rz = g / 2 (tensor shear): tau = 2 mu (eps_rz - sqrt(3)/2 eps_bar_p), with
    eps_bar_p = (2 sqrt(3) mu eps_rz - sigma_y0) / (3 mu + H) once sqrt(3) tau reaches sigma_y."""
    m = STEEL_J2
    erz = np.linspace(0.0, 0.01, 41)[1:]
    sigma, ebar, _ = _path(m, [(0, 0, 0, x) for x in erz])
    ebar_exact = (np.maximum(2 * math.sqrt(3) * m.mu * erz - m.yield_stress, 0)
                  / (3 * m.mu + m.hardening))
    tau = 2 * m.mu * (erz - math.sqrt(3) / 2 * ebar_exact)
    assert np.abs(sigma[:, 3] - tau).max() <= ROUND * tau.max()
    assert np.abs(sigma[:, :3]).max() <= ROUND * tau.max()  # no normal stress in pure shear
    assert np.abs(ebar - ebar_exact).max() <= ROUND * ebar_exact.max()


def test_consistency_and_dissipation_on_random_paths():
    """After every plastic step sigma_eq = sigma_y(eps_bar_p) to round-off; eps_bar_p never
    decreases; the dissipation sigma_{n+1} : d eps_p = sigma_eq d eps_bar_p >= 0."""
    m = J2(E=200e9, nu=0.3, yield_stress=250e6, hardening=5e9)
    rng = np.random.default_rng(7)
    strains = np.cumsum(rng.normal(scale=4e-4, size=(400, 4)), axis=0)
    eps_p, state, sigma = np.zeros(4), np.zeros(1), np.zeros(4)
    params = m.params()
    n_plastic = 0
    for eps in strains:
        old_p, old_e = eps_p.copy(), state[0]
        m.update(eps, eps_p, state, params, 1e-6, sigma)
        d = contract(sigma, eps_p - old_p)
        assert state[0] >= old_e
        if state[0] > old_e:
            n_plastic += 1
            sy = m.yield_stress + m.hardening * state[0]
            assert abs(von_mises(sigma) - sy) <= ROUND * sy
            assert d > 0.0
            # the differences eps_p - old and eps_bar_p - old_e carry the rounding of the
            # accumulated strains themselves, contracted with sigma (the pressure too: the
            # trace of d eps_p is 0 only to that rounding): 8 roundings of |sigma| |eps_p|
            accumulated = rounding(8, max(sy, np.abs(sigma).max())
                                   * max(state[0], np.abs(eps_p).max()))
            assert abs(d - von_mises(sigma) * (state[0] - old_e)) <= ROUND * d + accumulated
        else:
            assert von_mises(sigma) <= m.yield_stress + m.hardening * state[0]
            assert d == 0.0
        # the stress is always the elastic law of the elastic strain
        ee = eps - eps_p
        s_el = m.lmbda * ee[:3].sum() * np.array([1, 1, 1, 0]) + 2 * m.mu * ee
        strains = max(np.abs(eps).max(), np.abs(eps_p).max())
        elastic_round = rounding(4, (3 * m.lmbda + 2 * m.mu) * strains)
        assert np.abs(sigma - s_el).max() <= ROUND * np.abs(s_el).max() + elastic_round
    assert n_plastic > 100


def _viscous_uniaxial(eta, rate, t_end, n, H=2e9):
    m = J2(E=200e9, nu=0.3, yield_stress=250e6, hardening=H, viscosity=eta)
    dt = t_end / n
    t = dt * np.arange(1, n + 1)
    _, ebar, _ = _path(m, [(0, 0, rate * x, 0) for x in t], dt=dt)
    return m, t, ebar


def _ode_solution(m, eta, rate, t):
    """d eps_bar_p/dt = (2 mu e(t) - 3 mu eps_bar_p - sigma_y0 - H eps_bar_p)/eta, e = rate t,
    from rest at t_Y = sigma_y0 / (2 mu rate): with a = (3 mu + H)/eta, b = 2 mu rate / eta,
    eps_bar_p = b (s/a - (1 - exp(-a s))/a^2), s = t - t_Y."""
    a = (3 * m.mu + m.hardening) / eta
    b = 2 * m.mu * rate / eta
    s = np.maximum(t - m.yield_stress / (2 * m.mu * rate), 0.0)
    return b * (s / a - (1 - np.exp(-a * s)) / a ** 2)


def test_overstress_viscosity_converges_to_the_ode_at_first_order():
    eta, rate, t_end = 2e5, 1e3, 2e-5  # relaxation time eta / (3 mu + H) = 0.85 us
    errors = []
    for n in (200, 400, 800):
        m, t, ebar = _viscous_uniaxial(eta, rate, t_end, n)
        exact = _ode_solution(m, eta, rate, t)
        errors.append(np.abs(ebar - exact).max() / exact.max())
    # backward Euler: first order; the yield onset falls between steps, which adds an
    # O(dt) term of its own, so the ratio sits near 2 rather than exactly at it
    assert errors[0] < 0.05
    assert 1.6 < errors[0] / errors[1] < 2.5 and 1.6 < errors[1] / errors[2] < 2.5


@pytest.mark.parametrize("H", [0.0, 2e9])
def test_overstress_viscosity_tends_to_rate_independent(H):
    """With eta -> 0 the viscoplastic return tends to the rate-independent one: the
    difference in eps_bar_p is eta / dt / (3 mu + H + eta / dt) of the increment, O(eta)."""
    rate, t_end, n = 1e3, 2e-5, 100
    _, _, ref = _viscous_uniaxial(0.0, rate, t_end, n, H)
    diffs = []
    for eta in (1e3, 1e2, 1e1):
        _, _, ebar = _viscous_uniaxial(eta, rate, t_end, n, H)
        diffs.append(np.abs(ebar - ref).max() / ref.max())
    assert diffs[0] < 1e-3
    assert 9 < diffs[0] / diffs[1] < 11 and 9 < diffs[1] / diffs[2] < 11
