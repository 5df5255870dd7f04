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
it is specialised on the material's compiled ``update`` and built once per process
and material.
"""
from __future__ import annotations

from numba import njit

from ..q1 import N_POINTS

WORK_ROWS = 4 + N_POINTS  # the point's scratch (eps, eps_p, state, sigma) + the cell's strains

_KERNELS: dict = {}


def kernel(update):
    """The fused B-bar cell kernel for the point update ``update``."""
    if update in _KERNELS:
        return _KERNELS[update]

    @njit
    def fused(params, dt, dofs, dNdr, dNdz, N, inv_r, w, u, f, eps_p, state, sigma, work):
        """f += f_e over the cells (N); returns the plastic work increment
        sum_q w_q 1/2 (sigma_n + sigma_{n+1}) : (eps_p,{n+1} - eps_p,n) (J).
        ``work`` has WORK_ROWS rows."""
        eps, ep, s = work[0], work[1], work[2]
        st = work[3, :state.shape[2]]
        ns = state.shape[2]
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
                eps[0], eps[1], eps[2], eps[3] = e[0] + d, e[1] + d, e[2] + d, e[3]
                p0, p1, p2, p3 = eps_p[c, q, 0], eps_p[c, q, 1], eps_p[c, q, 2], eps_p[c, q, 3]
                ep[0], ep[1], ep[2], ep[3] = p0, p1, p2, p3
                for k in range(ns):
                    st[k] = state[c, q, k]
                update(eps, ep, st, params, dt, s)
                for k in range(ns):
                    state[c, q, k] = st[k]
                s0, s1, s2, s3 = s[0], s[1], s[2], s[3]
                wq = w[c, q]
                d0, d1, d2, d3 = ep[0] - p0, ep[1] - p1, ep[2] - p2, ep[3] - p3
                if d0 != 0.0 or d1 != 0.0 or d2 != 0.0 or d3 != 0.0:  # plastic: book its work
                    o0, o1, o2, o3 = sigma[c, q, 0], sigma[c, q, 1], sigma[c, q, 2], sigma[c, q, 3]
                    wp += 0.5 * wq * ((o0 + s0) * d0 + (o1 + s1) * d1 + (o2 + s2) * d2
                                      + 2.0 * (o3 + s3) * d3)
                    eps_p[c, q, 0], eps_p[c, q, 1], eps_p[c, q, 2], eps_p[c, q, 3] = \
                        ep[0], ep[1], ep[2], ep[3]
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

    _KERNELS[update] = fused
    return fused
