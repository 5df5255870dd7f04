"""Symmetric tensors at a point in the axisymmetric four-component notation.

A strain or stress is a float64 array ``a`` of four tensor components in the
order (rr, tt, zz, rz), with tt the hoop (theta theta) component and ``a[3]``
the tensor shear (eps_rz = gamma_rz / 2, not the engineering strain). The
other shear components vanish in axisymmetry without torsion, so

    tr a = a0 + a1 + a2,    a : b = a0 b0 + a1 b1 + a2 b2 + 2 a3 b3.

These are the building blocks of the return mappings (numba, no allocation).
Point update of a path-dependent material (the seam of the internal force):

    update(eps, eps_p, state, params, dt, sigma) -> None

``eps`` the total strain at t_{n+1}; ``eps_p`` the plastic strain, on entry at
t_n and on exit at t_{n+1}; ``state`` the material's other internal variables
(``state[0]`` the equivalent plastic strain, ``eps_bar_p``), updated in place;
``params`` the material's float64 parameter array; ``dt`` the step (s);
``sigma`` receives the Cauchy stress at t_{n+1} (Pa). Stresses are
sigma = C : (eps - eps_p) with the isotropic elastic C (Lame lambda, mu).

The internal force (:mod:`impact_fenics.internal_force.quadrature`) calls the
update once per quadrature point and step from a compiled cell kernel, with
small scratch arrays for ``eps``, ``eps_p``, ``state`` and ``sigma``: an
update must not allocate, and may read ``sigma`` only as output.

A material may also give the same update on scalars, as its ``point`` (the
package's J2 and Drucker-Prager do; their ``update`` calls it):

    point(e0, e1, e2, e3, p0, p1, p2, p3, state, k, params, dt) -> (s0, s1, s2, s3, q0, q1, q2, q3)

(e0..e3) the strain at t_{n+1}, (p0..p3) the plastic strain at t_n, the returned
stress at t_{n+1} (Pa) and plastic strain at t_{n+1}; the point's variables are
``state[k:k + n_state]`` of the array of every point's, updated in place. The cell
kernel then calls it with the strain and the state where they are, without the
copies through scratch arrays.
"""
from __future__ import annotations

import math

from numba import njit

SQRT_3_2 = math.sqrt(1.5)
SQRT_2_3 = math.sqrt(2.0 / 3.0)


@njit(cache=True)
def contract(a, b) -> float:
    """a : b (full double contraction of the 3x3 tensors)."""
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2] + 2.0 * a[3] * b[3]


@njit(cache=True)
def von_mises(s) -> float:
    """sqrt(3/2 dev s : dev s) (Pa for a stress)."""
    m = (s[0] + s[1] + s[2]) / 3.0
    d0, d1, d2 = s[0] - m, s[1] - m, s[2] - m
    return SQRT_3_2 * math.sqrt(d0 * d0 + d1 * d1 + d2 * d2 + 2.0 * s[3] * s[3])


@njit(cache=True)
def elastic_stress(lmbda, mu, eps, eps_p, sigma) -> None:
    """sigma = lambda tr(eps - eps_p) I + 2 mu (eps - eps_p) (Pa)."""
    e0, e1, e2, e3 = eps[0] - eps_p[0], eps[1] - eps_p[1], eps[2] - eps_p[2], eps[3] - eps_p[3]
    lt = lmbda * (e0 + e1 + e2)
    sigma[0] = lt + 2.0 * mu * e0
    sigma[1] = lt + 2.0 * mu * e1
    sigma[2] = lt + 2.0 * mu * e2
    sigma[3] = 2.0 * mu * e3
