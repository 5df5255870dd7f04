"""Scene files: a run described in TOML, checked in full before anything is built or written.

Units are SI: lengths in m, times in s, masses in kg, densities in kg/m^3,
moduli, pressures and stresses in Pa, forces in N, velocities in m/s. The keys,
their kinds, units and defaults are the table of :mod:`impact_fenics.scene_keys`
(the reference docs/scenes.md is written from it); this module reads by it.

:func:`read_scene` parses the file and checks every value (types, signs,
ranges, unknown and missing keys, names that refer to other tables) without
building anything. :func:`build` then makes the mesh and the
:class:`~impact_fenics.simulation.Simulation` through the library's API,
prefixing any error the mesh or the API finds (a missing group, surfaces that
do not pair, dt above the stable limit) with the table it comes from. Every
rank reads the same file and raises the same :class:`InputError`, so the
checks are collective.
"""
from __future__ import annotations

import math
import os
import tomllib
from dataclasses import dataclass, field
from typing import Any

from mpi4py import MPI

from . import plausibility, resources, rundir
from .errors import InputError
from .geometry import AXISYMMETRIC_GEOMETRY, Geometry
from .scene_keys import (DT_INTERVAL, ENERGY_EVERY, GENERATORS, METHODS, PLANE_QUANTITIES, PULSES,
                         QUAD_GENERATORS, QUANTITIES, REQUIRED, REQUIRED_PARAMS)
from .scene_materials import MaterialSpec, check_kinematics, read_material
from .scene_table import MISSING, Table, array_of, is_number, tables_of, toml_text, within
from .scene_wall import check_file_kind, check_kind, read_wall

COMPONENTS = {"r": 0, "z": 1}
PLANE_COMPONENTS = {"x": 0, "y": 1}
# ----------------------------------------------------------------------------- the scene

@dataclass
class MeshSpec:
    generator: str | None
    params: dict[str, Any]
    file: str | None


@dataclass
class BodySpec:
    name: str
    material: str
    velocity: tuple[float, float]  # (v_r, v_z), m/s
    strain: str = "small"  # "small" or "finite" (total Lagrangian, internal_force/finite.py)


@dataclass
class RigidSpec:
    name: str
    mass: float      # kg
    velocity: float  # m/s along z
    impedance: float = 0.0  # kg/s, of a rod driving the body (percussive drilling)
    velocity_x: float = 0.0  # m/s sideways (plane strain)
    prescribed: float | list | None = None  # m/s, or [(t, v)] (s, m/s): a prescribed z velocity


@dataclass
class ContactSpec:
    where: str
    method: str
    lower: str | None = None     # facet group below (node pairs)
    upper: str | None = None     # facet group above (node pairs)
    surface: str | None = None   # facet group under a rigid body
    rigid: str | None = None     # the rigid body's name
    radius: float | None = None  # m, rigid face radius
    button: float | None = None  # m, spherical button radius (else a flat face)
    penalty: float | str = "scaled"
    restitution: float = 0.0
    positions: str = "mass_weighted"
    film_solver: str = "fast"
    slave: str | None = None     # facet group of the slave nodes (node to segment)
    master: str | None = None    # facet group of the master segments (node to segment)
    reach: float | None = None   # m, node to segment: farthest master segment of a slave
    repair_every: int = 0        # node to segment: steps between re-pairings (0: never)
    friction: Any = None         # contact.friction.FrictionLaw, None: frictionless
    tangential_penalty: float | str = "scaled"  # N/m, penalty with friction
    given: tuple[str, ...] = ()  # the keys the file gave


@dataclass
class LoadSpec:
    where: str
    pulse: str                # "trapezoid" or "constant"
    params: dict[str, float]  # peak, t_rise, t_fall, t_end (s), or value and t_end (s, or None)
    facet: str | None = None
    rigid: str | None = None
    traction: tuple[float, float] | None = None
    area: float | None = None  # m^2
    incident: bool = False     # the pulse (N) is the incident wave in the body's rod


@dataclass
class FixedSpec:
    where: str
    facet: str
    components: list[str]


@dataclass
class ProbeSpec:
    where: str
    name: str
    point: tuple[float | None, float]  # (r, z) in m; r None: a gauge on the outer surface
    quantity: str
    length: float = 0.002  # a strain gauge's length (m)


@dataclass
class Scene:
    """A scene file, read and checked; no mesh built yet."""

    path: str
    title: str
    mesh: MeshSpec
    materials: dict[str, MaterialSpec]
    bodies: list[BodySpec]
    rigid: dict[str, RigidSpec]
    contacts: list[ContactSpec]
    loads: list[LoadSpec]
    fixed: list[FixedSpec]
    time: dict[str, Any]
    output: dict[str, Any]
    probes: list[ProbeSpec] = field(default_factory=list)
    force: bool = False  # run what the checks refuse (dt, penalty bound, memory, disk)
    wall: Any = None     # scene_wall.WallSpec of a [wall] table, or None
    warned: set[str] = field(default_factory=set)  # the plausibility findings said so far
    geometry: Geometry = AXISYMMETRIC_GEOMETRY  # the section: axisymmetric or plane strain
    ties: list[ContactSpec] = field(default_factory=list)  # [[tie]]: method "tie"

    @property
    def finite(self) -> bool:
        """A finite-strain scene ([bodies.NAME] strain = "finite"): its step follows the cells."""
        return any(b.strain == "finite" for b in self.bodies)

    @property
    def stem(self) -> str:
        return os.path.splitext(os.path.basename(self.path))[0]

    def set_method(self, method: str) -> None:
        """Use ``method`` for every contact (the command line's --method)."""
        if method not in METHODS:
            raise InputError(f"--method {method}: use one of {', '.join(METHODS)}")
        if self.wall is not None:
            self.wall.method = method
            return
        if not self.contacts:
            raise InputError(f"--method {method}: the scene has no [[contact]]")
        for c in self.contacts:
            c.method = method


