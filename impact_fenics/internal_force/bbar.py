"""Internal force of a path-dependent body on Q1 quadrilaterals: small strain with mean
dilatation (B-bar), state at the 2x2 Gauss points.

Per cell, from u^n (m) (the geometry and the notation of :mod:`..q1`):

    eps_q = B_q u_e,  theta_bar = sum_q w_q tr(eps_q) / V,
    eps_bar_q = eps_q + (theta_bar - tr eps_q) / 3 (1, 1, 1, 0)  -> point update -> sigma_q,
    f_e = sum_q w_q B_q' G (dev sigma_q + p_bar (1, 1, 1, 0)),  p_bar = sum_q w_q tr(sigma_q) / (3 V)

(= sum_q w_q B_bar_q' G sigma_q; G doubles the tensor shear), the hoop strain
u_r(x_q) / r_q in tr eps_q. The points' state (eps_p, state, sigma) is that of
:class:`.quadrature.QuadratureState` with four points; sigma_q is the material's
stress at the point (what the outputs average), p_bar only enters the force. With an
elastic update this force is K u with the B-bar K of the linear bodies
(:func:`..q1.bbar_element_matrices`), to round-off.

The kernel has the signature of the triangles' fused kernel
(:func:`.quadrature.kernels`), so :class:`.quadrature.QuadratureForce` runs either;
it is specialised on the material's compiled ``update`` (or its ``point`` on scalars,
behind its ``screen``, as the triangles' kernel) and built once per process and
material.
"""
from __future__ import annotations

from numba import njit

from ..q1 import N_POINTS

WORK_ROWS = 4 + N_POINTS  # the point's scratch (eps, eps_p, state, sigma) + the cell's strains

_KERNELS: dict = {}


@njit(cache=True)
def no_point(e0, e1, e2, e3, p0, p1, p2, p3, state, k, params, dt):
    """The stand-in of a material without a scalar ``point`` (here and in the triangles'
    kernel, :mod:`.quadrature`): never called."""
    return e0, e1, e2, e3, p0, p1, p2, p3


@njit(cache=True)
def no_screen(e0, e1, e2, e3, p0, p1, p2, p3, state, k, params):
    """The stand-in of a material without a ``screen``: never called."""
    return False, e0, e1, e2, e3


