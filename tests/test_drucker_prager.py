"""Drucker-Prager point update (impact_fenics.materials.drucker_prager) against oracles
that do not come from its closed-form return:

- uniaxial strain: the closed form of tests/uniaxial_strain.py (sigma_HEL, M_p), written
  out again in the test; pure shear with dilatancy: its own closed form (below);
- triaxial compression without hardening: the Mohr-Coulomb strength UCS + N sigma_conf
  that the cone is matched to (compression meridian), lateral stress held by a root
  solve around the update;
- hydrostatic tension: the cut-off p_t; the corner: an independent Newton solve
  (scipy) of the full backward-Euler equations on the 4-component tensor;
- every step of every path: the discrete KKT conditions checked from the outputs alone
  (stress = C:(eps - eps_p), the increment along the flow rule at sigma_{n+1},
  multipliers >= 0, f <= 0, t <= 0, complementarity), consistency f = 0 to
  round-off, and the plastic dissipation sigma : d eps_p >= 0;
- Perzyna: the exact solution of its linear ODE in uniaxial strain at a constant rate
  (first order in dt), and the rate-independent limit as the viscosity -> 0.

Round-off tolerances (tests/roundoff.py) are relative to the stress scale: a point
update takes under 128 roundings (the trial stress, p and q with a sqrt, the return to
the cone, the cut-off or the corner, the stress from the elastic strain: ROUND); the
elastic strain eps - eps_p is a difference of accumulated strains, rounded on their
size, which on long paths exceeds the elastic strain many times (76 times on the
random paths): C : (eps - eps_p) carries (3 lambda + 2 mu) max|eps| roundings of its
own, in the update and in the check. Closed forms of piecewise-linear paths are exact
to these.
"""
import math

import numpy as np
import pytest
from scipy.optimize import brentq, root

from impact_fenics.errors import InputError
from impact_fenics.materials.drucker_prager import DruckerPrager, update
from roundoff import LIBM, rounding
from uniaxial_strain import uniaxial_strain

GRANITE = dict(E=60e9, nu=0.25, density=2600.0, ucs=200e6, friction_angle=50.0,
               dilatancy_angle=10.0, tensile_strength=10e6)
# a cone that yields in uniaxial strain (alpha_f < 2 mu / K = 1.2 at nu = 0.25)
LOW_FRICTION = dict(GRANITE, friction_angle=20.0, dilatancy_angle=10.0, hardening=5e9)
I4 = np.array([1.0, 1.0, 1.0, 0.0])
W = np.array([1.0, 1.0, 1.0, 2.0])  # a : b = sum W a b in the 4-component notation
ROUND = rounding(128)  # of the stress scale: a point update (module docstring)


def pq(s):
    m = s[:3].sum() / 3.0
    d = s - m * I4
    return -m, math.sqrt(1.5 * np.sum(W * d * d))


def elastic(mat, e):
    return mat.lmbda * e[:3].sum() * I4 + 2.0 * mat.mu * e


