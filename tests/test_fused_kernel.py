"""The fused cell kernel of the small-strain path-dependent force against the kernel it
replaces, kept here while the new one lands.

Oracle: exact equivalence. The new kernel reads the same arrays through flat views,
hoists the rule's shape values and calls the materials' updates on scalars (J2's and
Drucker-Prager's ``point``; the latter skips a square root where a state is clearly
elastic, and the kernel runs that test, Drucker-Prager's ``screen``, inlined before it
calls ``point``), but performs the same floating-point operations in the same order on
every value it returns (J2's and Drucker-Prager's point functions are compiled with
numpy's error model, which removes the zero tests of their divisions, none of which is
by zero, and changes no operation); so the run must be the previous one (previous
kernel, previous updates, kept verbatim here) bit for bit (array_equal / ==, no
tolerance): the displacement, velocity, force, stresses, plastic strains and state
variables after every step, and the booked plastic work, on a J2 bar whose points yield
and unload, and on a Drucker-Prager bar whose points return to the cone and to the
tension cut-off; by the scalar ``point`` (behind the ``screen``, and alone) and by the
array ``update`` (the seam of a material that gives no ``point``); on triangles and, for
the B-bar kernel, which now calls ``screen`` and ``point`` the same way, on
quadrilaterals (the previous B-bar kernel kept verbatim here too). Under MPI each rank
runs both kernels on its own cells and ghosts, so the comparison holds on every rank.

J2 has a screen too, the exact elastic test (the first half of its ``point``, which
begins with it), and on triangles the kernel runs it at a cell's three points before it
updates any: the same operations on every value, in another order of independent
chains, so its bar must equal the previous run bit for bit as well; a point the screen
finds elastic books no work, as the previous kernel booked none there (eps_p - eps_p = 0).
The screen's decision is the previous update's branch, checked at trial states one ulp
and more either side of the yield surface.
"""
import math

import numpy as np
import pytest
from mpi4py import MPI
from numba import njit

from impact_fenics import meshing
from impact_fenics.bodies import Body, DeformableModel
from impact_fenics.integrator import Integrator
from impact_fenics.internal_force import bbar
from impact_fenics.internal_force.quadrature import QuadratureState, kernels
from impact_fenics.materials import drucker_prager as dp
from impact_fenics.materials import j2
from impact_fenics.materials.axisym import SQRT_2_3, elastic_stress
from impact_fenics.materials.drucker_prager import (ALPHA_F, ALPHA_G, BULK, EPS_BAR_P, ETA, K0,
                                                    K_RES, KAPPA, LMBDA, MU, P_T, DruckerPrager)
from impact_fenics.materials.j2 import J2
from impact_fenics.quad_meshes import quad_rectangle

COMM = MPI.COMM_WORLD
H = 0.05          # element size (m) of the bar r in [0, 0.25], z in [0, 0.5]
N_STEPS = 30


