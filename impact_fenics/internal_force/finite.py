"""Finite-strain internal force: total Lagrangian, bilinear quadrilaterals with mean dilatation.

Kinematics, in the reference coordinates (R, Z) (m):

    F = [[1 + du_r/dR, du_r/dZ, 0], [du_z/dR, 1 + du_z/dZ, 0], [0, 0, 1 + u_r/R]],  J = det F > 0,
    f_int,a = int P : Grad N_a 2 pi R dX   (N),   P = tau F^-T the first Piola-Kirchhoff stress.

**The element: Q1 with mean dilatation (F-bar), 2x2 Gauss.** Plastic flow is
isochoric; constant-strain triangles cannot follow an incompressible motion
(a CST patch has about as many volume constraints as dofs; axisymmetry adds
the hoop strain) and lock. The bilinear quadrilateral with the volume change
replaced by its cell mean,

    F_bar_q = (J_bar / J_q)^(1/3) F_q,   J_bar = int J dV_0 / V_0  (per cell, with 2 pi R),

has one volume constraint per cell (the Q1/P0 element of Nagtegaal, Parks &
Rice 1974, in the finite-strain form of Simo, Taylor & Pister 1985 and de
Souza Neto et al. 1996). Why this one here:

* it is fully integrated (2x2 points) in the deviatoric part: no hourglass
  modes, so no hourglass control and no hourglass work in the ledger (one-point
  Q1 would need both); every point keeps its own plastic state;
* one volume average per cell needs no second quadrature degree, so no form
  mixes degrees (mis-assembled by dolfinx 0.5.2) and, as everything happens in
  one compiled pass over the cells, no form at all;
* it is the element of the converged Taylor-bar references (Q1/P0);
* the lumped mass, int rho N_a 2 pi R dX, is positive at every node (N_a >= 0),
  axis nodes included; 2x2 Gauss integrates it exactly on any quadrilateral.

An F-bar patch on triangles was the alternative (keeps today's meshes); it
needs a patch data structure across ranks. Quadrilaterals make every body of a
mesh quadrilateral: the Integrator holds this force for the quadrilateral bodies
of a mesh beside the triangle-based forms.

The internal force is the exact derivative of sum_q w_q psi(F_bar_q) (for a
hyperelastic material), which gives per point the effective Kirchhoff stress

    tau_eff,q = dev tau_q + 1/3 J_q m_bar I,   m_bar = sum_q w_q tr tau_q / (J_bar V_0),
    f_int,a = sum_q w_q (tau_eff,q F_q^-T) : Grad N_a(X_q),

**Plane strain** (x, y) (the kernels compiled per geometry, the axisymmetric branch as
above): F_out = 1, J = det of the in-plane block, w_q = t |det dX/dxi| W_q, and

    F_bar_q = (J_bar / J_q)^(1/2) F_q on the in-plane block, F_bar_out = 1,
    tau_eff,q = tau_q - 1/2 tr2 tau_q I2 + 1/2 J_q m_bar2 I2,
    m_bar2 = sum_q w_q (tau_xx + tau_yy)_q / (J_bar V_0),

the exact gradient for the power 1/2 (tr2, I2: the in-plane trace and identity); the
out-of-plane stress tau_out is the material's and does no work (no hoop term).

tau_q = tau(F_bar_q) from the material's point update (:mod:`..materials.hencky`
signature), w_q the Gauss weight times |det dX/dxi| 2 pi R_q (m^3): the Q1 geometry
of :mod:`..q1`, shared with the small-strain (B-bar) forces.

One fused compiled pass over the owned cells reads a cell's nodal displacements
once, computes F at its four points (through the reference cell: Grad u = (du/dxi,
du/deta) J^-1, and f_a = sum_q (w_q P_q J_q^-T) : dN_a/dxi with the bilinear N_a's
constant reference gradients, see ``force``), J_bar, the four F-bar factors (in a loop of their
own: four independent chains of the cube root (near 1 a series, no division), which
inside the loop of the point updates stood on each point's critical path; one reciprocal
1 / J_q a point serves the factor's ratio J_bar / J_q and P's 1 / det = F_tt / J_q, one
1 / R_q F_tt and the hoop term w_q tau_tt / (F_tt R_q)), the point updates, tau_eff
and the element force (summed over the points, then added once per node into the local
owned + ghost array), then one reverse scatter sums the ghosts. It is compiled
with numpy's error model (no test and exception per division; float64, no
fast-math). It
returns the smallest J (a J <= 0 anywhere is an inverted element: the run
stops with a diagnosis) and the plastic work increment
sum_q w_q Delta W_p,q (J).
"""
from __future__ import annotations

import math

import numpy as np
from dolfinx import fem
from numba import njit

