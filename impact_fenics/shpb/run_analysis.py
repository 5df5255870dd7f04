"""``impact-fenics shpb RUN_DIR``: the Hopkinson analysis of a finished SHPB run (docs/shpb.md).

It reads the run's copy of its scene (``scene.toml``: the ``shpb`` mesh generator's
geometry, the bars' and the specimen's materials, the striker's speed, the gauges) and
its ``history.csv`` (the two strain gauges, the specimen faces' contact forces, the
optional face displacement probes), separates the waves and runs the 1-, 2- and 3-wave
analyses (:mod:`.waves`), and writes ``shpb.csv`` and three pictures into the run
directory. It replaces only files it wrote before (the run's manifest lists them);
anything else of that name is refused.

What it expects of the scene (scenes/shpb.toml is one):

* ``[mesh] generator = "shpb"``; bodies named ``striker``, ``incident``, ``specimen``,
  ``transmitter``; the struck end of the incident bar at z = 0 touching the striker at
  t = 0;
* ``[[probes]]`` of ``quantity = "strain_gauge"`` named ``incident_gauge`` (on the
  incident bar) and ``transmitter_gauge`` (on the transmitter), given by ``z``;
* the specimen's faces in ``[[contact]]`` sets (``specimen_front``, ``specimen_back``):
  their contact forces are the true face forces;
* optionally ``u_z`` probes named ``specimen_front_u`` and ``specimen_back_u`` inside the
  specimen near its faces: the true strain (u_front - u_back) / (z_back - z_front).
"""
from __future__ import annotations

import csv
import inspect
import math
import os
import sys
import tomllib
from dataclasses import dataclass, replace

import numpy as np

from ..errors import InputError
from .sizing import needed, pulse_duration, shaper_rise_time
from .waves import (REST_FRACTION, Analysis, Bars, Dispersion, Gauges, Specimen, Waves, analyse,
                    misfit, separate)

FILES = ("shpb.csv", "shpb_waves.png", "shpb_stress_strain.png", "shpb_equilibrium.png")
BODIES = ("striker", "incident", "specimen", "transmitter")
GAUGES = ("incident_gauge", "transmitter_gauge")
FACE_PROBES = ("specimen_front_u", "specimen_back_u")
BARS = ("striker", "incident", "transmitter")  # the linear bodies of the step
# the equilibrium ratio below which the specimen counts as in equilibrium (the plateau's)
R_EQUILIBRIUM = 0.05
# the share of the bars' yield stress that the incident stress rho c0 v / 2 may reach
# without a warning: the bar's surface carries the Pochhammer-Chree overshoot of the rise
# (some 10 % of the plateau at a sharp impact) and the gauges need the bars elastic
BAR_YIELD_FRACTION = 0.8
# the relative slack of the bars' length checks (bar_length_warning): 64 roundings
LENGTH_SLACK = 64 * np.finfo(float).eps


def bar_stress_warning(scene) -> str | None:
    """A warning line when the incident stress rho c0 v / 2 (Pa) of an SHPB scene (read by
    scene_file; the bars the incident bar's material, v the striker's speed) exceeds
    BAR_YIELD_FRACTION of ``[mesh] bar_yield_stress``; None otherwise or without it."""
    yield_stress = scene.mesh.params.get("bar_yield_stress")
    bodies = {b.name: b for b in scene.bodies}
    if yield_stress is None or "incident" not in bodies or "striker" not in bodies:
        return None
    m = scene.materials[bodies["incident"].material]
    stress = 0.5 * m.density * math.sqrt(m.E / m.density) * abs(bodies["striker"].velocity[1])
    if stress <= BAR_YIELD_FRACTION * yield_stress:
        return None
    return (f"warning: the incident stress rho c0 v / 2 = {stress / 1e6:.4g} MPa exceeds "
            f"{BAR_YIELD_FRACTION:g} of the bars' yield stress ({yield_stress / 1e6:.4g} MPa): "
            "real bars would not stay elastic; lower the striker's speed")


