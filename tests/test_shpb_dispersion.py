"""The Pochhammer–Chree first mode and the dispersion correction of a bar's strain record.

Oracles: the closed-form long-wave series of the frequency equation (Rayleigh–Love slope
and the next two terms, derived by hand/CAS from the same equation, independently of the
root finder), the Rayleigh speed in closed form at ν = 1/4, the short-wave limit by
Richardson extrapolation, the equation's own residual, and for the correction: exact
reversibility, the long-wave expansion of the phase shift (a third derivative in time),
and Parseval. Pure numpy: every MPI rank computes the same.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.polynomial import hermite

from impact_fenics.errors import InputError
from impact_fenics.shpb import dispersion

EPS = np.finfo(float).eps
NU_STEEL = 0.29


def love_series(nu: float) -> tuple[float, float, float]:
    """c_p/c₀ = 1 + b₂x² + b₄x⁴ + b₆x⁶ + O(x⁸), x = a/Λ: the frequency equation expanded in
    (ka)² (Bessel series of J₀, J₁/z) and solved order by order for (c/c_T)². b₂ = −ν²π²
    is Rayleigh–Love's slope."""
    b2 = -math.pi ** 2 * nu ** 2
    b4 = (math.pi ** 4 * nu ** 2 * (21 * nu ** 4 + 4 * nu ** 3 - 29 * nu ** 2 - 4 * nu + 7)
          / (6 * (nu - 1) * (nu + 1)))
    b6 = (-math.pi ** 6 * nu ** 2 * (396 * nu ** 7 - 252 * nu ** 6 - 824 * nu ** 5
                                     + 480 * nu ** 4 + 492 * nu ** 3 - 254 * nu ** 2
                                     - 69 * nu + 33)
          / (24 * (nu - 1) ** 2 * (nu + 1)))
    return b2, b4, b6


@pytest.mark.parametrize("nu", [0.25, NU_STEEL, 0.33])
def test_long_wave_limit_and_love_slope(nu):
    """At a/Λ ≤ 0.08 the root matches the series: after the Love term the remainder is the
    x⁴ term, after that the x⁶ term, each to within its own relative O(x²) correction
    (|b₈/b₆| x² ≈ |b₆/b₄| x² < 0.04 here), so twice the next term bounds it."""
    b2, b4, b6 = love_series(nu)
    assert dispersion.first_mode(0.0, nu) == 1.0
    # below a/Λ ≈ 1e-8 the Love term ν²π²x² is under one ulp of 1: the root is c₀
    assert abs(dispersion.first_mode(1e-9, nu) - 1.0) <= 2 * EPS
    for x in (0.005, 0.01, 0.02, 0.04, 0.08):
        c = float(dispersion.first_mode(x, nu))
        love = 1.0 + b2 * x ** 2
        two_terms = love + b4 * x ** 4
        print(f"nu={nu} a/L={x}: c/c0={c:.15f}  Love {love:.12f}  "
              f"(c - Love)/(b4 x^4)={(c - love) / (b4 * x ** 4):.6f}  "
              f"(c - 2 terms)/(b6 x^6)={(c - two_terms) / (b6 * x ** 6):.6f}")
        assert abs(c - love) <= 2.0 * abs(b4) * x ** 4
        # the x⁶ term against round-off in c/c₀ (a few ulps of 1)
        assert abs(c - two_terms) <= 2.0 * abs(b6) * x ** 6 + 8 * EPS


def test_rayleigh_speed_closed_form():
    """ν = 1/4 (λ = μ): (c_R/c_T)² = 2 − 2/√3, and (c₀/c_T)² = 2(1 + ν) = 5/2; the root
    is bracketed to a few ulps."""
    exact = math.sqrt((2.0 - 2.0 / math.sqrt(3.0)) / 2.5)
    got = dispersion.rayleigh_speed(0.25)
    print(f"c_R/c0 at nu=1/4: {got:.16f} (closed form {exact:.16f})")
    assert abs(got - exact) <= 8 * EPS


