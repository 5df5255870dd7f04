"""Logarithmic (Hencky) elastic strains of the multiplicative split F = F_e F_p, axisymmetric.

The finite-strain plasticity models (:mod:`.finite_j2`, :mod:`.johnson_cook`) keep
the inverse plastic right Cauchy-Green tensor a = C_p^-1 at each point in
``state[1:5]`` = (a_rr, a_zz, a_rz, a_tt) (a = I initially). With it the trial
elastic left Cauchy-Green tensor and its principal logarithmic strains are

    b_e = F a F',    eps_e,i = 1/2 ln lambda_i(b_e)     (Simo 1992; Simo & Hughes 1998, ch. 9).

Without torsion the hoop direction is principal; the (r, z) block is a
symmetric 2x2 matrix, split in closed form by its mean m, half-difference h and
shear s:

    lambda_1,2 = m +- d,   d = sqrt(h^2 + s^2),   (cos 2 theta, sin 2 theta) = (h, s) / d,

theta the angle of the eigenvector of lambda_1 from the r axis. Every tensor
with these principal axes is then written from its two in-plane principal values
x_1, x_2 without the eigenvectors themselves:

    X_rr, X_zz = (x_1 + x_2)/2 +- (x_1 - x_2)/2 cos 2 theta,   X_rz = (x_1 - x_2)/2 sin 2 theta.

For equal eigenvalues (d = 0: b_e = I at F = I, and on the axis) every direction
is principal; the split takes (cos 2 theta, sin 2 theta) = (1, 0), and since then
x_1 = x_2 exactly the tensors do not depend on it. Near equal eigenvalues the
direction is ill-conditioned (its error is EPS m / d), but it enters multiplied by
x_1 - x_2, which is of order d / m: the tensors keep an error of EPS times their
scale. The explicit scheme needs no derivative of the logarithm, so equal
eigenvalues need no other guard. The return mapping acts on the principal values
(the exponential map keeps the directions), then

    b_e,new = sum_i exp(2 eps_e,i) n_i n_i',   a_new = F^-1 b_e,new F^-T,
    tau = sum_i tau_i n_i n_i'   (Kirchhoff stress, Pa),

where exp(2 eps_e,i) = lambda_i,trial x_i with the return's factors
x_i = exp(-3 Delta gamma dev tau_i / q_trial), whose product is 1 (the return is
isochoric): two exponentials per yielding point.

Layout of F: (F_rr, F_rz, F_zr, F_zz, F_tt) with F_rz = d u_r / d Z.
The point update of every finite-strain material (the seam of
:mod:`..internal_force.finite`):

    update(F, state, params, dt, tau, work) -> plastic work increment (J/m^3)
    energy(F, state, params, work) -> stored elastic energy (J/m^3)

``tau`` receives the Kirchhoff stress (rr, tt, zz, rz) in Pa; ``work`` is a
float64 scratch array of 16 entries (no allocation per point): here
work[0:3] the principal log strains (1, 2 in the (r, z) plane, 3 hoop),
work[3:5] (cos 2 theta, sin 2 theta), work[5:8] the principal values of b_e
(trial, then returned), work[8:11] the principal stresses.

Compiled with numpy's error model (a float division by zero gives inf or nan, as
in numpy, instead of a test and a Python exception at every division) and inlined
into the force kernel (numba's inline="always": a call would pass each array as
seven scalars and spill the kernel's registers); float64 and no fast-math. The
materials' ``update`` functions are inlined the same way.
"""
from __future__ import annotations

import math

from numba import njit

SQRT_3_2 = math.sqrt(1.5)


@njit(cache=True, error_model="numpy", inline="always")
def trial_log_strains(F, state, work) -> None:
    """Principal trial elastic log strains into work[0:3], (cos 2 theta, sin 2 theta) into
    work[3:5], the principal values of the trial b_e into work[5:8]."""
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
    l1, l2, l3 = mean + d, mean - d, ftt * ftt * att
    work[0] = 0.5 * math.log(l1)
    work[1] = 0.5 * math.log(l2)
    work[2] = 0.5 * math.log(l3)
    if d > 0.0:
        inv = 1.0 / d
        work[3] = half * inv
        work[4] = s * inv
    else:  # b_e = m I in the plane: every direction is principal
        work[3] = 1.0
        work[4] = 0.0
    work[5], work[6], work[7] = l1, l2, l3