def shaper_stiffness(contacts: list[dict], h_bar: float, radius: float) -> float:
    """k (N/m) of the pulse shaper: the penalty p (N/m per node pair) of the ``[[contact]]``
    table (``contacts``: the scene file's tables) between ``striker_face`` and
    ``incident_struck`` times its round(radius / h_bar) + 1 node pairs; infinite when the
    striker meets the bar otherwise (DME, FILM, a scaled penalty: a flat pulse)."""
    for c in contacts:
        if {c.get("lower"), c.get("upper")} == {"striker_face", "incident_struck"}:
            penalty = c.get("penalty")
            if c.get("method") == "penalty" and isinstance(penalty, (int, float)):
                return float(penalty) * (int(round(radius / h_bar)) + 1)
    return math.inf


def incident_pulse(contacts: list[dict], g: dict, c0: float,
                   impedance: float) -> tuple[float, float]:
    """T (s): the incident pulse from its front until it stays below REST_FRACTION of its
    peak, 2 L_striker / c0 for a flat striker (:func:`.sizing.pulse_duration`); and the
    shaper's rise time (s, 0 for a flat striker) it follows from."""
    rise = shaper_rise_time(impedance, shaper_stiffness(contacts, g["h_bar"],
                                                        0.5 * g["bar_diameter"]))
    return pulse_duration(2.0 * g["striker_length"] / c0, rise, REST_FRACTION), rise


def bar_length_warning(scene) -> str | None:
    """A warning line when an SHPB scene's bars (or its t_end) are too short for the pulse
    they will carry (docs/shpb.md, "Sizing rule"; :mod:`.sizing`): naming each key and the
    length (m) or time (s) it needs; None when they suffice or the scene lacks a gauge."""
    g = _geometry(scene.mesh.params)
    bodies = {b.name: b for b in scene.bodies}
    probes = {p.name: p for p in scene.probes}
    if "incident" not in bodies or any(name not in probes for name in GAUGES):
        return None
    m = scene.materials[bodies["incident"].material]
    c0 = math.sqrt(m.E / m.density)
    radius = 0.5 * g["bar_diameter"]
    impedance = m.density * c0 * math.pi * radius ** 2
    contacts = [{"lower": c.lower, "upper": c.upper, "method": c.method, "penalty": c.penalty}
                for c in scene.contacts]
    pulse, rise = incident_pulse(contacts, g, c0, impedance)
    z_i = probes["incident_gauge"].point[1]
    d_i = g["incident_length"] - z_i
    d_t = probes["transmitter_gauge"].point[1] - g["incident_length"] - g["specimen_length"]
    need = needed(pulse, c0, z_i, d_i)
    # the distances are differences of positions summed from the scene's lengths: a few
    # roundings of the bars' whole length, far below LENGTH_SLACK of it
    slack = LENGTH_SLACK * (g["striker_length"] + g["incident_length"] + g["transmitter_length"])
    short = []
    if z_i < need.gauge_from_struck_end - slack or d_i < need.gauge_from_specimen - slack:
        short.append(f"[mesh] incident_length = {g['incident_length']:.4g} m needs "
                     f"{need.gauge_from_struck_end + need.gauge_from_specimen:.4g} m, the "
                     f"incident gauge at z >= {need.gauge_from_struck_end:.4g} m and "
                     f">= {need.gauge_from_specimen:.4g} m from the specimen")
    if g["transmitter_length"] - d_t < need.transmitter_length - slack:
        short.append(f"[mesh] transmitter_length = {g['transmitter_length']:.4g} m needs "
                     f"{d_t + need.transmitter_length:.4g} m")
    t_end = scene.time.get("t_end")
    if t_end is not None and t_end < need.t_end:
        short.append(f"[time] t_end = {t_end:.4g} s needs {need.t_end:.4g} s")
    if not short:
        return None
    shaped = f"shaper rise {rise * 1e6:.3g} us" if rise > 0.0 else "flat"
    return (f"warning: the bars are too short for the pulse of {pulse * 1e6:.4g} us ({shaped}, "
            f"its end at {REST_FRACTION:g} of its peak): " + "; ".join(short)
            + " (docs/shpb.md, \"Sizing rule\")")