def read_scene(path: str) -> Scene:
    """Parse and check a scene file; raises InputError naming the table and the key."""
    if os.path.isdir(path):
        raise InputError(f"scene file '{path}' is a directory: give the .toml file "
                         "(a run directory is rendered by impact-fenics plot)")
    if not os.path.isfile(path):
        raise InputError(f"scene file '{path}' does not exist")
    try:
        with open(path, "rb") as f:
            data = tomllib.load(f)
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"{path}: not valid TOML: {exc}")
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"scene file '{path}' cannot be read: {exc}")
    top = Table(data, f"[{os.path.basename(path)}, top level]", "top")
    title = top.value("title", os.path.basename(path))
    geometry = _read_geometry(top)
    for key in ("mesh", "time"):
        if key not in top:
            raise InputError(f"[{key}] is missing: the scene needs a [{key}] table")
    base = os.path.dirname(os.path.abspath(path))
    mesh = _read_mesh(top.data["mesh"], base)
    materials = {name: read_material(name, d, base) for name, d in
                 tables_of(top, "materials", "E (Pa), nu, density (kg/m^3)")}
    bodies = [_read_body(name, d, materials) for name, d in
              tables_of(top, "bodies", "a cell group of the mesh and its material")]
    if not bodies:
        raise InputError("[bodies] the scene has no deformable body: add a table [bodies.NAME] "
                         "for each cell group NAME of the mesh")
    check_kinematics(materials, bodies)
    rigid = {name: _read_rigid(name, d) for name, d in
             tables_of(top, "rigid", "a rigid body: mass (kg)")}
    for name in rigid:
        if any(b.name == name for b in bodies):
            raise InputError(f"[rigid.{name}] the name '{name}' is also a deformable body")
    contacts = [_read_contact(where, d, rigid) for where, d in array_of(top, "contact")]
    ties = [_read_tie(where, d, rigid) for where, d in array_of(top, "tie")]
    _check_contact_surfaces(contacts + ties)
    for name in rigid:
        users = [c.where for c in contacts + ties if c.rigid == name]
        if len(users) != 1:
            raise InputError(f"[rigid.{name}] a rigid body must be in exactly one [[contact]] "
                             f"or [[tie]] (it is in {len(users)}"
                             + (f": {', '.join(users)})" if users else ")"))
    loads = [_read_load(where, d, rigid) for where, d in array_of(top, "loads")]
    fixed = [_read_fixed(where, d, geometry) for where, d in array_of(top, "fixed")]
    time = _read_time(top.data["time"])
    output = _read_output(top.data.get("output", {}))
    probes = [_read_probe(where, d, k, geometry)
              for k, (where, d) in enumerate(array_of(top, "probes"))]
    names = [p.name for p in probes]
    for p in probes:
        if names.count(p.name) > 1 or p.name in ("step", "time", "dt"):
            raise InputError(f"{p.where} name = {toml_text(p.name)}: probe names must be unique "
                             "and not 'step', 'time' or 'dt'")
        if p.quantity in ("eps_p_eq", "yielded") and not any(
                materials[b.material].plastic for b in bodies):
            raise InputError(f"{p.where} quantity = {toml_text(p.quantity)}: needs a body of a "
                             'plastic material ([materials.NAME] model = "j2", ...)')
    force = top.value("force")
    scene = Scene(os.path.abspath(path), title, mesh, materials, bodies, rigid, contacts, loads,
                  fixed, time, output, probes, force)
    scene.ties = ties
    if "wall" in top:
        scene.wall = read_wall(top.data["wall"])
    scene.geometry = geometry
    if geometry.plane:
        _check_plane_strain(scene)
    else:
        for spec in rigid.values():
            if spec.velocity_x != 0.0:
                raise InputError(f"[rigid.{spec.name}] velocity_x: an axisymmetric rigid body "
                                 "moves along z only (the axis); a sideways velocity needs "
                                 'geometry = "plane_strain"')
        for c in contacts + ties:
            if "half_width" in c.given:
                raise InputError(f"{c.where} half_width: an axisymmetric rigid face has a "
                                 "radius (m) instead")
        for spec in materials.values():
            if spec.params.get("match") == "plane_strain":
                raise InputError(f'{spec.where} match = "plane_strain": the plane-strain match '
                                 'to Mohr-Coulomb needs geometry = "plane_strain" (this scene '
                                 "is axisymmetric)")
    check_kind(scene)
    return scene


def _read_geometry(top: Table) -> Geometry:
    """The scene's geometry, thickness and symmetry plane (top level)."""
    kind = top.value("geometry")
    if kind != "plane_strain":
        for key in ("thickness", "symmetry"):
            if key in top:
                raise top.error(key, 'only a plane-strain scene (geometry = "plane_strain") '
                                "has it")
        return AXISYMMETRIC_GEOMETRY
    return Geometry(kind, top.value("thickness", 1.0), top.value("symmetry"))


def _check_plane_strain(scene: Scene) -> None:
    """Refuse, in one line, a rigid face's radius (in plane strain its half_width). Node
    pairs (paired by x), node to segment, rigid faces (moving along y) and the wall run as
    in axisymmetry, friction too (along x, the in-plane tangent): the masses carry the
    measure. A finite-strain body runs as in axisymmetry (scene_wall.check_kind says on
    what): on ``quad_bar`` the rectangle x in [0, radius], y in [0, length] (with
    ``symmetry = "x=0"`` the half of a strip 2 radius wide), its kernel compiled for plane
    strain (docs/plane_strain.md)."""
    for c in scene.contacts + scene.ties:
        if c.rigid is not None and "radius" in c.given:
            raise InputError(f"{c.where} radius: a plane-strain rigid face has a half_width "
                             "(m; |x| <= half_width) instead")


def _check_contact_surfaces(contacts: list[ContactSpec]) -> None:
    """A facet group in two [[contact]] tables would be corrected twice a step: refused."""
    seen: dict[str, str] = {}
    for c in contacts:
        for name in (c.lower, c.upper, c.surface):
            if name is None:
                continue
            if name in seen:
                raise InputError(f"{c.where} the surface '{name}' is already in {seen[name]}: "
                                 "each facet group may be in one [[contact]] only")
            seen[name] = c.where