class Point:
    """One material point driven through a strain path, checking every step."""

    def __init__(self, mat, dt=1e-6):
        self.mat, self.params, self.dt = mat, mat.params(), dt
        self.eps_p, self.state, self.sigma = np.zeros(4), np.zeros(2), np.zeros(4)
        self.modes = set()

    def step(self, eps, check=True):
        ep_n, kappa_n = self.eps_p.copy(), self.state[1]
        update(eps, self.eps_p, self.state, self.params, self.dt, self.sigma)
        if check:
            self.kkt(eps, ep_n, kappa_n)
        return self.sigma.copy()

    def kkt(self, eps, ep_n, kappa_n):
        mat, s = self.mat, self.sigma
        scale = max(1.0, np.abs(s).max(), mat.k)
        strains = max(np.abs(eps).max(), np.abs(self.eps_p).max())
        elastic_round = rounding(4, (3 * mat.lmbda + 2 * mat.mu) * strains)
        np.testing.assert_allclose(s, elastic(mat, eps - self.eps_p),
                                   atol=ROUND * scale + elastic_round, rtol=0)
        dep = self.eps_p - ep_n
        dg = self.state[1] - kappa_n
        p, q = pq(s)
        k = max(mat.k + mat.hardening * self.state[1], self.params[7])
        f, t = q - mat.alpha_f * p - k, -p - mat.tensile_strength
        assert f <= ROUND * scale and t <= ROUND * scale
        dissipation = float(np.sum(W * s * dep))
        assert dissipation >= -ROUND * scale * np.abs(dep).max()
        if not np.any(dep):
            return
        # round-off of an increment taken from accumulated plastic strains: the update's
        # roundings of the increment, and one of each accumulated strain (the subtraction)
        tiny = ROUND * np.abs(dep).max() + rounding(2, np.abs(self.eps_p).max())
        # the increment must be dg (3/2 s/q + alpha_g/3 I) + dl I/3 with dl >= 0
        dev = s - s[:3].sum() / 3.0 * I4
        dep_dev = dep - dep[:3].mean() * I4
        if q > 1e-6 * scale:  # the direction 3/2 s/q is defined
            np.testing.assert_allclose(dep_dev, 1.5 * dg / q * dev,
                                       atol=ROUND * np.abs(dep).max() + tiny, rtol=0)
        else:  # at the corner circle's q = 0 only its size: sqrt(2/3 |dev d eps_p|^2) = dg
            assert math.sqrt(2 / 3 * np.sum(W * dep_dev ** 2)) == pytest.approx(
                dg, rel=ROUND, abs=2 * tiny)
        dl = dep[:3].sum() - mat.alpha_g * dg
        assert dg >= 0.0 and dl >= -tiny
        if dg > 0:  # complementarity (rate independent): on the cone
            assert abs(f) <= ROUND * scale
        if dl > tiny:
            assert abs(t) <= ROUND * scale
        self.modes.add((dg > 0, dl > tiny))


def test_matching_and_parameters():
    """alpha_f, k from phi and UCS; the cone passes through uniaxial compression."""
    mat = DruckerPrager(**GRANITE)
    s = math.sin(math.radians(50.0))
    # 6 s / (3 - s): 3 roundings, and the angle's conversion and sine (1 + LIBM), twice
    assert mat.alpha_f == pytest.approx(6 * s / (3 - s), rel=rounding(2 * (4 + LIBM)))
    # uniaxial compression: q = UCS, p = UCS/3 lies on the cone (terms of size UCS; alpha_f
    # and k: about 16 roundings each)
    assert mat.ucs - mat.alpha_f * mat.ucs / 3 - mat.k == pytest.approx(
        0.0, abs=rounding(40, mat.ucs))
    c = mat.cohesion
    # c from UCS and phi, k from c: a handful of products with a sine and a cosine each
    # (16 + 2 LIBM), 1 - s cancelling 1 / (1 - sin 50 deg) = 4.3 of the digits
    trig = rounding((16 + 2 * LIBM) / (1 - s))
    assert mat.k == pytest.approx(6 * c * math.cos(math.radians(50.0)) / (3 - s), rel=trig)
    assert mat.ucs == pytest.approx(2 * c * math.cos(math.radians(50)) / (1 - s), rel=trig)


def test_uniaxial_strain_closed_form():
    """sigma_zz follows (K + 4 mu/3) e up to sigma_HEL, then slope M_p."""
    mat = DruckerPrager(**LOW_FRICTION)
    u = uniaxial_strain(mat)
    K, mu, af, ag, h = mat.bulk, mat.mu, mat.alpha_f, mat.alpha_g, mat.hardening
    # the closed forms, written out independently: about 12 roundings each, their
    # differences (2 mu - K alpha) cancelling at most 4 of the digits here
    assert u.sigma_hel == pytest.approx((K + 4 * mu / 3) * mat.k / (2 * mu - K * af),
                                        rel=rounding(2 * 12 * 4))
    assert u.m_plastic == pytest.approx(
        K + 4 * mu / 3 - (2 * mu - K * af) * (2 * mu - K * ag) / (3 * mu + K * af * ag + h),
        rel=rounding(2 * 12 * 4))
    pt = Point(mat)
    e_end = 4.0 * u.e_yield
    for e in np.linspace(0.0, e_end, 57)[1:]:  # steps that straddle first yield
        s = pt.step(np.array([0.0, 0.0, -e, 0.0]))
        exact = u.m_elastic * e if e <= u.e_yield else \
            u.sigma_hel + u.m_plastic * (e - u.e_yield)
        assert -s[2] == pytest.approx(exact, rel=ROUND)
        assert s[0] == s[1]
    assert pt.modes == {(True, False)}


