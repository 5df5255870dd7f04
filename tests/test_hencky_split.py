"""The closed-form Hencky split against the previous one: stress and b_e to round-off.

The point update of the Hencky models writes every tensor of the (r, z) plane from its
two principal values and (cos 2 theta, sin 2 theta) = (h, s) / d, and returns b_e by
the trial eigenvalues times the return's factors. The previous update, kept here as the
reference, normalised the eigenvector (c, s) itself (a square root and a branch) and
took exp of the returned log strains. Both are exact in exact arithmetic, so they agree
to round-off (class (b) of tests/roundoff.py) on random deformation gradients and on the
degenerate ones: equal in-plane eigenvalues (F = I, an in-plane dilatation), zero shear,
a point on the axis (F_tt = F_rr, F_rz = 0), eigenvalues 1e-9 apart, a rotation.

What is compared is the Kirchhoff stress and b_e = F a F' (not the eigenvectors, which
are arbitrary for equal eigenvalues). Every check runs on one point, the same on every
rank.
"""
import math

import numpy as np
import pytest

from impact_fenics.materials.finite_j2 import FiniteJ2
from impact_fenics.materials.johnson_cook import JohnsonCook, flow_stress
from roundoff import LIBM, rounding
from test_johnson_cook_return import previous_return_increment, root_tolerance

SQRT_3_2 = math.sqrt(1.5)


# ---------------------------------------------------------------- the previous split
def _trial(F, state, work):
    frr, frz, fzr, fzz, ftt = F
    arr, azz, arz, att = state[1], state[2], state[3], state[4]
    m00, m01 = frr * arr + frz * arz, frr * arz + frz * azz
    m10, m11 = fzr * arr + fzz * arz, fzr * arz + fzz * azz
    p, q, s = m00 * frr + m01 * frz, m10 * fzr + m11 * fzz, m00 * fzr + m01 * fzz
    half = 0.5 * (p - q)
    d = math.sqrt(half * half + s * s)
    mean = 0.5 * (p + q)
    work[0] = 0.5 * math.log(mean + d)
    work[1] = 0.5 * math.log(mean - d)
    work[2] = 0.5 * math.log(ftt * ftt * att)
    c, sn = (half + d, s) if half >= 0.0 else (s, d - half)
    norm = math.sqrt(c * c + sn * sn)
    work[3], work[4] = (c / norm, sn / norm) if norm > 0.0 else (1.0, 0.0)


def _principal(lmbda, mu, work, out):
    tr = work[0] + work[1] + work[2]
    for i in range(3):
        out[i] = lmbda * tr + 2.0 * mu * work[i]
    m = (out[0] + out[1] + out[2]) / 3.0
    return SQRT_3_2 * math.sqrt(sum((out[i] - m) ** 2 for i in range(3)))


def _return(mu, dg, q, principal, work):
    m = (principal[0] + principal[1] + principal[2]) / 3.0
    k = 1.0 - 3.0 * mu * dg / q
    for i in range(3):
        dev = principal[i] - m
        work[i] -= 1.5 * dg * dev / q
        principal[i] = m + k * dev


def _kirchhoff(principal, work, tau):
    c, s = work[3], work[4]
    t1, t2 = principal[0], principal[1]
    tau[0], tau[2], tau[3], tau[1] = t1 * c * c + t2 * s * s, t1 * s * s + t2 * c * c, \
        (t1 - t2) * c * s, principal[2]


def _finish(F, principal, work, state, tau):
    _kirchhoff(principal, work, tau)
    c, s = work[3], work[4]
    l1, l2 = math.exp(2.0 * work[0]), math.exp(2.0 * work[1])
    b = np.array([[l1 * c * c + l2 * s * s, (l1 - l2) * c * s],
                  [(l1 - l2) * c * s, l1 * s * s + l2 * c * c]])
    det = F[0] * F[3] - F[1] * F[2]
    i00, i01, i10, i11 = F[3] / det, -F[1] / det, -F[2] / det, F[0] / det
    n00, n01 = i00 * b[0, 0] + i01 * b[0, 1], i00 * b[0, 1] + i01 * b[1, 1]
    n10, n11 = i10 * b[0, 0] + i11 * b[0, 1], i10 * b[0, 1] + i11 * b[1, 1]
    state[1], state[2], state[3] = n00 * i00 + n01 * i01, n10 * i10 + n11 * i11, n00 * i10 + n01 * i11
    state[4] = math.exp(2.0 * work[2]) / (F[4] * F[4])