def _read_mesh(data: Any, base: str) -> MeshSpec:
    where = "[mesh]"
    if not isinstance(data, dict):
        raise InputError(f"{where} must be a table, not {toml_text(data)}")
    if "generator" in data and "file" in data:
        raise InputError(f"{where} give either generator or file, not both")
    if "file" in data:
        t = Table(data, where, "mesh", ("file",))
        name = t.value("file", MISSING)
        full = name if os.path.isabs(name) else os.path.join(base, name)
        if not os.path.isfile(full):
            raise t.error("file", f"no such mesh file ({full})")
        return MeshSpec(None, {}, full)
    if "generator" not in data:
        raise InputError(f"{where} generator is missing: give generator = one of "
                         f"{', '.join(GENERATORS)}, or file = \"my_mesh.msh\"")
    generator = data["generator"]
    if not isinstance(generator, str) or generator not in GENERATORS:
        raise InputError(f"{where} generator = {toml_text(generator)}: unknown generator; use one of "
                         f"{', '.join(GENERATORS)}, or file = \"my_mesh.msh\"")
    t = Table(data, where, "mesh", (generator,))
    params: dict[str, Any] = {}
    for spec in t.section.keys:
        if generator not in spec.groups:
            continue
        if spec.kind == "breaks":
            if spec.name in t:
                params[spec.name] = _breaks(t, spec.name, spec.described)
        elif spec.name in t:
            params[spec.name] = t.value(spec.name)
        elif spec.name in REQUIRED_PARAMS.get(generator, ()):
            params[spec.name] = t.value(spec.name, MISSING)
    if generator == "wedge_on_block" and params.get("wedge_angle", 0.0) >= 180.0:
        raise t.error("wedge_angle", "must be below 180 deg (the wedge's included angle)")
    if generator in ("cylinder_on_block", "striker_on_plate"):  # before any estimate
        from .meshing import check_generator

        check_generator(generator, params)
    return MeshSpec(generator, params, None)


def _breaks(t: Table, key: str, what: str) -> tuple[tuple[float, int], ...]:
    v = t.data[key]
    ok = isinstance(v, list) and len(v) > 0 and all(
        isinstance(b, list) and len(b) == 2 and is_number(b[0]) and b[0] > 0
        and isinstance(b[1], int) and not isinstance(b[1], bool) and b[1] >= 1 for b in v)
    if not ok or any(v[k + 1][0] <= v[k][0] for k in range(len(v) - 1)):
        raise t.error(key, f"must be increasing radii with interval counts ({what})")
    return tuple((float(r), int(n)) for r, n in v)


def _read_body(name: str, data: dict, materials: dict[str, MaterialSpec]) -> BodySpec:
    t = Table(data, f"[bodies.{name}]", "bodies")
    material = t.value("material")
    if material not in materials:
        raise t.error("material", f"no table [materials.{material}] "
                                  f"(materials: {', '.join(materials) or 'none'})")
    return BodySpec(name, material, t.value("velocity"), t.value("strain"))


def _read_rigid(name: str, data: dict) -> RigidSpec:
    t = Table(data, f"[rigid.{name}]", "rigid")
    spec = RigidSpec(name, t.value("mass"), t.value("velocity"))
    if "impedance" in t:
        spec.impedance = t.value("impedance")
    if "velocity_x" in t:
        spec.velocity_x = t.value("velocity_x")
    if "prescribed_velocity" not in t:
        if spec.mass is None:
            raise InputError(f"[rigid.{name}] mass is missing: mass (kg), or a "
                             "prescribed_velocity (m/s)")
        return spec
    given = [k for k in ("mass", "velocity", "velocity_x", "impedance") if k in t]
    if given:
        raise InputError(f"[rigid.{name}] {given[0]} with prescribed_velocity: a prescribed "
                         "body's motion is given (no mass, initial or sideways velocity, rod)")
    v = t.data["prescribed_velocity"]
    if is_number(v):
        spec.prescribed = float(v)
    elif (isinstance(v, list) and v and all(isinstance(p, list) and len(p) == 2
                                            and all(is_number(x) for x in p) for p in v)):
        spec.prescribed = [(float(p[0]), float(p[1])) for p in v]
    else:
        raise t.error("prescribed_velocity", "give a velocity (m/s) or a table "
                      "[[t, v], ...] of times (s) and velocities (m/s)")
    return spec


def _read_contact(where: str, data: dict, rigid: dict[str, RigidSpec]) -> ContactSpec:
    is_rigid = isinstance(data, dict) and "rigid" in data
    is_segment = isinstance(data, dict) and not is_rigid and ("slave" in data or "master" in data)
    t = Table(data, where, "contact",
               ("rigid",) if is_rigid else ("segment",) if is_segment else ("pairs",))
    c = ContactSpec(where, t.value("method"), given=tuple(t.data))
    if is_rigid:
        size = _rigid_face(t, c, rigid, "rigid face")
        c.button = t.value("button")
        if c.button is not None and c.button < c.radius:
            raise t.error("button", f"must be >= the face {size} {toml_text(t.data[size])} m")
    elif is_segment:
        c.slave = t.value("slave")
        c.master = t.value("master")
        if c.slave == c.master:
            raise t.error("master", "the two contact surfaces must differ")
        c.reach = t.value("reach")
        c.repair_every = t.value("repair_every")
    else:
        c.lower = t.value("lower")
        c.upper = t.value("upper")
        if c.lower == c.upper:
            raise t.error("upper", "the two contact surfaces must differ")
    c.penalty = t.value("penalty")
    c.restitution = t.value("restitution")
    if not 0.0 <= c.restitution <= 1.0:
        raise t.error("restitution", "must lie in [0, 1] (0: the pair sticks, 1: elastic)")
    c.positions = t.value("positions")
    c.film_solver = t.value("film_solver")
    c.friction = read_friction(t)
    c.tangential_penalty = t.value("tangential_penalty")
    return c


