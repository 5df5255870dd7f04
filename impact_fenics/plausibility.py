"""Warnings for input that no real impact has: one line each on stderr (rank 0).

A scene in the wrong units (a density in g/cm^3, a modulus in MPa, a mesh
drawn in millimetres) runs happily and gives nonsense; these bounds catch it.
They are wide on purpose and only warn:

* dilatational wave speed c1 = sqrt(E (1 - nu) / ((1 + nu)(1 - 2 nu) rho)) in
  [WAVE_SPEED] m/s: from soft polymers (a few hundred m/s) to beryllium and
  diamond (about 13,000 and 18,000 m/s);
* initial speeds at most MAX_SPEED m/s (meteoroid impacts reach about 7e4 m/s;
  a small-strain model has long stopped meaning anything at 1e4 m/s);
* dt in [DT] s (below 1e-12 s no continuum model holds; above 1e-3 s no wave in
  a solid is resolved);
* the largest extent of the mesh in [SIZE] m (below 1 mm: a mesh in metres
  that should have been millimetres read the other way; above 100 m: a mesh
  drawn in millimetres);
* at most MAX_STEPS steps (beyond them, round-off and run time dominate).

A run shorter than one step (t_end < dt) is refused (Settings.steps).
"""
from __future__ import annotations

import math
import sys

import numpy as np
from mpi4py import MPI

WAVE_SPEED = (100.0, 20000.0)  # m/s
MAX_SPEED = 1.0e4              # m/s
DT = (1e-12, 1e-3)             # s
SIZE = (1e-3, 100.0)           # m
MAX_STEPS = 10_000_000


def wave_speed(E: float, nu: float, density: float) -> float:
    """Dilatational wave speed c1 (m/s) of an isotropic solid (E in Pa, density in kg/m^3)."""
    return math.sqrt(E * (1.0 - nu) / ((1.0 + nu) * (1.0 - 2.0 * nu) * density))


def warn(message: str, comm: MPI.Comm = MPI.COMM_WORLD) -> None:
    """One line ``warning: message`` on stderr from rank 0."""
    if comm.rank == 0:
        print(f"warning: {message}", file=sys.stderr, flush=True)


def check_scene(scene, sim, comm: MPI.Comm = MPI.COMM_WORLD) -> None:
    """Warn about each value of a built scene outside the bounds above."""
    check_values(scene, sim.settings.dt, sim.n_steps, sim.model.mesh, comm)


def check_values(scene, dt: float, n_steps: int, mesh, comm: MPI.Comm = MPI.COMM_WORLD) -> None:
    """Warn about each value outside the bounds above: the scene's materials and speeds,
    the step ``dt`` (s), ``n_steps`` and the extent of ``mesh`` (m)."""
    for m in scene.materials.values():
        c = wave_speed(m.E, m.nu, m.density)
        if not WAVE_SPEED[0] <= c <= WAVE_SPEED[1]:
            warn(f"[materials.{m.name}] wave speed {c:.4g} m/s is outside "
                 f"[{WAVE_SPEED[0]:g}, {WAVE_SPEED[1]:g}] m/s of real solids: check E (Pa) "
                 "and density (kg/m^3)", comm)
    speeds = [(f"[bodies.{b.name}] velocity", math.hypot(*b.velocity)) for b in scene.bodies]
    speeds += [(f"[rigid.{r.name}] velocity", abs(r.velocity)) for r in scene.rigid.values()]
    for where, v in speeds:
        if v > MAX_SPEED:
            warn(f"{where}: {v:.4g} m/s is above {MAX_SPEED:g} m/s, faster than any impact "
                 "a small-strain model describes: check the units (m/s)", comm)
    if not DT[0] <= dt <= DT[1]:
        warn(f"[time] dt = {dt:.4g} s is outside [{DT[0]:g}, {DT[1]:g}] s: check the units (s)",
             comm)
    if n_steps > MAX_STEPS:
        warn(f"[time] {n_steps:,} steps, more than {MAX_STEPS:,}: round-off and run "
             "time dominate; shorten t_end or coarsen the mesh", comm)
    x = mesh.geometry.x[:, :2]
    local = np.concatenate([-x.min(axis=0), x.max(axis=0)]) if x.size else np.full(4, -np.inf)
    box = np.empty(4)
    comm.Allreduce(local, box, op=MPI.MAX)  # -r_min, -z_min, r_max, z_max
    size = float(max(box[2] + box[0], box[3] + box[1]))
    if not SIZE[0] <= size <= SIZE[1]:
        warn(f"[mesh] the model is {size:.4g} m across, outside [{SIZE[0]:g}, {SIZE[1]:g}] m: "
             "is the mesh in metres (not millimetres)?", comm)