def previous_kernel(update):
    """The fused cell kernel as it was before (verbatim), specialised on ``update``."""

    @njit
    def fused(params, dt, dofs, dNdr, dNdz, N, inv_r, w, u, f, eps_p, state, sigma, work):
        """f += sum_q w_q B_q' sigma_q over the cells; returns the plastic work increment
        sum_q w_q 1/2 (sigma_n + sigma_{n+1}) : (eps_p,{n+1} - eps_p,n) (J)."""
        # the point's variables go through small scratch arrays: a view into the big
        # arrays per point would cost two reference-count updates each. (The generic
        # path's loop below repeats this point block: a compiled helper for it, called
        # or inlined by numba, made this kernel 2-5x slower.)
        eps, ep, s = work[0], work[1], work[2]
        st = work[3, :state.shape[2]]
        ns = state.shape[2]
        wp = 0.0
        for c in range(dofs.shape[0]):
            a0, a1, a2 = 2 * dofs[c, 0], 2 * dofs[c, 1], 2 * dofs[c, 2]
            ur0, ur1, ur2 = u[a0], u[a1], u[a2]
            uz0, uz1, uz2 = u[a0 + 1], u[a1 + 1], u[a2 + 1]
            gr0, gr1, gr2 = dNdr[c, 0], dNdr[c, 1], dNdr[c, 2]
            gz0, gz1, gz2 = dNdz[c, 0], dNdz[c, 1], dNdz[c, 2]
            e_rr = gr0 * ur0 + gr1 * ur1 + gr2 * ur2
            e_zz = gz0 * uz0 + gz1 * uz1 + gz2 * uz2
            e_rz = 0.5 * ((gz0 * ur0 + gz1 * ur1 + gz2 * ur2) + (gr0 * uz0 + gr1 * uz1 + gr2 * uz2))
            # P1 gradients are constant in the cell: f_i = B_i' sum_q w_q sigma_q needs the
            # weighted sums of sigma_rr, sigma_zz, sigma_rz and, for the hoop term, of
            # w_q sigma_tt,q / r_q N_i(x_q)
            S_rr = S_zz = S_rz = h0 = h1 = h2 = 0.0
            for q in range(3):
                ir = inv_r[c, q]
                n0, n1, n2 = N[q, 0], N[q, 1], N[q, 2]
                eps[0] = e_rr
                eps[1] = (n0 * ur0 + n1 * ur1 + n2 * ur2) * ir
                eps[2] = e_zz
                eps[3] = e_rz
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
                S_rr += wq * s0
                S_zz += wq * s2
                S_rz += wq * s3
                t = wq * s1 * ir
                h0 += t * n0
                h1 += t * n1
                h2 += t * n2
            f[a0] += gr0 * S_rr + gz0 * S_rz + h0
            f[a1] += gr1 * S_rr + gz1 * S_rz + h1
            f[a2] += gr2 * S_rr + gz2 * S_rz + h2
            f[a0 + 1] += gz0 * S_zz + gr0 * S_rz
            f[a1 + 1] += gz1 * S_zz + gr1 * S_rz
            f[a2 + 1] += gz2 * S_zz + gr2 * S_rz
        return wp

    return fused


def previous_bbar_kernel(update):
    """The fused B-bar cell kernel as it was before (verbatim), specialised on ``update``."""
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

    return fused


@njit
def previous_j2_update(eps, eps_p, state, params, dt, sigma) -> None:
    """The J2 radial return as it was before (verbatim)."""
    lmbda, mu = params[j2.LAMBDA], params[j2.MU]
    # trial stress sigma_tr = C : (eps - eps_p,n), its deviator and sigma_eq
    e0, e1, e2, e3 = eps[0] - eps_p[0], eps[1] - eps_p[1], eps[2] - eps_p[2], eps[3] - eps_p[3]
    lt = lmbda * (e0 + e1 + e2)
    s0, s1, s2, s3 = lt + 2.0 * mu * e0, lt + 2.0 * mu * e1, lt + 2.0 * mu * e2, 2.0 * mu * e3
    m = (s0 + s1 + s2) / 3.0
    d0, d1, d2 = s0 - m, s1 - m, s2 - m
    q2_tr = 1.5 * (d0 * d0 + d1 * d1 + d2 * d2 + 2.0 * s3 * s3)  # sigma_eq,tr^2
    sy = params[j2.YIELD_STRESS] + params[j2.HARDENING] * state[0]
    if q2_tr <= sy * sy:  # f_tr <= 0 (sigma_y > 0): elastic, no square root needed
        sigma[0], sigma[1], sigma[2], sigma[3] = s0, s1, s2, s3
        return
    q_tr = math.sqrt(q2_tr)
    f_tr = q_tr - sy
    viscous = params[j2.VISCOSITY] / dt if params[j2.VISCOSITY] > 0.0 else 0.0
    dg = f_tr / (3.0 * mu + params[j2.HARDENING] + viscous)  # Delta eps_bar_p
    k = 1.5 * dg / q_tr  # Delta eps_p = k s_tr
    eps_p[0] += k * d0
    eps_p[1] += k * d1
    eps_p[2] += k * d2
    eps_p[3] += k * s3
    state[0] += dg
    c = 2.0 * mu * k  # sigma = sigma_tr - 2 mu Delta eps_p
    sigma[0] = s0 - c * d0
    sigma[1] = s1 - c * d1
    sigma[2] = s2 - c * d2
    sigma[3] = s3 - c * s3


# the Drucker-Prager return's helpers as they were before (verbatim, renamed)
@njit
def previous_cohesion(params, kappa) -> float:
    """k(kappa) = max(k_0 + h kappa, k_res) (Pa)."""
    return max(params[K0] + params[dp.H] * kappa, params[K_RES])


