"""Values that no real impact has: a warning line each, and the cause a refusal names.

A scene in the wrong units (a density in g/cm^3, a modulus in MPa, a mesh
drawn in millimetres) runs happily and gives nonsense, or is refused for what
follows from the unit (a stable step 30 times too small, a step longer than
the run). These bounds catch it. They are wide on purpose and only warn, before
the estimate and the build; a refusal that follows names them as its likely
cause (scene_file.build):

* dilatational wave speed c1 = sqrt(E (1 - nu) / ((1 + nu)(1 - 2 nu) rho)) in
  [WAVE_SPEED] m/s: from soft polymers (a few hundred m/s) to beryllium and
  diamond (about 13,000 and 18,000 m/s);
* density in [DENSITY] kg/m^3 (polymer foams to osmium, 22,590 kg/m^3: below
  it, g/cm^3) and Young's modulus in [MODULUS] Pa (soft foams to diamond,
  1.2e12 Pa: below it, MPa or GPa);
* initial speeds at most MAX_SPEED m/s (meteoroid impacts reach about 7e4 m/s;
  a small-strain model has long stopped meaning anything at 1e4 m/s);
* dt in [DT] s (below 1e-12 s no continuum model holds; above 1e-3 s no wave in
  a solid is resolved);
* the largest extent of the model in [SIZE] m (below 1 mm: a mesh in metres
  that should have been millimetres read the other way; above 100 m: a mesh
  drawn in millimetres), its smallest element size in [ELEMENT] m (a mesh of
  10 mm elements drawn in millimetres has 10 m ones);
* at most MAX_STEPS steps (beyond them, round-off and run time dominate).

A run shorter than one step (t_end < dt) is refused (Settings.steps).
"""
from __future__ import annotations

import math
import sys
from dataclasses import dataclass

from mpi4py import MPI

from . import resources

WAVE_SPEED = (100.0, 20000.0)  # m/s
DENSITY = (25.0, 25000.0)      # kg/m^3
MODULUS = (1e5, 1.2e12)        # Pa
MAX_SPEED = 1.0e4              # m/s
DT = (1e-12, 1e-3)             # s
SIZE = (1e-3, 100.0)           # m
ELEMENT = (1e-6, 1.0)          # m
MAX_STEPS = 10_000_000


@dataclass(frozen=True)
class Finding:
    """One implausible value: ``key`` names it (a finding is said once), ``warning`` is its
    warning line, ``cause`` the clause a refusal it may explain appends."""

    key: str
    warning: str
    cause: str


def wave_speed(E: float, nu: float, density: float) -> float:
    """Dilatational wave speed c1 (m/s) of an isotropic solid (E in Pa, density in kg/m^3)."""
    return math.sqrt(E * (1.0 - nu) / ((1.0 + nu) * (1.0 - 2.0 * nu) * density))


def warn(message: str, comm: MPI.Comm = MPI.COMM_WORLD) -> None:
    """One line ``warning: message`` on stderr from rank 0."""
    if comm.rank == 0:
        print(f"warning: {message}", file=sys.stderr, flush=True)


def _material(m) -> Finding | None:
    """The finding of a scene material (E in Pa, density in kg/m^3), or None."""
    where = f"[materials.{m.name}]"
    units = []  # (what, value, the unit it was likely given in)
    if not DENSITY[0] <= m.density <= DENSITY[1]:
        units.append(("the density", f"{m.density:g} kg/m^3",
                      "g/cm^3?" if m.density < DENSITY[0] else "g/m^3?"))
    if not MODULUS[0] <= m.E <= MODULUS[1]:
        units.append(("Young's modulus", f"E = {m.E:g} Pa",
                      "MPa or GPa?" if m.E < MODULUS[0] else "kPa?"))
    c = wave_speed(m.E, m.nu, m.density)
    fast = not WAVE_SPEED[0] <= c <= WAVE_SPEED[1]
    if not (fast or units):
        return None
    said = "; ".join(f"{what} {value} is implausible ({unit})" for what, value, unit in units)
    if fast:
        warning = (f"{where} wave speed {c:.4g} m/s is outside [{WAVE_SPEED[0]:g}, "
                   f"{WAVE_SPEED[1]:g}] m/s of real solids: "
                   f"{said or 'check E (Pa) and density (kg/m^3)'}")
    else:
        warning = f"{where} {said}"
    cause = ("; ".join(f"{what} {value} of {where} is implausible ({unit})"
                       for what, value, unit in units) if units else
             f"the wave speed {c:.4g} m/s of {where} is implausible (E in Pa, density in kg/m^3?)")
    return Finding(where, warning, cause)


