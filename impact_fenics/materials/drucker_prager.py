"""Drucker-Prager plasticity for rock: a cone matched to Mohr-Coulomb, a tension
cut-off, non-associated flow, linear cohesion hardening or softening, optional
Perzyna viscosity. Small strain, the point update of :mod:`.axisym`.

Signs (those of every material here): tension positive; the pressure p = -tr(sigma)/3 is
positive in compression; q = sqrt(3/2 s : s) with s = dev sigma (Pa).

Yield surfaces (Pa) and plastic potential, de Souza Neto, Peric & Owen (2008),
*Computational Methods for Plasticity*, section 8.2 (written here with q
instead of sqrt(J2): q = sqrt(3 J2)):

    cone      f(sigma, kappa) = q - alpha_f p - k(kappa) <= 0
    cut-off   t(sigma)        = -p - p_t             <= 0   (mean stress <= p_t)
    potential g(sigma)        = q - alpha_g p

Flow on the cone, d eps_p = d gamma dg/dsigma = d gamma (3/2 s/q + alpha_g/3 I):
its deviatoric part has the norm sqrt(2/3 de_p : de_p) = d gamma, its volume
change is alpha_g d gamma (dilatant for alpha_g > 0). Flow on the cut-off is
associated and volumetric only, d eps_p = d lambda I/3.

Matching to Mohr-Coulomb on the compression meridian (the cone's outer edges,
de Souza Neto et al. eq. 8.85): in triaxial compression (axial stress
sigma_a, confinement sigma_c, both compressive) Mohr-Coulomb reads
sigma_a = UCS + N sigma_c with N = (1 + sin phi)/(1 - sin phi), and on that
meridian q = sigma_a - sigma_c, p = (sigma_a + 2 sigma_c)/3. The cone holds it
for every confinement when

    alpha_f = 6 sin phi / (3 - sin phi),    k = UCS (1 - alpha_f/3) = 6 c cos phi / (3 - sin phi),

with the cohesion c = UCS (1 - sin phi) / (2 cos phi). The uniaxial compressive
strength (q = UCS, p = UCS/3 on the cone) and the friction angle phi fix the
cone; the dilatancy angle psi (0 <= psi <= phi) gives alpha_g in the same way.
The tensile strength p_t fixes the cut-off (a mean-stress cut-off: hydrostatic
tension at most p_t; it is also the uniaxial tensile strength whenever the cone
allows that state, UT = 3 p_t).

Matching to Mohr-Coulomb in plane strain (``match = "plane_strain"``). The
compression-meridian cone overstates the strength of a body in plane strain at large
phi. In steady plane-strain flow (the out-of-plane plastic strain rate zero, so
3/2 s_out/q = -alpha_g/3) the cone's in-plane shear strength is that of Mohr-Coulomb,
(sigma_1 - sigma_3)/2 = c cos phi - (sigma_1 + sigma_3)/2 sin phi, exactly when

    alpha_g = 3 sin psi / sqrt(3 + sin^2 psi),
    alpha_f = 3 sin phi sqrt(3 + sin^2 psi) / (3 + sin phi sin psi),
    k       = 3 c cos phi sqrt(3 + sin^2 psi) / (3 + sin phi sin psi),

c = UCS (1 - sin phi) / (2 cos phi) as above (UCS then names Mohr-Coulomb's uniaxial
strength 2 c cos phi / (1 - sin phi), not the cone's). At psi = phi it is the associated
match alpha_f = alpha_g = 3 sin phi / sqrt(3 + sin^2 phi). alpha_g <= alpha_f holds
exactly when psi <= phi (sin phi (3 + sin^2 psi) >= sin psi (3 + sin phi sin psi)), so
the angles' check is the slopes' check in both matches. The point update is the same;
only the three parameters differ.

Hardening: k(kappa) = max(k_0 + h kappa, k_res), kappa = sum d gamma (the
deviatoric equivalent plastic strain), h = dk/dkappa (Pa) > 0 hardening, < 0
softening down to the residual k_res >= alpha_f p_t. That bound keeps the
cone's apex (p = -k/alpha_f) outside the cut-off, so the admissible region is
a truncated cone with one corner circle (p = -p_t, q = k - alpha_f p_t >= 0),
no apex return is ever needed and the plastic dissipation is non-negative:
sigma : d eps_p = d gamma (q - alpha_g p) = d gamma (k + (alpha_f - alpha_g) p) >= 0
on the cone (p >= -p_t, alpha_g <= alpha_f), and d lambda p_t >= 0 on the cut-off.

Return mapping (backward Euler, closed form; K bulk, mu shear modulus). From the
trial state (p*, q*, sigma_m* = -p*) the multipliers d gamma (cone) and
d lambda (cut-off) give

    q = q* - 3 mu d gamma,   sigma_m = sigma_m* - K (alpha_g d gamma + d lambda),   s = s* q / q*,

and the conditions (Perzyna viscosity eta, Pa s; eta = 0 rate-independent)

    cone:    f* - A d gamma - B d lambda = eta d gamma / dt
    cut-off: t* - C d gamma - D d lambda = eta d lambda / dt

with A = 3 mu + K alpha_f alpha_g + h, B = K alpha_f, C = K alpha_g, D = K. The
Perzyna law is gamma' = <f>/eta, lambda' = <t>/eta (overstress in Pa over a
viscosity in Pa s), integrated by backward Euler; eta/dt adds to A and D, and
eta -> 0 recovers the rate-independent update (de Souza Neto et al. 11.3).
The active set is found in order:

1. cone alone (d lambda = 0): d gamma = f*/(A + eta/dt), accepted if the
   result satisfies the cut-off and q >= 0;
2. cut-off alone (d gamma = 0): d lambda = t*/(D + eta/dt), accepted if the
   result lies inside the cone;
3. the corner: both, from the 2x2 system above.

The corner region. In the (p, q) plane the cone's return moves a trial point
along (K alpha_g, -3 mu) per unit d gamma, the cut-off's along (K, 0) per unit
d lambda. The trial states that return to the corner point (-p_t, k - alpha_f
p_t) are the wedge spanned at that point by the reversed directions
(-K alpha_g, 3 mu) and (-K, 0): above the cut-off's return line q = k -
alpha_f p_t and left of the line through the corner along the cone's flow.
Left of the wedge's lower edge the cut-off alone applies, right of its upper
edge the cone alone. With linear hardening the corner's position moves with
kappa, which the closed form of step 3 includes (rate-independent:
d gamma = (q* - k_n + alpha_f p_t) / (3 mu + h), then d lambda from the
cut-off's consistency).

Softening that reaches k_res within a step is exact too: the step is redone
with k = k_res and h = 0, which is the solution on that branch.

Point update (the seam of :mod:`.axisym`): ``update(eps, eps_p, state, params,
dt, sigma)``; state[0] the equivalent plastic strain int sqrt(2/3 deps_p :
deps_p) (the volumetric flow included, as in J2's definition of eps_bar_p), state[1] kappa.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from numba import njit

from ..errors import require
from .axisym import SQRT_2_3
from .elastic import IsotropicConstants
from .parameters import CLASS_DEFAULT, Parameter, check, non_negative, positive, word

# params layout (float64 array)
LMBDA, MU, BULK, ALPHA_F, ALPHA_G, K0, H, K_RES, P_T, ETA = range(10)
N_PARAMS = 10
N_STATE = 2
EPS_BAR_P, KAPPA = 0, 1


def alpha_of_angle(angle_deg: float) -> float:
    """Slope 6 sin(angle) / (3 - sin(angle)) of the compression-meridian match (dimensionless)."""
    s = math.sin(math.radians(angle_deg))
    return 6.0 * s / (3.0 - s)


MATCHES = ("compression", "plane_strain")  # the cone's match to Mohr-Coulomb


def plane_strain_match(friction_deg: float, dilatancy_deg: float,
                       cohesion: float) -> tuple[float, float, float]:
    """(alpha_f, alpha_g, k) of the plane-strain match to Mohr-Coulomb (slopes
    dimensionless, k in Pa, ``cohesion`` c in Pa; the module docstring's formulas)."""
    sf = math.sin(math.radians(friction_deg))
    sg = math.sin(math.radians(dilatancy_deg))
    root = math.sqrt(3.0 + sg * sg)
    denominator = 3.0 + sf * sg
    cos_phi = math.cos(math.radians(friction_deg))
    return (3.0 * sf * root / denominator, 3.0 * sg / root,
            3.0 * cohesion * cos_phi * root / denominator)


# ----------------------------------------------------------------------------- the update

@njit(cache=True, error_model="numpy")
def _cohesion(params, kappa) -> float:
    """k(kappa) = max(k_0 + h kappa, k_res) (Pa)."""
    return max(params[K0] + params[H] * kappa, params[K_RES])


@njit(cache=True, error_model="numpy")
def _multipliers(mode, f_tr, t_tr, a, b, c, d, vis):
    """(d gamma, d lambda) of the active set ``mode`` (1 cone, 2 cut-off, 3 both)."""
    if mode == 1:
        return f_tr / (a + vis), 0.0
    if mode == 2:
        return 0.0, t_tr / (d + vis)
    aa, dd = a + vis, d + vis
    det = aa * dd - b * c
    return (f_tr * dd - b * t_tr) / det, (aa * t_tr - c * f_tr) / det


@njit(cache=True, error_model="numpy")
def _try(mode, params, kappa_n, q_tr, p_tr, dt):
    """Multipliers of an active set, with the softening floor; returns
    (d gamma, d lambda, q, p, admissible)."""
    bulk, mu = params[BULK], params[MU]
    af, ag, p_t = params[ALPHA_F], params[ALPHA_G], params[P_T]
    vis = params[ETA] / dt if params[ETA] > 0.0 else 0.0
    k_n = _cohesion(params, kappa_n)
    h = params[H] if params[K0] + params[H] * kappa_n > params[K_RES] else 0.0
    for _ in range(2):
        f_tr = q_tr - af * p_tr - k_n
        t_tr = -p_tr - p_t
        a = 3.0 * mu + bulk * af * ag + h
        dg, dl = _multipliers(mode, f_tr, t_tr, a, bulk * af, bulk * ag, bulk, vis)
        if h < 0.0 and params[K0] + params[H] * (kappa_n + dg) < params[K_RES]:
            # softening passes the residual within the step: the intercept at the end is
            # k_res whatever the path, so the branch k = k_res, h = 0 is the solution
            k_n = params[K_RES]
            h = 0.0
            continue
        break
    q = q_tr - 3.0 * mu * dg
    p = p_tr + bulk * (ag * dg + dl)
    k_new = _cohesion(params, kappa_n + dg)
    tol = 1e-12 * (abs(q_tr) + abs(p_tr) + params[K0])
    ok = dg >= -tol and dl >= -tol and q >= -tol
    # the other condition must hold at the result (for Perzyna: no overstress there)
    if mode == 1:
        ok = ok and -p - p_t <= tol
    elif mode == 2:
        ok = ok and q - af * p - k_new <= tol
    return dg, dl, q, p, ok


@njit(cache=True, error_model="numpy")
def screen(e0, e1, e2, e3, p0, p1, p2, p3, state, k, params):
    """The trial stress C : (eps - eps_p,n) (Pa) and whether it is clearly elastic, on
    scalars: (elastic, s0, s1, s2, s3). Arguments as :func:`point`'s; no square root.

    Clearly inside both surfaces: the cut-off holds exactly (t_tr = sigma_m - p_t <= 0 <=
    tol in :func:`point`), the cone with a margin 1e-12 (k + |alpha_f p|) far above the
    few roundings of f_tr (each <= EPS (q + |alpha_f p| + k), q <= k + |alpha_f p|
    here), so f_tr <= 0 <= tol there: :func:`point`'s exact test would give elastic too,
    and the trial stress is the result either way. Small and without calls, so that a
    cell loop inlines it; :func:`point` begins with it. (The arrays are read before any
    branch: numba then drops their reference counting, which would keep it from being
    inlined.)"""
    lmbda, mu, af, p_t = params[LMBDA], params[MU], params[ALPHA_F], params[P_T]
    k_n = max(params[K0] + params[H] * state[k + KAPPA], params[K_RES])
    x0, x1, x2, x3 = e0 - p0, e1 - p1, e2 - p2, e3 - p3
    lt = lmbda * (x0 + x1 + x2)
    s0, s1, s2, s3 = lt + 2.0 * mu * x0, lt + 2.0 * mu * x1, lt + 2.0 * mu * x2, 2.0 * mu * x3
    m_tr = (s0 + s1 + s2) / 3.0
    elastic = False
    if m_tr <= p_t:
        d0, d1, d2 = s0 - m_tr, s1 - m_tr, s2 - m_tr
        q2_tr = 1.5 * (d0 * d0 + d1 * d1 + d2 * d2 + 2.0 * s3 * s3)
        p_tr = -m_tr
        bound = k_n + af * p_tr - 1e-12 * (k_n + abs(af * p_tr))
        elastic = bound > 0.0 and q2_tr <= bound * bound
    return elastic, s0, s1, s2, s3


@njit(cache=True, error_model="numpy")
def point(e0, e1, e2, e3, p0, p1, p2, p3, state, k, params, dt):
    """Drucker-Prager point update on scalars (the scalar seam of :mod:`.axisym`).

    (e0..e3) the total strain at t_{n+1}, (p0..p3) the plastic strain at t_n;
    state[k + 0] the equivalent plastic strain, state[k + 1] kappa, updated in place;
    dt (s). Returns the stress (Pa) and the plastic strain at t_{n+1}, eight floats.

    The update's functions are compiled with numpy's error model: no division in them
    is by zero for admissible parameters (dt > 0, h > -3 mu makes the multipliers'
    denominators positive, q* > 0 where it divides by it), and without a zero test and
    an exception path at each division numba drops the arrays' reference counts.
    """
    elastic, s0, s1, s2, s3 = screen(e0, e1, e2, e3, p0, p1, p2, p3, state, k, params)
    if elastic:  # clearly inside both surfaces (:func:`screen`)
        return s0, s1, s2, s3, p0, p1, p2, p3
    mu, af, p_t = params[MU], params[ALPHA_F], params[P_T]
    m_tr = (s0 + s1 + s2) / 3.0
    d0, d1, d2 = s0 - m_tr, s1 - m_tr, s2 - m_tr
    q2_tr = 1.5 * (d0 * d0 + d1 * d1 + d2 * d2 + 2.0 * s3 * s3)
    p_tr = -m_tr
    kappa_n = state[k + KAPPA]
    k_n = _cohesion(params, kappa_n)
    q_tr = math.sqrt(q2_tr)
    f_tr = q_tr - af * p_tr - k_n
    t_tr = -p_tr - p_t
    scale_tol = 1e-14 * (q_tr + abs(p_tr) + params[K0])
    if f_tr <= scale_tol and t_tr <= scale_tol:
        return s0, s1, s2, s3, p0, p1, p2, p3  # elastic
    dg, dl, q, p, ok = 0.0, 0.0, q_tr, p_tr, False
    if f_tr > scale_tol:
        dg, dl, q, p, ok = _try(1, params, kappa_n, q_tr, p_tr, dt)
    if not ok and t_tr > scale_tol:
        dg, dl, q, p, ok = _try(2, params, kappa_n, q_tr, p_tr, dt)
    if not ok:
        dg, dl, q, p, ok = _try(3, params, kappa_n, q_tr, p_tr, dt)
    dg = max(dg, 0.0)
    dl = max(dl, 0.0)
    q = max(q, 0.0)
    # plastic strain increment: d gamma (3/2 s/q + alpha_g/3 I) + d lambda I/3, written as
    # the elastic strain change that gives the stress change (exact for the linear return)
    dvol = (params[ALPHA_G] * dg + dl) / 3.0
    c_dev = 1.5 * dg / q_tr if q_tr > 0.0 else 0.0
    de0 = c_dev * d0 + dvol
    de1 = c_dev * d1 + dvol
    de2 = c_dev * d2 + dvol
    de3 = c_dev * s3
    state[k + EPS_BAR_P] += SQRT_2_3 * math.sqrt(de0 * de0 + de1 * de1 + de2 * de2
                                                 + 2.0 * de3 * de3)
    state[k + KAPPA] = kappa_n + dg
    # stress at n+1: the deviator scaled radially, the mean stress from p
    ratio = q / q_tr if q_tr > 0.0 else 0.0
    m = -p
    return (m + ratio * d0, m + ratio * d1, m + ratio * d2, ratio * s3,
            p0 + de0, p1 + de1, p2 + de2, p3 + de3)


@njit(cache=True, error_model="numpy")
def update(eps, eps_p, state, params, dt, sigma) -> None:
    """Drucker-Prager point update (the array seam of :mod:`.axisym`): :func:`point`.

    eps: total strain at t_{n+1}; eps_p: plastic strain, in/out; state[0]:
    equivalent plastic strain, state[1]: kappa, in/out; dt (s); sigma out (Pa).
    """
    (sigma[0], sigma[1], sigma[2], sigma[3], eps_p[0], eps_p[1], eps_p[2], eps_p[3]) = point(
        eps[0], eps[1], eps[2], eps[3], eps_p[0], eps_p[1], eps_p[2], eps_p[3], state, 0,
        params, dt)


# ----------------------------------------------------------------------------- the material

@dataclass(frozen=True)
class DruckerPrager(IsotropicConstants):
    """Drucker-Prager rock (see the module docstring for every formula).

    E (Pa), nu, density (kg/m^3); ``ucs`` the uniaxial compressive strength (Pa);
    ``friction_angle`` phi and ``dilatancy_angle`` psi in degrees, 0 <= psi <= phi < 90;
    ``tensile_strength`` p_t (Pa), the largest hydrostatic tension (mean-stress cut-off);
    ``hardening`` h = dk/dkappa (Pa; < 0 softens); ``residual`` k_res (Pa), the
    smallest cone intercept under softening (default and minimum alpha_f p_t);
    ``viscosity`` eta (Pa s) of the Perzyna law, 0 for rate independence; ``match``
    the cone's match to Mohr-Coulomb, "compression" (the compression meridian) or
    "plane_strain" (steady plane-strain flow; for plane-strain models only).
    """

    E: float = 60e9
    nu: float = 0.25
    density: float = 2600.0
    ucs: float = 200e6
    friction_angle: float = 50.0
    dilatancy_angle: float = 10.0
    tensile_strength: float = 10e6
    hardening: float = 0.0
    residual: float | None = None
    viscosity: float = 0.0
    match: str = "compression"
    linear: ClassVar[bool] = False
    n_state: ClassVar[int] = N_STATE
    strain: ClassVar[str] = "small"
    # the triangles' cell kernel runs the exact :func:`screen` at a cell's three points
    # before it updates any, and a cell found elastic skips the point loop
    # (:func:`..internal_force.quadrature.kernels`)
    screen_ahead: ClassVar[bool] = True
    parameters: ClassVar[tuple[Parameter, ...]] = (
        positive("ucs", "Pa", "uniaxial compressive strength"),
        Parameter("friction_angle", "deg", "friction angle phi", low=0.0, high=90.0,
                  high_open=True),
        non_negative("dilatancy_angle", "deg", "dilatancy angle psi (at most friction_angle)"),
        positive("tensile_strength", "Pa", "tensile strength p_t: the largest hydrostatic "
                 "tension (mean-stress cut-off; at most k / alpha_f)"),
        Parameter("hardening", "Pa", "cohesion hardening h = dk/dkappa (< 0 softens; above -3 mu)",
                  scene_default=0.0),
        Parameter("residual", "Pa", "smallest cone intercept k_res under softening, in "
                  "[alpha_f p_t, k]", scene_default=CLASS_DEFAULT, default_text="alpha_f p_t"),
        non_negative("viscosity", "Pa s", "Perzyna viscosity eta (0: rate-independent)",
                     scene_default=0.0),
        word("match", "the cone's match to Mohr-Coulomb: on the compression meridian, or "
             "in steady plane-strain flow (plane-strain scenes only)", MATCHES, "compression"),
    )
    update = staticmethod(update)  # the compiled point update (numba), signature of axisym
    point = staticmethod(point)    # the same on scalars (the scalar seam of axisym)
    screen = staticmethod(screen)  # its elastic test, on scalars, for a cell loop to inline

    def __post_init__(self) -> None:
        self.check_elastic()
        check(self)
        require(self.dilatancy_angle <= self.friction_angle,
                f"material.dilatancy_angle = {self.dilatancy_angle} deg: must lie in "
                f"[0, friction_angle = {self.friction_angle}] (psi > phi or psi < 0 "
                "allows negative plastic work)")
        require(self.alpha_f * self.tensile_strength <= self.k,
                f"material.tensile_strength = {self.tensile_strength} Pa: must be <= "
                f"k/alpha_f = {self.k / max(self.alpha_f, 1e-300):.4g} Pa (the cone's apex)")
        require(self.residual is None or self.alpha_f * self.tensile_strength <= self.residual
                <= self.k, f"material.residual = {self.residual} Pa: must lie in "
                           f"[alpha_f p_t = {self.alpha_f * self.tensile_strength:.4g}, "
                           f"k = {self.k:.4g}] Pa")
        require(self.hardening > -3.0 * self.mu,
                f"material.hardening = {self.hardening} Pa: must be > -3 mu = {-3 * self.mu:.4g} Pa")

    # the cone
    @property
    def plane_strain(self) -> bool:
        """Whether the cone is matched to Mohr-Coulomb in plane strain."""
        return self.match == "plane_strain"

    @property
    def alpha_f(self) -> float:
        """Friction slope of the cone, dq/dp (dimensionless)."""
        if self.plane_strain:
            return plane_strain_match(self.friction_angle, self.dilatancy_angle,
                                      self.cohesion)[0]
        return alpha_of_angle(self.friction_angle)

    @property
    def alpha_g(self) -> float:
        """Dilatancy slope of the plastic potential (dimensionless)."""
        if self.plane_strain:
            return plane_strain_match(self.friction_angle, self.dilatancy_angle,
                                      self.cohesion)[1]
        return alpha_of_angle(self.dilatancy_angle)

    @property
    def k(self) -> float:
        """Initial cone intercept k_0 (Pa): UCS (1 - alpha_f/3) on the compression
        meridian, 3 c cos phi sqrt(3 + sin^2 psi) / (3 + sin phi sin psi) in plane strain."""
        if self.plane_strain:
            return plane_strain_match(self.friction_angle, self.dilatancy_angle,
                                      self.cohesion)[2]
        return self.ucs * (1.0 - self.alpha_f / 3.0)

    @property
    def cohesion(self) -> float:
        """Mohr-Coulomb cohesion c = UCS (1 - sin phi) / (2 cos phi) (Pa)."""
        phi = math.radians(self.friction_angle)
        return self.ucs * (1.0 - math.sin(phi)) / (2.0 * math.cos(phi))

    def params(self) -> np.ndarray:
        """The float64 parameter array of :func:`update`."""
        p = np.zeros(N_PARAMS)
        p[LMBDA], p[MU], p[BULK] = self.lmbda, self.mu, self.bulk
        p[ALPHA_F], p[ALPHA_G] = self.alpha_f, self.alpha_g
        p[K0], p[H] = self.k, self.hardening
        p[K_RES] = self.alpha_f * self.tensile_strength if self.residual is None else self.residual
        p[P_T], p[ETA] = self.tensile_strength, self.viscosity
        return p