def previous_j2(F, state, params, tau):
    lmbda, mu, sy0, h = params
    work, principal = np.zeros(5), np.zeros(3)
    _trial(F, state, work)
    q = _principal(lmbda, mu, work, principal)
    f = q - (sy0 + h * state[0])
    if f > 0.0:
        dg = f / (3.0 * mu + h)
        _return(mu, dg, q, principal, work)
        state[0] += dg
        _finish(F, principal, work, state, tau)
    else:
        _kirchhoff(principal, work, tau)


def previous_johnson_cook(F, state, params, dt, tau):
    lmbda, mu = params[0], params[1]
    work, principal = np.zeros(5), np.zeros(3)
    _trial(F, state, work)
    q = _principal(lmbda, mu, work, principal)
    if q > flow_stress(params, state[0], 0.0, state[5]):
        x = previous_return_increment(params, mu, q, state[0], dt, state[5])
        if x > 0.0:
            _return(mu, x, q, principal, work)
            state[0] += x
            _finish(F, principal, work, state, tau)
            return
    _kirchhoff(principal, work, tau)


# ---------------------------------------------------------------- the cases
def _rotation(angle):
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, -s], [s, c]])


def _F(block, ftt):
    return np.array([block[0, 0], block[0, 1], block[1, 0], block[1, 1], ftt])


def cases():
    """(name, F, plastic state a = C_p^-1 (rr, zz, rz, tt)) of tens of percent of strain."""
    rng = np.random.default_rng(26)
    out = [("identity", _F(np.eye(2), 1.0), (1.0, 1.0, 0.0, 1.0)),
           ("in_plane_dilatation", _F(0.93 * np.eye(2), 1.2), (1.0, 1.0, 0.0, 1.0)),
           ("rotated_dilatation", _F(0.93 * _rotation(0.7), 1.2), (1.0, 1.0, 0.0, 1.0)),
           ("zero_shear", _F(np.diag([0.8, 1.3]), 0.95), (1.0, 1.0, 0.0, 1.0)),
           ("on_the_axis", _F(np.array([[1.15, 0.0], [0.2, 0.7]]), 1.15), (1.0, 1.0, 0.0, 1.0)),
           ("eigenvalues_1e-9_apart", _F(np.diag([1.0 + 1e-9, 1.0]) @ _rotation(0.3), 0.8),
            (1.0, 1.0, 0.0, 1.0)),
           ("equal_with_plastic_state", _F(np.eye(2), 0.9), (1.1, 1.1, 0.0, 1 / 1.21))]
    for i in range(40):
        block = np.eye(2) + 0.25 * rng.standard_normal((2, 2))
        a = np.eye(2) + 0.1 * rng.standard_normal((2, 2))
        a = a @ a.T  # symmetric positive definite
        out.append((f"random_{i}", _F(block, 1.0 + 0.2 * rng.standard_normal()),
                    (a[0, 0], a[1, 1], a[0, 1], 1.0 + 0.1 * rng.random())))
    return out


CASES = cases()


def b_e(F, state):
    """F a F' of the (r, z) block and F_tt^2 a_tt: (b_rr, b_zz, b_rz, b_tt)."""
    Fb = np.array([[F[0], F[1]], [F[2], F[3]]])
    a = np.array([[state[1], state[3]], [state[3], state[2]]])
    b = Fb @ a @ Fb.T
    return np.array([b[0, 0], b[1, 1], b[0, 1], F[4] * F[4] * state[4]])


def bounds(material, F, state0):
    """Round-off bounds of the stress (Pa) and of b_e.

    Both paths share the trial log strains bit for bit (the same expressions); they
    differ in how a tensor is made from its principal values: the previous path about
    14 roundings and a square root (c, s, their norm and the products), the new 6 and
    the quotient by d, so 24 + LIBM roundings on the principal stresses' scale. Near
    equal eigenvalues either direction errs by EPS x mean / d, multiplied by a principal
    difference of 2 mu (eps_1 - eps_2) ~ 2 mu d / mean: a further 2 mu on the scale.
    b_e: exp of the returned log strain against the trial eigenvalue times exp of the
    correction: 2 LIBM and the argument's error, |2 eps| relative (the log of the
    trial eigenvalue); the trial eigenvalue m - d carries EPS (m + d) / (m - d). The
    inverse F^-1 b F^-T and the test's F a F' again multiply by |F|^2 |F^-1|^2 (at most
    16 roundings on each side)."""
    work, principal = np.zeros(5), np.zeros(3)
    _trial(F, np.array(state0, dtype=float), work)
    _principal(material.lmbda, material.mu, work, principal)
    tau_scale = np.abs(principal).max() + 2.0 * material.mu
    b = b_e(F, state0)
    m, d = 0.5 * (b[0] + b[1]), math.hypot(0.5 * (b[0] - b[1]), b[2])
    Fb = np.array([[F[0], F[1]], [F[2], F[3]]])
    cond = np.linalg.norm(Fb) ** 2 * np.linalg.norm(np.linalg.inv(Fb)) ** 2
    b_scale = np.abs(b).max()
    n_b = (2 * LIBM + 2 * np.abs(work[:3]).max() + (m + d) / (m - d) + 2 * 16) * cond
    return rounding(24 + LIBM, tau_scale), rounding(n_b, b_scale)


