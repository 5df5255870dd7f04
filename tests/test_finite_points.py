"""Finite-strain point updates against closed forms, the energy, the small-strain J2 and an ODE.

Every check runs on one point (no mesh); the same on every rank. Round-off bounds count
roundings (tests/roundoff.py).
"""
import math

import numpy as np
import pytest

from impact_fenics.materials import j2
from impact_fenics.materials.finite_j2 import FiniteJ2
from impact_fenics.materials.johnson_cook import JohnsonCook, flow_stress
from impact_fenics.materials.neo_hookean import NeoHookean
from roundoff import LIBM, rounding

MATERIALS = [NeoHookean(E=117e9, nu=0.35), FiniteJ2(), JohnsonCook()]


def kirchhoff(material, F, state=None, dt=1e-8):
    state = material.initial_state().copy() if state is None else state
    tau = np.zeros(4)
    material.update(np.asarray(F, dtype=float), state, material.params(), dt, tau, np.zeros(16))
    return tau, state


@pytest.mark.parametrize("material", MATERIALS, ids=lambda m: type(m).__name__)
@pytest.mark.parametrize("angle", [0.0, 0.3, 1.2, math.pi])
def test_rigid_rotation_gives_zero_stress(material, angle):
    """F = Q (a rotation in the (r, z) plane, F_tt = 1): tau = 0 to round-off (objectivity):
    b = F F' = I and J = 1 to the roundings of cos, sin and the products (4 + 2 LIBM), the
    stress from them (the log strain or ln J and its terms: about 32 roundings and 2 LIBM
    more), of the moduli lambda + 2 mu."""
    c, s = math.cos(angle), math.sin(angle)
    tau, state = kirchhoff(material, [c, -s, s, c, 1.0])
    assert np.abs(tau).max() <= rounding(36 + 4 * LIBM, material.lmbda + 2 * material.mu)
    assert state[0] == 0.0 if material.n_state else True


def neo_hookean_piola(m, lr, lt, lz):
    """Closed form P = mu (F - F^-T) + lambda ln J F^-T of a diagonal F (Pa): (P_rr, P_tt, P_zz)."""
    lnj = math.log(lr * lt * lz)
    return [m.mu * (x - 1.0 / x) + m.lmbda * lnj / x for x in (lr, lt, lz)]


@pytest.mark.parametrize("stretch", [(1.0, 1.0, 1.4), (1.0, 1.0, 0.7), (1.3, 1.3, 1.0), (0.75, 0.75, 1.2)],
                         ids=["axial_tension", "axial_compression", "radial", "mixed"])
def test_neo_hookean_homogeneous_stretch(stretch):
    """Axial and radial stretches of tens of percent: P = tau F^-T matches the closed form
    of the first Piola stress to round-off (both: ln J and about 12 roundings on terms
    of the size of the moduli), and tau = 2 b dpsi/db agrees with the energy (central
    differences of psi in the stretches, error O(h^2) ~ 1e-10)."""
    m = NeoHookean(E=117e9, nu=0.35)
    lr, lt, lz = stretch
    tau, _ = kirchhoff(m, [lr, 0.0, 0.0, lz, lt])
    P = [tau[0] / lr, tau[1] / lt, tau[2] / lz]
    expected = neo_hookean_piola(m, lr, lt, lz)
    moduli = (m.lmbda + 2 * m.mu) * max(lr, lz, 1 / lr, 1 / lz)
    assert np.allclose(P, expected, rtol=0, atol=rounding(2 * (12 + LIBM), moduli))
    assert abs(tau[3]) == 0.0
    # dpsi/dlambda_i = P_ii
    h = 1e-5
    work = np.zeros(16)
    for i, idx in enumerate((0, 4, 3)):
        Fp, Fm = np.array([lr, 0, 0, lz, lt], float), np.array([lr, 0, 0, lz, lt], float)
        Fp[idx] += h
        Fm[idx] -= h
        dpsi = (m.energy(Fp, None, m.params(), work) - m.energy(Fm, None, m.params(), work)) / (2 * h)
        assert dpsi == pytest.approx(P[i], rel=1e-7, abs=1e-7 * m.mu)


def strain_path(scale, n=60):
    """A non-proportional small-strain path (rr, tt, zz, rz), amplitude ``scale``."""
    t = np.linspace(0.0, 1.0, n + 1)[1:]
    return np.stack([-0.4 * scale * t, -0.3 * scale * np.sin(2 * t), scale * t,
                     0.5 * scale * t * t], axis=1)