def test_pure_shear_with_dilatancy():
    """eps_rz alone: q = q* - 3 mu g = k_0 + h g + alpha_f p, p = K alpha_g g (dilatancy
    against zero total volume change builds pressure): g = (q* - k_0)/(3 mu + h + K af ag)."""
    mat = DruckerPrager(**dict(GRANITE, hardening=2e9))
    K, mu, af, ag, h = mat.bulk, mat.mu, mat.alpha_f, mat.alpha_g, mat.hardening
    pt = Point(mat)
    for g_rz in np.linspace(0.0, 0.01, 41)[1:]:
        s = pt.step(np.array([0.0, 0.0, 0.0, g_rz]))
        q_tr = math.sqrt(3.0) * 2 * mu * g_rz
        gam = max(0.0, (q_tr - mat.k) / (3 * mu + h + K * af * ag))
        p, q = pq(s)
        assert q == pytest.approx(q_tr - 3 * mu * gam, rel=ROUND)
        assert p == pytest.approx(K * ag * gam, abs=ROUND * mat.k)
    assert (True, False) in pt.modes


def test_softening_to_the_residual():
    """Softening past k_res in one step: the result is the branch k = k_res exactly."""
    mat = DruckerPrager(**dict(GRANITE, dilatancy_angle=0.0, hardening=-2e9, residual=40e6))
    pt = Point(mat)
    g_rz = 0.02
    s = pt.step(np.array([0.0, 0.0, 0.0, g_rz]))
    q_tr = math.sqrt(3.0) * 2 * mat.mu * g_rz
    gam = (q_tr - 40e6) / (3 * mat.mu)  # alpha_g = 0: no pressure, k = k_res
    assert pq(s)[1] == pytest.approx(40e6, rel=ROUND)
    # gamma = (q_tr - k_res) / 3 mu: the trial q's roundings (about 20 with a sqrt) and
    # the subtraction, q_tr / (q_tr - k_res) = 1.02 here
    assert pt.state[1] == pytest.approx(gam, rel=rounding(2 * (24 + LIBM)))
    assert mat.k + mat.hardening * gam < 40e6  # the floor was reached within the step


def test_triaxial_compression_reaches_mohr_coulomb():
    """Confine at sigma_c, then compress axially with the lateral stress held: without
    hardening the axial stress levels off at UCS + N sigma_c (Mohr-Coulomb, N =
    (1 + sin phi)/(1 - sin phi)), since the cone is matched on the compression meridian;
    the plastic volume change per kappa is alpha_g."""
    mat = DruckerPrager(**GRANITE)
    pt = Point(mat)
    s_c = 20e6
    e_h = -s_c / (3 * mat.bulk)
    pt.step(np.array([e_h, e_h, e_h, 0.0]))
    e_lat = e_h
    axial = []
    for e_z in np.linspace(e_h, -0.02, 80)[1:]:
        def lateral(x):
            trial = Point(mat)
            trial.eps_p[:], trial.state[:] = pt.eps_p, pt.state
            return trial.step(np.array([x, x, e_z, 0.0]), check=False)[0] + s_c
        e_lat = brentq(lateral, e_lat - 0.05, e_lat + 0.05, xtol=1e-16, rtol=1e-15)
        ep0, k0 = pt.eps_p.copy(), pt.state[1]
        s = pt.step(np.array([e_lat, e_lat, e_z, 0.0]))
        axial.append(-s[2])
        if pt.state[1] > k0:
            # increments taken from accumulated strains (one rounding of each) and the
            # update's own roundings of the increment
            d_kappa = pt.state[1] - k0
            assert (pt.eps_p - ep0)[:3].sum() == pytest.approx(
                mat.alpha_g * d_kappa, rel=ROUND,
                abs=rounding(8, np.abs(pt.eps_p).max() + pt.state[1]))
    sn = math.sin(math.radians(GRANITE["friction_angle"]))
    mc = mat.ucs + (1 + sn) / (1 - sn) * s_c
    # the lateral root is solved to xtol 1e-16 + rtol 1e-15 |e_lat| in strain, a stress
    # of E times that; the point's own round-off on top
    root = mat.E * (1e-16 + 1e-15 * abs(e_lat)) / mc
    assert axial[-1] == pytest.approx(mc, rel=ROUND + root)
    assert max(axial) <= mc * (1 + ROUND + root)
    assert (True, False) in pt.modes