def findings(scene, dt: float | None = None, n_steps: int | None = None,
             size: float | None = None, h: float | None = None) -> list[Finding]:
    """Every implausible value of ``scene`` (scene_file.Scene) and of what is known about
    its run: the step ``dt`` (s), ``n_steps``, the largest extent ``size`` (m) of the
    model and its smallest element size ``h`` (m) (each None where not known yet)."""
    out = [f for f in (_material(m) for m in scene.materials.values()) if f is not None]
    speeds = [(f"[bodies.{b.name}] velocity", math.hypot(*b.velocity)) for b in scene.bodies]
    speeds += [(f"[rigid.{r.name}] velocity", abs(r.velocity)) for r in scene.rigid.values()]
    for where, v in speeds:
        if v > MAX_SPEED:
            out.append(Finding(where, f"{where}: {v:.4g} m/s is above {MAX_SPEED:g} m/s, faster "
                                      "than any impact a small-strain model describes: check "
                                      "the units (m/s)",
                               f"the speed {v:.4g} m/s of {where[:where.index(']') + 1]} is "
                               "implausible (mm/s?)"))
    if dt is not None and not DT[0] <= dt <= DT[1]:
        out.append(Finding("[time] dt", f"[time] dt = {dt:.4g} s is outside [{DT[0]:g}, "
                                        f"{DT[1]:g}] s: check the units (s)",
                           f"the step dt = {dt:.4g} s is implausible (s?)"))
    if n_steps is not None and n_steps > MAX_STEPS:
        out.append(Finding("[time] steps", f"[time] {n_steps:,} steps, more than {MAX_STEPS:,}: "
                                           "round-off and run time dominate; shorten t_end or "
                                           "coarsen the mesh",
                           f"{n_steps:,} steps are implausible"))
    for key, what, value, (lo, hi) in (("size", "the model is {} m across", size, SIZE),
                                       ("h", "the elements are {} m", h, ELEMENT)):
        if value is not None and not lo <= value <= hi:
            said = what.format(f"{value:.4g}")
            guess = "a mesh in millimetres?" if value > hi else "check the units: m"
            out.append(Finding(f"[mesh] {key}", f"[mesh] {said}, outside [{lo:g}, {hi:g}] m: "
                                                "is the mesh in metres (not millimetres)?",
                               f"{said} ({guess})"))
    return out


def model_size(mesh, comm: MPI.Comm = MPI.COMM_WORLD) -> float:
    """The largest extent (m) of ``mesh`` in r or z, the same on every rank (collective)."""
    import numpy as np

    x = mesh.geometry.x[:, :2]
    local = np.concatenate([-x.min(axis=0), x.max(axis=0)]) if x.size else np.full(4, -np.inf)
    box = np.empty(4)
    comm.Allreduce(local, box, op=MPI.MAX)  # -r_min, -z_min, r_max, z_max
    return float(max(box[2] + box[0], box[3] + box[1]))


def report(found: list[Finding], said: set[str], comm: MPI.Comm = MPI.COMM_WORLD) -> None:
    """Warn about each finding whose key is not in ``said`` yet, and add it there."""
    for f in found:
        if f.key not in said:
            said.add(f.key)
            warn(f.warning, comm)


def explained(message: str, found: list[Finding]) -> str:
    """A refusal's ``message`` with the causes of ``found`` appended (unchanged if none)."""
    if not found:
        return message
    return f"{message}; {'; '.join(f.cause for f in found)}"


# ----------------------------------------------------------------------------- a scene before meshing

def warn_implausible(scene, comm: MPI.Comm = MPI.COMM_WORLD) -> None:
    """Warn (rank 0, once each) about the scene's values that no real impact has, as far as
    they are known before meshing (the rules above): materials, speeds, a given dt, the
    size of a generator mesh."""
    report(findings(scene, dt=scene.time["dt"], **mesh_sizes(scene)), scene.warned, comm)


def mesh_sizes(scene, size: float | None = None) -> dict[str, float | None]:
    """The model's largest extent ``size`` and smallest element size ``h`` (m) as far as
    known before meshing (a generator's parameters; ``size`` if given)."""
    if scene.mesh.generator is None:
        return {"size": size, "h": None}
    params = resources.generator_params(scene)
    return {"size": resources.generator_size(scene.mesh.generator, params) if size is None
            else size,
            "h": min(r.h for r in resources.generator_regions(scene.mesh.generator, params))}


def explained_refusal(message: str, scene, size: float | None) -> str:
    """A refusal of the step (above the stable limit, longer than the run) with the scene's
    implausible units that may cause it (materials, the model's size (m) ``size``, its
    elements, dt)."""
    found = [f for f in findings(scene, dt=scene.time["dt"], **mesh_sizes(scene, size))
             if f.key.startswith(("[materials", "[mesh]", "[time] dt"))]
    return explained(message, found)
