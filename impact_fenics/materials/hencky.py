"""Logarithmic (Hencky) elastic strains of the multiplicative split F = F_e F_p, axisymmetric.

The finite-strain plasticity models (:mod:`.finite_j2`, :mod:`.johnson_cook`) keep
the inverse plastic right Cauchy-Green tensor a = C_p^-1 at each point in
``state[1:5]`` = (a_rr, a_zz, a_rz, a_tt) (a = I initially). With it the trial
elastic left Cauchy-Green tensor and its principal logarithmic strains are

    b_e = F a F',    eps_e,i = 1/2 ln lambda_i(b_e)     (Simo 1992; Simo & Hughes 1998, ch. 9).

Without torsion the hoop direction is principal, lambda_3 = F_tt^2 a_tt; the (r, z)
block is a symmetric 2x2 matrix of mean m, half-difference h = (b_rr - b_zz) / 2 and
shear s, with eigenvalues lambda_1,2 = m +- d, d^2 = h^2 + s^2. Every tensor with its
principal axes is X = x_m I + x_d (h, s) in the plane (X_rr, X_zz = x_m +- x_d h,
X_rz = x_d s), x_m the mean of its two principal values and x_d half their difference
over d; so the eigenvectors, and d itself, are never needed:

    eps_m = (eps_1 + eps_2) / 2 = 1/4 ln(lambda_1 lambda_2) = 1/4 ln(m^2 - d^2),
    g = (eps_1 - eps_2) / (2 d) = atanh(t) / (2 m t),   t = d / m,

and atanh(t) / t = sum_k u^k / (2k + 1) in u = t^2 = d^2 / m^2 (series to u^6 for
u <= 1/256, i.e. |eps_1 - eps_2| <= 0.0626: every point within the elastic strains of
a metal; else g and eps_m from ln(m +- d) and 1 / d). The Kirchhoff stress
tau = lambda tr eps I + 2 mu eps is then (tau_m, tau_d, tau_tt) = (lambda tr eps +
2 mu eps_m, 2 mu g, lambda tr eps + 2 mu eps_3), tr eps = 2 eps_m + eps_3, and with
a = (eps_m - eps_3) / 3 the deviator's principal values are (a +- g d, -2a):

    q^2 = 3/2 dev tau : dev tau = 4 mu^2 (9 a^2 + 3 g^2 d^2).

An elastic point takes two logarithms, one division (1 / m) and no square root. The
return (the exponential map keeps the principal axes) scales the deviator by
k = 1 - 3 mu Delta gamma / q_trial: eps_m -> eps_m - (1 - k) a, eps_3 -> eps_3 +
2 (1 - k) a, g -> k g, the trace unchanged. The returned b_e = exp(2 eps) is

    b_m = exp(2 eps_m) cosh w,   b_d = exp(2 eps_m) sinh(w) / d,   w = 2 g d,
    b_tt = det b_e,trial / exp(2 eps_m)^2   (the return is isochoric),

cosh w and sinh(w) / w from their series in w^2 (to w^10, for w^2 <= 1/64; else the
library's): one exponential per yielding point. Then a_new = F^-1 b_e,new F^-T.
Equal eigenvalues (d = 0: b_e = I at F = I, and on the axis) need no guard: h = s = 0
and g is the series' 1 / (2m).

Layout of F: (F_rr, F_rz, F_zr, F_zz, F_tt) with F_rz = d u_r / d Z.
The point update of every finite-strain material (the seam of
:mod:`..internal_force.finite`):

    update(F, state, params, dt, tau, work) -> plastic work increment (J/m^3)
    energy(F, state, params, work) -> stored elastic energy (J/m^3)

``tau`` receives the Kirchhoff stress (rr, tt, zz, rz) in Pa; ``work`` is a
float64 scratch array of 16 entries (no allocation per point). The package's models
call the functions below that take and return scalars (:func:`log_strains`,
:func:`stresses`, :func:`flow`, :func:`set_kirchhoff`, :func:`set_returned_state`:
:func:`left_cauchy_green` and :func:`set_plastic_state` in one, with one division for the
hoop entry); the functions of the same steps through ``work`` serve a material written
against the scratch array.

Compiled with numpy's error model (a float division by zero gives inf or nan, as
in numpy, instead of a test and a Python exception at every division) and inlined
into the force kernel (numba's inline="always": a call would pass each array as
seven scalars and spill the kernel's registers); float64 and no fast-math. The
materials' ``update`` functions are inlined the same way.
"""
from __future__ import annotations