@dataclass
class Setup:
    """What the analysis needs of the run: the bars, the specimen, the gauges, the incident
    pulse (s), the bars' radius (m) and Poisson's ratio, the striker speed (m/s), the
    specimen's material table (with its body's kinematics as ``strain``, "small" or
    "finite"), the gauges' and the contact columns of history.csv. ``pulse`` is the
    whole incident pulse (a shaped one lasts longer than 2 L_striker / c0, ``flat``)."""

    bars: Bars
    specimen: Specimen
    gauges: Gauges
    pulse: float
    flat: float
    radius: float
    nu: float
    speed: float
    specimen_material: dict
    front_force: str | None
    back_force: str | None
    face_probes: tuple[float, float] | None

    @property
    def transit(self) -> float:
        """The specimen's elastic transit L_s / c_s (s), c_s = sqrt(E_s / rho_s) its bar
        speed."""
        m = self.specimen_material
        return self.specimen.length / math.sqrt(float(m["E"]) / float(m["density"]))


def _need(cond: bool, message: str) -> None:
    if not cond:
        raise InputError(message)


def _geometry(mesh: dict) -> dict:
    """The ``shpb`` generator's parameters, its defaults filled in."""
    from .. import meshing

    params = {k: v.default for k, v in inspect.signature(meshing.shpb).parameters.items()
              if v.default is not inspect.Parameter.empty and k != "comm"}
    params.update({k: v for k, v in mesh.items() if k != "generator"})
    return params


def _probe_z(probe: dict) -> float:
    return float(probe["z"]) if "z" in probe else float(probe["point"][1])


def read_setup(run_dir: str, columns: list[str]) -> Setup:
    """The analysis' inputs from ``run_dir/scene.toml`` (``columns``: history.csv's)."""
    path = os.path.join(run_dir, "scene.toml")
    _need(os.path.isfile(path), f"shpb: '{run_dir}' holds no scene.toml: it is not the "
                                "directory of a run from a scene file")
    try:
        with open(path, "rb") as f:
            scene = tomllib.load(f)
    except (OSError, tomllib.TOMLDecodeError) as exc:
        raise InputError(f"shpb: '{path}' cannot be read: {exc}") from None
    mesh = scene.get("mesh", {})
    _need(mesh.get("generator") == "shpb", f"shpb: '{path}' is not an SHPB scene ([mesh] "
                                           "generator = \"shpb\")")
    g = _geometry(mesh)
    bodies, materials = scene.get("bodies", {}), scene.get("materials", {})
    for name in BODIES:
        _need(name in bodies, f"shpb: '{path}' has no [bodies.{name}]")
    bar = materials.get(bodies["incident"].get("material"), {})
    try:
        E, rho, nu = float(bar["E"]), float(bar["density"]), float(bar["nu"])
    except (KeyError, TypeError, ValueError):
        raise InputError(f"shpb: '{path}': the incident bar's material needs E, nu and "
                         "density") from None
    radius = 0.5 * g["bar_diameter"]
    bars = Bars(E=E, density=rho, area=math.pi * radius ** 2)
    c0 = bars.c0
    specimen = Specimen(length=g["specimen_length"],
                        area=math.pi * (0.5 * g["specimen_diameter"]) ** 2)
    probes = {p.get("name"): p for p in scene.get("probes", [])}
    for name in GAUGES:
        _need(name in probes and probes[name].get("quantity") == "strain_gauge",
              f"shpb: '{path}' has no strain_gauge probe named '{name}'")
        _need(name in columns, f"shpb: history.csv has no column '{name}'")
    front = g["incident_length"]
    back = front + g["specimen_length"]
    z_i, z_t = _probe_z(probes["incident_gauge"]), _probe_z(probes["transmitter_gauge"])
    _need(0.0 < z_i < front, f"shpb: the incident gauge (z = {z_i} m) is not on the incident "
                             f"bar (0 < z < {front} m)")
    _need(back < z_t < back + g["transmitter_length"],
          f"shpb: the transmitter gauge (z = {z_t} m) is not on the transmitter bar "
          f"({back} < z < {back + g['transmitter_length']} m)")
    gauges = Gauges(incident=front - z_i, transmitter=z_t - back, arrival=z_i / c0)
    forces = {}
    for k, contact in enumerate(scene.get("contact", [])):
        prefix = f"c{k}_" if len(scene.get("contact", [])) > 1 else ""
        faces = {contact.get(key) for key in ("lower", "upper", "slave", "master")}
        for face in ("specimen_front", "specimen_back"):
            if face in faces and prefix + "contact_force" in columns:
                forces[face] = prefix + "contact_force"
    face_probes = None
    if all(n in probes and n in columns for n in FACE_PROBES):
        face_probes = (_probe_z(probes[FACE_PROBES[0]]), _probe_z(probes[FACE_PROBES[1]]))
    velocity = bodies["striker"].get("velocity", [0.0, 0.0])
    flat = 2.0 * g["striker_length"] / c0
    return Setup(bars=bars, specimen=specimen, gauges=gauges,
                 pulse=incident_pulse(scene.get("contact", []), g, c0, rho * c0 * bars.area)[0],
                 flat=flat, radius=radius, nu=nu,
                 speed=abs(float(velocity[1])),
                 specimen_material={**materials.get(bodies["specimen"].get("material"), {}),
                                    "strain": bodies["specimen"].get("strain", "small")},
                 front_force=forces.get("specimen_front"),
                 back_force=forces.get("specimen_back"), face_probes=face_probes)


