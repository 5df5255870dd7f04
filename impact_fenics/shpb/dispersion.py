"""Pochhammer–Chree dispersion of a free elastic bar, and the dispersion correction of
a strain record taken on the bar.

A harmonic longitudinal wave exp(i(ωt − kz)) in a free, infinitely long, isotropic elastic
cylinder of radius a travels at the phase velocity c = ω/k that makes the Pochhammer–Chree
frequency equation vanish. With the squared radial wave numbers (times a)

    p² = (ka)² (c²/c_L² − 1),      q² = (ka)² (c²/c_T² − 1),      ξ = ka = 2π a/Λ,

and the even, entire functions  F(s) = J₀(√s),  G(s) = J₁(√s)/√s  (I₀ and I₁/√(−s) for
s < 0), the equation divided by q ξ⁴ reads

    2 p̂² (q̂² + 1) G(p²) G(q²) − (q̂² − 1)² F(p²) G(q²) − 4 p̂² G(p²) F(q²) = 0,

with p̂² = p²/ξ², q̂² = q²/ξ². Written this way it is real on both sides of c = c_T (where q²
changes sign) and every term carries one function of p² and one of q², so the exponential
growth of I₀, I₁ is scaled out of all three terms alike (scipy's i0e, i1e).

The first (lowest) mode's phase velocity c_p falls from the bar speed c₀ = √(E/ρ) at long
waves, as c_p/c₀ ≈ 1 − ν²π²(a/Λ)² (Rayleigh–Love), to the Rayleigh surface-wave speed c_R at
short waves. :func:`first_mode` finds it by bracketing and bisection; :func:`phase_velocity`
interpolates a table of it made once per ν (a cubic spline) and :func:`correct`
moves a recorded strain pulse along the bar component by component with it.
"""
from __future__ import annotations

import functools
import math

import numpy as np
from scipy import interpolate, optimize, special

from impact_fenics.errors import InputError

# the table: a/Λ from 0 to A_OVER_LAMBDA_MAX, fine where the curve bends (a/Λ < 1)
A_OVER_LAMBDA_MAX = 20.0
_TABLE_GRID = np.concatenate([np.linspace(0.0, 1.0, 801),
                              np.linspace(1.0, 4.0, 601)[1:],
                              np.linspace(4.0, A_OVER_LAMBDA_MAX, 641)[1:]])
_SCAN_POINTS = 400       # sign scan in c/c₀ before the bisection
_BISECTIONS = 60         # halvings of a bracket of width < 1: below one ulp of c/c₀


def _check_nu(nu: float) -> float:
    nu = float(nu)
    if not (0.0 < nu < 0.5):
        raise InputError(f"the bar's Poisson's ratio must lie in (0, 0.5), got {nu}")
    return nu


def _speed_ratios(nu: float) -> tuple[float, float]:
    """(c₀/c_L)² = (1 + ν)(1 − 2ν)/(1 − ν) and (c₀/c_T)² = 2(1 + ν)."""
    return (1.0 + nu) * (1.0 - 2.0 * nu) / (1.0 - nu), 2.0 * (1.0 + nu)