import math

from numba import njit

THIRD = 1.0 / 3.0
# u = (d / m)^2 at most this for the series of atanh (|eps_1 - eps_2| = atanh(d / m) <= 0.0626)
U_SERIES = 1.0 / 256.0
# 1 / (2k + 1), k = 0..6: atanh(t) / t = sum_k u^k / (2k + 1), u = t^2; the first term left
# out, u^7 / 15, is below 1e-18 (relative) for u <= U_SERIES
_A1, _A2, _A3, _A4, _A5, _A6 = 1.0 / 3.0, 1.0 / 5.0, 1.0 / 7.0, 1.0 / 9.0, 1.0 / 11.0, 1.0 / 13.0
# 1 / (2k)! and 1 / (2k + 1)!, k = 1..5: cosh w and sinh(w) / w in x = w^2 for x <= X_SERIES
# (|w| <= 1/8; the first terms left out, x^6 / 12! and x^6 / 13!, below 1e-19 relative)
X_SERIES = 1.0 / 64.0
_C1, _C2, _C3, _C4, _C5 = 1.0 / 2.0, 1.0 / 24.0, 1.0 / 720.0, 1.0 / 40320.0, 1.0 / 3628800.0
_S1, _S2, _S3, _S4, _S5 = (1.0 / 6.0, 1.0 / 120.0, 1.0 / 5040.0, 1.0 / 362880.0,
                           1.0 / 39916800.0)


# ------------------------------------------------------------ the point update, in scalars
@njit(cache=True, error_model="numpy", inline="always")
def log_strains(F, state):
    """The trial b_e = F a F' and its log strains: (eps_m, g, eps_3, h, s, d^2, det b_e),
    eps_m = (eps_1 + eps_2) / 2 and g = (eps_1 - eps_2) / (2 d) (-, 1 / d's unit: -)."""
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
    h = 0.5 * (p - q)
    mean = 0.5 * (p + q)
    dd = h * h + s * s
    l3 = ftt * ftt * att
    inv_m = 1.0 / mean
    u = dd * inv_m * inv_m
    if u <= U_SERIES:  # eps_1 - eps_2 = atanh(d / m): no square root, no 1 / d
        det2 = mean * mean - dd
        em = 0.25 * math.log(det2)
        u2 = u * u  # Estrin's scheme: pairs, then u^2 (4 deep where Horner's is 6)
        g = 0.5 * inv_m * (1.0 + u * ((_A1 + u * _A2) + u2 * ((_A3 + u * _A4)
                                                             + u2 * (_A5 + u * _A6))))
    else:
        d = math.sqrt(dd)
        l1, l2 = mean + d, mean - d
        det2 = l1 * l2
        e1, e2 = math.log(l1), math.log(l2)
        em = 0.25 * (e1 + e2)
        g = 0.25 * (e1 - e2) / d
    return em, g, 0.5 * math.log(l3), h, s, dd, det2 * l3


@njit(cache=True, error_model="numpy", inline="always")
def stresses(lmbda, mu, em, g, e3, dd):
    """The Kirchhoff stress of the log strains (Pa): (tau_m, tau_d, tau_tt, q^2), tau_m =
    lambda tr eps + 2 mu eps_m the in-plane mean, tau_d = 2 mu g (half the in-plane
    difference over d), q^2 = 3/2 dev tau : dev tau = 4 mu^2 (9 a^2 + 3 g^2 d^2) (Pa^2),
    a = (eps_m - eps_3) / 3: the square, so that an elastic point compares q^2 with
    sigma_y^2 and takes no square root."""
    a = (em - e3) * THIRD
    vol = lmbda * (2.0 * em + e3)
    two_mu = 2.0 * mu
    return (vol + two_mu * em, two_mu * g, vol + two_mu * e3,
            two_mu * two_mu * (9.0 * a * a + 3.0 * g * g * dd))


@njit(cache=True, error_model="numpy", inline="always")
def flow(mu, dgamma, q_trial, em, g, e3, tau_m, tau_d, tau_tt):
    """The exponential-map return: dev tau scaled by k = 1 - 3 mu dgamma / q_trial, the log
    strains moved by -dgamma 3/2 dev tau / q_trial (eps_m by -(1 - k) a, eps_3 by
    2 (1 - k) a, g to k g); returns (eps_m, g, eps_3, tau_m, tau_d, tau_tt)."""
    return scale_deviator(mu, 1.0 - 3.0 * mu * dgamma / q_trial, em, g, e3, tau_m, tau_d,
                          tau_tt)