from .. import compat
from ..errors import UnstableRunError
from ..geometry import Geometry
from ..q1 import GAUSS, N_POINTS, QuadGeometry
from .base import Booking

WORK = 16  # scratch entries a point update may use
# the Gauss points' reference coordinates, 1/2 -+ 1/(2 sqrt 3) (LO + HI = 1)
LO, HI = float(GAUSS[0, 0]), float(GAUSS[3, 0])
THIRD = 1.0 / 3.0
# the binomial series (1 + e)^(1/3) = 1 + sum_k C(1/3, k) e^k, k = 1..12, for |e| <= E_SERIES
E_SERIES = 1.0 / 16.0
_B1, _B2, _B3, _B4 = 1.0 / 3.0, -1.0 / 9.0, 5.0 / 81.0, -10.0 / 243.0
_B5, _B6, _B7, _B8 = 22.0 / 729.0, -154.0 / 6561.0, 374.0 / 19683.0, -935.0 / 59049.0
_B9, _B10 = 21505.0 / 1594323.0, -55913.0 / 4782969.0
_B11, _B12 = 147407.0 / 14348907.0, -1179256.0 / 129140163.0


@njit(cache=True, error_model="numpy", inline="always")
def root_series(e: float) -> float:
    """(1 + e)^(1/3) for |e| <= E_SERIES: the branch of :func:`cube_root` nearest 1."""
    e2 = e * e
    e4 = e2 * e2
    p = (((_B1 + _B2 * e) + e2 * (_B3 + _B4 * e)) + e4 * ((_B5 + _B6 * e) + e2 * (_B7 + _B8 * e))
         + (e4 * e4) * ((_B9 + _B10 * e) + e2 * (_B11 + _B12 * e)))
    return 1.0 + e * p


@njit(cache=True, error_model="numpy", inline="always")
def cube_root(x: float) -> float:
    """x^(1/3) (x > 0) within 3 ulp, in the kernel's own arithmetic (no library call).

    Nearest 1, |e| = |x - 1| <= 1/16 (the F-bar ratio of nearly every point: on the Taylor
    bar 97 % to 99.7 % of them), the binomial series itself to e^12, evaluated in Estrin's
    scheme (pairs c_k + c_k+1 e, then e^2, e^4 and e^8: 9 operations deep where Horner's
    is 24, without a division): the first term left out, C(1/3, 13) e^13, is below
    0.0082 x 2^-52 = 1.9e-18, and the sum 1 + e p rounds once on 1 (half an ulp of y)
    while e p (<= 0.022) carries a few roundings of its own size (0.15 ulp of y), so the
    root is within 1 ulp.
    Further from 1, 1/16 < |x - 1| <= 1/8, without a division: the inverse root
    r = x^(-1/3) from its series to e^3 (e = x - 1; relative error 35/243 e^4 <= 3.5e-5),
    two Newton steps r <- r + r (1 - x r^3) / 3 (each takes a relative error delta to
    2 delta^2: 2.5e-9, then 1.2e-17), y = x r^2 and the Newton step on y of the branch
    below, y - (y^3 - x) / (3 y^2) with 1 / y^2 = r^2 (the step is of the order of y's
    rounding, so r's error does not show). Elsewhere on [1/8, 8] (every ratio of a sound
    mesh): Halley's iteration y <- y (y^3 + 2x) / (2 y^3 + x) twice from its first step from
    1, (1 + 2x) / (2 + x), whose relative error e (at most 0.15, at x = 8) becomes about
    e^3 / 3 per step, and one Newton step y - (y^3 - x) / (3 y^2) to take the last 1e-10 to
    round-off. Elsewhere numpy's cbrt."""
    e = x - 1.0
    if -E_SERIES <= e <= E_SERIES:
        return root_series(e)
    if -0.125 <= e <= 0.125:
        r = 1.0 + e * (-THIRD + e * (2.0 / 9.0 + e * (-14.0 / 81.0)))
        r = r + r * (1.0 - x * r * r * r) * THIRD
        r = r + r * (1.0 - x * r * r * r) * THIRD
        r2 = r * r
        y = x * r2
        return y - (y * y * y - x) * r2 * THIRD
    if 0.125 <= x <= 8.0:
        y = (1.0 + 2.0 * x) / (2.0 + x)
        y3 = y * y * y
        y = y * (y3 + 2.0 * x) / (2.0 * y3 + x)
        y3 = y * y * y
        y = y * (y3 + 2.0 * x) / (2.0 * y3 + x)
        return y - (y * y * y - x) / (3.0 * y * y)
    return np.cbrt(x)