@njit(cache=True, error_model="numpy", inline="always")
def principal_kirchhoff(lmbda, mu, work) -> float:
    """Trial Kirchhoff principal stresses tau_i = lambda tr eps + 2 mu eps_i into work[8:11]
    (Pa) from the log strains in work[0:3]; returns the von Mises value sqrt(3/2 s:s)."""
    tr = work[0] + work[1] + work[2]
    t0 = work[8] = lmbda * tr + 2.0 * mu * work[0]
    t1 = work[9] = lmbda * tr + 2.0 * mu * work[1]
    t2 = work[10] = lmbda * tr + 2.0 * mu * work[2]
    m = (t0 + t1 + t2) / 3.0
    d0, d1, d2 = t0 - m, t1 - m, t2 - m
    return SQRT_3_2 * math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)


@njit(cache=True, error_model="numpy", inline="always")
def radial_return(mu, dgamma, q_trial, work) -> None:
    """Scale the deviator of the principal stresses (work[8:11]) by 1 - 3 mu dgamma / q_trial, take
    dgamma 3/2 dev tau / q_trial off the log strains (the exponential-map return) and
    multiply the principal values of b_e by x_i = exp(-3 dgamma dev tau_i / q_trial)
    (x_3 = 1 / (x_1 x_2): the deviator's principal values sum to zero)."""
    t0, t1, t2 = work[8], work[9], work[10]
    m = (t0 + t1 + t2) / 3.0
    k = 1.0 - 3.0 * mu * dgamma / q_trial
    r = 1.5 * dgamma / q_trial
    dev0, dev1, dev2 = t0 - m, t1 - m, t2 - m
    work[0] -= r * dev0
    work[1] -= r * dev1
    work[2] -= r * dev2
    work[8] = m + k * dev0
    work[9] = m + k * dev1
    work[10] = m + k * dev2
    x0 = math.exp(-2.0 * r * dev0)
    x1 = math.exp(-2.0 * r * dev1)
    work[5] *= x0
    work[6] *= x1
    work[7] /= x0 * x1


@njit(cache=True, error_model="numpy", inline="always")
def kirchhoff(work, tau) -> None:
    """tau (rr, tt, zz, rz) (Pa) from the principal stresses in work[8:11] and the directions
    in work[3:5]."""
    c2, s2 = work[3], work[4]
    mean = 0.5 * (work[8] + work[9])
    half = 0.5 * (work[8] - work[9])
    tau[0] = mean + half * c2
    tau[2] = mean - half * c2
    tau[3] = half * s2
    tau[1] = work[10]


@njit(cache=True, error_model="numpy", inline="always")
def finish(F, work, state, tau) -> None:
    """tau as :func:`kirchhoff`, and a = C_p^-1 = F^-1 b_e F^-T from the returned principal
    values of b_e in work[5:8] (after plastic flow only: an elastic step leaves a
    unchanged)."""
    kirchhoff(work, tau)
    c2, s2 = work[3], work[4]
    mean = 0.5 * (work[5] + work[6])
    half = 0.5 * (work[5] - work[6])
    brr, bzz, brz = mean + half * c2, mean - half * c2, half * s2
    frr, frz, fzr, fzz, ftt = F[0], F[1], F[2], F[3], F[4]
    inv = 1.0 / (frr * fzz - frz * fzr)
    i00, i01, i10, i11 = fzz * inv, -frz * inv, -fzr * inv, frr * inv  # F^-1
    n00 = i00 * brr + i01 * brz  # F^-1 b
    n01 = i00 * brz + i01 * bzz
    n10 = i10 * brr + i11 * brz
    n11 = i10 * brz + i11 * bzz
    state[1] = n00 * i00 + n01 * i01  # (F^-1 b F^-T)_rr
    state[2] = n10 * i10 + n11 * i11
    state[3] = n00 * i10 + n01 * i11
    state[4] = work[7] / (ftt * ftt)


@njit(cache=True, error_model="numpy", inline="always")
def elastic_energy(lmbda, mu, work) -> float:
    """psi_e = mu |dev eps_e|^2 + K/2 (tr eps_e)^2 (J/m^3) of the log strains in work[0:3]."""
    tr = work[0] + work[1] + work[2]
    m = tr / 3.0
    d0, d1, d2 = work[0] - m, work[1] - m, work[2] - m
    return mu * (d0 * d0 + d1 * d1 + d2 * d2) + 0.5 * (lmbda + 2.0 * mu / 3.0) * tr * tr


@njit(cache=True, error_model="numpy", inline="always")
def stored_energy(F, state, params, work) -> float:
    """psi_e (J/m^3) at F with the plastic state a = C_p^-1 in state[1:5]; params[0:2] =
    (lambda, mu) in Pa (the ``energy`` of every Hencky model)."""
    trial_log_strains(F, state, work)
    return elastic_energy(params[0], params[1], work)