def read_history(run_dir: str) -> dict[str, np.ndarray]:
    """history.csv's columns (float arrays by name)."""
    path = os.path.join(run_dir, "history.csv")
    try:
        with open(path, newline="") as f:
            rows = list(csv.reader(f))
        names = rows[0]
        data = np.array([[float(x) for x in row] for row in rows[1:]], dtype=float)
    except (OSError, IndexError, ValueError) as exc:
        raise InputError(f"shpb: '{path}' cannot be read as a history: {exc}") from None
    _need(data.ndim == 2 and data.shape[0] >= 3 and data.shape[1] == len(names),
          f"shpb: '{path}' has too few rows")
    return {name: data[:, k] for k, name in enumerate(names)}


def uniform(t: np.ndarray) -> slice:
    """The leading rows of ``t`` sampled at one spacing (a run's last row, written after
    the last step, may come sooner than ``history_every`` steps after the one before)."""
    step = t[1] - t[0]
    n = len(t)
    while n > 2 and abs((t[n - 1] - t[n - 2]) - step) > 1e-6 * step:
        n -= 1
    return slice(0, n)


def material_law(material: dict, strain: np.ndarray, rate: float) -> np.ndarray | None:
    """The specimen's engineering stress (Pa) in uniaxial stress at the engineering strain
    ``strain`` (compression positive, monotonic loading) and the strain rate ``rate``
    (1/s), small strain: elastic sigma = E eps; j2 (linear hardening H, overstress
    viscosity eta) sigma = min(E eps, (sigma_0 + H eps) E / (E + H)),
    sigma_0 = sigma_y + eta rate. None for another model.

    A finite-strain j2 specimen (``material["strain"] == "finite"``: Hencky elasticity,
    the yield on the Kirchhoff stress tau = J sigma) follows the same line in tau against
    the log strain e = -ln(1 - eps): tau = min(E e, (sigma_y + H e) E / (E + H)). A uniform
    specimen of length L carries tau = F L / (A_0 L_0) whatever its J (A = J A_0 L_0 / L),
    so its engineering stress F / A_0 is tau / (1 - eps): returned, so that every curve
    is compared in its own engineering measure."""
    model = material.get("model", "elastic")
    E = float(material.get("E", 0.0))
    finite = material.get("strain", "small") == "finite"
    if finite and model != "j2":
        return None
    if finite:
        strain = np.asarray(strain, dtype=float)
        log = -np.log1p(-strain)
        H = float(material.get("hardening", 0.0))
        tau = np.minimum(E * log, (float(material["yield_stress"]) + H * log) * E / (E + H))
        return tau / (1.0 - strain)
    if model == "elastic":
        return E * strain
    if model == "j2":
        H = float(material.get("hardening", 0.0))
        s0 = float(material["yield_stress"]) + float(material.get("viscosity", 0.0)) * rate
        return np.minimum(E * strain, (s0 + H * strain) * E / (E + H))
    return None


