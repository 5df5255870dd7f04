"""The scalar Hencky point update against the eigenvalue form it replaced: round-off only.

The previous update (kept below as the reference, in Python) split the trial b_e into its
eigenvalues m +- d (a square root), took three logarithms, normalised the direction by
1 / d and returned b_e by the trial eigenvalues times exp(-3 dgamma dev tau_i / q). The
present one (materials/hencky.py) takes the in-plane mean log strain from ln(m^2 - d^2),
half the difference over d from atanh's series in u = (d / m)^2 (u <= 1/256, else the
logarithms of m +- d), and the returned b_e from exp(2 eps_m) and the series of cosh and
sinh / w. Both are exact in exact arithmetic; they are compared one step from one state
(class (b) of tests/roundoff.py), finite J2 at copper's constants on:

* points near the yield surface (b_e within 0.2 % to 3 % of a pressure times I: the
  series' regime, where every Taylor-bar point lies), loaded elastically and plastically;
* the large trial strains of tests/test_hencky_split.py (25 % random F, the logarithms'
  regime) and its degenerate cases (equal eigenvalues, the axis, 1e-9 apart);
* b_e at u just below and above 1/256 (both branches of the series, to round-off of each
  other).

The bounds (:func:`bounds`). The trial log strains: the smaller eigenvalue m - d is known
to EPS (m + d) absolutely in both paths (b's roundings are on the scale m + d), so the log
strains agree to EPS (16 + 2 LIBM) kappa, kappa = (m + d) / (m - d) the condition of the
eigenproblem (16: b's 8 roundings, m, d^2, the difference or the series' 14 on a term at
most u / 3 of the sum, counted once more); they move the stress by (3 lambda + 2 mu) times
that, plus the 24 + LIBM roundings of the stress on its scale (as test_hencky_split). A
return scales dev tau by sigma_y / q: an error delta of dev tau moves q by at most
sqrt(3/2) sqrt(3) delta <= 2.2 delta, which moves sigma_y / q dev tau by at most
(1 + 2.2 sqrt(2/3)) delta < 3 delta; so 3 x the trial bound after a return, and
dgamma = (q - sigma_y) / (3 mu + H) moves by 2.2 delta / (3 mu + H). The returned b_e: as
test_hencky_split's bound (its exp and the F^-1 b F^-T products times cond(F)^2) plus the
shift of the returned log strains, 3 x the trial's, relative.
"""
import math

import numpy as np
import pytest

from impact_fenics.materials.finite_j2 import FiniteJ2
from roundoff import LIBM, rounding
from test_hencky_split import CASES, b_e

SQRT_3_2 = math.sqrt(1.5)
COPPER = FiniteJ2(E=117e9, nu=0.35, yield_stress=400e6, hardening=100e6)


def previous_update(F, state, params, tau):
    """The eigenvalue form of the update (three logarithms, 1 / d, two exponentials)."""
    lmbda, mu, sy0, hard = params
    frr, frz, fzr, fzz, ftt = F
    arr, azz, arz, att = state[1], state[2], state[3], state[4]
    m00, m01 = frr * arr + frz * arz, frr * arz + frz * azz
    m10, m11 = fzr * arr + fzz * arz, fzr * arz + fzz * azz
    p, q, s = m00 * frr + m01 * frz, m10 * fzr + m11 * fzz, m00 * fzr + m01 * fzz
    half = 0.5 * (p - q)
    d = math.sqrt(half * half + s * s)
    mean = 0.5 * (p + q)
    lam = [mean + d, mean - d, ftt * ftt * att]
    eps = [0.5 * math.log(x) for x in lam]
    c2, s2 = (half / d, s / d) if d > 0.0 else (1.0, 0.0)
    tr = sum(eps)
    t = [lmbda * tr + 2.0 * mu * e for e in eps]
    m = sum(t) / 3.0
    qt = SQRT_3_2 * math.sqrt(sum((x - m) ** 2 for x in t))
    f = qt - (sy0 + hard * state[0])
    if f > 0.0:
        dg = f / (3.0 * mu + hard)
        k, r = 1.0 - 3.0 * mu * dg / qt, 1.5 * dg / qt
        dev = [x - m for x in t]
        t = [m + k * x for x in dev]
        x0, x1 = math.exp(-2.0 * r * dev[0]), math.exp(-2.0 * r * dev[1])
        lam = [lam[0] * x0, lam[1] * x1, lam[2] / (x0 * x1)]
        state[0] += dg
        bm, bh = 0.5 * (lam[0] + lam[1]), 0.5 * (lam[0] - lam[1])
        brr, bzz, brz = bm + bh * c2, bm - bh * c2, bh * s2
        inv = 1.0 / (frr * fzz - frz * fzr)
        i00, i01, i10, i11 = fzz * inv, -frz * inv, -fzr * inv, frr * inv
        n00, n01 = i00 * brr + i01 * brz, i00 * brz + i01 * bzz
        n10, n11 = i10 * brr + i11 * brz, i10 * brz + i11 * bzz
        state[1], state[2], state[3] = n00 * i00 + n01 * i01, n10 * i10 + n11 * i11, \
            n00 * i10 + n01 * i11
        state[4] = lam[2] / (ftt * ftt)
    tm, th = 0.5 * (t[0] + t[1]), 0.5 * (t[0] - t[1])
    tau[:] = tm + th * c2, t[2], tm - th * c2, th * s2
    return eps, t