@pytest.mark.parametrize("nu", [0.25, NU_STEEL, 0.45])
def test_short_wave_limit_is_rayleigh(nu):
    """c_p → c_R as a/Λ → ∞, with an O(Λ/a) curvature correction: the Richardson limit
    2c(2x) − c(x) removes it, and the change of that limit from (20, 40) to (40, 80)
    estimates what remains (three times its error for an O(1/x²) remainder); twice that
    estimate allows for the O(1/x³) terms."""
    c = {x: float(dispersion.first_mode(x, nu)) for x in (20.0, 40.0, 80.0)}
    coarse = 2.0 * c[40.0] - c[20.0]
    fine = 2.0 * c[80.0] - c[40.0]
    c_r = dispersion.rayleigh_speed(nu)
    print(f"nu={nu}: c_R/c0={c_r:.9f} c(20)={c[20.0]:.9f} c(80)={c[80.0]:.9f} "
          f"Richardson {fine:.9f}, error {fine - c_r:.2e}, estimate {(fine - coarse) / 3:.2e}")
    assert abs(fine - c_r) <= 2.0 * abs(fine - coarse) / 3.0


@pytest.mark.parametrize("nu", [0.25, NU_STEEL, 0.45])
def test_root_satisfies_frequency_equation(nu):
    """At the root the three terms cancel to their round-off (each term a product of about
    six rounded factors, a Bessel function a few ulps: 16 ε of their sizes) plus the
    function's change over the root's last bisection bracket (2 ulps of c/c₀)."""
    x = np.array([0.01, 0.1, 0.3, 0.5, 1.0, 2.0, 5.0, 10.0, 20.0])
    c = dispersion.first_mode(x, nu)
    terms = dispersion.frequency_terms(c, x, nu)
    residual = np.abs(sum(terms))
    size = sum(np.abs(t) for t in terms)
    step = 1e-6
    slope = np.abs(dispersion.frequency_function(c + step, x, nu)
                   - dispersion.frequency_function(c - step, x, nu)) / (2 * step)
    bound = 16 * EPS * size + slope * 2 * EPS * c
    print(f"nu={nu}: residual / term sizes = {np.max(residual / size):.2e}, "
          f"residual / bound = {np.max(residual / bound):.2f}")
    assert np.all(residual <= bound)


def test_table_interpolation():
    """The cubic-spline table against the root finder between its nodes, within the
    linear-interpolation bound h² |c''|/8 of each interval (in the tabulated variable
    (a/Λ)²; c'' from the nodes' divided differences); the cubic spline does better."""
    grid = dispersion._TABLE_GRID
    s = grid ** 2
    c = dispersion.first_mode(grid, NU_STEEL)
    h = np.diff(s)
    second = np.abs(np.diff(np.diff(c) / h) / (0.5 * (h[1:] + h[:-1])))
    # the larger second difference of the interval's two stencils
    curvature = np.maximum(np.concatenate([second[:1], second]),
                           np.concatenate([second, second[-1:]]))
    mid = np.sqrt(0.5 * (s[1:] + s[:-1]))
    error = np.abs(dispersion.phase_velocity(mid, NU_STEEL) - dispersion.first_mode(mid, NU_STEEL))
    bound = h ** 2 * curvature / 8.0 + 8 * EPS
    worst = error.argmax()
    print(f"table: max interpolation error {error[worst]:.2e} (bound there {bound[worst]:.2e})")
    assert np.all(error <= 2.0 * bound)
    # the frequency-indexed reading agrees with the wavelength-indexed one
    frequency = mid * dispersion.first_mode(mid, NU_STEEL)
    by_frequency = dispersion.phase_velocity_at(frequency / 0.01, 0.01, NU_STEEL, 1.0)
    assert np.all(np.abs(by_frequency - dispersion.first_mode(mid, NU_STEEL)) <= 2.0 * bound)


# an SHPB-like bar: 20 mm steel, c₀ = 5000 m/s, gauge 1 m from the face
RADIUS = 0.01
C0 = 5000.0
DISTANCE = 1.0