def _read_tie(where: str, data: dict, rigid: dict[str, RigidSpec]) -> ContactSpec:
    """A [[tie]]: a facet group bonded to a rigid body, its face selected as a rigid
    [[contact]]'s (``radius``, or ``half_width`` in plane strain)."""
    t = Table(data, where, "tie")
    c = ContactSpec(where, "tie", given=tuple(t.data))
    _rigid_face(t, c, rigid, "tied face")
    return c


def _rigid_face(t: Table, c: ContactSpec, rigid: dict[str, RigidSpec], what: str) -> str:
    """The keys of a face under a rigid body into ``c``: ``surface``, ``rigid`` (a
    [rigid.NAME] of ``rigid``) and its size, ``radius`` (m), or ``half_width`` (m) in plane
    strain; returns the size's key. ``what`` names the face in the error."""
    c.surface = t.value("surface")
    c.rigid = t.value("rigid")
    if c.rigid not in rigid:
        raise t.error("rigid", f"no table [rigid.{c.rigid}] "
                               f"(rigid bodies: {', '.join(rigid) or 'none'})")
    size = "half_width" if "half_width" in t.data else "radius"
    if size not in t.data:
        raise InputError(f"{c.where} radius is missing: give the {what}'s radius (m; "
                         "half_width in plane strain)")
    c.radius = t.value(size)
    return size


def read_friction(t: Table):
    """The ``friction`` key of a [[contact]] or the [wall]: its law
    (contact.friction.friction_law), None when absent or zero (frictionless)."""
    from .contact.friction import friction_law

    if "friction" not in t.data:
        return None
    law = friction_law(t.data["friction"], f"{t.where} friction")
    return None if law.is_zero else law


def _read_load(where: str, data: dict, rigid: dict[str, RigidSpec]) -> LoadSpec:
    if not isinstance(data, dict):
        raise InputError(f"{where} must be a table")
    pulse = data.get("pulse", "trapezoid")
    if not isinstance(pulse, str) or pulse not in PULSES:
        raise InputError(f"{where} pulse = {toml_text(pulse)}: use one of {', '.join(PULSES)}")
    on_rigid = "rigid" in data
    t = Table(data, where, "loads", ("rigid" if on_rigid else "facet", pulse))
    load = LoadSpec(where, t.value("pulse"), {})
    for key in PULSES[pulse]:
        load.params[key] = t.value(key)
    if pulse == "trapezoid":
        t_rise, t_fall, t_end = (load.params[k] for k in ("t_rise", "t_fall", "t_end"))
        if t_rise < 0:
            raise t.error("t_rise", "must be >= 0 (s)")
        if t_fall < t_rise:
            raise t.error("t_fall", f"must be >= t_rise = {toml_text(t.data['t_rise'])} (s)")
        if not t_end > 0 or t_end < t_fall:
            raise t.error("t_end", f"must be > 0 and >= t_fall = {toml_text(t.data['t_fall'])} (s)")
    if on_rigid:
        load.rigid = t.value("rigid")
        if load.rigid not in rigid:
            raise t.error("rigid", f"no table [rigid.{load.rigid}] "
                                   f"(rigid bodies: {', '.join(rigid) or 'none'})")
        load.area = t.value("area")
        load.incident = t.value("incident")
        if load.incident and load.area is not None:
            raise t.error("area", "an incident wave is a force in N: give no area")
        if rigid[load.rigid].prescribed is not None:
            raise t.error("rigid", f"[rigid.{load.rigid}] has a prescribed_velocity: its "
                                   "motion is given, a force on it does nothing")
        if load.incident and not rigid[load.rigid].impedance > 0:
            raise t.error("incident", f"[rigid.{load.rigid}] needs impedance (kg/s) > 0")
    else:
        load.facet = t.value("facet")
        load.traction = t.value("traction")
        if load.traction == (0.0, 0.0):
            raise t.error("traction", "must not be zero")
    return load


def _read_fixed(where: str, data: dict, geometry: Geometry) -> FixedSpec:
    t = Table(data, where, "fixed")
    facet = t.value("facet")
    comps = t._get("components", t.section.key("components").described, MISSING)
    first, second = geometry.axes
    if (not isinstance(comps, list) or not comps or len(set(map(str, comps))) != len(comps)
            or not all(isinstance(c, str) and c in (first, second) for c in comps)):
        raise t.error("components", f"must be a list of distinct components \"{first}\" and "
                      f"\"{second}\"" + (" (plane strain)" if geometry.plane else ""))
    return FixedSpec(where, facet, list(comps))


def _read_time(data: Any) -> dict[str, Any]:
    t = Table(data, "[time]", "time")
    if ("dt" in t) == ("cfl" in t):
        raise InputError("[time] give exactly one of dt (the time step in s) or cfl "
                         "(a fraction of the stable limit)")
    if ("t_end" in t) == ("n_steps" in t):
        raise InputError("[time] give exactly one of t_end (the end time in s) or n_steps")
    return {key: t.value(key) for key in t.section.allowed()}


def _read_output(data: Any) -> dict[str, Any]:
    t = Table(data, "[output]", "output")
    return {key: t.value(key) for key in t.section.allowed()}


def _read_probe(where: str, data: dict, k: int, geometry: Geometry) -> ProbeSpec:
    t = Table(data, where, "probes")
    quantity = t.value("quantity")
    names = PLANE_QUANTITIES if geometry.plane else QUANTITIES
    if quantity not in names:
        raise t.error("quantity", f"use one of {', '.join(names)}"
                      + (" (plane strain)" if geometry.plane else ""))
    if quantity == "section" and "point" in t:
        raise t.error("point", 'a quantity = "section" is the plane z = const: give z, not point')
    if "z" in t:  # a surface gauge: r is the mesh's outer radius at z (build); a section
        if quantity not in ("strain_gauge", "section"):
            raise t.error("z", f'only a quantity = "strain_gauge" or "section" is placed by z '
                          f"alone, not {toml_text(quantity)}: give point = [r, z]")
        if "point" in t:
            raise t.error("z", "give point or z, not both")
        point = (None, t.value("z"))
    elif quantity == "section":
        raise t.error("quantity", 'a quantity = "section" needs z, the height of its plane (m)')
    else:
        point = t.value("point", REQUIRED)
        if point[0] < 0 and not geometry.plane:
            raise t.error("point", "r must be >= 0 (m)")
    name = t.value("name", f"{quantity}_{k}")
    length = t.value("length")
    if "length" in t and quantity != "strain_gauge":
        raise t.error("length", f'only a quantity = "strain_gauge" has a gauge length, not '
                      f"{toml_text(quantity)}")
    return ProbeSpec(where, name, point, quantity, length)