def _state_of(F, b):
    """a = F^-1 b F^-T (rr, zz, rz, tt) for b_e = (b_rr, b_zz, b_rz, b_tt)."""
    Fb = np.array([[F[0], F[1]], [F[2], F[3]]])
    inv = np.linalg.inv(Fb)
    a = inv @ np.array([[b[0], b[2]], [b[2], b[1]]]) @ inv.T
    return (a[0, 0], a[1, 1], a[0, 1], b[3] / F[4] ** 2)


def near_yield_cases():
    """(name, F, a): 25 % random F with b_e = J^(2/3) (I + 2 e), e a random deviator of
    0.2 % (elastic at copper's 400 MPa: 2 mu 0.002 sqrt(3/2) is about 210 MPa) or 1 % to
    1.5 % (plastic), J = 1 +- 3 %."""
    rng = np.random.default_rng(8)
    out = []
    for i in range(40):
        block = np.eye(2) + 0.25 * rng.standard_normal((2, 2))
        if np.linalg.det(block) < 0.3:
            continue
        F = np.array([block[0, 0], block[0, 1], block[1, 0], block[1, 1],
                      1.0 + 0.2 * rng.random()])
        size = 0.002 if i % 2 == 0 else 0.01 + 0.005 * rng.random()
        e = rng.standard_normal(4)
        e[:3] -= e[:3].mean()  # (rr, zz, tt) traceless; e[3] the shear
        e *= size / np.linalg.norm(e)
        j23 = (1.0 + 0.03 * rng.uniform(-1.0, 1.0)) ** (2.0 / 3.0)
        b = j23 * np.array([1.0 + 2 * e[0], 1.0 + 2 * e[1], 2 * e[3], 1.0 + 2 * e[2]])
        out.append((f"near_yield_{i}", F, _state_of(F, b)))
    return out


def series_edge_cases():
    """b_e with (d / m)^2 = 1/256 (1 +- 1e-6) and at 1/256 (to its rounding), F a rotation times a
    stretch: the series and the logarithms on each side of the switch."""
    out = []
    for i, rel in enumerate((1.0 - 1e-6, 1.0, 1.0 + 1e-6)):
        m, t, angle = 1.01, math.sqrt(rel) / 16.0, 0.4 + 0.3 * i
        d = m * t
        b = (m + d * math.cos(angle), m - d * math.cos(angle), d * math.sin(angle), 0.98)
        c, s = math.cos(0.2), math.sin(0.2)
        F = np.array([1.2 * c, -0.9 * s, 1.2 * s, 0.9 * c, 1.1])
        out.append((f"series_edge_{i}", F, _state_of(F, b)))
    return out


ALL = near_yield_cases() + series_edge_cases() + CASES


def bounds(material, F, a, eps, t):
    """(trial stress bound (Pa), b_e bound, kappa): see the module's docstring."""
    b = b_e(F, (0.0,) + tuple(a))
    m, d = 0.5 * (b[0] + b[1]), math.hypot(0.5 * (b[0] - b[1]), b[2])
    kappa = (m + d) / (m - d)
    d_eps = rounding((16 + 2 * LIBM) * kappa)
    tau_scale = max(abs(x) for x in t) + 2.0 * material.mu
    d_tau = (3.0 * material.lmbda + 2.0 * material.mu) * d_eps + rounding(24 + LIBM, tau_scale)
    Fb = np.array([[F[0], F[1]], [F[2], F[3]]])
    cond = np.linalg.norm(Fb) ** 2 * np.linalg.norm(np.linalg.inv(Fb)) ** 2
    b_scale = np.abs(b).max()
    n_b = (2 * LIBM + 2 * max(abs(x) for x in eps) + kappa + 2 * 16) * cond
    d_b = rounding(n_b, b_scale) + 2.0 * 3.0 * d_eps * cond * b_scale
    return d_tau, d_b, kappa