@njit(cache=True, error_model="numpy", inline="always")
def cell_deformation(c, dofs, dxi, N, inv_R, u, Fq, Jq, plane) -> None:
    """F at the four points of cell c through the reference cell, the one place F is formed
    (the force, the stored energy and the cell means call it, inlined):

        Grad u = (du/dxi, du/deta) J^-1,   F = I + Grad u,   F_tt = 1 + u_r / R,

    with du/dxi at the points from the node differences u_1 - u_0 and u_3 - u_2 (bilinear
    N_a: du/dxi is linear in eta alone, du/deta in xi alone, so two values each per cell)
    and J^-1 = ``dxi`` (n, 4, 4) = (dxi/dR, dxi/dZ, deta/dR, deta/dZ) at the points (1/m);
    u_r at the point from N (4 points, 4 nodes) and ``inv_R`` = 1 / R_q (1/m). Writes, per
    point q, Fq[q, 0:5] = (F_rr, F_rz, F_zr, F_zz, F_tt), Jq[q] = J_q = det F, Fq[q, 5] =
    1 / J_q and, in axisymmetry, Fq[q, 7] = 1 / R_q (plane strain, ``plane``: F_tt = 1,
    J_q the in-plane determinant)."""
    # the cell's nodal displacements, read once for its four points
    k0, k1, k2, k3 = 2 * dofs[c, 0], 2 * dofs[c, 1], 2 * dofs[c, 2], 2 * dofs[c, 3]
    u0r, u1r, u2r, u3r = u[k0], u[k1], u[k2], u[k3]
    u0z, u1z, u2z, u3z = u[k0 + 1], u[k1 + 1], u[k2 + 1], u[k3 + 1]
    # du/dxi at eta = LO, HI and du/deta at xi = LO, HI (1 - LO = HI)
    ar, br, cr, dr = u1r - u0r, u3r - u2r, u2r - u0r, u3r - u1r
    az, bz, cz, dz = u1z - u0z, u3z - u2z, u2z - u0z, u3z - u1z
    xr0, xr1 = ar * HI + br * LO, ar * LO + br * HI
    er0, er1 = cr * HI + dr * LO, cr * LO + dr * HI
    xz0, xz1 = az * HI + bz * LO, az * LO + bz * HI
    ez0, ez1 = cz * HI + dz * LO, cz * LO + dz * HI
    for q in range(4):
        # point q at (xi, eta) = (LO or HI by q % 2, LO or HI by q // 2)
        xr, xz = (xr0, xz0) if q < 2 else (xr1, xz1)
        er, ez = (er0, ez0) if q % 2 == 0 else (er1, ez1)
        a0, a1, a2, a3 = dxi[c, q, 0], dxi[c, q, 1], dxi[c, q, 2], dxi[c, q, 3]
        frr = 1.0 + (xr * a0 + er * a2)
        frz = xr * a1 + er * a3
        fzr = xz * a0 + ez * a2
        fzz = 1.0 + (xz * a1 + ez * a3)
        det2 = frr * fzz - frz * fzr
        if plane:
            ftt = 1.0
            jq = det2
        else:
            inv_r = inv_R[c, q]
            Fq[q, 7] = inv_r
            ftt = 1.0 + (N[q, 0] * u0r + N[q, 1] * u1r + N[q, 2] * u2r + N[q, 3] * u3r) * inv_r
            jq = det2 * ftt
        Fq[q, 0], Fq[q, 1], Fq[q, 2], Fq[q, 3], Fq[q, 4] = frr, frz, fzr, fzz, ftt
        Jq[q] = jq
        Fq[q, 5] = 1.0 / jq


@njit(cache=True, error_model="numpy", inline="always")
def fbar_factors(jbar: float, Fq, plane) -> None:
    """The four points' F-bar factors (J_bar / J_q)^(1/3) (plane strain: ^(1/2)) into
    Fq[q, 6], from 1 / J_q in Fq[q, 5] (:func:`cell_deformation`): four independent
    chains of the root, no division."""
    for q in range(4):
        if plane:
            Fq[q, 6] = math.sqrt(jbar * Fq[q, 5])
        else:
            Fq[q, 6] = cube_root(jbar * Fq[q, 5])


@njit(cache=True, error_model="numpy", inline="always")
def scaled_gradient(Fq, q: int, fbar, plane) -> None:
    """F_bar_q = Fq[q, 6] F_q into ``fbar`` (5 entries; plane strain: F_bar_tt = 1)."""
    alpha = Fq[q, 6]
    fbar[0], fbar[1], fbar[2], fbar[3] = (alpha * Fq[q, 0], alpha * Fq[q, 1],
                                          alpha * Fq[q, 2], alpha * Fq[q, 3])
    fbar[4] = 1.0 if plane else alpha * Fq[q, 4]


_KERNELS: dict = {}


