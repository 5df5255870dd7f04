"""The [wall] table of a scene file, and what a finite-strain scene may hold.

A scene chooses finite strain per body, ``strain = "finite"`` in [bodies.NAME]
(default ``"small"``). Finite-strain bodies are Q1 mean-dilatation quadrilaterals
(internal_force/finite.py) and run in the one loop (:class:`~.simulation.Simulation`,
built by :func:`.scene_file.build`) under a step that follows their cells
(:class:`~.stepping.FollowingStep`: cfl x the current limit re-estimated every
``dt_interval`` steps, or a fixed dt checked against it). Its cells are quadrilaterals
(:func:`quadrilateral_generator`; on triangles it is refused in one line: constant-strain
triangles lock under isochoric flow). A finite-strain scene is a scene like any other:
its bodies, each small or finite strain, on a mesh of quadrilaterals, which is

* ``[mesh] generator = "quad_bar"`` (radius, length in m, n_r cells across the radius,
  square cells; the bar spans 0 <= z <= length): one body;
* ``generator = "rod_on_anvil"`` (:func:`.quad_meshes.rod_on_anvil`: the rod "rod" of
  quad_bar's cells on the anvil block "anvil", anvil_radius and anvil_depth in m,
  default 3 and 2 radius, squares of the rod's size; facet groups rod_contact,
  anvil_contact, anvil_bottom, ...);
* ``coaxial_bars_sized``, ``shpb`` or ``block`` with ``quadrilaterals = true``;
* ``[mesh] file = "NAME.msh"`` of quadrilaterals only (gmsh's recombined surfaces; the
  bodies its cell groups, the faces its facet groups, as on triangles): a file of
  triangles is refused in one line when the estimate counts its cells
  (:func:`check_file_kind`);

with, as on triangles, [[contact]] between bodies (node pairs, node to segment with
``repair_every``; on quad_bar, one body, a rigid face only), [rigid.NAME] bodies in
contact with a face ([[contact]] rigid, surface, radius), [[loads]] on facets and on
rigid bodies (a ``"constant"`` pulse may end at ``t_end``), [rigid.NAME] parts of
``prescribed_velocity`` (the crosshead of ``scenes/upsetting_finite.toml``), [[fixed]] faces,
[[probes]] (on quad_bar and rod_on_anvil, not named as the bar's tracked nodes'
probes: u_z_top, u_z_bottom, u_r_corner) and a ``[wall]``: the rigid plane z (m,
default 0, at or below the bodies), a fixed rigid part under every boundary node with
its contact set (:mod:`.contact.plane`), frictionless or with ``friction`` (film,
dme and the penalty's tangential spring: contact/friction.py),
with ``method`` = "film", "dme" or "penalty" and, for penalty, ``penalty`` = a
stiffness in N/m or "scaled"; ``face`` = "contact" (default: every boundary node a
unilateral candidate, so the rim of the impact face may lift off) or, on quad_bar only,
"held" (u_z = 0 on the face Z = 0 from t = 0, free to slide radially: the condition of
the converged Taylor-bar references; needs z = 0; the face's stop, 1/2 m_face v0^2 in
J, is reported as impact_face_loss). On quad_bar and rod_on_anvil the summary has the
bar's (the rod's) final length and face radius (:func:`.scenes.track_bar`).

Its materials have a finite-strain form (``"j2"``: multiplicative J2, Hencky elasticity,
linear hardening, rate-independent; ``"johnson_cook"``; ``"neo_hookean"``) or are a class
of one's own with ``strain = "finite"`` (the kinematics is checked with the materials,
:mod:`.scene_materials`). A rigid body's motion follows from its mass and forces, or is
prescribed (``prescribed_velocity``: a constant or a table, docs/friction.md 12).

``[time]`` gives t_end (s) and either cfl (<= 1) or dt (a fixed step, s);
dt_interval (steps, default 10); n_steps, force_dt and converged_dt are refused.

A small-strain scene may not use dt_interval; its [wall] is the same plane, with
``face = "contact"`` only (a held face is a [[fixed]] u_z). On ``quad_bar`` it has one
body, Q1 with mean dilatation, in contact with rigid bodies only.
Every refusal is an InputError naming the table and the key (exit 2).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from .errors import FINITE_STRAIN_NEEDS_QUADRILATERALS, InputError
from .scene_keys import QUAD_GENERATORS
from .scene_table import Table


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


# generators that make quadrilaterals with quadrilaterals = true (quad_bar and rod_on_anvil
# always do)
QUAD_OPTION = ("coaxial_bars_sized", "shpb", "block")


def quadrilateral_generator(generator: str | None, params: dict) -> bool:
    """Whether the generator mesh is of Q1 quadrilaterals (a finite-strain body's cells)."""
    return generator in QUAD_GENERATORS or (generator in QUAD_OPTION
                                            and bool(params.get("quadrilaterals")))


def _one_bar(scene) -> None:
    """A scene on quad_bar has one body, and its [[contact]] tables rigid faces only."""
    if len(scene.bodies) > 1:
        raise InputError('[mesh] generator = "quad_bar" makes one body; the scene has '
                         f"{len(scene.bodies)} ([bodies])")
    for c in scene.contacts:
        if c.rigid is None:
            raise InputError(f'{c.where} a contact between deformable faces needs two '
                             'bodies: [mesh] generator = "quad_bar" makes one (a rigid '
                             "body's [[contact]] runs on it)")


def check_file_kind(scene, quadrilaterals: bool) -> None:
    """A finite-strain scene's mesh file holds quadrilaterals only (``quadrilaterals``: the
    file's count, :func:`.meshing.msh_size`); one line otherwise."""
    if scene.finite and not quadrilaterals:  # (the reader refuses two cell types)
        raise InputError(f'[mesh] file = "{scene.mesh.file}": the file\'s cells are triangles '
                         f"(recombine its surfaces in gmsh): {FINITE_STRAIN_NEEDS_QUADRILATERALS}")


def check_kind(scene) -> None:
    """What a finite-strain scene may hold, and what a small-strain one may not (one line)."""
    bar = scene.mesh.generator == "quad_bar"
    if not scene.finite:
        if scene.wall is not None and scene.wall.face == "held":
            raise InputError('[wall] face = "held": a finite-strain body\'s condition; hold a '
                             "small-strain body's face with [[fixed]] (components = [\"z\"])")
        if bar:
            _one_bar(scene)
        if scene.time["dt_interval"] is not None:
            raise InputError("[time] dt_interval: only a finite-strain scene re-estimates its step")
        return
    # a mesh file's cells are counted with the estimate (scene_file.estimate, every rank:
    # check_file_kind); a generator's are known from its name
    if scene.mesh.generator and not quadrilateral_generator(scene.mesh.generator,
                                                            scene.mesh.params):
        raise InputError(f'[mesh] generator = "{scene.mesh.generator}": a finite-strain body '
                         'needs generator = "quad_bar" or "rod_on_anvil", or quadrilaterals = '
                         f"true ({', '.join(QUAD_OPTION)}), or a mesh file of quadrilaterals: "
                         f"{FINITE_STRAIN_NEEDS_QUADRILATERALS}")
    if bar:
        _one_bar(scene)
    if scene.wall is not None and scene.wall.face == "held" and not bar:
        raise InputError('[wall] face = "held": it holds the face Z = 0 of the bar of generator '
                         '= "quad_bar"; hold a face of another mesh with [[fixed]]')
    if scene.mesh.generator in QUAD_GENERATORS:  # the bar's (the rod's) tracked nodes' probes
        tracked = {f"{a}_{end}" for a, end in (("u_z", "top"), ("u_z", "bottom"),
                                               ("u_r", "corner"), ("u_y", "top"),
                                               ("u_y", "bottom"), ("u_x", "corner"))}
        for p in scene.probes:
            if p.name in tracked:
                raise InputError(f"{p.where} name = \"{p.name}\": the bar's tracked nodes' "
                                 "probe has it (u_z_top, u_z_bottom, u_r_corner; plane strain "
                                 "u_y_top, u_y_bottom, u_x_corner): choose another")
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
