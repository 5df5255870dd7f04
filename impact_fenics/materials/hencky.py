"""Logarithmic (Hencky) elastic strains of the multiplicative split F = F_e F_p, axisymmetric.

The finite-strain plasticity models (:mod:`.finite_j2`, :mod:`.johnson_cook`) keep
the inverse plastic right Cauchy-Green tensor a = C_p^-1 at each point in
``state[1:5]`` = (a_rr, a_zz, a_rz, a_tt) (a = I initially). With it the trial
elastic left Cauchy-Green tensor and its principal logarithmic strains are

    b_e = F a F',    eps_e,i = 1/2 ln lambda_i(b_e)     (Simo 1992; Simo & Hughes 1998, ch. 9).

Without torsion the hoop direction is principal; the (r, z) block is a
symmetric 2x2 matrix, whose unit eigenvectors follow in closed form; for
equal eigenvalues (b_e = I at F = I) every direction is principal and the
update takes (1, 0): the explicit scheme needs no derivative of the
logarithm, so equal eigenvalues need no other guard. The return mapping
acts on the principal values (the exponential map keeps the directions), then

    b_e,new = sum_i exp(2 eps_e,i) n_i n_i',   a_new = F^-1 b_e,new F^-T,
    tau = sum_i tau_i n_i n_i'   (Kirchhoff stress, Pa).

Layout of F: (F_rr, F_rz, F_zr, F_zz, F_tt) with F_rz = d u_r / d Z.
The point update of every finite-strain material (the seam of
:mod:`..internal_force.finite`):

    update(F, state, params, dt, tau, work) -> plastic work increment (J/m^3)
    energy(F, state, params, work) -> stored elastic energy (J/m^3)

``tau`` receives the Kirchhoff stress (rr, tt, zz, rz) in Pa; ``work`` is a
float64 scratch array of 16 entries (no allocation per point): here
work[0:3] the principal log strains (1, 2 in the (r, z) plane, 3 hoop),
work[3:5] (cos theta, sin theta), work[8:11] the principal stresses.
"""
from __future__ import annotations

import math

from numba import njit

SQRT_3_2 = math.sqrt(1.5)


@njit(cache=True)
def trial_log_strains(F, state, work) -> None:
    """Principal trial elastic log strains into work[0:3], the in-plane direction into work[3:5]."""
    frr, frz, fzr, fzz, ftt = F[0], F[1], F[2], F[3], F[4]
    arr, azz, arz, att = state[1], state[2], state[3], state[4]
    # F a (2x2), then b = (F a) F'
    m00 = frr * arr + frz * arz
    m01 = frr * arz + frz * azz
    m10 = fzr * arr + fzz * arz
    m11 = fzr * arz + fzz * azz
    p = m00 * frr + m01 * frz
    q = m10 * fzr + m11 * fzz
    s = m00 * fzr + m01 * fzz
    half = 0.5 * (p - q)
    d = math.sqrt(half * half + s * s)
    mean = 0.5 * (p + q)
    work[0] = 0.5 * math.log(mean + d)
    work[1] = 0.5 * math.log(mean - d)
    work[2] = 0.5 * math.log(ftt * ftt * att)
    # unit eigenvector of the larger eigenvalue: (lambda_1 - q, s) or (s, lambda_1 - p),
    # whichever has the larger first entry (both vanish only for equal eigenvalues)
    if half >= 0.0:
        c, sn = half + d, s
    else:
        c, sn = s, d - half
    norm = math.sqrt(c * c + sn * sn)
    if norm > 0.0:
        work[3] = c / norm
        work[4] = sn / norm
    else:  # b_e = m I: every direction is principal
        work[3] = 1.0
        work[4] = 0.0


@njit(cache=True)
def principal_kirchhoff(lmbda, mu, work, out) -> float:
    """Trial Kirchhoff principal stresses tau_i = lambda tr eps + 2 mu eps_i into out[0:3]
    (Pa) from the log strains in work[0:3]; returns the von Mises value sqrt(3/2 s:s)."""
    tr = work[0] + work[1] + work[2]
    for i in range(3):
        out[i] = lmbda * tr + 2.0 * mu * work[i]
    m = (out[0] + out[1] + out[2]) / 3.0
    d0, d1, d2 = out[0] - m, out[1] - m, out[2] - m
    return SQRT_3_2 * math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)


@njit(cache=True)
def radial_return(mu, dgamma, q_trial, principal, work) -> None:
    """Scale the deviator of the principal stresses by 1 - 3 mu dgamma / q_trial and take
    dgamma 3/2 dev tau / q_trial off the log strains (the exponential-map return)."""
    m = (principal[0] + principal[1] + principal[2]) / 3.0
    k = 1.0 - 3.0 * mu * dgamma / q_trial
    for i in range(3):
        dev = principal[i] - m
        work[i] -= 1.5 * dgamma * dev / q_trial
        principal[i] = m + k * dev


@njit(cache=True)
def kirchhoff(principal, work, tau) -> None:
    """tau (rr, tt, zz, rz) (Pa) from the principal stresses and the directions in work[3:5]."""
    c, s = work[3], work[4]
    cc, ss, cs = c * c, s * s, c * s
    t1, t2 = principal[0], principal[1]
    tau[0] = t1 * cc + t2 * ss
    tau[2] = t1 * ss + t2 * cc
    tau[3] = (t1 - t2) * cs
    tau[1] = principal[2]


@njit(cache=True)
def finish(F, principal, work, state, tau) -> None:
    """tau as :func:`kirchhoff`, and a = C_p^-1 from the returned log strains in work[0:3]
    (after plastic flow only: an elastic step leaves a unchanged)."""
    kirchhoff(principal, work, tau)
    c, s = work[3], work[4]
    cc, ss, cs = c * c, s * s, c * s
    l1, l2 = math.exp(2.0 * work[0]), math.exp(2.0 * work[1])
    brr, bzz, brz = l1 * cc + l2 * ss, l1 * ss + l2 * cc, (l1 - l2) * cs
    frr, frz, fzr, fzz, ftt = F[0], F[1], F[2], F[3], F[4]
    det = frr * fzz - frz * fzr
    i00, i01, i10, i11 = fzz / det, -frz / det, -fzr / det, frr / det  # F^-1
    n00 = i00 * brr + i01 * brz  # F^-1 b
    n01 = i00 * brz + i01 * bzz
    n10 = i10 * brr + i11 * brz
    n11 = i10 * brz + i11 * bzz
    state[1] = n00 * i00 + n01 * i01  # (F^-1 b F^-T)_rr
    state[2] = n10 * i10 + n11 * i11
    state[3] = n00 * i10 + n01 * i11
    state[4] = math.exp(2.0 * work[2]) / (ftt * ftt)


@njit(cache=True)
def elastic_energy(lmbda, mu, work) -> float:
    """psi_e = mu |dev eps_e|^2 + K/2 (tr eps_e)^2 (J/m^3) of the log strains in work[0:3]."""
    tr = work[0] + work[1] + work[2]
    m = tr / 3.0
    d0, d1, d2 = work[0] - m, work[1] - m, work[2] - m
    return mu * (d0 * d0 + d1 * d1 + d2 * d2) + 0.5 * (lmbda + 2.0 * mu / 3.0) * tr * tr


@njit(cache=True)
def stored_energy(F, state, params, work) -> float:
    """psi_e (J/m^3) at F with the plastic state a = C_p^-1 in state[1:5]; params[0:2] =
    (lambda, mu) in Pa (the ``energy`` of every Hencky model)."""
    trial_log_strains(F, state, work)
    return elastic_energy(params[0], params[1], work)