def kernels(update, energy, n_state: int = 1, point_copy: bool = False, plane: bool = False):
    """The fused force pass and the stored-energy pass, specialised on a material (its point
    update, its energy, the length of a point's state (at least 1) and whether the update
    runs on a copy of the point's state and stress, see ``force``) and on the geometry
    (``plane``: plane strain, a compile-time constant; see the module's docstring)."""
    n_state = max(int(n_state), 1)
    point_copy = bool(point_copy)
    plane = bool(plane)
    key = (update, energy, n_state, point_copy, plane)
    if key in _KERNELS:
        return _KERNELS[key]

    @njit(fastmath=False, error_model="numpy")
    def force(params, dt, dofs, dxi, N, inv_R, w, volume, u, f, state, tau, Fq, Jq, fbar,
              work, point_state, point_tau):
        """f += f_int (N) over the cells; state and tau (Kirchhoff, Pa) updated in place.
        ``dxi`` (n, 4, 4): (dxi/dR, dxi/dZ, deta/dR, deta/dZ) at the points (1/m), the
        inverse of the reference map's Jacobian. ``inv_R``: 1 / R_q (1/m) at the points, the
        quotient made once at set-up (unread in plane strain).
        Returns (plastic work increment (J), smallest J, cell of the smallest J). ``Fq``
        (4, 8) is the cell's scratch: per point F (5 entries), 1 / J_q, the F-bar factor
        and 1 / R_q.

        The gradients go through the reference cell: F from :func:`cell_deformation`
        (Grad u = (du/dxi, du/deta) J^-1, from the node differences), and f_a = sum_q
        (P J^-T) : dN_a/dxi with the constant reference gradients (the module's docstring);
        a point reads 4 entries of J^-1 where Grad N_a took 8.

        The point update works on the views state[c, q] and tau[c, q], or, with
        ``point_copy`` (a material whose update has a loop: Johnson-Cook's return), on the
        scratch arrays ``point_state`` and ``point_tau``, copied in and out. A view costs an
        atomic reference count pair per point wherever numba cannot prune the pair, which
        it cannot around a loop in a branch; the copy costs some 20 loads and stores a point
        (measured: 2 ms a step of 400,000 points), so the simple updates keep the views."""
        wp = 0.0
        j_min = np.inf
        c_min = -1
        for c in range(dofs.shape[0]):
            cell_deformation(c, dofs, dxi, N, inv_R, u, Fq, Jq, plane)
            jbar = 0.0
            for q in range(4):
                jq = Jq[q]
                jbar += w[c, q] * jq
                if jq < j_min:
                    j_min = jq
                    c_min = c
            jbar /= volume[c]
            if jbar <= 0.0 or j_min <= 0.0:
                return wp, j_min, c_min
            fbar_factors(jbar, Fq, plane)
            m_bar = 0.0
            for q in range(4):
                scaled_gradient(Fq, q, fbar, plane)
                if point_copy:
                    for i in range(n_state):
                        point_state[i] = state[c, q, i]
                    wp += w[c, q] * update(fbar, point_state, params, dt, point_tau, work)
                    for i in range(n_state):
                        state[c, q, i] = point_state[i]
                    for i in range(4):
                        tau[c, q, i] = point_tau[i]
                else:
                    wp += w[c, q] * update(fbar, state[c, q], params, dt, tau[c, q], work)
                if plane:
                    m_bar += w[c, q] * (tau[c, q, 0] + tau[c, q, 2])
                else:
                    m_bar += w[c, q] * (tau[c, q, 0] + tau[c, q, 1] + tau[c, q, 2])
            m_bar /= jbar * volume[c]
            sxr0 = sxr1 = ser0 = ser1 = sxz0 = sxz1 = sez0 = sez1 = 0.0
            hr0 = hr1 = hr2 = hr3 = 0.0
            for q in range(4):
                t0, t1, t2, t3 = tau[c, q, 0], tau[c, q, 1], tau[c, q, 2], tau[c, q, 3]
                frr, frz, fzr, fzz, ftt = Fq[q, 0], Fq[q, 1], Fq[q, 2], Fq[q, 3], Fq[q, 4]
                if plane:
                    # tau_eff = tau - 1/2 tr2 tau I2 + 1/2 J m_bar2 I2 (in-plane block only)
                    shift = 0.5 * Jq[q] * m_bar - 0.5 * (t0 + t2)
                    trr, ttt, tzz, trz = t0 + shift, 0.0, t2 + shift, t3
                else:
                    p = (t0 + t1 + t2) / 3.0
                    shift = Jq[q] * m_bar / 3.0 - p  # tau_eff = tau - p I + J m_bar / 3 I
                    trr, ttt, tzz, trz = t0 + shift, t1 + shift, t2 + shift, t3
                # w_q F^-1 of the (r, z) block; P = tau_eff F^-T, P_ij = sum_k tau_ik Finv_jk
                wq = w[c, q]
                scale = wq * ftt * Fq[q, 5]  # w_q / det of the (r, z) block = w_q F_tt / J_q
                i00, i01, i10, i11 = fzz * scale, -frz * scale, -fzr * scale, frr * scale
                prr = trr * i00 + trz * i01
                prz = trr * i10 + trz * i11
                pzr = trz * i00 + tzz * i01
                pzz = trz * i10 + tzz * i11
                # w_q tau_tt / (F_tt R) with 1 / F_tt = det / J_q; no hoop term in plane
                ptt = 0.0 if plane else wq * ttt * (frr * fzz - frz * fzr) * Fq[q, 5] * Fq[q, 7]
                # (P J^-T) by the reference gradients, summed over the points of a row or column
                a0, a1, a2, a3 = dxi[c, q, 0], dxi[c, q, 1], dxi[c, q, 2], dxi[c, q, 3]
                qxr, qer = prr * a0 + prz * a1, prr * a2 + prz * a3
                qxz, qez = pzr * a0 + pzz * a1, pzr * a2 + pzz * a3
                if q < 2:
                    sxr0 += qxr
                    sxz0 += qxz
                else:
                    sxr1 += qxr
                    sxz1 += qxz
                if q % 2 == 0:
                    ser0 += qer
                    sez0 += qez
                else:
                    ser1 += qer
                    sez1 += qez
                if not plane:
                    hr0 += ptt * N[q, 0]
                    hr1 += ptt * N[q, 1]
                    hr2 += ptt * N[q, 2]
                    hr3 += ptt * N[q, 3]
            # f_a = sum_q Q_xi dN_a/dxi + Q_eta dN_a/deta: dN/dxi = (-(1 - eta), 1 - eta, -eta,
            # eta), dN/deta = (-(1 - xi), -xi, 1 - xi, xi)
            ar, br = HI * sxr0 + LO * sxr1, LO * sxr0 + HI * sxr1
            cr, dr = HI * ser0 + LO * ser1, LO * ser0 + HI * ser1
            az, bz = HI * sxz0 + LO * sxz1, LO * sxz0 + HI * sxz1
            cz, dz = HI * sez0 + LO * sez1, LO * sez0 + HI * sez1
            # the cell's force, summed over its points, added once per node
            k0, k1, k2, k3 = 2 * dofs[c, 0], 2 * dofs[c, 1], 2 * dofs[c, 2], 2 * dofs[c, 3]
            f[k0] += (-ar - cr) + hr0
            f[k1] += (ar - dr) + hr1
            f[k2] += (cr - br) + hr2
            f[k3] += (br + dr) + hr3
            f[k0 + 1] += -az - cz
            f[k1 + 1] += az - dz
            f[k2 + 1] += cz - bz
            f[k3 + 1] += bz + dz
        return wp, j_min, c_min

    @njit(fastmath=False, error_model="numpy")
    def stored(params, dofs, dxi, N, inv_R, w, volume, u, state, Fq, Jq, fbar, work):
        """sum_q w_q psi(F_bar_q) (J) with the current state: F, J_bar and F_bar as ``force``
        forms them."""
        total = 0.0
        for c in range(dofs.shape[0]):
            cell_deformation(c, dofs, dxi, N, inv_R, u, Fq, Jq, plane)
            jbar = 0.0
            for q in range(4):
                jbar += w[c, q] * Jq[q]
            jbar /= volume[c]
            fbar_factors(jbar, Fq, plane)
            for q in range(4):
                scaled_gradient(Fq, q, fbar, plane)
                total += w[c, q] * energy(fbar, state[c, q], params, work)
        return total

    _KERNELS[key] = (force, stored)
    return force, stored