# ----------------------------------------------------------------------------- output directory

def check_output_dir(path: str, where: str, comm: MPI.Comm = MPI.COMM_WORLD) -> None:
    """Fail early, on every rank, if the run may not write to ``path`` (the rules of
    :mod:`impact_fenics.rundir`: not a directory of the user's, not locked by another
    run, writable). Nothing is created here: the run stages its output in
    ``path.partial`` and checks again, atomically, when it takes the lock."""
    error = rundir.directory_problem(path) if comm.rank == 0 else None
    error = comm.bcast(error, root=0)
    if error:
        raise InputError(f"{where} {toml_text(path)}: the output directory cannot be used: {error}")


# ----------------------------------------------------------------------------- resources

def estimate(scene: Scene, comm: MPI.Comm = MPI.COMM_WORLD,
             cold: float = 0.0) -> resources.Estimate:
    """Cells, dofs, steps, memory, time and disk of the scene's run on ``comm``, before
    meshing (a mesh file is read for its counts); ``cold``: the share of the run's numba
    kernels that compile (jit_watch.cold_share)."""
    o = scene.output
    if scene.mesh.generator is not None:
        params = resources.generator_params(scene)
        regions = resources.generator_regions(scene.mesh.generator, params)
        nodes = sum(r.nodes for r in regions)
        radius = resources.contact_radius(scene.mesh.generator, params)
    else:
        from . import meshing

        with within("[mesh]"):
            counts = meshing.msh_size(scene.mesh.file, comm)
        check_file_kind(scene, counts["quadrilaterals"])
        kind = "quad" if counts["quadrilaterals"] else "unstructured"
        regions = [resources.Region(name, float(n), 0.0, h, kind)
                   for name, (n, h) in counts["groups"].items()]
        nodes, radius = float(counts["nodes"]), None
    cells = sum(r.cells for r in regions)
    speeds = {b.name: plausibility.wave_speed(m.E, m.nu, m.density)
              for b in scene.bodies for m in (scene.materials[b.material],)}
    fastest = max(speeds.values())
    t = scene.time
    flattening = False
    if t["n_steps"] is not None:
        n_steps = float(t["n_steps"])
    else:
        dt = t["dt"]
        if dt is None:
            dt = t["cfl"] * min(resources.DT_FACTOR[r.kind] * r.h / speeds.get(r.body, fastest)
                                for r in regions)
            # a body that strikes the wall flattens (its cells' limit falls); one at rest
            # on it, pressed by a platen (upsetting), barely does
            flattening = scene.finite and scene.wall is not None and any(
                b.velocity != (0.0, 0.0) for b in scene.bodies if b.strain == "finite")
        n_steps = math.ceil(t["t_end"] / dt - 1e-9) * (resources.FLATTENING if flattening else 1)
    plastic = any(scene.materials[b.material].plastic for b in scene.bodies)
    finite_bodies = {b.name for b in scene.bodies if b.strain == "finite"}
    finite_cells = sum(r.cells for r in regions  # (a one-body generator names no body)
                       if r.body in finite_bodies or (not r.body and finite_bodies))
    h_min = min(r.h for r in regions)
    pairs = []
    for c in scene.contacts + scene.ties:  # the nodes of the (slave, lower, tied) face
        across = c.radius if c.rigid is not None else radius
        pairs.append(across / h_min + 1 if across else math.sqrt(cells))
    # the bar against the wall alone (the Taylor bar: its steps' flattening factor holds
    # the wall's rows and the energy rows); anything else is counted as every scene
    taylor = (scene.finite and scene.mesh.generator == "quad_bar" and not scene.contacts)
    if scene.wall is not None and not taylor:  # its set: every boundary node
        pairs.append(4 * math.sqrt(cells))
    if taylor:
        columns, cell_fields = 19, 6  # (the bar's probes, dt, contact and energy columns)
        energy_columns = 0
    else:
        columns = 3 + len(scene.probes) + sum(
            6 + 2 * (c.rigid is not None)
            + (c.rigid is not None and scene.rigid[c.rigid].prescribed is not None)
            for c in scene.contacts + scene.ties)  # (a prescribed part's reaction)
        columns += 6 if scene.wall is not None else 0
        if scene.finite and scene.mesh.generator in QUAD_GENERATORS:
            columns += 3  # the bar's (the rod's) tracked nodes
        cell_fields = 5 + (2 if plastic else 0)  # the stresses (+ eps_p_eq, yielded)
        energy_columns = 13 + len(scene.bodies) + sum(r.prescribed is None  # (momentum)
                                                      for r in scene.rigid.values())
    shape = resources.RunShape(
        cells, nodes, n_steps, comm.size, finite=scene.finite, finite_cells=finite_cells,
        plastic=plastic,
        flattening=flattening, history_columns=columns, history_every=o["history_every"],
        energy_columns=energy_columns, energy_every=o["energy_every"] or ENERGY_EVERY,
        output_every=o["output_every"], fields=o["fields"], cell_fields=cell_fields,
        pairs=pairs, pairs_every=o["pairs_every"], plots=o["plots"], cold=cold)
    return resources.estimate(shape)