def kernel(update, point=None, screen=None):
    """The fused B-bar cell kernel for the point update ``update``; with ``point`` (and
    ``screen``) the same update on scalars, called as the triangles' kernel calls them
    (:func:`.quadrature.kernels`)."""
    if screen is not None and point is None:
        raise ValueError("a screen needs the scalar point it screens for")
    key = (update, point, screen)
    if key in _KERNELS:
        return _KERNELS[key]
    scalar, screened = point is not None, screen is not None  # constants of the kernel
    point = no_point if point is None else point
    screen = no_screen if screen is None else screen

    @njit
    def fused(params, dt, dofs, dNdr, dNdz, N, inv_r, w, u, f, eps_p, state, sigma, work):
        """f += f_e over the cells (N); returns the plastic work increment
        sum_q w_q 1/2 (sigma_n + sigma_{n+1}) : (eps_p,{n+1} - eps_p,n) (J).
        ``work`` has WORK_ROWS rows."""
        eps, ep, s = work[0], work[1], work[2]
        st = work[3, :state.shape[2]]
        ns = state.shape[2]
        st_q = state.reshape(-1)  # the scalar seam's view: point (c, q) at ns (4 c + q)
        wp = 0.0
        for c in range(dofs.shape[0]):
            # the strains at the four points (rows 4..7 of work), their traces' weighted mean
            theta_bar = vol = 0.0
            for q in range(4):
                rr = tt = zz = rz = 0.0
                for a in range(4):
                    k = 2 * dofs[c, a]
                    gr, gz = dNdr[c, q, a], dNdz[c, q, a]
                    ur, uz = u[k], u[k + 1]
                    rr += gr * ur
                    tt += N[q, a] * ur
                    zz += gz * uz
                    rz += gz * ur + gr * uz
                e = work[4 + q]
                e[0], e[1], e[2], e[3] = rr, tt * inv_r[c, q], zz, 0.5 * rz
                wq = w[c, q]
                theta_bar += wq * (e[0] + e[1] + e[2])
                vol += wq
            theta_bar /= vol
            # the point updates at eps_bar_q; the weighted mean pressure
            p_bar = 0.0
            for q in range(4):
                e = work[4 + q]
                d = (theta_bar - (e[0] + e[1] + e[2])) / 3.0
                b0, b1, b2, b3 = e[0] + d, e[1] + d, e[2] + d, e[3]  # eps_bar_q
                p0, p1, p2, p3 = eps_p[c, q, 0], eps_p[c, q, 1], eps_p[c, q, 2], eps_p[c, q, 3]
                k0 = ns * (4 * c + q)  # the point's first state variable in st_q
                elastic = False
                if screened:  # the material's elastic test: the trial stress, no call
                    elastic, s0, s1, s2, s3 = screen(b0, b1, b2, b3, p0, p1, p2, p3, st_q, k0,
                                                     params)
                    q0, q1, q2, q3 = p0, p1, p2, p3
                if elastic:
                    pass
                elif scalar:
                    s0, s1, s2, s3, q0, q1, q2, q3 = point(b0, b1, b2, b3, p0, p1, p2, p3, st_q,
                                                           k0, params, dt)
                else:
                    eps[0], eps[1], eps[2], eps[3] = b0, b1, b2, b3
                    ep[0], ep[1], ep[2], ep[3] = p0, p1, p2, p3
                    for k in range(ns):
                        st[k] = state[c, q, k]
                    update(eps, ep, st, params, dt, s)
                    for k in range(ns):
                        state[c, q, k] = st[k]
                    s0, s1, s2, s3 = s[0], s[1], s[2], s[3]
                    q0, q1, q2, q3 = ep[0], ep[1], ep[2], ep[3]
                wq = w[c, q]
                d0, d1, d2, d3 = q0 - p0, q1 - p1, q2 - p2, q3 - p3
                if d0 != 0.0 or d1 != 0.0 or d2 != 0.0 or d3 != 0.0:  # plastic: book its work
                    o0, o1, o2, o3 = sigma[c, q, 0], sigma[c, q, 1], sigma[c, q, 2], sigma[c, q, 3]
                    wp += 0.5 * wq * ((o0 + s0) * d0 + (o1 + s1) * d1 + (o2 + s2) * d2
                                      + 2.0 * (o3 + s3) * d3)
                    eps_p[c, q, 0], eps_p[c, q, 1], eps_p[c, q, 2], eps_p[c, q, 3] = \
                        q0, q1, q2, q3
                sigma[c, q, 0], sigma[c, q, 1], sigma[c, q, 2], sigma[c, q, 3] = s0, s1, s2, s3
                p_bar += wq * (s0 + s1 + s2)
            p_bar /= 3.0 * vol
            # f_a += w_q B_q' G (dev sigma_q + p_bar (1, 1, 1, 0))
            for q in range(4):
                s0, s1, s2, s3 = sigma[c, q, 0], sigma[c, q, 1], sigma[c, q, 2], sigma[c, q, 3]
                shift = p_bar - (s0 + s1 + s2) / 3.0
                wq = w[c, q]
                t_rr, t_tt, t_zz, t_rz = (wq * (s0 + shift), wq * (s1 + shift) * inv_r[c, q],
                                          wq * (s2 + shift), wq * s3)
                for a in range(4):
                    k = 2 * dofs[c, a]
                    gr, gz = dNdr[c, q, a], dNdz[c, q, a]
                    f[k] += gr * t_rr + N[q, a] * t_tt + gz * t_rz
                    f[k + 1] += gz * t_zz + gr * t_rz
        return wp

    _KERNELS[key] = fused
    return fused