def test_cut_off_hydrostatic_tension():
    """Hydrostatic tension: mean stress 3 K e up to p_t, then held at p_t with the
    volumetric plastic strain 3 e - p_t / K; no deviatoric flow, kappa unchanged."""
    mat = DruckerPrager(**GRANITE)
    pt = Point(mat)
    for e in np.linspace(0.0, 5e-4, 21)[1:]:
        s = pt.step(e * I4)
        m = min(3 * mat.bulk * e, mat.tensile_strength)
        np.testing.assert_allclose(s, m * I4, atol=ROUND * mat.k, rtol=0)
        # 3 e - p_t / K against the update's volumetric return: a few roundings (8) of the
        # volumetric strain, accumulated over the 20 steps
        assert pt.eps_p[:3].sum() == pytest.approx(
            max(0.0, 3 * e - mat.tensile_strength / mat.bulk), abs=rounding(8 * 20, 3 * e))
    assert pt.state[1] == 0.0
    assert pt.modes == {(False, True)}


def _independent_return(mat, eps, ep_n, kappa_n):
    """Backward Euler on the full tensor: unknowns sigma (4), d gamma, d lambda; the flow
    direction at sigma_{n+1}; both surfaces active (the corner). Solved by scipy."""
    af, ag, h, p_t = mat.alpha_f, mat.alpha_g, mat.hardening, mat.tensile_strength
    scale = mat.k

    def residual(x):
        s, dg, dl = x[:4] * scale, 1e-3 * x[4], 1e-3 * x[5]
        p, q = pq(s)
        dev = s - s[:3].sum() / 3.0 * I4
        dep = dg * (1.5 * dev / q + ag / 3.0 * I4) + dl / 3.0 * I4
        r1 = (s - elastic(mat, eps - ep_n - dep)) / scale
        r2 = (q - af * p - (mat.k + h * (kappa_n + dg))) / scale
        r3 = (-p - p_t) / scale
        return np.concatenate([r1, [r2, r3]])

    s_tr = elastic(mat, eps - ep_n)
    x0 = np.concatenate([s_tr / scale, [0.1, 0.1]])  # multipliers in units of 1e-3
    x = root(residual, x0, method="lm", tol=1e-14).x
    assert np.abs(residual(x)).max() < 1e-13  # solved (residuals in units of k)
    return x[:4] * scale, 1e-3 * x[4], 1e-3 * x[5]


@pytest.mark.parametrize("hardening", [0.0, 3e9])
def test_corner_against_independent_solve(hardening):
    """Hydrostatic tension with shear lands in the corner wedge: the closed form equals
    the scipy solve of the full equations, and both multipliers are > 0."""
    mat = DruckerPrager(**dict(GRANITE, hardening=hardening))
    eps = np.array([4e-4, 4e-4, 4e-4, 1.5e-3])
    pt = Point(mat)
    s = pt.step(eps)
    assert pt.modes == {(True, True)}
    s_ref, dg, dl = _independent_return(mat, eps, np.zeros(4), 0.0)
    # the oracle is a Levenberg-Marquardt solve stopped at tol 1e-14 (its residual
    # < 1e-13 in units of k): its own accuracy, not round-off, sets these two
    np.testing.assert_allclose(s, s_ref, atol=1e-8 * mat.k, rtol=0)
    assert pt.state[1] == pytest.approx(dg, rel=1e-8)
    assert dg > 0 and dl > 0
    p, q = pq(s)
    # on the corner: the cut-off and the cone at the update's own kappa, to a point's
    # round-off
    assert p == pytest.approx(-mat.tensile_strength, rel=ROUND)
    assert q == pytest.approx(mat.k + hardening * pt.state[1] - mat.alpha_f * mat.tensile_strength,
                              rel=ROUND)


def test_random_paths_kkt_and_dissipation():
    """Random steps whose trial states cover every region (cone, cut-off, corner, elastic
    unloading): the KKT conditions and sigma : d eps_p >= 0 at every step, with
    hardening and with softening. Each step jumps to eps_p + a random elastic strain:
    mean part uniform in [-2e-3, 1e-3], shear parts of scale 1e-3."""
    rng = np.random.default_rng(7)
    for hardening in (4e9, -1e9):
        mat = DruckerPrager(**dict(GRANITE, hardening=hardening))
        pt = Point(mat)
        for _ in range(400):
            e = rng.normal(scale=1e-3, size=4)
            e -= e[:3].mean() * I4
            pt.step(pt.eps_p + e + rng.uniform(-2e-3, 1e-3) * I4)
        # softened to k_res = alpha_f p_t the corner circle shrinks to q = 0: no cut-off alone
        expected = {(True, False), (True, True)} | ({(False, True)} if hardening > 0 else set())
        assert expected <= pt.modes