@njit
def previous_multipliers(mode, f_tr, t_tr, a, b, c, d, vis):
    """(d gamma, d lambda) of the active set ``mode`` (1 cone, 2 cut-off, 3 both)."""
    if mode == 1:
        return f_tr / (a + vis), 0.0
    if mode == 2:
        return 0.0, t_tr / (d + vis)
    aa, dd = a + vis, d + vis
    det = aa * dd - b * c
    return (f_tr * dd - b * t_tr) / det, (aa * t_tr - c * f_tr) / det


@njit
def previous_try(mode, params, kappa_n, q_tr, p_tr, dt):
    """Multipliers of an active set, with the softening floor; returns
    (d gamma, d lambda, q, p, admissible)."""
    bulk, mu = params[BULK], params[MU]
    af, ag, p_t = params[ALPHA_F], params[ALPHA_G], params[P_T]
    vis = params[ETA] / dt if params[ETA] > 0.0 else 0.0
    k_n = previous_cohesion(params, kappa_n)
    h = params[dp.H] if params[K0] + params[dp.H] * kappa_n > params[K_RES] else 0.0
    for _ in range(2):
        f_tr = q_tr - af * p_tr - k_n
        t_tr = -p_tr - p_t
        a = 3.0 * mu + bulk * af * ag + h
        dg, dl = previous_multipliers(mode, f_tr, t_tr, a, bulk * af, bulk * ag, bulk, vis)
        if h < 0.0 and params[K0] + params[dp.H] * (kappa_n + dg) < params[K_RES]:
            # softening passes the residual within the step: the intercept at the end is
            # k_res whatever the path, so the branch k = k_res, h = 0 is the solution
            k_n = params[K_RES]
            h = 0.0
            continue
        break
    q = q_tr - 3.0 * mu * dg
    p = p_tr + bulk * (ag * dg + dl)
    k_new = previous_cohesion(params, kappa_n + dg)
    tol = 1e-12 * (abs(q_tr) + abs(p_tr) + params[K0])
    ok = dg >= -tol and dl >= -tol and q >= -tol
    # the other condition must hold at the result (for Perzyna: no overstress there)
    if mode == 1:
        ok = ok and -p - p_t <= tol
    elif mode == 2:
        ok = ok and q - af * p - k_new <= tol
    return dg, dl, q, p, ok


@njit
def previous_dp_update(eps, eps_p, state, params, dt, sigma) -> None:
    """The Drucker-Prager point update as it was before (verbatim)."""
    lmbda, mu = params[LMBDA], params[MU]
    af, p_t = params[ALPHA_F], params[P_T]
    elastic_stress(lmbda, mu, eps, eps_p, sigma)  # the trial stress
    s0 = sigma[0]
    s1 = sigma[1]
    s2 = sigma[2]
    s3 = sigma[3]
    m_tr = (s0 + s1 + s2) / 3.0
    d0, d1, d2 = s0 - m_tr, s1 - m_tr, s2 - m_tr
    q_tr = math.sqrt(1.5 * (d0 * d0 + d1 * d1 + d2 * d2 + 2.0 * s3 * s3))
    p_tr = -m_tr
    kappa_n = state[KAPPA]
    f_tr = q_tr - af * p_tr - previous_cohesion(params, kappa_n)
    t_tr = -p_tr - p_t
    scale_tol = 1e-14 * (q_tr + abs(p_tr) + params[K0])
    if f_tr <= scale_tol and t_tr <= scale_tol:
        return  # elastic
    dg, dl, q, p, ok = 0.0, 0.0, q_tr, p_tr, False
    if f_tr > scale_tol:
        dg, dl, q, p, ok = previous_try(1, params, kappa_n, q_tr, p_tr, dt)
    if not ok and t_tr > scale_tol:
        dg, dl, q, p, ok = previous_try(2, params, kappa_n, q_tr, p_tr, dt)
    if not ok:
        dg, dl, q, p, ok = previous_try(3, params, kappa_n, q_tr, p_tr, dt)
    dg = max(dg, 0.0)
    dl = max(dl, 0.0)
    q = max(q, 0.0)
    # stress at n+1: the deviator scaled radially, the mean stress from p
    ratio = q / q_tr if q_tr > 0.0 else 0.0
    m = -p
    sigma[0] = m + ratio * d0
    sigma[1] = m + ratio * d1
    sigma[2] = m + ratio * d2
    sigma[3] = ratio * s3
    # plastic strain increment: d gamma (3/2 s/q + alpha_g/3 I) + d lambda I/3, written as
    # the elastic strain change that gives the stress change (exact for the linear return)
    dvol = (params[ALPHA_G] * dg + dl) / 3.0
    c_dev = 1.5 * dg / q_tr if q_tr > 0.0 else 0.0
    e0 = c_dev * d0 + dvol
    e1 = c_dev * d1 + dvol
    e2 = c_dev * d2 + dvol
    e3 = c_dev * s3
    eps_p[0] += e0
    eps_p[1] += e1
    eps_p[2] += e2
    eps_p[3] += e3
    state[EPS_BAR_P] += SQRT_2_3 * math.sqrt(e0 * e0 + e1 * e1 + e2 * e2 + 2.0 * e3 * e3)
    state[KAPPA] = kappa_n + dg