def gaussian(t: np.ndarray, centre: float, sigma: float, order: int = 0) -> np.ndarray:
    """The order-th time derivative of exp(−(t − centre)²/(2σ²)) (Hermite polynomials)."""
    u = (t - centre) / (sigma * math.sqrt(2.0))
    coefficients = np.zeros(order + 1)
    coefficients[order] = 1.0
    scale = (-1.0 / (sigma * math.sqrt(2.0))) ** order
    return scale * hermite.hermval(u, coefficients) * np.exp(-u * u)


def shpb_pulse():
    """A 60 µs pulse with 5 µs Gaussian edges (content up to the slowest group velocity),
    with room behind it for the dispersed tail: the envelope lags by at most
    Δz (1/c_g,min − 1/c₀) ≈ 330 µs, and 40 edge widths more let its Airy tail decay."""
    dt = 0.2e-6
    sigma = 5e-6
    lag = DISTANCE / C0 * (1.0 / dispersion.slowest_group_velocity(NU_STEEL) - 1.0)
    start = 20 * sigma
    end = start + 60e-6
    t = np.arange(int((end + lag + 40 * sigma) / dt)) * dt
    pulse = np.where(t < start, gaussian(t, start, sigma),
                     np.where(t > end, gaussian(t, end, sigma), 1.0))
    return t, 1e-3 * pulse


def fft_roundoff(t: np.ndarray, distance: float) -> float:
    """Relative 2-norm round-off of a forward and an inverse FFT with a phase product
    between: each transform ≲ ε log₂ m (its stage count) for the padded length m, which is
    at most 4n + 2 × the lag in samples; the complex exponential and product a few ε."""
    dt = t[1] - t[0]
    lag = abs(distance) / C0 * (1.0 / dispersion.slowest_group_velocity(NU_STEEL) - 1.0)
    size = 2.0 * (2 * t.size + lag / dt + 1.0)
    return (2.0 * math.log2(size) + 8.0) * EPS


def leak(t: np.ndarray, strain: np.ndarray, distance: float) -> np.ndarray:
    """What the move carries beyond the record's end: the same record with three times
    its length of rest appended, moved, read after the original end."""
    n = t.size
    longer = np.arange(4 * n) * (t[1] - t[0])
    moved = dispersion.correct(longer, np.concatenate([strain, np.zeros(3 * n)]), distance,
                               RADIUS, NU_STEEL, C0)
    return moved[n:]


def test_forward_then_back_is_identity():
    """Propagating by +Δz and correcting by −Δz multiplies each padded component by
    e^{−iθ} e^{+iθ}: the record comes back to the round-off of four FFTs, plus what the
    first move carried past the record's end (cut off, so not moved back: its 2-norm
    bounds its share, the back move being unitary)."""
    t, strain = shpb_pulse()
    moved = dispersion.correct(t, strain, DISTANCE, RADIUS, NU_STEEL, C0)
    back = dispersion.correct(t, moved, -DISTANCE, RADIUS, NU_STEEL, C0)
    change = np.max(np.abs(moved - strain)) / np.max(np.abs(strain))
    error = np.max(np.abs(back - strain))
    cut = np.linalg.norm(leak(t, strain, DISTANCE))
    bound = 2.0 * fft_roundoff(t, DISTANCE) * np.linalg.norm(strain) + cut
    peak = np.max(np.abs(strain))
    print(f"round trip over {DISTANCE} m: the pulse changed by {change:.2%} of its peak, "
          f"back to {error / peak:.2e} of it (bound {bound / peak:.2e}, "
          f"of which the cut tail {cut / peak:.2e})")
    assert change > 0.05  # the dispersion is no round-off
    assert error <= bound


def test_parseval_energy_kept():
    """The phase shift is unitary on the padded transform (the Nyquist bin untouched):
    Σ ε² of the moved record plus that of what it carried past the record's end is the
    original Σ ε² to the FFTs' round-off."""
    t, strain = shpb_pulse()
    moved = dispersion.correct(t, strain, DISTANCE, RADIUS, NU_STEEL, C0)
    energy = np.sum(strain ** 2)
    cut = np.sum(leak(t, strain, DISTANCE) ** 2)
    drift = abs(np.sum(moved ** 2) + cut - energy) / energy
    print(f"Parseval: relative energy change {drift:.2e}, of which cut off {cut / energy:.2e}")
    assert drift <= 2.0 * fft_roundoff(np.arange(4 * t.size) * (t[1] - t[0]), DISTANCE)