def _bessel_pair(s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """F(s) = J₀(√s) and G(s) = J₁(√s)/√s, for s < 0 I₀(√−s) and I₁(√−s)/√−s, both times
    exp(−√−s) there (the scale that every term of the frequency equation shares)."""
    z = np.sqrt(np.abs(s))
    z_safe = np.where(z == 0.0, 1.0, z)
    positive = s >= 0.0
    f = np.where(positive, special.j0(z), special.i0e(z))
    g = np.where(positive, special.j1(z_safe), special.i1e(z_safe)) / z_safe
    return f, np.where(z == 0.0, 0.5, g)


def frequency_terms(c_over_c0, a_over_lambda, nu: float):
    """The three terms of the scaled frequency equation (module docstring) at the phase
    velocity c/c₀ and the radius over the wavelength a/Λ (both dimensionless, broadcast).
    Their sum is the frequency function; it vanishes on a mode."""
    beta_l, beta_t = _speed_ratios(_check_nu(nu))
    r2 = np.asarray(c_over_c0, dtype=float) ** 2
    xi2 = (2.0 * math.pi * np.asarray(a_over_lambda, dtype=float)) ** 2
    p2_hat = r2 * beta_l - 1.0
    q2_hat = r2 * beta_t - 1.0
    fp, gp = _bessel_pair(xi2 * p2_hat)
    fq, gq = _bessel_pair(xi2 * q2_hat)
    return (2.0 * p2_hat * (q2_hat + 1.0) * gp * gq,
            -((q2_hat - 1.0) ** 2) * fp * gq,
            -4.0 * p2_hat * gp * fq)


def frequency_function(c_over_c0, a_over_lambda, nu: float) -> np.ndarray:
    """The Pochhammer–Chree frequency function (the sum of :func:`frequency_terms`)."""
    t1, t2, t3 = frequency_terms(c_over_c0, a_over_lambda, nu)
    return t1 + t2 + t3


@functools.lru_cache(maxsize=None)
def rayleigh_speed(nu: float) -> float:
    """The Rayleigh wave speed over the bar speed, c_R/c₀, for Poisson's ratio ν: the root
    y = (c_R/c_T)² in (0, 1) of (2 − y)² = 4 √(1 − κy) √(1 − y), κ = (c_T/c_L)²."""
    beta_l, beta_t = _speed_ratios(_check_nu(nu))
    kappa = beta_l / beta_t

    def rayleigh(y: float) -> float:
        return (2.0 - y) ** 2 - 4.0 * math.sqrt(1.0 - kappa * y) * math.sqrt(1.0 - y)

    # y = 0 is the trivial root; the function is negative at y = 1/2 for every ν and 1 at 1
    y = optimize.brentq(rayleigh, 0.5, 1.0, xtol=1e-300, rtol=4.0 * np.finfo(float).eps,
                        maxiter=200)
    return math.sqrt(y / beta_t)


def first_mode(a_over_lambda, nu: float) -> np.ndarray:
    """The first mode's phase velocity c_p/c₀ at radius over wavelength a/Λ (array, ≥ 0),
    by root finding: a sign scan of the frequency function upward in c/c₀ from below c_R
    (the first sign change is the lowest mode; c = 0 is a trivial root and is left
    below the scan), then bisection of that bracket to one ulp. a/Λ = 0 gives 1."""
    nu = _check_nu(nu)
    x = np.atleast_1d(np.asarray(a_over_lambda, dtype=float))
    if np.any(~np.isfinite(x)) or np.any(x < 0.0):
        raise InputError("a/Λ must be finite and non-negative")
    c_low = 0.9 * rayleigh_speed(nu)
    # a little above c₀, so that a root within round-off of c₀ (a/Λ → 0) is bracketed
    grid = np.linspace(c_low, 1.001, _SCAN_POINTS)
    values = frequency_function(grid[None, :], x[:, None], nu)
    change = np.signbit(values[:, :-1]) != np.signbit(values[:, 1:])
    has_root = change.any(axis=1)
    first = np.argmax(change, axis=1)
    lo = grid[first]
    hi = grid[first + 1]
    f_lo = frequency_function(lo, x, nu)
    for _ in range(_BISECTIONS):
        mid = 0.5 * (lo + hi)
        f_mid = frequency_function(mid, x, nu)
        same = np.signbit(f_mid) == np.signbit(f_lo)
        lo = np.where(same, mid, lo)
        f_lo = np.where(same, f_mid, f_lo)
        hi = np.where(same, hi, mid)
    root = 0.5 * (lo + hi)
    root = np.where(x == 0.0, 1.0, root)
    if np.any(~has_root & (x > 0.0)):
        raise RuntimeError("no first-mode root bracketed between 0.9 c_R and 1.001 c0")
    return root.reshape(np.shape(a_over_lambda))


@functools.lru_cache(maxsize=None)
def _table(nu: float):
    """The first mode tabulated once per ν: c_p/c₀ against (a/Λ)² and against the square
    of the normalised frequency f a/c₀ = (a/Λ)(c_p/c₀), both cubic splines (c_p is even in
    both, so in their squares it is smooth up to 0), the last frequency of the table, its
    c_p/c₀, and the least group velocity over c₀ (d(f a/c₀)/d(a/Λ)).

    A spline, not a monotone (PCHIP) cubic: c_p is not monotone (it dips below c_R before
    rising to it), and a PCHIP's curvature jumps at every node; in a correction those jumps
    ring as slowly decaying tails before and after the pulse, which a twice continuously
    differentiable spline keeps far smaller."""
    c = first_mode(_TABLE_GRID, nu)
    frequency = _TABLE_GRID * c
    return (interpolate.CubicSpline(_TABLE_GRID ** 2, c, extrapolate=False),
            interpolate.CubicSpline(frequency ** 2, c, extrapolate=False),
            float(frequency[-1]), float(c[-1]),
            float(np.min(np.diff(frequency) / np.diff(_TABLE_GRID))))


def phase_velocity(a_over_lambda, nu: float) -> np.ndarray:
    """The first mode's phase velocity c_p/c₀ at radius over wavelength a/Λ
    (dimensionless, array), interpolated in the table of :func:`first_mode` (a/Λ up to
    A_OVER_LAMBDA_MAX; beyond it, the table's last value, near c_R)."""
    of_x, _, _, c_last, _ = _table(_check_nu(nu))
    x = np.asarray(a_over_lambda, dtype=float)
    return np.where(x > A_OVER_LAMBDA_MAX, c_last,
                    of_x(np.minimum(x, A_OVER_LAMBDA_MAX) ** 2))


def phase_velocity_at(frequency, radius: float, nu: float, c0: float) -> np.ndarray:
    """The first mode's phase velocity c_p (m/s) at the frequency f (Hz, array) in a bar
    of radius a (m) and bar speed c₀ (m/s): the table read at f a/c₀."""
    _, of_frequency, frequency_last, c_last, _ = _table(_check_nu(nu))
    omega_hat = np.abs(np.asarray(frequency, dtype=float)) * radius / c0
    ratio = np.where(omega_hat > frequency_last, c_last,
                     of_frequency(np.minimum(omega_hat, frequency_last) ** 2))
    return c0 * ratio


def slowest_group_velocity(nu: float) -> float:
    """The first mode's least group velocity over c₀ (from the table; it bounds how far a
    dispersed pulse's envelope lags the bar-speed delay)."""
    return _table(_check_nu(nu))[4]


def _uniform_step(t: np.ndarray) -> float:
    dt = (t[-1] - t[0]) / (t.size - 1)
    # a sampling clock's times carry round-off of a few ulps of the largest time
    slack = 64.0 * np.finfo(float).eps * max(abs(t[0]), abs(t[-1]))
    if not dt > 0.0 or np.max(np.abs(np.diff(t) - dt)) > max(1e-6 * dt, slack):
        raise InputError("the dispersion correction needs uniformly sampled, increasing times")
    return dt


def correct(t: np.ndarray, strain: np.ndarray, distance: float, radius: float, nu: float,
            c0: float) -> np.ndarray:
    """Move a strain pulse recorded on a bar along it by `distance` with the first mode's
    dispersion, keeping the non-dispersive delay out.

    t: uniformly sampled times (s); strain: the record there (dimensionless), at rest at
    both ends; distance Δz (m): the path along the wave's direction of travel, positive to
    propagate (the incident wave from its gauge to the bar's end face), negative to undo a
    propagation (the reflected or transmitted wave brought back from its gauge to the
    face); radius a (m), Poisson's ratio ν and bar speed c₀ (m/s) of the bar.

    Each Fourier component ε̂(ω) of the zero-padded record becomes
    ε̂(ω) exp(−i ω Δz (1/c_p(ω) − 1/c₀)): the component's own travel time over Δz minus
    the bar-speed delay Δz/c₀, which the caller applies as to an uncorrected signal. The
    amplitudes are kept: the first mode's radial variation of strain and modulus across
    the section (which changes the surface strain's relation to the mean stress at short
    wavelengths) is left out. The record is zero-padded so that no component's shift wraps
    round the transform; the Nyquist bin of the even transform length is left as is (a
    real cosine cannot take a phase). Returns the moved record at the same times.
    """
    t = np.asarray(t, dtype=float)
    strain = np.asarray(strain, dtype=float)
    if t.ndim != 1 or strain.shape != t.shape or t.size < 2:
        raise InputError("the dispersion correction needs times and strains of one equal "
                         "length, at least two samples")
    if not (np.all(np.isfinite(strain)) and np.all(np.isfinite(t))):
        raise InputError("the dispersion correction needs finite times and strains")
    for name, value in (("radius", radius), ("bar wave speed c0", c0)):
        if not (math.isfinite(value) and value > 0.0):
            raise InputError(f"the dispersion correction needs a positive {name}, got {value}")
    if not math.isfinite(distance):
        raise InputError(f"the dispersion correction needs a finite distance, got {distance}")
    dt = _uniform_step(t)
    n = t.size
    # the envelope of a dispersed pulse lags the bar-speed delay by at most
    # |Δz| (1/c_g,min − 1/c₀): pad by that beyond the record's own length
    lag = abs(distance) / c0 * (1.0 / slowest_group_velocity(nu) - 1.0)
    shift = int(math.ceil(lag / dt))
    size = 1 << int(math.ceil(math.log2(2 * n + shift)))
    spectrum = np.fft.rfft(strain, size)
    frequency = np.fft.rfftfreq(size, dt)
    c_p = phase_velocity_at(frequency, radius, nu, c0)
    phase = 2.0 * math.pi * frequency * distance * (1.0 / c_p - 1.0 / c0)
    phase[-1] = 0.0  # the Nyquist bin (size is even)
    return np.fft.irfft(spectrum * np.exp(-1j * phase), size)[:n]
