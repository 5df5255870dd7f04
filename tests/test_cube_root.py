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