def test_long_wave_pulse_is_unchanged_to_second_order():
    """A Gaussian of σ = 50 µs (length c₀σ = 0.25 m, 25 radii): with
    1/c_p − 1/c₀ = (1/c₀)[−b₂ω̂² + (3b₂² − b₄)ω̂⁴ + …], ω̂ = ωa/(2πc₀), each component's phase
    is θ = Kω³ + K₅ω⁵ + …, K = Δz ν² a²/(4c₀³), so e^{−iθ} turns the pulse into
    ε + K ε''' − K₅ ε⁽⁵⁾ + (K²/2) ε⁽⁶⁾ + …: the change is the dispersion's second order
    K ε''' (relative size ν²(a/Λ)²), and what remains is bounded by twice the next terms."""
    b2, b4, _ = love_series(NU_STEEL)
    sigma = 50e-6
    dt = 1e-6
    t = np.arange(1201) * dt
    centre = 600e-6
    strain = gaussian(t, centre, sigma)
    moved = dispersion.correct(t, strain, DISTANCE, RADIUS, NU_STEEL, C0)
    k3 = DISTANCE * NU_STEEL ** 2 * RADIUS ** 2 / (4.0 * C0 ** 3)
    k5 = DISTANCE / C0 * (3.0 * b2 ** 2 - b4) * (RADIUS / (2.0 * math.pi * C0)) ** 4
    second = k3 * gaussian(t, centre, sigma, 3)
    rest = np.max(np.abs(moved - strain - second))
    next_terms = (np.max(np.abs(k5 * gaussian(t, centre, sigma, 5)))
                  + np.max(np.abs(0.5 * k3 ** 2 * gaussian(t, centre, sigma, 6))))
    print(f"long wave: change {np.max(np.abs(moved - strain)):.3e} of a unit peak, "
          f"K e''' {np.max(np.abs(second)):.3e}, remainder {rest:.2e} "
          f"(next terms {next_terms:.2e})")
    assert np.max(np.abs(moved - strain)) <= 1.1 * np.max(np.abs(second))
    assert rest <= 2.0 * next_terms + fft_roundoff(t, DISTANCE) * np.linalg.norm(strain)


def test_bad_input():
    t = np.linspace(0.0, 1e-4, 101)
    strain = np.zeros_like(t)
    with pytest.raises(InputError, match="uniformly sampled"):
        dispersion.correct(t ** 2, strain, 1.0, RADIUS, NU_STEEL, C0)
    with pytest.raises(InputError, match="Poisson"):
        dispersion.correct(t, strain, 1.0, RADIUS, 0.5, C0)
    with pytest.raises(InputError, match="radius"):
        dispersion.correct(t, strain, 1.0, -RADIUS, NU_STEEL, C0)
    with pytest.raises(InputError, match="equal length"):
        dispersion.correct(t, strain[:-1], 1.0, RADIUS, NU_STEEL, C0)


def pochhammer_terms(c: float, x: float, nu: float) -> tuple[complex, complex, complex]:
    """The three terms of the Pochhammer frequency equation of a free solid cylinder in
    its textbook form (radius a = 1, c₀ = 1, k = 2π x, x = a/Λ, ω = k c):

        2α (β² + k²) J₁(α) J₁(β) − (β² − k²)² J₀(α) J₁(β) − 4k² αβ J₁(α) J₀(β) = 0,
        α² = k² (c²/c_L² − 1),  β² = k² (c²/c_T² − 1),

    with complex square roots and scipy's Bessel functions of complex argument: written
    here independently of :mod:`impact_fenics.shpb.dispersion` (no rescaling, no real
    forms). Above c_T the sum is real; below it, i times a real number."""
    from scipy import special

    ct2 = 1.0 / (2.0 * (1.0 + nu))
    cl2 = (1.0 - nu) / ((1.0 + nu) * (1.0 - 2.0 * nu))
    k = 2.0 * math.pi * x
    alpha = np.sqrt(complex(k * k * (c * c / cl2 - 1.0)))
    beta = np.sqrt(complex(k * k * (c * c / ct2 - 1.0)))
    j0a, j1a = special.jv(0, alpha), special.jv(1, alpha)
    j0b, j1b = special.jv(0, beta), special.jv(1, beta)
    return (2.0 * alpha * (beta ** 2 + k * k) * j1a * j1b,
            -((beta ** 2 - k * k) ** 2) * j0a * j1b,
            -4.0 * k * k * alpha * beta * j1a * j0b)