def kernels_cold(scene: Scene) -> float:
    """The share (0 to 1) of the kernels the scene's run loads at set-up whose numba cache
    is cold (a first run, or an edited module): see jit_watch.cold_share."""
    from . import jit_watch

    if scene.finite:
        from .internal_force import finite

        kernels = (finite.velocity_update, finite.trapezoid_work)
    else:
        from . import energy, simulation, step_block  # noqa: F401  (the run's modules)

        kernels = (energy.copy_state, energy.strain_from_prediction, energy.half_dot,
                   energy.energy_verdict, energy._output_sums, step_block.count_beyond)
    return jit_watch.cold_share(kernels)


def check_resources(scene: Scene, comm: MPI.Comm = MPI.COMM_WORLD, quiet: bool = False,
                    out_dir: str | None = None, running: bool = True) -> resources.Estimate:
    """Estimate the run before meshing; print it on rank 0 (and, when the run follows
    (``running``), "compiling kernels (first run only)" when numba's cache is cold);
    refuse a run beyond the available memory, or whose outputs pass the free space of
    ``out_dir``'s disk, unless forced."""
    cold = kernels_cold(scene)
    cold = max(comm.allgather(cold))
    est = estimate(scene, comm, cold)
    available = resources.available_memory() if comm.rank == 0 else None
    disk = resources.free_disk(out_dir) if (comm.rank == 0 and out_dir) else None
    available, disk = comm.bcast((available, disk), root=0)
    if comm.rank == 0 and not quiet:
        for line in est.lines(available, disk[1] if disk else None):
            print(line, flush=True)
        if cold and running:
            print("compiling kernels (first run only)", flush=True)
    if scene.force:
        return est
    if available and est.memory > available:
        raise InputError(f"[mesh] the run needs about {est.memory / 1e9:.3g} GB ("
                         f"{est.cells:,.0f} cells, {est.n_steps:,.0f} steps), more than the "
                         f"{available / 1e9:.3g} GB available: coarsen the mesh or shorten "
                         "the run, or force it (force = true or --force)")
    if disk and est.disk > disk[1]:
        what = (f"fields {resources.size_text(est.fields)}: {est.frames:,.0f} frames"
                if est.fields else "no fields")
        raise InputError(f"[output] the run writes about {resources.size_text(est.disk)} ({what}), "
                         f"more than the {resources.size_text(disk[1])} free in {disk[0]}: raise "
                         "output_every, set fields = false or free the disk, or force it "
                         "(force = true or --force)")
    return est


# ----------------------------------------------------------------------------- building