def _check_writable(run_dir: str) -> None:
    """Refuse when a file the command writes exists and is not the command's own (the
    run's manifest lists it at its size): a file the command did not write is kept."""
    from ..rundir import read_marker

    listed = (read_marker(run_dir) or {}).get("files")
    listed = listed if isinstance(listed, dict) else {}
    for name in FILES:
        path = os.path.join(run_dir, name)
        if os.path.lexists(path) and listed.get(name) != (
                os.path.getsize(path) if os.path.isfile(path) else None):
            raise InputError(f"shpb: '{path}' exists and was not written by an earlier "
                             "analysis of this run: it is never replaced; move it away")


@dataclass
class Result:
    """The analysis of a run, with the truth from its faces on the face time axis."""

    setup: Setup
    waves: Waves
    analysis: Analysis
    force_front_true: np.ndarray | None
    force_back_true: np.ndarray | None
    strain_true: np.ndarray | None
    plateau: np.ndarray
    rate: float
    law: np.ndarray | None

    def equilibrium_time(self, truth: bool = False) -> float | None:
        """The time (s) from the incident front's arrival at the front face to the first
        sample where R <= R_EQUILIBRIUM: R of the gauges' face forces, or with ``truth``
        of the faces' contact forces (None without them, or when R never falls so far)."""
        if truth:
            if self.force_front_true is None or self.force_back_true is None:
                return None
            f, b = self.force_front_true, self.force_back_true
            with np.errstate(divide="ignore", invalid="ignore"):
                ratio = np.where(f + b > 0.0, 2.0 * np.abs(f - b) / (f + b), np.inf)
        else:
            ratio = self.analysis.equilibrium
        hit = np.flatnonzero(ratio <= R_EQUILIBRIUM)
        return None if hit.size == 0 else float(self.waves.t[hit[0]] - self.waves.t[0])


def time_split(run_dir: str) -> tuple[float, float] | None:
    """The loop's internal-force seconds of the bars (the linear bodies, BARS) and of the
    specimen, from the run's summary.json (each body's ``f_int_seconds``); None without."""
    import json

    try:
        with open(os.path.join(run_dir, "summary.json")) as f:
            bodies = json.load(f)["bodies"]
        return (sum(float(bodies[b]["f_int_seconds"]) for b in BARS),
                float(bodies["specimen"]["f_int_seconds"]))
    except (OSError, ValueError, KeyError, TypeError):
        return None


def analyse_run(run_dir: str, dispersion: bool = False) -> Result:
    """Read and analyse the run in ``run_dir`` (nothing written)."""
    from ..rundir import read_marker

    _need(os.path.isdir(run_dir), f"shpb: run directory '{run_dir}' does not exist")
    _need(os.path.isfile(os.path.join(run_dir, "history.csv"))
          and os.path.isfile(os.path.join(run_dir, "scene.toml")),
          f"shpb: '{run_dir}' is not a run directory (no history.csv and scene.toml): give "
          "the --out folder of an SHPB scene's run")
    status = (read_marker(run_dir) or {}).get("status", "completed")
    _need(not isinstance(status, str) or status.startswith("completed"),
          f"shpb: the run in '{run_dir}' is {status}: its records end early (run it to the end)")
    h = read_history(run_dir)
    setup = read_setup(run_dir, list(h))
    rows = uniform(h["time"])
    t = h["time"][rows]
    gauge_i, gauge_t = -h["incident_gauge"][rows], -h["transmitter_gauge"][rows]
    disp = Dispersion(setup.radius, setup.nu) if dispersion else None
    # the window: the whole pulse where the incident gauge and the record hold it (bars
    # sized by docs/shpb.md's rule); else the flat striker's 2 L_st / c0, as the run's
    # bar-length warning said
    if misfit(t, setup.bars, setup.gauges, setup.pulse) is not None:
        setup = replace(setup, pulse=setup.flat)
    waves = separate(t, gauge_i, gauge_t, setup.bars, setup.gauges, setup.pulse, disp)
    result = analyse(waves, setup.bars, setup.specimen)

    def at_faces(name: str | None) -> np.ndarray | None:
        return None if name is None else np.interp(waves.t, t, h[name][rows])

    strain_true = None
    if setup.face_probes is not None:
        z_f, z_b = setup.face_probes
        u_f, u_b = at_faces(FACE_PROBES[0]), at_faces(FACE_PROBES[1])
        strain_true = (u_f - u_b) / (z_b - z_f)
    plateau = result.plateau()
    rate = float(np.median(result.rate_3[plateau])) if plateau.any() else float(
        np.median(result.rate_3))
    law = material_law(setup.specimen_material, result.strain_3, rate)
    return Result(setup, waves, result, at_faces(setup.front_force),
                  at_faces(setup.back_force), strain_true, plateau, rate, law)


