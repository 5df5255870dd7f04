"""The split Hopkinson pressure bar's waves, from the gauges to the specimen (docs/shpb.md).

Signs: compression positive everywhere (strains, stresses, forces, strain rates). The
bars are linear elastic with the bar wave speed c0 = sqrt(E / rho) (m/s); a wave moving
towards the specimen carries the particle velocity +c0 eps, one moving away -c0 eps.

At the specimen's front face (the incident bar's end) and back face (the transmitter's):

    F_front = E A_b (eps_I + eps_R),     F_back = E A_b eps_T                (N)
    v_front = c0 (eps_I - eps_R),        v_back = c0 eps_T                   (m/s)

so the specimen shortens at the rate (v_front - v_back) / L_s:

    3-wave:  rate = c0 (eps_I - eps_R - eps_T) / L_s,   stress = (F_front + F_back) / (2 A_s)
    2-wave:  stress = F_front / A_s
    1-wave:  rate = -2 c0 eps_R / L_s,                   stress = F_back / A_s

(the 1-wave forms assume equilibrium, eps_I + eps_R = eps_T). The engineering strain is
the time integral of the rate (trapezoid rule from the incident wave's arrival at the
front face), the true strain -ln(1 - eps) and the true stress sigma (1 - eps) (constant
volume); the equilibrium ratio R = 2 |F_front - F_back| / (F_front + F_back).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from .dispersion import correct, slowest_group_velocity

# A record the dispersion correction moves backwards is at rest at its end when its last
# sample is within this fraction of its gauge's peak (the incident gauge's: the incident
# wave's): the zero padding after a record cut at s makes a step of s, whose short waves
# the backward move carries ahead of it as ringing of the order of s; at 1 % of the
# incident wave that is about half the 2 % a 3-wave stress is held to (the stress is
# E A_b (eps_I + eps_R + eps_T) / (2 A_s), and eps_I + eps_R + eps_T = 2 eps_T in
# equilibrium, about eps_I when the specimen passes on about half the incident wave).
REST_FRACTION = 0.01


@dataclass(frozen=True)
class Bars:
    """The incident and transmitter bars (the same material and section): Young's modulus
    ``E`` (Pa), ``density`` (kg/m^3) and cross-section ``area`` (m^2)."""

    E: float
    density: float
    area: float

    @property
    def c0(self) -> float:
        """The bar wave speed sqrt(E / rho) (m/s)."""
        return math.sqrt(self.E / self.density)


@dataclass(frozen=True)
class Specimen:
    """The specimen's initial ``length`` L_s (m) and cross-section ``area`` A_s (m^2)."""

    length: float
    area: float


@dataclass(frozen=True)
class Gauges:
    """Where the gauges are: ``incident`` (m), the distance from the incident bar's gauge to
    the specimen's front face; ``transmitter`` (m), from the back face to the transmitter
    bar's gauge; ``arrival`` (s), the time the incident wave's front reaches the incident
    gauge (its distance from the struck end over c0, for a striker that hits at t = 0)."""

    incident: float
    transmitter: float
    arrival: float


@dataclass
class Waves:
    """The three waves at the specimen's faces on one uniform time axis ``t`` (s): the
    incident, reflected and transmitted strains (compression positive) that the faces
    see at t, starting when the incident wave reaches the front face."""

    t: np.ndarray
    incident: np.ndarray
    reflected: np.ndarray
    transmitted: np.ndarray
    cut: tuple[str, ...] = ()
    """The dispersion-corrected waves ('reflected', 'transmitted') whose gauge record
    ends before the wave has passed (not at rest to REST_FRACTION of the gauge's peak) within the
    slowest group's lag after their window: the correction moves the cut into them."""


def _shifted(t: np.ndarray, signal: np.ndarray, at: np.ndarray) -> np.ndarray:
    """``signal`` (sampled at the increasing times ``t``) read at the times ``at`` by linear
    interpolation; 0 outside the record."""
    return np.interp(at, t, signal, left=0.0, right=0.0)


@dataclass(frozen=True)
class Dispersion:
    """The bars' ``radius`` (m) and Poisson's ratio ``nu``, for the dispersion correction
    (:func:`.dispersion.correct`) of :func:`separate`."""

    radius: float
    nu: float