def run_both(material, F, a, previous):
    state0 = material.initial_state().copy()
    state0[1:5] = a
    new_state, old_state = state0.copy(), state0.copy()
    tau_new, tau_old = np.zeros(4), np.zeros(4)
    material.update(F, new_state, material.params(), 1e-7, tau_new, np.zeros(16))
    previous(F, old_state, material.params(), tau_old)
    return state0, new_state, old_state, tau_new, tau_old


@pytest.mark.parametrize("name, F, a", CASES, ids=[c[0] for c in CASES])
def test_finite_j2_split_matches_the_previous_one(name, F, a):
    """Finite J2 (yielding at 200 MPa, so most cases flow): the stress and the returned
    b_e of the closed form against the previous split, within :func:`bounds`."""
    material = FiniteJ2(E=117e9, nu=0.35, yield_stress=200e6, hardening=100e6)
    state0, new, old, tau_new, tau_old = run_both(
        material, F, a, lambda F, s, p, t: previous_j2(F, s, p, t))
    tau_bound, b_bound = bounds(material, F, state0)
    assert np.abs(tau_new - tau_old).max() <= tau_bound, name
    assert np.abs(b_e(F, new) - b_e(F, old)).max() <= b_bound, name
    assert new[0] == pytest.approx(old[0], rel=rounding(64 + 2 * LIBM), abs=1e-300)


@pytest.mark.parametrize("name, F, a", CASES[:8] + CASES[-4:], ids=[c[0] for c in CASES[:8] + CASES[-4:]])
def test_johnson_cook_split_matches_the_previous_one(name, F, a):
    """Johnson-Cook: the same comparison through its own return, against the previous split
    with the previous return (regula falsi). The two returns stop by the same rule on the
    same trial stress q, so their increments differ by dx <= root_tolerance(q, mu) (see
    tests/test_johnson_cook_return.py); that moves the principal deviatoric stresses by
    3 mu dx |dev_i| / q <= 3 mu dx, and the returned b_e's principal values by the factor
    exp(3 dx |dev_i| / q) - 1 <= 3 dx (|dev_i| <= q), relative: both added to the bounds."""
    material = JohnsonCook()
    state0, new, old, tau_new, tau_old = run_both(
        material, F, a, lambda F, s, p, t: previous_johnson_cook(F, s, p, 1e-7, t))
    tau_bound, b_bound = bounds(material, F, state0)
    work, principal = np.zeros(5), np.zeros(3)
    _trial(F, state0, work)
    dx = root_tolerance(_principal(material.lmbda, material.mu, work, principal), material.mu)
    assert new[0] == pytest.approx(old[0], rel=0, abs=dx), name
    b_scale = max(np.abs(b_e(F, new)).max(), np.abs(b_e(F, old)).max())
    assert np.abs(tau_new - tau_old).max() <= tau_bound + 3.0 * material.mu * dx, name
    assert np.abs(b_e(F, new) - b_e(F, old)).max() <= b_bound + 3.0 * dx * b_scale, name


def test_the_cases_yield_and_include_equal_eigenvalues():
    """The comparison covers flow at equal in-plane eigenvalues (d = 0 exactly) and most
    random cases flow: else it would compare the elastic branch only."""
    material = FiniteJ2(E=117e9, nu=0.35, yield_stress=200e6, hardening=100e6)
    flowed = {}
    for name, F, a in CASES:
        state = material.initial_state().copy()
        state[1:5] = a
        material.update(F, state, material.params(), 1e-7, np.zeros(4), np.zeros(16))
        flowed[name] = state[0] > 0.0
    assert flowed["in_plane_dilatation"] and flowed["rotated_dilatation"]
    assert flowed["equal_with_plastic_state"] and flowed["on_the_axis"]
    assert sum(flowed[n] for n, _, _ in CASES if n.startswith("random")) >= 30