@njit(cache=True, error_model="numpy", inline="always")
def scale_deviator(mu, k, em, g, e3, tau_m, tau_d, tau_tt):
    """:func:`flow` given its factor k = 1 - 3 mu dgamma / q_trial (-)."""
    c = 1.0 - k
    ca = c * (em - e3) * THIRD
    two_mu_ca = 2.0 * mu * ca
    return (em - ca, k * g, e3 + 2.0 * ca, tau_m - two_mu_ca, k * tau_d,
            tau_tt + 2.0 * two_mu_ca)


@njit(cache=True, error_model="numpy", inline="always")
def exp_in_plane(em, g, dd):
    """The (r, z) block of b_e = exp(2 eps) of the log strains: (exp(2 eps_m), its mean
    exp(2 eps_m) cosh w, its half difference over d exp(2 eps_m) sinh(w) / d), w = 2 g d
    (-)."""
    x = 4.0 * g * g * dd  # w^2
    if x <= X_SERIES:
        ch = 1.0 + x * (_C1 + x * (_C2 + x * (_C3 + x * (_C4 + x * _C5))))
        sh = 2.0 * g * (1.0 + x * (_S1 + x * (_S2 + x * (_S3 + x * (_S4 + x * _S5)))))
    else:
        d = math.sqrt(dd)
        ch = math.cosh(2.0 * g * d)
        sh = math.sinh(2.0 * g * d) / d
    e2m = math.exp(2.0 * em)
    return e2m, e2m * ch, e2m * sh


@njit(cache=True, error_model="numpy", inline="always")
def left_cauchy_green(em, g, dd, det_b):
    """b_e = exp(2 eps) of the log strains: (its in-plane mean exp(2 eps_m) cosh w, its
    half difference over d exp(2 eps_m) sinh(w) / d, w = 2 g d, and its hoop value
    det b_e / exp(2 eps_m)^2) (-)."""
    e2m, b_m, b_d = exp_in_plane(em, g, dd)
    return b_m, b_d, det_b / (e2m * e2m)


@njit(cache=True, error_model="numpy", inline="always")
def set_kirchhoff(tau, tau_m, tau_d, tau_tt, h, s) -> None:
    """tau (rr, tt, zz, rz) (Pa) = tau_m I + tau_d (h, s) in the plane, tau_tt."""
    tau[0] = tau_m + tau_d * h
    tau[1] = tau_tt
    tau[2] = tau_m - tau_d * h
    tau[3] = tau_d * s


@njit(cache=True, error_model="numpy", inline="always")
def set_plastic_block(F, state, b_m, b_d, h, s) -> None:
    """The (r, z) block of a = C_p^-1 = F^-1 b_e F^-T into state[1:4] from the block of
    b_e = b_m I + b_d (h, s)."""
    brr, bzz, brz = b_m + b_d * h, b_m - b_d * h, b_d * s
    frr, frz, fzr, fzz = F[0], F[1], F[2], F[3]
    inv = 1.0 / (frr * fzz - frz * fzr)
    i00, i01, i10, i11 = fzz * inv, -frz * inv, -fzr * inv, frr * inv  # F^-1
    n00 = i00 * brr + i01 * brz  # F^-1 b
    n01 = i00 * brz + i01 * bzz
    n10 = i10 * brr + i11 * brz
    n11 = i10 * brz + i11 * bzz
    state[1] = n00 * i00 + n01 * i01  # (F^-1 b F^-T)_rr
    state[2] = n10 * i10 + n11 * i11
    state[3] = n00 * i10 + n01 * i11


@njit(cache=True, error_model="numpy", inline="always")
def set_plastic_state(F, state, b_m, b_d, b_tt, h, s) -> None:
    """a = C_p^-1 = F^-1 b_e F^-T into state[1:5] from b_e = b_m I + b_d (h, s), b_tt."""
    set_plastic_block(F, state, b_m, b_d, h, s)
    state[4] = b_tt / (F[4] * F[4])