def misfit(t: np.ndarray, bars: Bars, gauges: Gauges, pulse: float) -> str | None:
    """Why the waves of an incident pulse lasting ``pulse`` (s) cannot be separated from
    gauge records sampled at the increasing times ``t`` (s); None when they can. They
    overlap at the incident gauge when the pulse is longer than 2 d_I / c0, and the last
    face sample, arrival + d_I / c0 + pulse (on the records' step), must have reached the
    farther gauge, max(d_I, d_T) / c0 later, before the record ends."""
    c0 = bars.c0
    d_i, d_t = gauges.incident, gauges.transmitter
    if pulse > 2.0 * d_i / c0:
        return (f"shpb: the incident pulse ({pulse * 1e6:.1f} us) is longer than the time the "
                f"incident gauge has before the reflection returns ({2e6 * d_i / c0:.1f} us): "
                "the waves overlap at the gauge; move it farther from the specimen or shorten "
                "the striker")
    dt = float(t[1] - t[0])
    last = gauges.arrival + d_i / c0 + dt * math.floor(pulse / dt)
    if last + max(d_i, d_t) / c0 > t[-1]:
        return (f"shpb: the record ends at {t[-1] * 1e6:.1f} us, before the transmitted and "
                "reflected waves have passed their gauges "
                f"({(last + max(d_i, d_t) / c0) * 1e6:.1f} us): run longer")
    return None


def separate(t: np.ndarray, incident_gauge: np.ndarray, transmitter_gauge: np.ndarray,
             bars: Bars, gauges: Gauges, pulse: float,
             dispersion: Dispersion | None = None) -> Waves:
    """The waves at the specimen's faces from the two gauges' records (strains, compression
    positive, sampled at the increasing times ``t``, s), the incident pulse lasting
    ``pulse`` (s; 2 L_striker / c0).

    The incident gauge records the incident wave from ``gauges.arrival`` and the reflected
    one from arrival + 2 d_I / c0, when the incident front has gone to the face and back:
    the waves do not overlap at the gauge when the pulse is no longer than 2 d_I / c0
    (else refused). The face sees the incident wave d_I / c0 after the gauge and the
    reflected one d_I / c0 before; the transmitted wave reaches the transmitter gauge
    d_T / c0 after the back face. The face time axis starts at the incident front's
    arrival at the front face, steps like ``t`` and lasts the pulse.

    With ``dispersion`` each wave is first moved between its gauge and its face with the
    first mode's phase velocity of every frequency (the Pochhammer–Chree correction,
    :func:`.dispersion.correct`: the incident wave forward over d_I, the reflected and the
    transmitted back over d_I and d_T), then shifted by the bar speed as without it. The
    records must then be uniformly sampled and at rest at both ends."""
    t = np.asarray(t, dtype=float)
    c0 = bars.c0
    d_i, d_t = gauges.incident, gauges.transmitter
    if not (d_i > 0.0 and d_t > 0.0):
        raise InputError("shpb: the gauges must lie on the bars, away from the specimen "
                         f"(distances {d_i} m and {d_t} m)")
    problem = misfit(t, bars, gauges, pulse)
    if problem is not None:
        raise InputError(problem)
    dt = float(t[1] - t[0])
    start = gauges.arrival + d_i / c0  # the incident front at the front face
    face = start + dt * np.arange(int(math.floor(pulse / dt)) + 1)
    switch = gauges.arrival + 2.0 * d_i / c0  # the reflection's first arrival at the gauge
    before = np.where(t < switch, incident_gauge, 0.0)
    after = np.where(t >= switch, incident_gauge, 0.0)
    transmitted = np.asarray(transmitter_gauge, dtype=float)
    cut: list[str] = []
    if dispersion is not None:
        a, nu = dispersion.radius, dispersion.nu
        incident_peak = float(np.max(np.abs(incident_gauge)))
        for name, record, d in (("reflected", after, d_i), ("transmitted", transmitted, d_t)):
            reach = d / c0 * (1.0 / slowest_group_velocity(nu) - 1.0)
            peak = incident_peak if name == "reflected" else float(np.max(np.abs(record)))
            if (t[-1] - reach < face[-1] + d / c0
                    and abs(float(record[-1])) > REST_FRACTION * peak):
                cut.append(name)
        before = correct(t, before, d_i, a, nu, c0)
        after = correct(t, after, -d_i, a, nu, c0)
        transmitted = correct(t, transmitted, -d_t, a, nu, c0)
    return Waves(t=face, incident=_shifted(t, before, face - d_i / c0),
                 reflected=_shifted(t, after, face + d_i / c0),
                 transmitted=_shifted(t, transmitted, face + d_t / c0), cut=tuple(cut))