@njit(cache=True)
def velocity_update(coef, f, v, dt_avg) -> float:
    """v += dt_avg coef f (coef = -1/m, 0 on fixed dofs); returns dt_avg 1/2 (v^- + v~) . f (J)."""
    work = 0.0
    for i in range(coef.size):
        vo = v[i]
        vn = vo + dt_avg * coef[i] * f[i]
        v[i] = vn
        work += 0.5 * dt_avg * (vo + vn) * f[i]
    return work


@njit(cache=True)
def trapezoid_work(f, u, f_prev, u_prev) -> float:
    """1/2 (f_prev + f) . (u - u_prev) (J), and stores f, u as the previous ones."""
    work = 0.0
    for i in range(f.size):
        work += 0.5 * (f_prev[i] + f[i]) * (u[i] - u_prev[i])
        f_prev[i] = f[i]
        u_prev[i] = u[i]
    return work


@njit(cache=True)
def cell_length_min(dofs, X, u) -> float:
    """Smallest characteristic length A / max diagonal (m) of the cells in the current
    configuration x = X + u (A the area; for a square of side h it is h / sqrt 2)."""
    best = np.inf
    for c in range(dofs.shape[0]):
        n0, n1, n2, n3 = dofs[c, 0], dofs[c, 1], dofs[c, 2], dofs[c, 3]
        x0r, x0z = X[n0, 0] + u[2 * n0], X[n0, 1] + u[2 * n0 + 1]
        x1r, x1z = X[n1, 0] + u[2 * n1], X[n1, 1] + u[2 * n1 + 1]
        x2r, x2z = X[n2, 0] + u[2 * n2], X[n2, 1] + u[2 * n2 + 1]
        x3r, x3z = X[n3, 0] + u[2 * n3], X[n3, 1] + u[2 * n3 + 1]
        d1r, d1z = x3r - x0r, x3z - x0z  # diagonals 0-3 and 1-2
        d2r, d2z = x2r - x1r, x2z - x1z
        area = 0.5 * abs(d1r * d2z - d1z * d2r)
        # max(sqrt a, sqrt b) = sqrt(max(a, b)) exactly (sqrt correctly rounded, monotone)
        dmax = math.sqrt(max(d1r * d1r + d1z * d1z, d2r * d2r + d2z * d2z))
        length = area / dmax
        if length < best:
            best = length
    return best