@pytest.mark.parametrize("material", MATERIALS, ids=lambda m: type(m).__name__)
def test_small_strain_limit(material):
    """At strains eps ~ 1e-4 and 1e-5 every finite-strain material gives the small-strain
    stress (linear elasticity, or the radial return of materials/j2.py with the same
    yield stress, here 10 % of the strain scale times E so that the path yields) up to the
    neglected terms, O(eps) relative: the difference shrinks tenfold with the strain."""
    errors = []
    for scale in (1e-4, 1e-5):
        sy = 0.1 * scale * material.E
        if isinstance(material, JohnsonCook):  # rate- and temperature-free, no hardening
            mat = JohnsonCook(E=material.E, nu=material.nu, A=sy, B=0.0, C=0.0, chi=0.0)
            small = j2.J2(E=material.E, nu=material.nu, yield_stress=sy, hardening=0.0)
        elif isinstance(material, FiniteJ2):
            mat = FiniteJ2(E=material.E, nu=material.nu, yield_stress=sy, hardening=0.05 * material.E)
            small = j2.J2(E=material.E, nu=material.nu, yield_stress=sy, hardening=0.05 * material.E)
        else:
            mat, small = material, None
        state = mat.initial_state().copy()
        eps_p, st_small, sig_small = np.zeros(4), np.zeros(1), np.zeros(4)
        err = 0.0
        for e in strain_path(scale):
            F = [1.0 + e[0], e[3], e[3], 1.0 + e[2], 1.0 + e[1]]
            tau, state = kirchhoff(mat, F, state)
            J = (F[0] * F[3] - F[1] * F[2]) * F[4]
            sigma = tau / J
            if small is None:
                tr = e[0] + e[1] + e[2]
                sig_small = np.array([mat.lmbda * tr + 2 * mat.mu * e[0], mat.lmbda * tr + 2 * mat.mu * e[1],
                                      mat.lmbda * tr + 2 * mat.mu * e[2], 2 * mat.mu * e[3]])
            else:
                j2.update(e, eps_p, st_small, small.params(), 1e-8, sig_small)
            err = max(err, np.abs(sigma - sig_small).max() / np.abs(sig_small).max())
        if small is not None:
            assert state[0] == pytest.approx(st_small[0], rel=20 * scale)  # yielded alike
            assert st_small[0] > 0
        errors.append(err)
    assert errors[0] < 5 * 1e-4  # O(eps): the neglected terms are eps^2 against eps
    assert errors[1] < errors[0] / 5  # and shrink with eps


def test_johnson_cook_against_ode():
    """Isochoric uniaxial extension at a constant log-strain rate (1e4 1/s, to 0.4): the
    return mapping with adiabatic heating converges (first order in dt) to the direct
    integration of the same equations. On this path the elastic log strain is e - ep
    (coaxial), so q = 3 mu (rate t - ep) and, past the elastic limit t_y = A / (3 mu rate),
    ep' = rate0 exp((q / (g(ep) (1 - T*^m)) - 1) / C), T' = chi q ep' / (rho c_p):
    integrated by SciPy's LSODA at rtol 1e-10 (Radau and BDF agree to 1e-9)."""
    from scipy.integrate import solve_ivp

    m = JohnsonCook()
    p = m.params()
    rate, e_end = 1e4, 0.4
    t_end = e_end / rate

    def rhs(t, y):
        ep, T = y
        q = 3 * m.mu * (rate * t - ep)
        ts = min(max((T - m.t_room) / (m.t_melt - m.t_room), 0.0), 1.0)
        g = (m.A + m.B * max(ep, 0.0) ** m.n) * (1.0 - ts ** m.m)
        epd = m.rate0 * math.exp(min((q / g - 1.0) / m.C, 50.0))
        return [epd, m.chi * q * epd / (m.density * m.c_p)]

    t_y = m.A / (3 * m.mu * rate)
    sol = solve_ivp(rhs, (t_y, t_end), [0.0, m.t_room], method="LSODA", rtol=1e-10,
                    atol=[1e-15, 1e-10])
    assert sol.status == 0
    ep_ref, T_ref = sol.y[:, -1]
    q_ref = 3 * m.mu * (e_end - ep_ref)
    errs = []
    for n in (400, 1600):
        dt = t_end / n
        state = m.initial_state().copy()
        tau = np.zeros(4)
        for k in range(1, n + 1):
            x = rate * dt * k
            F = [math.exp(-x / 2), 0.0, 0.0, math.exp(x), math.exp(-x / 2)]
            m.update(np.array(F), state, p, dt, tau, np.zeros(16))
        q = tau[2] - tau[0]  # uniaxial: sqrt(3/2 |dev tau|^2) = |tau_zz - tau_rr|
        errs.append((abs(q - q_ref) / q_ref, abs(state[0] - ep_ref) / ep_ref,
                     abs(state[5] - T_ref) / (T_ref - m.t_room)))
    coarse, fine = np.array(errs[0]), np.array(errs[1])
    print("JC errors (q, ep, T) at dt = t/400 and t/1600:", coarse, fine)
    assert T_ref - m.t_room > 10.0  # the heating is felt (tens of K)
    assert np.all(fine < 5e-4)  # first order: dt = t_end / 1600
    assert np.all(fine[:2] < coarse[:2] / 3)  # q and ep shrink as dt (4x smaller dt)
    # the heating books the trapezoid of sigma_y over each increment: its error is already
    # at the 1e-6 level on both (the first-order errors of q and ep nearly cancel in it)
    assert fine[2] < 1e-5 and coarse[2] < 1e-5


def test_johnson_cook_bracket_infinite_slope():
    """n < 1: at eps_bar_p = 0 the slope is infinite; the bracketed solve still returns the
    point on the yield surface, q_{n+1} = sigma_y(eps_bar_p, rate, T_n), to the solve's own
    stopping rule (materials/johnson_cook.py: the residual within 1e-13 of the trial q,
    q + 3 mu d eps_bar_p, or the bracket within 1e-15 of that / 3 mu in eps_bar_p, which
    moves q by 3 mu + the slope times that) and the point's round-off (64 roundings with
    its exp and log)."""
    m = JohnsonCook(n=0.2, C=0.0, chi=0.0)
    state = m.initial_state().copy()
    tau, state = kirchhoff(m, [math.exp(-0.005), 0, 0, math.exp(0.01), math.exp(-0.005)], state)
    q = tau[2] - tau[0]
    assert state[0] > 0
    slope = m.B * m.n * state[0] ** (m.n - 1)
    q_trial = q + 3 * m.mu * state[0]
    stop = max(1e-13, 1e-15 * (3 * m.mu + slope) / (3 * m.mu)) * q_trial / q
    assert q == pytest.approx(flow_stress(m.params(), state[0], 0.0, state[5]),
                              rel=stop + rounding(64 + 4 * LIBM))