def columns(r: Result) -> dict[str, np.ndarray]:
    """shpb.csv's columns: the analysis', the waves at the faces, the plateau mask, the
    truth from the faces and the material law at the 3-wave strain."""
    cols = r.analysis.columns()
    cols |= {"incident": r.waves.incident, "reflected": r.waves.reflected,
             "transmitted": r.waves.transmitted, "plateau": r.plateau.astype(float)}
    area = r.setup.specimen.area
    if r.force_front_true is not None:
        cols["force_front_true"] = r.force_front_true
    if r.force_back_true is not None:
        cols["force_back_true"] = r.force_back_true
    if r.force_front_true is not None and r.force_back_true is not None:
        cols["stress_true"] = 0.5 * (r.force_front_true + r.force_back_true) / area
    if r.strain_true is not None:
        cols["strain_true"] = r.strain_true
    if r.law is not None:
        cols["stress_law_3"] = r.law
    return cols


def _write_csv(path: str, cols: dict[str, np.ndarray]) -> None:
    tmp = path + ".tmp"
    names = list(cols)
    with open(tmp, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(names)
        for row in zip(*(cols[n] for n in names)):
            w.writerow([repr(float(x)) for x in row])
    os.replace(tmp, path)


def _pictures(run_dir: str, r: Result) -> list[str]:
    """shpb_waves.png, shpb_stress_strain.png, shpb_equilibrium.png (matplotlib)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    us = 1e6 * r.waves.t
    a = r.analysis
    written = []

    fig, ax = plt.subplots(figsize=(7, 4))
    for name, y in (("incident", r.waves.incident), ("reflected", r.waves.reflected),
                    ("transmitted", r.waves.transmitted)):
        ax.plot(us, 1e3 * y, label=name)
    ax.set_xlabel("time at the specimen's faces (µs)")
    ax.set_ylabel("bar strain (10⁻³, compression +)")
    ax.legend()
    ax.set_title("the waves at the specimen's faces")
    written.append(_save(fig, plt, os.path.join(run_dir, "shpb_waves.png")))

    fig, ax = plt.subplots(figsize=(7, 4.5))
    mpa = 1e-6
    ax.plot(a.strain_1, mpa * a.stress_1, label="1-wave")
    ax.plot(a.strain_3, mpa * a.stress_2, label="2-wave", alpha=0.7)
    ax.plot(a.strain_3, mpa * a.stress_3, label="3-wave")
    if r.law is not None:
        ax.plot(a.strain_3, mpa * r.law, "k--", label=f"material law at {r.rate:.3g} 1/s")
    cols = columns(r)
    if "stress_true" in cols:
        x = cols.get("strain_true", a.strain_3)
        ax.plot(x, mpa * cols["stress_true"], ":", color="grey",
                label="truth: face forces" + (" and displacements" if "strain_true" in cols
                                              else " (3-wave strain)"))
    if r.plateau.any():
        ax.plot(a.strain_3[r.plateau], mpa * a.stress_3[r.plateau], ".", ms=2, color="C3",
                label="plateau (R ≤ 5 %, rate within 10 %)")
    ax.set_xlabel("engineering strain (compression +)")
    ax.set_ylabel("engineering stress (MPa)")
    ax.legend(fontsize=8)
    ax.set_title("stress–strain")
    written.append(_save(fig, plt, os.path.join(run_dir, "shpb_stress_strain.png")))

    fig, ax = plt.subplots(figsize=(7, 3.5))
    ratio = np.where(np.isfinite(a.equilibrium), a.equilibrium, np.nan)
    ax.plot(us, ratio)
    ax.axhline(0.05, color="k", ls="--", lw=0.8)
    ax.set_ylim(0, 1)
    ax.set_xlabel("time at the specimen's faces (µs)")
    ax.set_ylabel("R = 2|F_front − F_back| / (F_front + F_back)")
    ax.set_title("equilibrium")
    written.append(_save(fig, plt, os.path.join(run_dir, "shpb_equilibrium.png")))
    return written


def _save(fig, plt, path: str) -> str:
    fig.tight_layout()
    tmp = path[:-4] + ".tmp.png"
    fig.savefig(tmp, dpi=120)
    plt.close(fig)
    os.replace(tmp, path)
    return path


def write(run_dir: str, r: Result) -> list[str]:
    """Write shpb.csv and the pictures into ``run_dir`` and add them to its manifest."""
    from ..rundir import record_files

    _check_writable(run_dir)
    path = os.path.join(run_dir, "shpb.csv")
    _write_csv(path, columns(r))
    written = [path]
    try:
        written += _pictures(run_dir, r)
    except Exception as exc:  # a picture must not cost the results
        print(f"warning: shpb pictures not written: {exc}", file=sys.stderr, flush=True)
    record_files(run_dir, written)
    return written


def summary_lines(r: Result) -> list[str]:
    """What the analysis found, a few lines for the console."""
    a, p = r.analysis, r.plateau
    lines = [f"shpb: incident pulse {r.setup.pulse * 1e6:.1f} us, {len(a.t)} samples at the "
             f"faces; striker {r.setup.speed:g} m/s (rho c0 v / 2 = "
             f"{r.setup.bars.density * r.setup.bars.c0 * r.setup.speed / 2e6:.4g} MPa)"]
    if p.any():
        lines.append(f"plateau: {int(p.sum())} samples, strain rate {r.rate:.4g} 1/s, "
                     f"3-wave strain {a.strain_3[p][0]:.4g} to {a.strain_3[p][-1]:.4g}, "
                     f"3-wave stress {1e-6 * float(np.mean(a.stress_3[p])):.4g} MPa mean")
    else:
        lines.append("plateau: none (the equilibrium ratio never fell to 5 %)")
    transit = r.setup.transit
    for label, truth in (("gauges", False), ("face forces", True)):
        t_eq = r.equilibrium_time(truth)
        if t_eq is not None:
            lines.append(f"equilibrium (R <= {R_EQUILIBRIUM:g}, {label}): {t_eq * 1e6:.3g} us "
                         f"after the incident front, {t_eq / transit:.3g} transits of the "
                         f"specimen (L_s / c_s = {transit * 1e6:.3g} us)")
    return lines


def cut_warning(waves: Waves) -> str | None:
    """A warning line naming the dispersion-corrected waves whose gauge record ends
    before the wave has passed (``Waves.cut``); None when there are none."""
    if not waves.cut:
        return None
    return (f"warning: the dispersion correction moves the cut at the end of the record into "
            f"the {' and the '.join(waves.cut)} wave: the gauge's record ends before the "
            "wave has passed it; run longer, with the incident gauge as far from the struck "
            "end as from the specimen (docs/shpb.md, \"The dispersion-corrected curve\")")


def time_lines(run_dir: str) -> list[str]:
    """The step's internal-force time split between the bars and the specimen (a line)."""
    split = time_split(run_dir)
    if split is None:
        return []
    bars, specimen = split
    total = bars + specimen
    return [f"internal forces: bars (linear) {bars:.3g} s ({bars / total:.0%}), specimen "
            f"(nonlinear) {specimen:.3g} s ({specimen / total:.0%})"] if total > 0 else []


def run_command(run_dir: str, dispersion: bool = False, quiet: bool = False) -> int:
    """``impact-fenics shpb RUN_DIR``: analyse, write (rank 0), print; returns 0."""
    from mpi4py import MPI

    run_dir = os.path.expanduser(run_dir)
    r = analyse_run(run_dir, dispersion)
    if MPI.COMM_WORLD.rank == 0:
        line = cut_warning(r.waves)
        if line is not None:
            print(line, file=sys.stderr, flush=True)
        for path in write(run_dir, r):
            if not quiet:
                print(path)
        if not quiet:
            for line in summary_lines(r) + time_lines(run_dir):
                print(line)
    return 0
