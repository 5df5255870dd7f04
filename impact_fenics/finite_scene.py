"""Finite-strain scene files: the [wall] table, what a finite-strain scene may hold, its build.

A scene chooses finite strain per body, ``strain = "finite"`` in [bodies.NAME]
(default ``"small"``). Finite-strain bodies are Q1 mean-dilatation
quadrilaterals (internal_force/finite.py) and a dolfinx 0.5.2 mesh has one
cell type, so such a scene runs on its own driver (:mod:`.finite_run`, a
variable step re-estimated every ``dt_interval`` steps) and holds, for now:

* one body on ``[mesh] generator = "quad_bar"`` (radius, length in m, n_r cells
  across the radius, square cells; the bar spans 0 <= z <= length);
* its material: a model with a finite-strain form (``"j2"``: multiplicative J2,
  Hencky elasticity, linear hardening, rate-independent; ``"johnson_cook"``;
  ``"neo_hookean"``) or a class of one's own with ``strain = "finite"``
  (the kinematics is checked with the materials, :mod:`.scene_materials`);
* optionally a ``[wall]``: the rigid plane z (m, default 0, at or below the bar),
  frictionless or with ``friction`` (film and dme: contact/friction.py), with
  ``method`` = "film", "dme" or "penalty" and, for
  penalty, ``penalty`` = a stiffness in N/m or "scaled" (the default: beta = 1
  at every step); a stiffness whose beta = p dt^2 / m exceeds 4/3 is refused
  unless forced (contact/plane.py); ``face`` = "contact" (default: every boundary
  node a unilateral candidate, so the rim of the impact face may lift off) or
  "held" (u_z = 0 on the face Z = 0 from t = 0, free to slide radially: the
  condition of the converged Taylor-bar references; needs z = 0; the face's
  stop, 1/2 m_face v0^2 in J, is reported as impact_face_loss);
* ``[time]`` t_end (s) and either cfl (the step as a fraction, <= 1, of the
  current element limit) or dt (a fixed step, s); dt_interval (steps, default
  10);
* no [[contact]], [rigid], [[loads]], [[fixed]] or [[probes]] (refused, one line).

A small-strain scene may not use dt_interval; its [wall] is the same plane below every
boundary node (a fixed rigid part with its contact set, :mod:`.contact.plane`), with
``face = "contact"`` only (a held face is a [[fixed]] u_z). On ``quad_bar`` it has one
body, Q1 with mean dilatation (the Simulation of scene_file.py, :func:`quad_bar_mesh`),
in contact with rigid bodies only.
Every refusal is an InputError naming the table and the key (exit 2).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from mpi4py import MPI

from .errors import FINITE_STRAIN_NEEDS_QUADRILATERALS, InputError
from .scene_keys import DT_INTERVAL  # steps between re-estimates, unless [time] dt_interval
from .scene_table import Table, within


@dataclass
class WallSpec:
    z: float                      # m, the plane z = const (normal +z)
    method: str                   # film, dme or penalty
    penalty: float | str = "scaled"  # N/m, or "scaled" (beta = 1 each step)
    face: str = "contact"         # the impact face: unilateral contact, or held (u_z = 0)
    friction: Any = None          # contact.friction.FrictionLaw (small strain), None: none
    tangential_penalty: float | str = "scaled"  # N/m, penalty with friction
    given: tuple[str, ...] = ()


def read_wall(data: Any) -> WallSpec:
    """The [wall] table."""
    t = Table(data, "[wall]", "wall")
    wall = WallSpec(t.value("z"), t.value("method"), given=tuple(t.data), face=t.value("face"))
    if wall.face == "held" and wall.z != 0.0:
        raise t.error("face", f"it keeps the bar's face Z = 0 on the wall and needs z = 0 "
                      f"(got z = {wall.z!r} m)")
    wall.penalty = t.value("penalty")
    if "friction" in t.data:
        from .contact.friction import friction_law

        law = friction_law(t.data["friction"], "[wall] friction")
        wall.friction = None if law.is_zero else law
    wall.tangential_penalty = t.value("tangential_penalty")
    return wall


def check_kind(scene) -> None:
    """What a finite-strain scene may hold, and what a small-strain one may not (one line)."""
    kinds = {b.strain for b in scene.bodies}
    if not scene.finite:
        if scene.wall is not None and scene.wall.face == "held":
            raise InputError('[wall] face = "held": a finite-strain body\'s condition; hold a '
                             "small-strain body's face with [[fixed]] (components = [\"z\"])")
        if scene.mesh.generator == "quad_bar":
            if len(scene.bodies) > 1:
                raise InputError('[mesh] generator = "quad_bar" makes one body; the scene has '
                                 f"{len(scene.bodies)} ([bodies])")
            for c in scene.contacts:
                if c.rigid is None:
                    raise InputError(f'{c.where} a contact between deformable faces needs two '
                                     'bodies: [mesh] generator = "quad_bar" makes one (a rigid '
                                     "body's [[contact]] runs on it)")
        if scene.time["dt_interval"] is not None:
            raise InputError("[time] dt_interval: only a finite-strain scene re-estimates its step")
        return
    body = next(b for b in scene.bodies if b.strain == "finite")
    where = f'[bodies.{body.name}] strain = "finite":'
    if len(scene.bodies) > 1 or len(kinds) > 1:
        raise InputError(f"{where} a finite-strain scene has one body for now (the mesh is "
                         "quadrilateral and no body-to-body contact runs on it)")
    if scene.mesh.generator != "quad_bar":
        given = (f'generator = "{scene.mesh.generator}"' if scene.mesh.generator
                 else f'file = "{scene.mesh.file}"')
        file_note = "" if scene.mesh.generator else " (a mesh file is not read for one yet)"
        raise InputError(f'[mesh] {given}: a finite-strain body needs generator = "quad_bar"'
                         f"{file_note}: {FINITE_STRAIN_NEEDS_QUADRILATERALS}")
    if scene.wall is not None and scene.wall.friction is not None \
            and scene.wall.method == "penalty":
        raise InputError(f"[wall] friction = {scene.wall.friction.text()}: the penalty's "
                         "tangential spring is not built for a finite-strain body (use method "
                         "= \"film\" or \"dme\")")
    for key, what in (("contacts", "[[contact]]"), ("rigid", "[rigid.NAME]"),
                      ("loads", "[[loads]]"), ("probes", "[[probes]]")):
        if getattr(scene, key):
            raise InputError(f"{what}: not available with finite strain yet ({where} runs "
                             "against a [wall] only)")
    t = scene.time
    if t["n_steps"] is not None:
        raise InputError("[time] n_steps: the finite-strain step varies with the deformation; "
                         "give t_end (s)")
    if t["cfl"] is not None and t["cfl"] > 1.0:
        raise InputError(f"[time] cfl = {t['cfl']!r}: must be <= 1 (the fraction of the current "
                         "element limit min(A / max diagonal) / c)")
    for key in ("force_dt", "converged_dt"):
        if t[key]:
            raise InputError(f"[time] {key}: not available with finite strain (a fixed dt above "
                             "the current limit stops the run; the limit is re-estimated)")
    if scene.wall is not None and scene.wall.method != "penalty" and "penalty" in scene.wall.given:
        from .plausibility import warn

        warn(f'[wall] penalty = {scene.wall.penalty!r} is ignored by method = '
             f'"{scene.wall.method}" (only penalty reads it)')


def quad_bar_cells_along(p: dict) -> int:
    """n_z of the quad_bar mesh of [mesh] parameters ``p``: square cells, round(n_r length /
    radius) along the bar."""
    return max(1, round(p["n_r"] * p["length"] / p["radius"]))


def quad_bar_mesh(scene, comm: MPI.Comm):
    """The TaggedMesh of a small-strain scene on ``quad_bar``: every cell in its one body's
    group, the facet groups axis (r = 0), outer, bottom (z = 0) and top."""
    from .finite_run import quad_bar
    from .quad_meshes import tag_rectangle

    p = scene.mesh.params
    mesh = quad_bar(comm, p["radius"], p["length"], p["n_r"], quad_bar_cells_along(p))
    return tag_rectangle(mesh, scene.bodies[0].name)


def build(scene, overrides: dict[str, Any] | None = None, comm: MPI.Comm = MPI.COMM_WORLD):
    """The :class:`~impact_fenics.finite_run.FiniteRun` of a checked finite-strain scene;
    ``overrides`` sets fields of its FiniteSettings (out, quiet, ...)."""
    from . import plausibility
    from .finite_run import FiniteRun, FiniteSettings, quad_bar

    plausibility.warn_implausible(scene, comm)
    body = scene.bodies[0]
    spec = scene.materials[body.material]
    material = spec.material(body.strain)  # built and checked by read_scene
    p = scene.mesh.params
    n_z = quad_bar_cells_along(p)
    with within("[mesh]"):
        mesh = quad_bar(comm, p["radius"], p["length"], p["n_r"], n_z)
    t, o = scene.time, scene.output
    settings = FiniteSettings(t_end=t["t_end"], dt=t["dt"],
                              safety=t["cfl"] if t["cfl"] is not None else 0.5,
                              dt_interval=t["dt_interval"] or DT_INTERVAL,
                              history_every=o["history_every"], output_every=o["output_every"],
                              out=o["dir"], fields=o["fields"], plots=o["plots"],
                              force=scene.force)
    settings.summary_extra = {"scene_file": scene.path, "title": scene.title,
                              "mesh": f"{p['n_r']} x {n_z} quadrilaterals", "body": body.name,
                              "material": spec.model}
    for key, value in (overrides or {}).items():
        setattr(settings, key, value)
    wall = scene.wall
    held = None
    if wall is not None and wall.face == "held":
        held = face_nodes(mesh, 0.0, 1e-9 * p["length"])
    with within("[wall]" if wall is not None else "[bodies]"):
        run = FiniteRun(mesh, material, settings, velocity=body.velocity,
                        wall=wall.method if wall else None, z_wall=wall.z if wall else 0.0,
                        penalty=wall.penalty if wall else "scaled", name=body.name,
                        fixed_z=held, friction=wall.friction if wall else None)
    if wall is not None:
        # a held face stops at t = 0 (FiniteRun zeroes its u_z velocity): that loss is
        # outside the run's ledger, which starts from the rest of the bar
        m_face = float(np.sum(run.mass[2 * held + 1])) if held is not None else 0.0
        settings.summary_extra["wall_face"] = wall.face
        settings.summary_extra["impact_face_loss"] = comm.allreduce(
            0.5 * m_face * float(body.velocity[1]) ** 2)
    size = plausibility.model_size(mesh, comm)
    dt = settings.dt if settings.dt is not None else settings.safety * run.dt_limit()
    if settings.dt is not None and settings.dt > run.dt_limit():
        raise InputError(plausibility.explained_refusal(
            f"[time] dt = {settings.dt!r} s is above the stable limit {run.dt_limit():.4g} s "
            "of the undeformed cells; use cfl or a smaller dt", scene, size))
    n_steps = math.ceil(settings.t_end / dt)
    plausibility.report(plausibility.findings(scene, dt=dt, n_steps=n_steps,
                                              **plausibility.mesh_sizes(scene, size)),
                        scene.warned, comm)
    return run


def face_nodes(mesh, z_face: float, tol: float) -> np.ndarray:
    """Owned nodes of the face Z = z_face (m) of a quad_bar mesh, numbered as FiniteRun
    numbers them (the dofs of a P1 vector space on ``mesh``)."""
    from . import compat

    V = compat.vector_space(mesh, "Lagrange", 1)
    xy = V.tabulate_dof_coordinates()[: V.dofmap.index_map.size_local, :2]
    return np.flatnonzero(np.abs(xy[:, 1] - z_face) <= tol)