def _perzyna_uniaxial(mat, rate, t_end, n):
    pt = Point(mat, dt=t_end / n)
    for k in range(1, n + 1):
        s = pt.step(np.array([0.0, 0.0, -rate * k * pt.dt, 0.0]), check=False)
    return -s[2]


def test_perzyna_exact_ode_and_rate_independent_limit():
    """Uniaxial strain at a constant rate e' with gamma' = f / eta: after first yield
    (time t_y) the overstress obeys f' = c e' - A f / eta (c = 2 mu - K alpha_f,
    A = 3 mu + K af ag + h), so gamma(t) = (c e'/A) [s - (eta/A)(1 - exp(-A s/eta))],
    s = t - t_y, and the axial stress is M_el e - (2 mu - K alpha_g) gamma. Backward
    Euler converges to it at first order in dt; as eta -> 0 it tends to the
    rate-independent response (difference proportional to eta)."""
    base = DruckerPrager(**LOW_FRICTION)
    u = uniaxial_strain(base)
    K, mu, af, ag, h = base.bulk, base.mu, base.alpha_f, base.alpha_g, base.hardening
    rate = 100.0  # 1/s
    t_y = u.e_yield / rate
    t_end = 3.0 * t_y
    A, c = 3 * mu + K * af * ag + h, 2 * mu - K * af
    eta = 0.2 * A * (t_end - t_y)  # relaxation time eta/A: a fifth of the plastic phase
    mat = DruckerPrager(**dict(LOW_FRICTION, viscosity=eta))
    s_pl = t_end - t_y
    gamma = c * rate / A * (s_pl - eta / A * (1 - math.exp(-A * s_pl / eta)))
    exact = u.m_elastic * rate * t_end - (2 * mu - K * ag) * gamma
    errors = [abs(_perzyna_uniaxial(mat, rate, t_end, n) - exact) for n in (200, 400, 800)]
    assert errors[1] < 0.6 * errors[0] and errors[2] < 0.6 * errors[1]  # first order
    # backward Euler on a relaxation of time tau = eta/A errs by O(dt/tau) of the viscous
    # part of the stress, (2 mu - K ag) c e' tau / A: at most (2 mu - K ag) c e' dt / A
    dt = t_end / 800
    assert errors[2] < (2 * mu - K * ag) * c * rate * dt / A
    # eta -> 0: the difference from the rate-independent point shrinks in proportion
    ri = _perzyna_uniaxial(base, rate, t_end, 400)
    diffs = [abs(_perzyna_uniaxial(DruckerPrager(**dict(LOW_FRICTION, viscosity=v)), rate, t_end,
                                   400) - ri) for v in (eta * 1e-2, eta * 1e-3, eta * 1e-4)]
    assert diffs[1] < 0.15 * diffs[0] and diffs[2] < 0.15 * diffs[1]
    assert diffs[2] < 1e-5 * ri


@pytest.mark.parametrize("change, words", [
    (dict(dilatancy_angle=60.0), "dilatancy_angle"),
    (dict(dilatancy_angle=-1.0), "dilatancy_angle"),
    (dict(friction_angle=90.0), "friction_angle"),
    (dict(ucs=0.0), "ucs"),
    (dict(tensile_strength=-1e6), "tensile_strength"),
    (dict(tensile_strength=50e6), "apex"),
    (dict(viscosity=-1.0), "viscosity"),
    (dict(nu=0.5), "nu"),
    (dict(E=-1.0), "E"),
])
def test_bad_input(change, words):
    with pytest.raises(InputError, match=words):
        DruckerPrager(**dict(GRANITE, **change))


def test_uniaxial_strain_bound_refused():
    """The granite cone (phi = 50 deg > 30 deg) never yields in uniaxial strain: refused."""
    with pytest.raises(InputError, match="2 mu/K"):
        uniaxial_strain(DruckerPrager(**GRANITE))