def pochhammer_root(x: float, nu: float) -> tuple[float, float]:
    """The first mode's c/c₀ at a/Λ = x by a sign scan and bisection of the textbook
    equation (its real part above c_T, its imaginary part below; c = c_T, where β = 0
    makes every term vanish, is never bracketed), and the root's round-off: 16 ε of the
    terms' sizes (each term a Bessel product of a few ulps and a dozen roundings) over
    the equation's slope there."""
    ct = math.sqrt(1.0 / (2.0 * (1.0 + nu)))

    def f(c: float) -> float:
        total = sum(pochhammer_terms(c, x, nu))
        return total.imag if c < ct else total.real

    # below c_T first (from 0.5 c₀, under the Rayleigh speed, above the trivial root 0):
    # any root there is the lowest mode; else the first root above c_T
    for lo_end, hi_end in ((0.5, ct * (1.0 - 1e-9)), (ct * (1.0 + 1e-9), 1.0 + 1e-9)):
        grid = np.linspace(lo_end, hi_end, 2001)
        values = np.array([f(c) for c in grid])
        change = np.flatnonzero(np.signbit(values[:-1]) != np.signbit(values[1:]))
        if change.size:
            lo, hi = grid[change[0]], grid[change[0] + 1]
            f_lo = f(lo)
            for _ in range(80):
                mid = 0.5 * (lo + hi)
                f_mid = f(mid)
                if np.signbit(f_mid) == np.signbit(f_lo):
                    lo, f_lo = mid, f_mid
                else:
                    hi = mid
            root = 0.5 * (lo + hi)
            step = 1e-7 * root
            slope = abs(f(root + step) - f(root - step)) / (2.0 * step)
            size = sum(abs(t) for t in pochhammer_terms(root, x, nu))
            return root, 16.0 * EPS * size / slope
    raise AssertionError(f"no root at a/Λ = {x}")


@pytest.mark.parametrize("nu", [0.25, NU_STEEL])
def test_first_mode_against_the_textbook_equation(nu):
    """The first mode of the code (its rescaled real form, scanned and bisected) against
    the root of the textbook Pochhammer equation solved here by its own scan and
    bisection, from long waves through c_T (which the first mode crosses near
    a/Λ ≈ 0.65) to short ones: equal within the two roots' round-off (each 16 ε of its
    terms over the slope) plus two ulps of each bisection's last bracket. The page's
    table (docs/shpb.md, 5 digits) agrees to its last digit."""
    table = {0.25: {0.1: 0.99333, 0.25: 0.93479, 0.5: 0.69344, 0.75: 0.61163, 1.0: 0.58932,
                    2.0: 0.57830},
             NU_STEEL: {0.1: 0.99113, 0.25: 0.92175, 0.5: 0.68927, 0.75: 0.60877,
                        1.0: 0.58607, 2.0: 0.57408}}[nu]
    for x, printed in table.items():
        oracle, roundoff = pochhammer_root(x, nu)
        got = float(dispersion.first_mode(x, nu))
        bound = 2.0 * roundoff + 4.0 * EPS
        print(f"nu={nu} a/L={x}: code {got:.16f} textbook {oracle:.16f} "
              f"difference {got - oracle:+.1e} (bound {bound:.1e})")
        assert abs(got - oracle) <= bound
        assert abs(oracle - printed) <= 0.5e-5 + 4.0 * EPS
