"""Uniaxial strain of a Drucker-Prager material: the closed form behind the point test and
a future plastic wave test (the two amplitudes and speeds of a uniaxial-strain bar).

Derivation, in the module's conventions (impact_fenics.materials.drucker_prager:
tension positive, p = -tr sigma/3, cone q = k + alpha_f p, potential slope alpha_g,
k(kappa) = k_0 + h kappa with kappa = sum d gamma, the deviatoric equivalent
plastic strain, so h is per unit of that measure).

Compress along z with eps_rr = eps_tt = 0, e = -eps_zz > 0 (a compressive strain).

Elastic: sigma_zz = -(K + 4 mu/3) e, sigma_rr = sigma_tt = -(K - 2 mu/3) e, so
p = K e and q = |sigma_zz - sigma_rr| = 2 mu e. The cone is reached when
2 mu e = k + alpha_f K e, i.e. e_Y = k / (2 mu - K alpha_f), which needs
2 mu > K alpha_f, i.e. alpha_f < 2 mu / K = 3 (1 - 2 nu) / (1 + nu). The
Hugoniot elastic limit (the axial stress magnitude there) is

    sigma_HEL = (K + 4 mu / 3) k / (2 mu - K alpha_f).

Plastic: the deviator stays along z, so the radial return is exact and
increments add. Per de > 0 the trial state moves by dq* = 2 mu de,
dp* = K de; the return moves q by -3 mu d gamma and p by K alpha_g d gamma.
Consistency, dq - alpha_f dp - h d gamma = 0, gives

    d gamma = (2 mu - K alpha_f) de / (3 mu + K alpha_f alpha_g + h).

The axial stress magnitude is S = p + 2 q / 3 (sigma_zz = -p + s_zz with
s_zz = -2 q / 3), so dS = (K + 4 mu/3) de - (2 mu - K alpha_g) d gamma and the
plastic modulus is

    M_p = K + 4 mu/3 - (2 mu - K alpha_f)(2 mu - K alpha_g) / (3 mu + K alpha_f alpha_g + h),

which must be > 0 (else the stress falls under growing strain: no plastic
wave). Here h = dk/dkappa per unit kappa (the deviatoric plastic strain; not per unit
of an eps_bar_p that also counts the volumetric flow).
A bar in uniaxial strain then carries an elastic precursor sigma_HEL at
c_L = sqrt((K + 4 mu/3)/rho) and a plastic front at c_p = sqrt(M_p / rho).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from impact_fenics.errors import require


@dataclass(frozen=True)
class UniaxialStrain:
    """Closed-form uniaxial-strain response (Pa, m/s); see the module docstring."""

    e_yield: float      # compressive strain at first yield
    sigma_hel: float    # axial stress magnitude at first yield (Pa)
    m_elastic: float    # K + 4 mu / 3 (Pa)
    m_plastic: float    # M_p (Pa)
    c_elastic: float    # sqrt(m_elastic / rho) (m/s)
    c_plastic: float    # sqrt(M_p / rho) (m/s)


def uniaxial_strain(material) -> UniaxialStrain:
    """The closed form for a DruckerPrager material; refuses slopes at or above 2 mu / K
    and M_p <= 0 (one InputError line each)."""
    K, mu, h = material.bulk, material.mu, material.hardening
    af, ag = material.alpha_f, material.alpha_g
    bound = 2.0 * mu / K
    require(af < bound, f"alpha_f = {af:.4g} >= 2 mu/K = {bound:.4g}: the cone never yields "
                        "in uniaxial strain (lower the friction angle)")
    require(ag < bound, f"alpha_g = {ag:.4g} >= 2 mu/K = {bound:.4g}: no plastic uniaxial-strain "
                        "wave (lower the dilatancy angle)")
    m_el = K + 4.0 * mu / 3.0
    m_p = m_el - (2 * mu - K * af) * (2 * mu - K * ag) / (3 * mu + K * af * ag + h)
    require(m_p > 0, f"plastic modulus M_p = {m_p:.4g} Pa <= 0: no plastic uniaxial-strain wave")
    e_y = material.k / (2.0 * mu - K * af)
    return UniaxialStrain(e_y, m_el * e_y, m_el, m_p, math.sqrt(m_el / material.density),
                          math.sqrt(m_p / material.density))