@njit(cache=True, error_model="numpy")
def cell_means(tau, state, w, volume, dofs, dxi, N, inv_R, u, Fq, Jq, out_sigma, out_eps, out_t,
               i_temp, plane) -> None:
    """Per cell: Cauchy stress (rr, tt, zz, rz) = mean tau / J_bar (Pa), mean eps_bar_p and,
    when ``i_temp`` >= 0, mean state[i_temp] (the temperature, K); ``plane``: plane strain.
    J_q from :func:`cell_deformation`."""
    for c in range(dofs.shape[0]):
        cell_deformation(c, dofs, dxi, N, inv_R, u, Fq, Jq, plane)
        jbar = 0.0
        for q in range(4):
            jbar += w[c, q] * Jq[q]
        jbar /= volume[c]
        for i in range(4):
            s = 0.0
            for q in range(4):
                s += w[c, q] * tau[c, q, i]
            out_sigma[c, i] = s / (volume[c] * jbar)
        e = 0.0
        t = 0.0
        for q in range(4):
            e += w[c, q] * state[c, q, 0]
            if i_temp >= 0:
                t += w[c, q] * state[c, q, i_temp]
        out_eps[c] = e / volume[c]
        out_t[c] = t / volume[c] if i_temp >= 0 else 0.0


class FiniteStrainForce:
    """f_int(u) of the finite-strain material ``material`` on the owned ``cells`` (Q1 mesh).

    ``u`` is the displacement Function (its ghost entries must be current on entry
    to :meth:`compute`); the force goes to ``self.f`` (owned entries summed). The driver
    sets :attr:`coef`, -1/m (1/kg) on the free owned dofs and 0 on the fixed ones, before
    the first increment.

    A step is two halves, :meth:`evaluate` (f_int(u^n), the points moved to u^n, the
    trapezoid work booked) and :meth:`add_increment` (v += h_n coef f, the kinetic
    identity's work booked and returned); :meth:`velocity_increment` runs both. A driver
    that writes the state at u^n with v^{n-1/2} calls the halves with its outputs between.
    The point updates take the step just taken, h_{n-1/2} (h_{1/2} at the first step),
    from :meth:`set_step`. ``geometry``: the model's (axisymmetric or plane strain)."""

    def __init__(self, V: fem.FunctionSpace, node_xy: np.ndarray, cells: np.ndarray, material,
                 u: fem.Function, geometry: Geometry):
        self.V, self.material, self.u = V, material, u
        self.coef: np.ndarray | None = None
        self.h = self.h_avg = self.h_taken = None
        self.work_local = 0.0       # sum h_n 1/2 (v^- + v~) . f^n (J): the kinetic identity's
        self.last_work = 0.0        # its term of the last step (J)
        self.trapezoid_local = 0.0  # sum 1/2 (f^{n-1} + f^n) . (u^n - u^{n-1}) (J)
        self.node_xy = np.ascontiguousarray(node_xy)
        self.plane = geometry.plane
        self.geometry = QuadGeometry(compat.cell_dofs(V), node_xy, cells, geometry)
        n = cells.size
        self.params = material.params()
        self.state = np.empty((n, N_POINTS, max(material.n_state, 1)))
        self.state[:] = material.initial_state()
        self.tau = np.zeros((n, N_POINTS, 4))
        self._Fq = np.zeros((N_POINTS, 8))
        self._Jq = np.zeros(N_POINTS)
        self._fbar = np.zeros(5)
        self._work = np.zeros(WORK)
        self._point_state = np.zeros(self.state.shape[-1])
        self._point_tau = np.zeros(4)
        self._frame = None  # a frame's copies of state and tau, its force and cell values
        self.f = fem.Function(V)
        self.n_owned = V.dofmap.index_map.size_local * V.dofmap.index_map_bs
        self.f_owned = self.f.x.array[: self.n_owned]
        self.plastic_work_local = 0.0
        self.j_min = 1.0
        self.u_owned = self.u.x.array[: self.n_owned]
        # the step's arrays and communicator, looked up once (each lookup costs ~0.3 us)
        self._u_all, self._f_all = self.u.x.array, self.f.x.array
        self._comm = V.mesh.comm
        self._serial = self._comm.size == 1
        self._f_prev = np.zeros(self.n_owned)
        self._u_prev = np.zeros(self.n_owned)
        self.wave_speed = material.wave_speed()  # c (m/s), elastic dilatational
        self._force, self._stored = kernels(material.update, material.energy, material.n_state,
                                            getattr(material, "point_copy", False), self.plane)
        self._load_kernels()

    def _load_kernels(self) -> None:
        """Compile (or load from the cache) the step's and the outputs' kernels for the types
        of these arrays, now at set-up, without running them: the force and the stored
        energy are specialised on the material (closures, compiled once per process, about
        a second), which would otherwise compile inside the first timed step."""
        from ..jit_watch import load

        g, u = self.geometry, self.u.x.array
        load(self._force, self.params, 1.0, g.dofs, g.dxi, g.N, g.inv_R, g.w, g.volume, u,
             self.f.x.array, self.state, self.tau, self._Fq, self._Jq, self._fbar, self._work,
             self._point_state, self._point_tau)
        load(self._stored, self.params, g.dofs, g.dxi, g.N, g.inv_R, g.w, g.volume, u,
             self.state, self._Fq, self._Jq, self._fbar, self._work)
        load(cell_length_min, g.dofs, self.node_xy, u)
        load(trapezoid_work, self.f_owned, self.u_owned, self._f_prev, self._u_prev)
        load(velocity_update, self.f_owned, self.f_owned, self.f_owned, 1.0)
        n = g.dofs.shape[0]
        load(cell_means, self.tau, self.state, g.w, g.volume, g.dofs, g.dxi, g.N, g.inv_R,
             u, self._Fq, self._Jq, np.zeros((n, 4)), np.zeros(n), np.zeros(n), -1, self.plane)

    def compute(self, dt: float) -> np.ndarray:
        """f_int(u^n) (N), owned view; the state moves to the current u. Raises
        UnstableRunError on a non-positive J (inverted element)."""
        g = self.geometry
        arr = self._f_all
        arr.fill(0.0)
        wp, j_min, c_min = self._force(self.params, dt, g.dofs, g.dxi, g.N, g.inv_R, g.w,
                                       g.volume, self._u_all, arr, self.state, self.tau,
                                       self._Fq, self._Jq, self._fbar, self._work,
                                       self._point_state, self._point_tau)
        comm = self._comm
        j_all = j_min if self._serial else comm.allreduce(j_min, op=_MIN)
        if not j_all > 0.0:
            where = ""
            if j_min <= 0.0 and c_min >= 0:
                xy = self.node_xy[g.dofs[c_min]].mean(axis=0)
                first, second = ("X", "Y") if self.plane else ("R", "Z")  # reference
                where = f" (cell at {first} = {xy[0]:.4g} m, {second} = {xy[1]:.4g} m)"
            where = "".join(comm.allgather(where))
            raise UnstableRunError(f"an element inverted: J = det F = {j_all:.3g} <= 0{where}; "
                                   "the mesh is too coarse for this deformation or dt too large")
        self.j_min = j_all
        if not self._serial:  # (one rank: no ghosts to sum)
            compat.scatter_add(self.f.x)
        self.plastic_work_local += wp
        return self.f_owned

    # ------------------------------------------------------------ the protocol
    def set_step(self, h: float, h_avg: float) -> None:
        """The step h = h_{n+1/2} and h_avg = h_n (s); the one taken before becomes the
        point updates' step."""
        self.h_taken = float(h) if self.h is None else self.h
        self.h, self.h_avg = float(h), float(h_avg)

    def evaluate(self) -> np.ndarray:
        """f_int(u^n) (N, owned view) at the step just taken, and its trapezoid work booked."""
        f = self.compute(self.h_taken)
        self.trapezoid_local += trapezoid_work(f, self.u_owned, self._f_prev, self._u_prev)
        return f

    def add_increment(self, v: np.ndarray, h_avg: float) -> float:
        """v += h_avg coef f^n (m/s) with the f of :meth:`evaluate`; returns the work
        h_avg 1/2 (v^- + v~) . f^n (J), also booked in :attr:`work_local`."""
        work = velocity_update(self.coef, self.f_owned, v, h_avg)
        self.work_local += work
        self.last_work = work
        return work

    def velocity_increment(self, u: np.ndarray, v: np.ndarray, h_avg: float) -> None:
        """:meth:`evaluate` then :meth:`add_increment` (``u`` is the force's own Function's
        owned array)."""
        self.evaluate()
        self.add_increment(v, h_avg)

    def stable_dt(self) -> float:
        """min over the current cells of L / c (s): L = A / (largest diagonal), c the
        material's elastic dilatational speed (collective)."""
        local = self.length_min_local()
        return (local if self._serial else self._comm.allreduce(local, op=_MIN)) / self.wave_speed

    def book(self) -> Booking:
        """work: the trapezoid work; stored: sum_q w_q psi(F_bar_q); dissipated: the
        plastic work (J, this rank)."""
        return Booking(work=self.trapezoid_local, stored=self.stored_energy_local(),
                       dissipated=self.plastic_work_local)

    def stored_energy_local(self, u: np.ndarray | None = None) -> float:
        """sum_q w_q psi(F_bar_q) (J) on this rank's cells at the current state and the
        current u, or ``u`` (m, every local entry: the state u^n a step kept)."""
        g = self.geometry
        u = self.u.x.array if u is None else u
        return self._stored(self.params, g.dofs, g.dxi, g.N, g.inv_R, g.w, g.volume,
                            u, self.state, self._Fq, self._Jq, self._fbar, self._work)

    def length_min_local(self) -> float:
        """Smallest current characteristic cell length on this rank (m)."""
        return cell_length_min(self.geometry.dofs, self.node_xy, self.u.x.array)

    def cell_values(self, u: np.ndarray | None = None
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Per owned cell: Cauchy stress (n, 4) (Pa), mean eps_bar_p (n,), mean temperature (K,
        0 without one) of the committed point state (tau and the state of the last
        :meth:`compute`), its J_bar at the current u or ``u``. Between steps the points hold
        the update at u^n while u is u^{n+1}: a frame takes :meth:`frame_values`."""
        g = self.geometry
        n = g.dofs.shape[0]
        sig, eps, temp = np.zeros((n, 4)), np.zeros(n), np.zeros(n)
        i_temp = getattr(self.material, "temperature_index", -1)
        cell_means(self.tau, self.state, g.w, g.volume, g.dofs, g.dxi, g.N, g.inv_R,
                   self.u.x.array if u is None else u, self._Fq, self._Jq, sig, eps, temp, i_temp,
                   self.plane)
        return sig, eps, temp

    def frame_values(self, u: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`cell_values` of the points' update at the displacement ``u`` (m, the local
        array, ghosts current) from the committed state: the Cauchy stress (Pa, sigma =
        tau(F_bar) / J_bar, both of ``u``), eps_bar_p and temperature a frame writes with
        ``u``. The committed state is left as it is.

        A frame comes after the step that moved u^n to u^{n+1}, while the points hold the
        update at u^n; this is the update the next step makes at u^{n+1} (the same fused
        kernel, from the same state, over the step just taken, h_{n+1/2}), on copies of the
        state and tau. The arrays (made at the first frame) are reused by the next call."""
        g = self.geometry
        if self._frame is None:
            n = g.dofs.shape[0]
            self._frame = (np.empty_like(self.state), np.empty_like(self.tau),
                           np.empty_like(self.f.x.array), np.zeros((n, 4)), np.zeros(n),
                           np.zeros(n))
        state, tau, f, sig, eps, temp = self._frame
        np.copyto(state, self.state)
        np.copyto(tau, self.tau)
        f.fill(0.0)
        self._force(self.params, self.h, g.dofs, g.dxi, g.N, g.inv_R, g.w, g.volume, u,
                    f, state, tau, self._Fq, self._Jq, self._fbar, self._work,
                    self._point_state, self._point_tau)
        cell_means(tau, state, g.w, g.volume, g.dofs, g.dxi, g.N, g.inv_R, u, self._Fq,
                   self._Jq, sig, eps, temp, getattr(self.material, "temperature_index", -1),
                   self.plane)
        return sig, eps, temp


from mpi4py import MPI as _MPI  # noqa: E402

_MIN = _MPI.MIN