@dataclass
class Analysis:
    """The specimen's history from its bars' waves (compression positive): on the face time
    axis ``t`` (s), the face forces (N) and the equilibrium ratio, the strain rates (1/s),
    engineering strains and stresses (Pa) of the 1-, 2- and 3-wave analyses and their
    true values."""

    t: np.ndarray
    force_front: np.ndarray
    force_back: np.ndarray
    equilibrium: np.ndarray
    rate_1: np.ndarray
    rate_3: np.ndarray
    strain_1: np.ndarray
    strain_3: np.ndarray
    stress_1: np.ndarray
    stress_2: np.ndarray
    stress_3: np.ndarray

    def true_strain(self, strain: np.ndarray) -> np.ndarray:
        """-ln(1 - eps) of an engineering strain (compression positive)."""
        return -np.log1p(-strain)

    def true_stress(self, stress: np.ndarray, strain: np.ndarray) -> np.ndarray:
        """sigma (1 - eps) (Pa): the engineering stress on the current section of a specimen
        of constant volume."""
        return stress * (1.0 - strain)

    def plateau(self, r_max: float = 0.05, band: float = 0.1) -> np.ndarray:
        """Where the analysis can be trusted: the equilibrium ratio at most ``r_max`` and the
        3-wave strain rate within ``band`` of the loading's median rate: the median over
        the samples of ratio at most ``r_max`` whose rate is at least half the largest
        there (the unloading at a pulse's end, which a whole shaped pulse holds, is not
        the test's rate; a boolean mask of t)."""
        ok = self.equilibrium <= r_max
        if not ok.any():
            return ok
        rate = self.rate_3[ok]
        loading = rate[rate >= 0.5 * rate.max()] if rate.max() > 0.0 else rate
        median = float(np.median(loading))
        return ok & (np.abs(self.rate_3 - median) <= band * abs(median))

    def columns(self) -> dict[str, np.ndarray]:
        """Every series by its CSV column name (units in the names' docs/shpb.md table)."""
        return {"time": self.t, "force_front": self.force_front, "force_back": self.force_back,
                "equilibrium_ratio": self.equilibrium, "strain_rate_1": self.rate_1,
                "strain_rate_3": self.rate_3, "strain_1": self.strain_1,
                "strain_3": self.strain_3, "stress_1": self.stress_1,
                "stress_2": self.stress_2, "stress_3": self.stress_3,
                "true_strain_3": self.true_strain(self.strain_3),
                "true_stress_3": self.true_stress(self.stress_3, self.strain_3)}


def _integral(t: np.ndarray, rate: np.ndarray) -> np.ndarray:
    """The running trapezoid integral of ``rate`` over ``t``, 0 at t[0]."""
    out = np.zeros_like(rate)
    out[1:] = np.cumsum(0.5 * (rate[1:] + rate[:-1]) * np.diff(t))
    return out


def analyse(waves: Waves, bars: Bars, specimen: Specimen) -> Analysis:
    """The 1-, 2- and 3-wave analyses of ``waves`` (module docstring)."""
    c0, stiffness = bars.c0, bars.E * bars.area
    front = stiffness * (waves.incident + waves.reflected)
    back = stiffness * waves.transmitted
    total = front + back
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(total > 0.0, 2.0 * np.abs(front - back) / total, np.inf)
    rate_1 = -2.0 * c0 * waves.reflected / specimen.length
    rate_3 = c0 * (waves.incident - waves.reflected - waves.transmitted) / specimen.length
    return Analysis(t=waves.t, force_front=front, force_back=back, equilibrium=ratio,
                    rate_1=rate_1, rate_3=rate_3, strain_1=_integral(waves.t, rate_1),
                    strain_3=_integral(waves.t, rate_3), stress_1=back / specimen.area,
                    stress_2=front / specimen.area, stress_3=0.5 * total / specimen.area)