@pytest.mark.parametrize("name, F, a", ALL, ids=[c[0] for c in ALL])
def test_the_scalar_update_matches_the_eigenvalue_form(name, F, a):
    """Stress, eps_bar_p and the returned b_e within :func:`bounds` (3 x the trial bound
    after a return)."""
    mat = COPPER if not name.startswith("random") else FiniteJ2(
        E=117e9, nu=0.35, yield_stress=200e6, hardening=100e6)
    state0 = mat.initial_state().copy()
    state0[1:5] = a
    new, old = state0.copy(), state0.copy()
    tau_new, tau_old = np.zeros(4), np.zeros(4)
    mat.update(F, new, mat.params(), 1e-7, tau_new, np.zeros(16))
    eps, t = previous_update(F, old, tuple(mat.params()), tau_old)
    d_tau, d_b, kappa = bounds(mat, F, a, eps, t)
    flowed = old[0] > 0.0
    factor = 3.0 if flowed else 1.0
    assert (new[0] > 0.0) == flowed, name
    assert np.abs(tau_new - tau_old).max() <= factor * d_tau, name
    assert abs(new[0] - old[0]) <= 2.2 * d_tau / (3.0 * mat.mu + mat.hardening) \
        + rounding(8, old[0]), name
    assert np.abs(b_e(F, new) - b_e(F, old)).max() <= d_b, name


def test_the_cases_cover_both_branches_and_both_outcomes():
    """The near-yield cases are in the series' regime and half of them flow; the large
    ones in the logarithms'; the edge cases on both sides of u = 1/256."""
    def u_of(F, a):
        b = b_e(F, (0.0,) + tuple(a))
        m = 0.5 * (b[0] + b[1])
        return ((0.5 * (b[0] - b[1])) ** 2 + b[2] ** 2) / (m * m)
    near = near_yield_cases()
    assert all(u_of(F, a) <= 1.0 / 256.0 for _, F, a in near)
    flowed = []
    for _, F, a in near:
        state = COPPER.initial_state().copy()
        state[1:5] = a
        COPPER.update(F, state, COPPER.params(), 1e-7, np.zeros(4), np.zeros(16))
        flowed.append(state[0] > 0.0)
    assert 0.3 * len(near) <= sum(flowed) <= 0.7 * len(near)
    assert sum(u_of(F, a) > 1.0 / 256.0 for name, F, a in CASES if name.startswith("random")) \
        >= 30
    edge = [u_of(F, a) - 1.0 / 256.0 for _, F, a in series_edge_cases()]
    assert edge[0] < 0.0 < edge[2]


def barely_yielding():
    """(name, F, a, material): the large random cases of test_hencky_split with the yield
    stress at 0.9 of the trial q, so that the return keeps 0.9 of the trial's in-plane
    difference: w = 2 g d = k (eps_1 - eps_2) beyond the series' 1/8, the library's cosh
    and sinh."""
    out = []
    for name, F, a in CASES:
        if not name.startswith("random"):
            continue
        state = COPPER.initial_state().copy()
        state[1:5] = a
        lmbda, mu = COPPER.lmbda, COPPER.mu
        eps, t = previous_update(F, state.copy(), (lmbda, mu, 1e300, 0.0), np.zeros(4))
        m = sum(t) / 3.0
        q = SQRT_3_2 * math.sqrt(sum((x - m) ** 2 for x in t))
        material = FiniteJ2(E=COPPER.E, nu=COPPER.nu, yield_stress=0.9 * q, hardening=100e6)
        k = 1.0 - 3.0 * mu * (0.1 * q / (3.0 * mu + 100e6)) / q
        if k * abs(eps[0] - eps[1]) > 0.125:
            out.append((f"barely_{name}", F, a, material))
    return out


BARELY = barely_yielding()


@pytest.mark.parametrize("name, F, a, material", BARELY, ids=[c[0] for c in BARELY])
def test_the_returned_b_e_beyond_the_series(name, F, a, material):
    """The return's library branch of cosh and sinh: the same comparison and bounds."""
    state0 = material.initial_state().copy()
    state0[1:5] = a
    new, old = state0.copy(), state0.copy()
    tau_new, tau_old = np.zeros(4), np.zeros(4)
    material.update(F, new, material.params(), 1e-7, tau_new, np.zeros(16))
    eps, t = previous_update(F, old, tuple(material.params()), tau_old)
    d_tau, d_b, _ = bounds(material, F, a, eps, t)
    assert old[0] > 0.0 and new[0] > 0.0, name
    assert np.abs(tau_new - tau_old).max() <= 3.0 * d_tau, name
    assert abs(new[0] - old[0]) <= 2.2 * d_tau / (3.0 * material.mu + material.hardening) \
        + rounding(8, old[0]), name
    assert np.abs(b_e(F, new) - b_e(F, old)).max() <= d_b, name


def test_some_returns_go_beyond_the_series():
    """At least ten of the barely yielding cases take the library's cosh and sinh."""
    assert len(BARELY) >= 10