def build(scene: Scene, settings_overrides: dict[str, Any] | None = None,
          comm: MPI.Comm = MPI.COMM_WORLD):
    """The mesh and the :class:`~impact_fenics.simulation.Simulation` of a checked scene.

    ``settings_overrides`` sets fields of the Settings (e.g. out, quiet)."""
    from . import loads as ld, meshing
    from .bodies import Body, DeformableModel
    from .contact import pair_surfaces, rigid_face, spherical_button
    from .contact.tie import Tie, tie_face, tie_radial_dofs
    from .probes import locate_cell, outer_radius
    from .scenes import make_method
    from .simulation import Settings, Simulation

    plausibility.warn_implausible(scene, comm)
    with within("[mesh]"):
        if scene.mesh.file is not None:
            tmesh = meshing.load_msh(scene.mesh.file, comm=comm)
        elif scene.mesh.generator == "quad_bar":  # Q1: a finite-strain or small-strain bar
            tmesh = quad_bar_mesh(scene, comm)
        elif scene.mesh.generator == "rod_on_anvil":  # Q1: a rod on an anvil block
            tmesh = rod_on_anvil_mesh(scene, comm)
        else:
            generate = getattr(meshing, scene.mesh.generator)
            tmesh = generate(comm=comm, **scene.mesh.params)
    _check_groups(scene, tmesh)
    size = plausibility.model_size(tmesh.mesh, comm)
    with within("[bodies]"):
        model = DeformableModel(tmesh, [Body(b.name, scene.materials[b.material].material(b.strain))
                                        for b in scene.bodies], geometry=scene.geometry)
    fixed = []
    wall = scene.wall
    held = wall is not None and wall.face == "held"
    if held:  # the impact face Z = 0 held in z from t = 0 (its velocity zeroed there)
        fixed.append(model.facet_dofs("bottom", 1))
    components = PLANE_COMPONENTS if scene.geometry.plane else COMPONENTS
    for f in scene.fixed:
        with within(f.where):
            fixed += [model.facet_dofs(f.facet, components[c]) for c in f.components]
    for c in scene.ties:  # a bonded face does not slide: its u_r (u_x) held
        with within(c.where):
            fixed.append(tie_radial_dofs(model, c.surface, c.radius))
    surface_loads, rigid_loads = [], {name: [] for name in scene.rigid}
    incident = {name: [] for name in scene.rigid}
    for spec in scene.loads:
        pulse = (ld.Trapezoid(**spec.params) if spec.pulse == "trapezoid"
                 else _constant(spec.params["value"], spec.params["t_end"]))
        if spec.rigid is not None and spec.incident:
            incident[spec.rigid].append((1.0, pulse))
        elif spec.rigid is not None:
            rigid_loads[spec.rigid].append((-spec.area if spec.area else 1.0, pulse))
        else:
            with within(spec.where):
                surface_loads.append(ld.SurfaceLoad(model, spec.facet, pulse, spec.traction))
    t, o = scene.time, scene.output
    policy = None
    if scene.finite:  # the step follows the finite cells: re-estimated, or a fixed dt checked
        from .stepping import FollowingStep

        policy = FollowingStep(None, t["t_end"], t["dt"],
                               t["cfl"] if t["cfl"] is not None else 0.5,
                               t["dt_interval"] or DT_INTERVAL)
    settings = Settings(dt=t["dt"], cfl=t["cfl"], t_end=t["t_end"], n_steps=t["n_steps"],
                        force_dt=t["force_dt"] or scene.force, force=scene.force,
                        converged_dt=t["converged_dt"], out=o["dir"],
                        output_every=o["output_every"],
                        energy_every=o["energy_every"] or ENERGY_EVERY,
                        history_every=o["history_every"],
                        pairs_every=o["pairs_every"], fields=o["fields"], plots=o["plots"],
                        title=scene.title)
    for key, value in (settings_overrides or {}).items():
        setattr(settings, key, value)
    velocity = {b.name: b.velocity for b in scene.bodies if b.velocity != (0.0, 0.0)}
    try:
        sim = Simulation(model, settings, fixed=fixed, loads=surface_loads,
                         initial_velocity=velocity, policy=policy)
    except InputError as exc:  # (with the implausible units that may cause it)
        hint = " with force_dt = true" if "stable limit" in str(exc) else ""
        raise InputError(plausibility.explained_refusal(f"[time] {exc}{hint}", scene, size)) from None
    if policy is not None and t["dt"] is not None and t["dt"] > policy.limit:
        raise InputError(plausibility.explained_refusal(
            f"[time] dt = {t['dt']!r} s is above the stable limit {policy.limit:.4g} s "
            "of the undeformed cells; use cfl or a smaller dt", scene, size))
    for c in scene.contacts:
        _warn_ignored_keys(c, comm)
        with within(c.where):
            method = make_method(c.method, penalty=c.penalty, restitution=c.restitution,
                                 positions=c.positions, film_solver=c.film_solver)
            if c.slave is not None:
                from .contact.segments import node_to_segment

                sim.add_contact(node_to_segment(model, c.slave, c.master, reach=c.reach), method)
                if c.repair_every:
                    sim.contacts[-1].set_repairing(c.repair_every)
            elif c.rigid is None:
                sim.add_contact(pair_surfaces(model, c.lower, c.upper), method)
            else:
                body = _rigid_body(scene.rigid[c.rigid], rigid_loads, incident)
                profile = None if c.button is None else spherical_button(c.button)
                sim.add_contact(rigid_face(model, c.surface, c.radius, body.name, profile),
                                method, rigid=body)
            if c.friction is not None:
                sim.contacts[-1].set_friction(c.friction, c.tangential_penalty, scene.force)
    for c in scene.ties:
        with within(c.where):
            sim.add_contact(tie_face(model, c.surface, c.radius, c.rigid), Tie(),
                            rigid=_rigid_body(scene.rigid[c.rigid], rigid_loads, incident))
    if scene.wall is not None:  # a fixed rigid part under every boundary node
        from .contact.plane import boundary_nodes, plane_below, wall_part

        w = scene.wall
        if scene.finite and w.method != "penalty" and "penalty" in w.given:
            plausibility.warn(f'[wall] penalty = {w.penalty!r} is ignored by method = '
                              f'"{w.method}" (only penalty reads it)', comm)
        with within("[wall]"):
            cons = plane_below(comm, boundary_nodes(model.V, model.n_owned // 2), model.node_xy,
                               model.offset, w.z, model.length_scale)
            sim.add_contact(cons, make_method(w.method, penalty=w.penalty), rigid=wall_part())
            if w.friction is not None:
                sim.contacts[-1].set_friction(w.friction, w.tangential_penalty, scene.force)
    if scene.finite and scene.mesh.generator in QUAD_GENERATORS:
        _track_the_bar(sim, scene, held)
    for p in scene.probes:
        with within(p.where):
            if p.quantity == "section":  # its plane checked now (Probes builds it in run)
                from .section import section_body

                section_body(model, p.point[1])
                sim.add_probe(p.name, (0.0, p.point[1]), p.quantity)
                continue
            if p.point[0] is None:  # a gauge on the surface
                r = outer_radius(model.mesh, p.point[1])
                if not math.isfinite(r):
                    raise InputError(f"z = {p.point[1]!r}: no cell of the mesh is at that height")
                p.point = (r, p.point[1])
            # a point outside the mesh fails here, not in run(); a gauge's two ends
            ends = ([(p.point[0], p.point[1] + s * 0.5 * p.length) for s in (-1, 1)]
                    if p.quantity == "strain_gauge" else [p.point])
            held = []
            for point in ends:
                try:
                    locate_cell(model.mesh, point, model.geometry.axes)
                except InputError:
                    if len(ends) == 1:
                        raise
                    a, b = model.geometry.axes
                    raise InputError(f"the gauge's end ({a}={point[0]!r}, {b}={point[1]!r}) m lies "
                                     "outside the mesh") from None
                held.append(_one_body_at(tmesh, point, comm))
            if len(set(held)) > 1:
                raise InputError(f"the gauge's ends lie in two bodies ({' and '.join(held)}): "
                                 "put it within one")
        sim.add_probe(p.name, p.point, p.quantity, p.length)
    plausibility.report(plausibility.findings(scene, dt=sim.settings.dt, n_steps=sim.n_steps,
                                              **plausibility.mesh_sizes(scene, size)), scene.warned, comm)
    return sim


def _rigid_body(spec: RigidSpec, rigid_loads: dict, incident: dict):
    """The RigidBody of [rigid.NAME] ``spec``: prescribed, or free with its loads' force,
    its rod and its rod's incident wave (the [[loads]] on it, by body name)."""
    from .contact import RigidBody
    from .contact.prescribed import prescribed_velocity

    if spec.prescribed is not None:
        return RigidBody(spec.name, math.inf,
                         prescribed=prescribed_velocity(spec.name, spec.prescribed))
    return RigidBody(spec.name, spec.mass, _force(rigid_loads[spec.name]), v=spec.velocity,
                     impedance=spec.impedance, v_x=spec.velocity_x,
                     incident=_force(incident[spec.name]) if incident[spec.name] else None)


def quad_bar_mesh(scene: Scene, comm: MPI.Comm):
    """The TaggedMesh of a scene on ``quad_bar``: every cell in its one body's group, the
    facet groups axis (r = 0), outer, bottom (z = 0) and top."""
    from .quad_meshes import quad_bar, quad_bar_cells_along, tag_rectangle

    p = scene.mesh.params
    mesh = quad_bar(comm, p["radius"], p["length"], p["n_r"], quad_bar_cells_along(p))
    return tag_rectangle(mesh, scene.bodies[0].name)


def rod_on_anvil_mesh(scene: Scene, comm: MPI.Comm):
    """The TaggedMesh of a scene on ``rod_on_anvil`` (:func:`.quad_meshes.rod_on_anvil`:
    the rod n_r x round(n_r length / radius) square cells, the anvil 3 radius wide and
    2 radius deep unless given)."""
    from .quad_meshes import quad_bar_cells_along, rod_on_anvil

    p = scene.mesh.params
    return rod_on_anvil(comm, p["radius"], p["length"], p["n_r"], quad_bar_cells_along(p),
                        p.get("anvil_radius") or 3.0 * p["radius"],
                        p.get("anvil_depth") or 2.0 * p["radius"])


def _track_the_bar(sim, scene: Scene, held: bool) -> None:
    """A finite-strain bar's figures (:func:`.scenes.track_bar`: probes at its tracked
    nodes, its final length, face radius and energies at u^N; on ``rod_on_anvil`` the
    rod's) into
    ``sim.scene_figures``, with the scene's mesh, body and material and, with a [wall],
    its face and, for a held face, the face's stop at t = 0, 1/2 m_face v0^2 (J) as
    ``impact_face_loss`` (outside the run's ledger, which starts from the rest of the
    bar)."""
    import numpy as np

    from .scenes import track_bar

    from .quad_meshes import quad_bar_cells_along

    p, model, comm = scene.mesh.params, sim.model, sim.comm
    rod = scene.mesh.generator == "rod_on_anvil"
    figures = track_bar(sim, p["radius"], p["length"], body="rod" if rod else None)
    body = next(b for b in scene.bodies if b.name == "rod") if rod else scene.bodies[0]
    extra = {"mesh": f"{p['n_r']} x {quad_bar_cells_along(p)} quadrilaterals",
             "body": body.name, "material": scene.materials[body.material].model}
    if scene.wall is not None:
        extra["wall_face"] = scene.wall.face
        m_face = 0.0
        if held:
            xy = model.node_xy[: model.n_owned // 2]
            face = np.flatnonzero(np.abs(xy[:, 1]) <= 1e-9 * p["length"])
            m_face = float(np.sum(sim.integrator.mass[2 * face + 1]))
        extra["impact_face_loss"] = comm.allreduce(0.5 * m_face * float(body.velocity[1]) ** 2)
    sim.scene_figures = lambda s: {**figures(s), **extra}


# contact keys that only one method reads
_METHOD_KEYS = {"penalty": ("penalty",), "restitution": ("dme",), "positions": ("dme",),
                "film_solver": ("film",), "tangential_penalty": ("penalty",)}


def _warn_ignored_keys(c: ContactSpec, comm: MPI.Comm) -> None:
    """One warning line per key of a [[contact]] that its method does not read."""
    for key, methods in _METHOD_KEYS.items():
        if c.method not in methods and key in c.given:
            plausibility.warn(f"{c.where} {key} = {toml_text(getattr(c, key))} is ignored by "
                              f"method = \"{c.method}\" (only {', '.join(methods)} reads it)",
                              comm)


def _one_body_at(tmesh, point: tuple[float, float], comm: MPI.Comm) -> str:
    """The body that holds a probe point; refuse one on the interface of two bodies (its
    value would depend on which body's cell is chosen)."""
    import numpy as np

    from .compat import colliding_cells

    x = np.array([[point[0], point[1], 0.0]])
    cells = colliding_cells(tmesh.mesh, x).links(0)
    names = {name for name, tag in tmesh.cell_names.items()
             if np.isin(cells, tmesh.cell_tags.find(tag)).any()}
    names = set().union(*comm.allgather(names))
    if len(names) > 1:
        raise InputError(f"point = [{point[0]!r}, {point[1]!r}] lies on the interface of the "
                         f"bodies {' and '.join(sorted(names))}: its value depends on the body; "
                         "move it into one of them")
    return names.pop()


def _constant(value: float, t_end: float | None):
    """A constant pulse: ``value`` for 0 <= t < t_end (s), 0 from t_end on (held when
    t_end is None)."""
    from .loads import Constant

    if t_end is None:
        return Constant(value)
    return lambda t: value if t < t_end else 0.0


def _force(terms: list[tuple[float, Any]]):
    """The z force (N) on a rigid body: the sum of scale * pulse(t)."""
    if not terms:
        return lambda t: 0.0
    if len(terms) == 1:
        scale, pulse = terms[0]
        return lambda t: scale * pulse(t)
    return lambda t: sum(scale * pulse(t) for scale, pulse in terms)


def _check_groups(scene: Scene, tmesh) -> None:
    """Every name of a group the scene uses exists in the mesh, and every cell group is a body."""
    cells, facets = tmesh.cell_names, tmesh.facet_names
    have_c = ", ".join(sorted(cells)) or "none"
    have_f = ", ".join(sorted(facets)) or "none"
    for b in scene.bodies:
        if b.name not in cells:
            raise InputError(f"[bodies.{b.name}] the mesh has no cell group named '{b.name}' "
                             f"(it has: {have_c})")
    bodies = {b.name for b in scene.bodies}
    for name in cells:
        if name not in bodies:
            raise InputError(f"[bodies] the mesh cell group '{name}' is not a body: add a table "
                             f"[bodies.{name}] with its material")
    refs = [(c.where, k, getattr(c, k)) for c in scene.contacts + scene.ties
            for k in ("lower", "upper", "surface", "slave", "master") if getattr(c, k) is not None]
    refs += [(ld.where, "facet", ld.facet) for ld in scene.loads if ld.facet is not None]
    refs += [(f.where, "facet", f.facet) for f in scene.fixed]
    for where, key, name in refs:
        if name not in facets:
            raise InputError(f"{where} {key} = {toml_text(name)}: the mesh has no facet group named "
                             f"'{name}' (it has: {have_f})")