def _bar_mesh(quad: bool = False):
    """The bar's mesh: triangles, or with ``quad`` quadrilaterals of side H."""
    return (quad_rectangle(COMM, 0.0, 0.0, 0.25, 0.5, round(0.25 / H), round(0.5 / H), "bar")
            if quad else meshing.bar(radius=0.25, length=0.5, h=H, structured=True, comm=COMM))


def _bar(material, strain: float, seed: int, tension: float = 0.0, quad: bool = False,
         tm=None) -> Integrator:
    """The bar of ``material``, axis fixed, in a random state of strains ~ ``strain``
    (displacements strain x H) below z = 1/4 and velocities that change them by about as
    much over the run: points load, yield and unload; plus the uniform dilatation
    eps = ``tension`` I (u = tension x (r, z)) everywhere. Triangles, or with ``quad``
    quadrilaterals of side H (the B-bar kernel); on the mesh ``tm`` if given (two runs
    compared dof by dof share one: two partitions of the same mesh need not be equal)."""
    tm = _bar_mesh(quad) if tm is None else tm
    model = DeformableModel(tm, [Body("bar", material)])
    c = math.sqrt((material.lmbda + 2.0 * material.mu) / material.density)
    dt = 0.2 * H / c  # below the element bound (about 0.5 h / c on these cells)
    integ = Integrator(model, dt, model.axis_dofs())
    rng = np.random.default_rng(seed + 7919 * COMM.rank)
    n = model.n_owned
    xy = model.node_xy[: n // 2]  # owned nodes (r, z) (m); dof 2 a + i is node a's i-th
    lower = np.repeat(xy[:, 1] < 0.25, 2)
    u0 = strain * H * rng.standard_normal(n) * lower + tension * xy.reshape(-1)
    v0 = strain * H / (N_STEPS * dt) * rng.standard_normal(n)
    integ.set_initial(u0, v0)
    return integ


def _run_both(material, strain: float, tension: float, previous_update, seam: str,
              quad: bool = False) -> list:
    """Run the bar twice, with the previous kernel and update and with the new kernel on
    the material's ``seam`` ('point' behind its screen if it has one, 'unscreened' or
    'array'); compare every step. ``quad``: on quadrilaterals, the B-bar kernels."""
    tm = _bar_mesh(quad)
    runs = [_bar(material, strain, seed=3, tension=tension, quad=quad, tm=tm) for _ in range(2)]
    old, new = runs[0].nonlinear[0], runs[1].nonlinear[0]
    old._fused = (previous_bbar_kernel if quad else previous_kernel)(previous_update)
    if not quad:  # the previous kernel read eps_p and sigma as (cells, points, 4)
        old.qs = QuadratureState(old.cells.size, material.n_state, 3)
    if seam == "array":
        new._fused = (bbar.kernel(material.update) if quad
                      else kernels(material.update, material.n_state)[0])
    elif seam == "unscreened":
        new._fused = (bbar.kernel(material.update, material.point) if quad
                      else kernels(material.update, material.n_state, material.point)[0])
    assert new._fused is not old._fused
    for _ in range(N_STEPS):
        for integ in runs:
            integ.predict()
            integ.advance()
        a, b = runs
        assert np.array_equal(a.u_owned, b.u_owned)
        assert np.array_equal(a.v_owned, b.v_owned)
        assert np.array_equal(old.f.x.array, new.f.x.array)
        for name in ("sigma", "eps_p", "state"):
            assert np.array_equal(getattr(old.qs, name), getattr(new.qs, name)), name
        assert old.plastic_work_local == new.plastic_work_local
        assert old.deformation_work_local == new.deformation_work_local
    return [new.qs, new.plastic_work_local]


@pytest.mark.parametrize("quad", [False, True], ids=["triangles", "quadrilaterals"])
@pytest.mark.parametrize("seam", ["point", "unscreened", "array"])
def test_j2_bar_bit_for_bit(seam, quad):
    qs, wp = _run_both(J2(E=200e9, nu=0.3, density=7850.0, yield_stress=250e6,
                          hardening=2e9), 3e-3, 0.0, previous_j2_update, seam, quad)
    yielded = COMM.allreduce(int((qs.state[..., 0] > 0.0).sum()))
    points = COMM.allreduce(int(qs.state[..., 0].size))
    assert yielded > points // 4  # the return mapping ran, not only the elastic branch
    assert COMM.allreduce(wp) > 0.0


@pytest.mark.parametrize("quad", [False, True], ids=["triangles", "quadrilaterals"])
@pytest.mark.parametrize("seam", ["point", "unscreened", "array"])
def test_drucker_prager_bar_bit_for_bit(seam, quad):
    rock = DruckerPrager(hardening=-5e9, viscosity=0.0)
    # the dilatation: a mean stress 3 K 1e-3 = 120 MPa above p_t = 10 MPa, a small deviator
    qs, wp = _run_both(rock, 4e-3, 1e-3, previous_dp_update, seam, quad)
    eps_bar, kappa = qs.state[..., 0], qs.state[..., 1]
    cone = COMM.allreduce(int((kappa > 0.0).sum()))                           # d gamma > 0
    cut_off = COMM.allreduce(int(((eps_bar > 0.0) & (kappa == 0.0)).sum()))   # d lambda only
    assert cone > 0 and cut_off > 0
    assert COMM.allreduce(wp) > 0.0


def test_drucker_prager_update_near_its_surfaces():
    """The update (its elastic test without the square root) against the previous one, bit
    for bit, at trial states on the cone and on the cut-off moved by relative amounts from
    one ulp to 1e-6 either way, and at random states; and the screen the cell kernel
    runs in front of it: where it says elastic, the previous update gave the trial stress."""
    rock = DruckerPrager(hardening=1e9)
    prm = rock.params()
    rng = np.random.default_rng(11)
    af, k0, p_t = prm[ALPHA_F], prm[K0], prm[P_T]
    deltas = [0.0] + [sg * d for d in (1e-16, 1e-15, 1e-13, 1e-12, 1e-11, 1e-9, 1e-6)
                      for sg in (-1.0, 1.0)]
    young, nu = rock.E, rock.nu
    cases = screened = 0
    for _ in range(200):
        kappa = abs(rng.standard_normal()) * 1e-3 * (rng.random() < 0.5)
        k = max(k0 + prm[dp.H] * kappa, prm[dp.K_RES])
        n = rng.standard_normal(4)
        n[:3] -= n[:3].mean()                                    # a deviatoric direction
        n /= math.sqrt(n[0] ** 2 + n[1] ** 2 + n[2] ** 2 + 2.0 * n[3] ** 2)
        for d in deltas:
            for which in ("cone", "cut_off", "random"):
                if which == "cone":   # q = k + alpha_f p (1 + d)
                    p = rng.uniform(-p_t, 2.0 * k)
                    q = (k + af * p) * (1.0 + d)
                elif which == "cut_off":  # sigma_m = p_t (1 + d), inside the cone
                    p = -p_t * (1.0 + d)
                    q = rng.uniform(0.0, k - af * p_t)
                else:
                    p, q = rng.uniform(-2.0 * p_t, 3.0 * k), rng.uniform(0.0, 3.0 * k)
                sig = -p * np.array([1.0, 1.0, 1.0, 0.0]) + SQRT_2_3 * q * n
                tr = sig[:3].sum()
                eps_p = 1e-4 * rng.standard_normal(4)
                eps = eps_p + ((1.0 + nu) * sig - nu * tr * np.array([1.0, 1.0, 1.0, 0.0])) / young
                out = []
                for upd in (previous_dp_update, dp.update):
                    ep, st, s = eps_p.copy(), np.array([0.0, kappa]), np.zeros(4)
                    upd(eps, ep, st, prm, 1e-7, s)
                    out.append((ep, st, s))
                for a, b in zip(*out):
                    assert np.array_equal(a, b), (which, d)
                # the screen the cell kernel runs: elastic only where the previous update
                # returned the trial stress, which it gives (bit for bit)
                elastic, *trial = dp.screen(*eps, *eps_p, np.array([0.0, kappa]), 0, prm)
                if elastic:
                    ep, st, s = out[0]
                    assert np.array_equal(ep, eps_p) and st[0] == 0.0 and st[1] == kappa
                    assert np.array_equal(np.array(trial), s), (which, d)
                screened += elastic
                cases += 1
    assert cases == 200 * len(deltas) * 3
    assert 0 < screened < cases  # the screen decided some states, not all


def test_j2_kernel_screens_ahead():
    """J2's and Drucker-Prager's forces on triangles run the kernel that screens a cell's
    points ahead and skips the point loop for an elastic cell (the one the bar tests
    compare)."""
    for material in (J2(yield_stress=250e6), DruckerPrager()):
        integ = _bar(material, strain=1e-4, seed=1)
        ahead = getattr(material, "screen_ahead", False)
        assert integ.nonlinear[0].cell_kernel is kernels(
            material.update, material.n_state, material.point, material.screen, ahead)[0]
        assert ahead


@pytest.mark.parametrize("viscosity", [0.0, 1e3])
def test_j2_screen_and_point_near_the_yield_surface(viscosity):
    """J2's screen and point against the previous radial return, bit for bit, at trial
    states whose sigma_eq,tr is sigma_y moved by relative amounts from one ulp to 0.3
    either way, rate-independent and viscous: where the screen says elastic the previous
    update returned the trial stress (which the screen gives) and kept the state, and
    point equals the previous update everywhere."""
    steel = J2(yield_stress=250e6, hardening=2e9, viscosity=viscosity)
    prm = steel.params()
    dt = 1e-7
    rng = np.random.default_rng(5)
    deltas = [0.0] + [sg * d for d in (1e-16, 2e-16, 1e-15, 1e-13, 1e-9, 1e-6, 0.3)
                      for sg in (-1.0, 1.0)]
    one = np.array([1.0, 1.0, 1.0, 0.0])
    elastic_cases = yielded = cases = 0
    for _ in range(200):
        eb = abs(rng.standard_normal()) * 1e-3 * (rng.random() < 0.5)
        sy = steel.yield_stress + steel.hardening * eb
        n = rng.standard_normal(4)
        n[:3] -= n[:3].mean()                                    # a deviatoric direction
        n /= math.sqrt(n[0] ** 2 + n[1] ** 2 + n[2] ** 2 + 2.0 * n[3] ** 2)
        p = rng.uniform(-2.0, 2.0) * sy
        for d in deltas:
            sig = p * one + SQRT_2_3 * sy * (1.0 + d) * n
            eps_p = 1e-4 * rng.standard_normal(4)
            eps = eps_p + ((1.0 + steel.nu) * sig - steel.nu * sig[:3].sum() * one) / steel.E
            ep, st, s = eps_p.copy(), np.array([eb]), np.zeros(4)
            previous_j2_update(eps, ep, st, prm, dt, s)
            state = np.array([eb])
            elastic, *trial = j2.screen(*eps, *eps_p, state, 0, prm)
            if elastic:  # the previous update returned the trial stress, eps_p and eb kept
                assert np.array_equal(np.array(trial), s), d
                assert st[0] == eb and np.array_equal(ep, eps_p), d
            out = j2.point(*eps, *eps_p, state, 0, prm, dt)
            assert np.array_equal(np.array(out[:4]), s) and np.array_equal(np.array(out[4:]), ep)
            assert state[0] == st[0]
            elastic_cases += elastic
            yielded += st[0] > eb
            cases += 1
    assert elastic_cases > 0 and yielded > 0  # both branches, at the surface's edge


def test_screen_without_point_is_refused():
    """A screen only stands in front of the scalar point it screens for."""
    with pytest.raises(ValueError, match="screen"):
        kernels(dp.update, dp.N_STATE, None, dp.screen)
    with pytest.raises(ValueError, match="screen"):
        bbar.kernel(dp.update, None, dp.screen)


def test_state_of_another_size_is_refused():
    """The kernel is built for the material's number of state variables."""
    integ = _bar(J2(yield_stress=250e6), strain=1e-4, seed=1)
    force = integ.nonlinear[0]
    g, qs = force.geometry, force.qs
    wrong = np.zeros(qs.state.shape[:2] + (2,))
    with pytest.raises(ValueError, match="n_state"):
        force.cell_kernel(force.params, force.dt, g.dofs, g.dNdr, g.dNdz, g.N, g.inv_r, g.w,
                          force.u.x.array, force.f.x.array, qs.kernel_arrays[0], wrong,
                          qs.kernel_arrays[2], force.work)
