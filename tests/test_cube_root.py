"""The F-bar kernel's cube root against exact cubes.

y = m / 2^16 with m < 2^17 has at most 17 significant bits, so y^3 has at most 51 and is
a double exactly: x = y^3 is an oracle that needs no library cube root. m over
[2^15, 2^17) gives y in [1/2, 2), x over the iteration's range [1/8, 8); the same y
times 1/4 and 4 (exact) test the library fallback on either side. The bound: 3 ulp of y,
the last Newton step's residual y^3 - x (two roundings on x, over 3 y^2) and the step's
own roundings, inside the library's allowance of tests/roundoff.py (LIBM = 4).
"""
import numpy as np
from numba import njit

from impact_fenics.internal_force.finite import cube_root
from roundoff import LIBM


@njit(cache=True)
def _roots(x, out):
    for i in range(x.size):
        out[i] = cube_root(x[i])


def test_cube_root_of_exact_cubes():
    y0 = np.arange(2 ** 15, 2 ** 17, dtype=np.float64) / 2.0 ** 16
    for scale, iterated in ((0.25, False), (1.0, True), (4.0, False)):
        y = scale * y0
        x = y * y * y
        assert np.array_equal(x / y / y, y)  # the cubes are exact
        assert np.all((x >= 0.125) & (x < 8.0)) == iterated
        out = np.empty_like(x)
        _roots(x, out)
        assert (np.abs(out - y) / np.spacing(y)).max() <= LIBM - 1


def test_cube_root_series_within_one_ulp():
    """The branch |x - 1| <= 1/16 (the binomial series): within 1 ulp, as its docstring
    derives (the truncation 1.9e-18, the final 1 + e p rounding once on 1 (1/2 ulp of y
    at most, as y's ulp is 1 or 1/2 of 1's), e p <= 0.022 carrying a few roundings of its
    own size, 0.15 ulp). Oracles: the exact cubes of the branch, and random x near 1 in
    exact rational arithmetic: y - x^(1/3) = (y^3 - x) / (y^2 + y x^(1/3) + x^(2/3)), whose
    denominator lies within (3 min(y, x^(1/3))^2, 3 max(...)^2): evaluated with y, it errs by
    a relative 2 |y - x^(1/3)| / y, so a residual of 1 ulp reads as 1 ulp (1 + 1e-15)."""
    from fractions import Fraction

    y0 = np.arange(2 ** 15, 2 ** 17, dtype=np.float64) / 2.0 ** 16
    x = y0 * y0 * y0
    branch = np.abs(x - 1.0) <= 1.0 / 16.0
    y, x = y0[branch], x[branch]
    assert y.size > 2700  # the branch is 1/8 wide in x, about 1/24 in y: 2732 exact cubes
    out = np.empty_like(x)
    _roots(x, out)
    assert (np.abs(out - y) / np.spacing(y)).max() <= 1
    rng = np.random.default_rng(3)
    x = 1.0 + rng.uniform(-1.0 / 16.0, 1.0 / 16.0, 2000)
    out = np.empty_like(x)
    _roots(x, out)
    for xi, yi in zip(x, out):
        yf, xf = Fraction(float(yi)), Fraction(float(xi))
        err = abs(yf ** 3 - xf) / (3 * yf * yf)  # |y - x^(1/3)| within (1 + 1e-15)
        assert float(err) <= float(np.spacing(yi)) * (1.0 + 1e-15)