@njit(cache=True, error_model="numpy", inline="always")
def set_returned_state(F, state, em, g, dd, det_b, h, s) -> None:
    """a = C_p^-1 = F^-1 b_e F^-T into state[1:5] for b_e = exp(2 eps) of the returned log
    strains: :func:`left_cauchy_green` then :func:`set_plastic_state` with one division
    where they take two in a row, the hoop entry

        a_tt = b_tt / F_tt^2 = det b_e,trial / (exp(2 eps_m)^2 F_tt^2)

    (the same roundings in number, 4, in another order: F_tt^2 is formed beside the
    exponential, off the chain that follows it)."""
    e2m, b_m, b_d = exp_in_plane(em, g, dd)
    set_plastic_block(F, state, b_m, b_d, h, s)
    ftt = F[4]
    state[4] = det_b / ((e2m * e2m) * (ftt * ftt))


@njit(cache=True, error_model="numpy", inline="always")
def energy_density(lmbda, mu, em, g, e3, dd) -> float:
    """psi_e = mu |dev eps_e|^2 + K/2 (tr eps_e)^2 (J/m^3), |dev eps|^2 = 6 a^2 + 2 g^2 d^2,
    a = (eps_m - eps_3) / 3."""
    tr = 2.0 * em + e3
    a = (em - e3) * THIRD
    return mu * (6.0 * a * a + 2.0 * g * g * dd) + 0.5 * (lmbda + 2.0 * mu * THIRD) * tr * tr


@njit(cache=True, error_model="numpy", inline="always")
def stored_energy(F, state, params, work) -> float:
    """psi_e (J/m^3) at F with the plastic state a = C_p^-1 in state[1:5]; params[0:2] =
    (lambda, mu) in Pa (the ``energy`` of every Hencky model; ``work`` unused)."""
    em, g, e3, h, s, dd, det_b = log_strains(F, state)
    return energy_density(params[0], params[1], em, g, e3, dd)


# ------------------------------------------------------------ the same through ``work``
# For a material written against a scratch array (the demos' FiniteVoceJ2): work[0:7] =
# the tuple of log_strains, work[8:11] = (tau_m, tau_d, tau_tt), work[11:14] the returned
# b_e of left_cauchy_green. (The package's materials use the scalar functions: a value
# stored to work and loaded back does not stay in a register, as the compiler cannot prove
# work apart from F, state and tau.)
@njit(cache=True, error_model="numpy", inline="always")
def trial_log_strains(F, state, work) -> None:
    """The tuple of :func:`log_strains` into work[0:7]."""
    work[0], work[1], work[2], work[3], work[4], work[5], work[6] = log_strains(F, state)


@njit(cache=True, error_model="numpy", inline="always")
def principal_kirchhoff(lmbda, mu, work) -> float:
    """(tau_m, tau_d, tau_tt) of :func:`stresses` into work[8:11]; returns q (Pa)."""
    work[8], work[9], work[10], q2 = stresses(lmbda, mu, work[0], work[1], work[2], work[5])
    return math.sqrt(q2)


@njit(cache=True, error_model="numpy", inline="always")
def radial_return(mu, dgamma, q_trial, work) -> None:
    """:func:`flow` on work[0:3] and work[8:11], and the returned b_e into work[11:14]."""
    work[0], work[1], work[2], work[8], work[9], work[10] = flow(
        mu, dgamma, q_trial, work[0], work[1], work[2], work[8], work[9], work[10])
    work[11], work[12], work[13] = left_cauchy_green(work[0], work[1], work[5], work[6])


@njit(cache=True, error_model="numpy", inline="always")
def kirchhoff(work, tau) -> None:
    """tau (rr, tt, zz, rz) (Pa) of work[8:11] (:func:`set_kirchhoff`)."""
    set_kirchhoff(tau, work[8], work[9], work[10], work[3], work[4])


@njit(cache=True, error_model="numpy", inline="always")
def finish(F, work, state, tau) -> None:
    """tau as :func:`kirchhoff`, and a = C_p^-1 from the returned b_e in work[11:14]
    (after plastic flow only: an elastic step leaves a unchanged)."""
    kirchhoff(work, tau)
    set_plastic_state(F, state, work[11], work[12], work[13], work[3], work[4])


@njit(cache=True, error_model="numpy", inline="always")
def elastic_energy(lmbda, mu, work) -> float:
    """:func:`energy_density` of the log strains in work."""
    return energy_density(lmbda, mu, work[0], work[1], work[2], work[5])
