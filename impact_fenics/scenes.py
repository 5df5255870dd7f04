"""The scenes of the paper and of the tests, built once and shared by demos, tests and studies.

Each builder returns a ready :class:`~impact_fenics.simulation.Simulation`
(contact and probes added). Units: m, s, kg, Pa.
"""
from __future__ import annotations

import math
from dataclasses import replace

from mpi4py import MPI

import numpy as np

from . import loads, meshing, statics
from .bodies import Body, DeformableModel
from .contact import DME, FILM, Penalty, RigidBody, pair_surfaces, rigid_face, spherical_button
from .errors import InputError, require
from .materials import STEEL, LinearElastic
from .simulation import Settings, Simulation



def elastic_bar(settings: Settings, h: float = 0.005, nu: float = 0.0, peak: float = 100e6,
                t_rise: float = 2e-5, t_fall: float = 1e-4, t_end: float = 1.2e-4,
                radius: float = 0.05, length: float = 1.0, structured: bool = True,
                clamp_far_end: bool = False, tmesh: meshing.TaggedMesh | None = None,
                material=None, comm: MPI.Comm = MPI.COMM_WORLD) -> Simulation:
    """A steel bar (radius, length in m) loaded on z = 0 by a trapezoid pressure pulse (Pa);
    with ``clamp_far_end`` its end z = length has u_z = 0. ``tmesh``: a bar mesh built
    already (then radius, length, h and structured are its own); ``material``: another
    material than steel with Poisson's ratio ``nu``."""
    material = replace(STEEL, nu=nu) if material is None else material
    if tmesh is None:
        tmesh = meshing.bar(radius=radius, length=length, h=h, structured=structured, comm=comm)
    model = DeformableModel(tmesh, [Body("bar", material)])
    pulse = loads.Trapezoid(peak=peak, t_rise=t_rise, t_fall=t_fall, t_end=t_end)
    fixed = [model.facet_dofs("free_end", 1)] if clamp_far_end else []
    return Simulation(model, settings, fixed=fixed,
                      loads=[loads.SurfaceLoad(model, "loaded_end", pulse)])


def make_method(method: str, penalty: float | str = "scaled", restitution: float = 0.0,
                positions: str = "mass_weighted", film_solver: str = "fast",
                auto_reading: str = "mean_of_inverse"):
    """A contact method by name: 'penalty', 'film' or 'dme'."""
    if method == "penalty":
        return Penalty(penalty, auto_reading=auto_reading)
    if method == "film":
        return FILM(film_solver)
    if method == "dme":
        return DME(restitution, positions)
    raise InputError(f"method = '{method}': use penalty, film or dme")


def bar_impact(settings: Settings, method, h: float = 0.02, nu: float = 0.3, v0: float = 5.0,
               radius: float = 0.1, striker_length: float = 0.8, target_length: float = 0.85,
               structured: bool = False, observe: tuple[float, float] | None = (0.1, 0.2),
               comm: MPI.Comm = MPI.COMM_WORLD) -> Simulation:
    """Two coaxial steel bars touching at z = 0; the striker (below) moves at v0 (m/s) in +z.

    ``observe`` is the (r, z) point of the target where sigma_zz is recorded."""
    material = replace(STEEL, nu=nu)
    tmesh = meshing.coaxial_bars(radius=radius, striker_length=striker_length,
                                 target_length=target_length, h=h, structured=structured, comm=comm)
    model = DeformableModel(tmesh, [Body("striker", material), Body("target", material)])
    sim = Simulation(model, settings, initial_velocity={"striker": (0.0, v0)})
    sim.add_contact(pair_surfaces(model, "striker_contact", "target_contact"), method)
    if observe is not None:
        sim.add_probe("sigma_zz_obs", observe, "sigma_zz")
    return sim


# The paper's punch scene: constraints per punch radius (m) on our block mesh.
PUNCH_RADII = {1: 1.0, 3: 3.0, 6: 6.0}


def punch_indentation(settings: Settings, method, radius: float = 1.0, punch_mass: float = 0.1,
                      peak: float = 200e6, t_rise: float = 1e-5, t_fall: float = 9e-5,
                      t_end: float = 1e-4, block: dict | None = None,
                      tmesh: meshing.TaggedMesh | None = None,
                      comm: MPI.Comm = MPI.COMM_WORLD) -> Simulation:
    """A rigid flat punch (one z dof, mass in kg) of radius R_z (m) pushed into a steel block
    by -sigma(t) pi R_z^2, sigma a trapezoid pulse (Pa). ``tmesh``: a punch_block mesh built
    already (else one is made from ``block``)."""
    if tmesh is None:
        tmesh = meshing.punch_block(comm=comm, **(block or {}))
    model = DeformableModel(tmesh, [Body("block", STEEL)])
    area = 3.141592653589793 * radius ** 2
    pulse = loads.Trapezoid(peak=peak, t_rise=t_rise, t_fall=t_fall, t_end=t_end)
    punch = RigidBody("punch", punch_mass, force=lambda t: -area * pulse(t))
    bottom = model.facet_dofs("bottom", 1)
    sim = Simulation(model, settings, fixed=[bottom])
    sim.add_contact(rigid_face(model, "surface", radius, "punch"), method, rigid=punch)
    return sim


# The bit-rock scene of percussive drilling (demos/bit_rock.py gives the sources). Granite-like
# rock and a steel rod of 32 mm diameter: Z = rho c0 A (kg/s).
GRANITE = LinearElastic(E=60e9, nu=0.25, density=2600.0)
ROD_IMPEDANCE = 7850.0 * math.sqrt(200e9 / 7850.0) * math.pi * 0.016 ** 2


def rock_extent(rock, t_end: float, bit_radius: float) -> float:
    """Radius and depth (m) of the rock block: a wave from the bit's edge that reaches the
    boundary comes back to the bit after 2 L / c_L, so L = bit_radius + c_L t_end / 2 keeps
    every echo away from the bit until t_end (5 % margin)."""
    return bit_radius + 1.05 * rock.wave_speed() * t_end / 2.0


def bit_rock(settings: Settings, method, rock=GRANITE, bit_radius: float = 0.01,
             button_radius: float | None = None, bit_mass: float = 0.5,
             impedance: float = ROD_IMPEDANCE,
             incident: loads.TimeFunction = loads.Trapezoid(150e3, 1e-5, 7e-5, 8e-5),
             h_surface: float | None = None, grading: float = 0.05,
             tmesh: meshing.TaggedMesh | None = None,
             comm: MPI.Comm = MPI.COMM_WORLD) -> Simulation:
    """A rigid bit (mass in kg, one z dof) on a rock block, driven by a rod of impedance Z
    (kg/s) carrying the incident compressive force wave ``incident(t)`` (N).

    The bit's face has radius ``bit_radius`` (m): flat, or a spherical button of radius
    ``button_radius`` (m) touching at r = 0. The block (punch_block mesh, bottom held in
    z) is :func:`rock_extent` wide and deep for the run's t_end; the element size is
    ``h_surface`` (default bit_radius / 10) under the face, growing by ``grading`` (m/m)
    with the distance from it. Needs ``settings.t_end``."""
    require(bit_radius > 0, f"bit radius = {bit_radius} m: must be > 0")
    if tmesh is None:
        require(settings.t_end is not None and settings.t_end > 0,
                "bit_rock: give t_end (s); it sizes the rock block")
        h = bit_radius / 10.0 if h_surface is None else h_surface
        size = rock_extent(rock, settings.t_end, bit_radius)
        n = max(1, int(round(bit_radius / h)))
        tmesh = meshing.punch_block(width=size, depth=size, h_surface=h, grading=grading,
                                    h_max=size / 8.0, breaks=((bit_radius, n),), comm=comm)
    model = DeformableModel(tmesh, [Body("block", rock)])
    bit = RigidBody("bit", bit_mass, impedance=impedance, incident=incident)
    sim = Simulation(model, settings, fixed=[model.facet_dofs("bottom", 1)])
    profile = None if button_radius is None else spherical_button(button_radius)
    sim.add_contact(rigid_face(model, "surface", bit_radius, "bit", profile), method, rigid=bit)
    return sim


def held_dofs(model: DeformableModel) -> np.ndarray:
    """Global indices of the owned dofs the bit-rock (and punch) block holds: u_r on the
    axis, u_z on the bottom."""
    return model.to_global(np.concatenate([model.axis_dofs(), model.facet_dofs("bottom", 1)]))


def static_stiffness(sim: Simulation, delta: float = 1e-4) -> float:
    """Static indentation stiffness K_h (N/m) of a rigid flat face on the scene's mesh: the
    constrained surface nodes held at u_z = -delta (m), one direct solve with K."""
    model, c = sim.model, sim.contacts[0]
    face = statics.owned(model, c.constraints.lower)
    force = statics.rigid_indentation(model, sim.integrator.K, held_dofs(model), face, delta)
    return force / delta
def bar_impact_sized(settings: Settings, method, n_striker: int = 6, n_target: int = 9,
                     nu: float = 0.0, v0: float = 5.0, radius: float = 0.05,
                     striker_length: float = 0.2, target_length: float = 0.2,
                     structured: bool = True, node_to_node: bool = False,
                     comm: MPI.Comm = MPI.COMM_WORLD) -> Simulation:
    """Two coaxial steel bars touching at z = 0 whose contact faces have ``n_striker`` and
    ``n_target`` intervals (element sizes radius/n, m); the striker (below) moves at v0
    (m/s) in +z. Node-to-segment contact with the finer face as slave (the target when
    n_target >= n_striker); ``node_to_node`` pairs matching faces instead (the reduction)."""
    from .contact.segments import node_to_segment

    material = replace(STEEL, nu=nu)
    tmesh = meshing.coaxial_bars_sized(radius=radius, striker_length=striker_length,
                                       target_length=target_length, h_striker=radius / n_striker,
                                       h_target=radius / n_target, structured=structured,
                                       comm=comm)
    model = DeformableModel(tmesh, [Body("striker", material), Body("target", material)])
    sim = Simulation(model, settings, initial_velocity={"striker": (0.0, v0)})
    if node_to_node:
        sim.add_contact(pair_surfaces(model, "striker_contact", "target_contact"), method)
    elif n_target >= n_striker:
        sim.add_contact(node_to_segment(model, "target_contact", "striker_contact"), method)
    else:
        sim.add_contact(node_to_segment(model, "striker_contact", "target_contact"), method)
    return sim


ALUMINIUM = LinearElastic(E=70e9, nu=0.33, density=2700.0)


def nosed_striker(settings: Settings, method, v0: float = 5.0, nose_radius: float = 0.02,
                  h_striker: float = 0.02 / 8, h_block: float = 0.02 / 12,
                  block_material: LinearElastic = ALUMINIUM, hold_block: bool = True,
                  comm: MPI.Comm = MPI.COMM_WORLD) -> Simulation:
    """A steel striker with a hemispherical nose (radius m) hitting an aluminium block at
    v0 (m/s, -z), node to segment: the block's top under the nose (finer) is the slave,
    the nose's segments the master, so the normals are inclined (u_r and u_z both
    enter). The block bottom is held in z (unless not ``hold_block``). Block nodes up to
    the nose radius below the nose are in reach (most stay open)."""
    from .contact.segments import node_to_segment

    tmesh = meshing.nosed_striker_on_block(nose_radius=nose_radius, h_striker=h_striker,
                                           h_block=h_block, comm=comm)
    model = DeformableModel(tmesh, [Body("striker", STEEL), Body("block", block_material)])
    fixed = [model.facet_dofs("block_bottom", 1)] if hold_block else []
    sim = Simulation(model, settings, fixed=fixed, initial_velocity={"striker": (0.0, -v0)})
    sim.add_contact(node_to_segment(model, "block_contact", "nose", reach=1.01 * nose_radius),
                    method)
    return sim


def taylor_bar(settings: Settings, material, radius: float = 3.2e-3, length: float = 32.4e-3,
               n_r: int = 4, v0: float = 227.0, method="film",
               face: str = "contact", t_end: float = 80e-6, dt: float | None = None,
               cfl: float = 0.5, dt_interval: int = 10, friction=None,
               comm: MPI.Comm = MPI.COMM_WORLD) -> Simulation:
    """The Taylor bar: a finite-strain ``material`` cylinder (radius, length in m, n_r x
    round(n_r length / radius) square Q1 cells, the body "bar") at ``v0`` (m/s) onto the
    fixed plane z = 0 under every boundary node, contact by ``method`` (a name of
    :func:`make_method` or a method; None: no wall),
    ``face`` "contact" or "held" (u_z = 0 on the face Z = 0 from t = 0), Coulomb
    ``friction`` on the plane (film, dme); the step follows the cells (cfl x the current
    limit re-estimated every dt_interval steps, or a fixed ``dt`` checked), to ``t_end``
    (s). Its summary's shape and energies at u^N: ``sim.run(extra=sim.scene_figures)``
    (:func:`track_bar`), as the scene file's run gives them."""
    from .contact.plane import boundary_nodes, plane_below, wall_part
    from .quad_meshes import quad_bar, tag_rectangle
    from .stepping import FollowingStep

    n_z = max(1, round(n_r * length / radius))
    model = DeformableModel(tag_rectangle(quad_bar(comm, radius, length, n_r, n_z), "bar"),
                            [Body("bar", material)])
    fixed = [model.facet_dofs("bottom", 1)] if face == "held" else []
    sim = Simulation(model, settings, fixed=fixed, initial_velocity={"bar": (0.0, -v0)},
                     policy=FollowingStep(None, t_end, dt, cfl, dt_interval))
    if method is not None:
        nodes = boundary_nodes(model.V, model.n_owned // 2)
        sim.add_contact(plane_below(comm, nodes, model.node_xy, model.offset, 0.0,
                                    model.length_scale),
                        make_method(method) if isinstance(method, str) else method,
                        rigid=wall_part())
        if friction is not None:
            sim.contacts[-1].set_friction(friction)
    sim.scene_figures = track_bar(sim, radius, length)
    return sim


def track_bar(sim: Simulation, radius: float, length: float, body: str | None = None):
    """A bar's shape (0 <= r <= radius, 0 <= z <= length, m): displacement probes at the
    ends of its axis and at the corner of its impact face (history.csv: u_z_top,
    u_z_bottom, u_r_corner; in plane strain, (x, y): u_y_top, u_y_bottom, u_x_corner),
    and the function of the run's end that gives
    ``final_length`` (m, z of the node that started at (0, L) less z of the one that
    started at (0, 0)), ``final_face_radius`` (m, r of the node that started at (R, 0)),
    from those nodes' displacements, and the stored energy psi(u^N) ``stored_elastic``
    and the plastic work ``plastic_work`` (J) of the finite-strain bodies' points at u^N
    (the summary's evaluation there; the last energy row's are of the step before).
    ``body``: the bar is this body of a scene whose other body touches it at z = 0 (an
    anvil): the nodes are the body's, and the probes on z = 0 read its cells at z = 1e-9 L."""
    model, comm = sim.model, sim.comm
    plane = model.geometry.plane  # plane strain: (x, y), the names u_x, u_y
    across, along = ("u_x", "u_y") if plane else ("u_r", "u_z")
    tol = 1e-9 * length  # m: far above round-off, far below a cell
    corners = ((0.0, length), (0.0, 0.0), (radius, 0.0))  # the tracked nodes (m)
    lift = 0.0 if body is None else tol  # a point on the interface is in both bodies' cells
    for (name, quantity), (r, z) in zip(((f"{along}_top", along), (f"{along}_bottom", along),
                                         (f"{across}_corner", across)), corners):
        sim.add_probe(name, (r, z if z > 0.0 else lift), quantity)
    xy = model.node_xy[: model.n_owned // 2]
    mine = (np.arange(xy.shape[0]) if body is None
            else np.unique(model.body_dofs(body, 0) // 2))
    nodes = [mine[np.hypot(xy[mine, 0] - r, xy[mine, 1] - z) <= tol] for r, z in corners]

    first, second = ("x", "y") if plane else ("r", "z")
    definition = (f"final_length: the {'length on x = 0' if plane else 'axis length'}, "
                  f"{second} of the node that started at (0, L) minus {second} of the one that "
                  f"started at (0, 0) (m); final_face_radius: {first} of the node that started "
                  "at (R, 0) (m)")

    def figures(s: Simulation) -> dict:
        u = s.integrator.u_owned
        vals = np.full(3, -np.inf)  # top z, -bottom z, corner r (one MAX reduction)
        for k, (sign, column) in enumerate(((1.0, 1), (-1.0, 1), (1.0, 0))):
            if nodes[k].size:
                i = int(nodes[k][0])
                vals[k] = sign * (xy[i, column] + u[2 * i + column])
        comm.Allreduce(MPI.IN_PLACE, vals, op=MPI.MAX)
        forces = s.integrator.finite
        shares = np.array([sum(f.stored_energy_local() for f in forces),
                           sum(f.plastic_work_local for f in forces)])
        comm.Allreduce(MPI.IN_PLACE, shares)
        return {"final_length": float(vals[0] + vals[1]), "final_face_radius": float(vals[2]),
                "stored_elastic": float(shares[0]), "plastic_work": float(shares[1]),
                "length_definition": definition}
    return figures


# ----------------------------------------------------------------------------- Taylor anvil

def taylor_anvil(settings: Settings, material, anvil=STEEL, anvil_scale: float = 1.0,
                 radius: float = 3.2e-3, length: float = 32.4e-3, n_r: int = 4,
                 v0: float = 227.0, method="film", anvil_radius: float | None = None,
                 anvil_depth: float | None = None, hold_anvil: bool = True,
                 t_end: float = 80e-6, dt: float = 2.0 ** -28, dt_interval: int = 10,
                 repair_every: int = 5, comm: MPI.Comm = MPI.COMM_WORLD) -> Simulation:
    """The Taylor rod (a finite-strain ``material``, radius and length in m, n_r x
    round(n_r length / radius) square Q1 cells, the body "rod") at ``v0`` (m/s, -z) onto an
    ``anvil`` (a linear elastic material, small strain; its E and density both times
    ``anvil_scale``, which keeps its wave speed and stable step and multiplies its
    impedance), the body "anvil": r <= anvil_radius, -anvil_depth <= z <= 0 (default 3 R
    and 2 R), square cells of the rod's size, on the same mesh as a second cell group
    (:func:`~.quad_meshes.rod_on_anvil`). The rod's face (slave) meets the anvil's top
    (master) through node-to-segment contact by ``method``, re-paired every
    ``repair_every`` steps as the foot spreads; ``hold_anvil``: the anvil's bottom held in
    u_z (free otherwise). The step is the fixed ``dt`` (s; it must divide t_end: the
    segment kind takes a constant step) under the step that follows the rod's cells
    (checked every dt_interval steps; the run stops, exit 3, once their limit falls
    below dt). Its summary's rod shape and energies: ``sim.run(extra=sim.scene_figures)``
    (:func:`track_bar`)."""
    from .contact.segments import node_to_segment
    from .quad_meshes import rod_on_anvil
    from .stepping import FollowingStep

    require(anvil_scale > 0, f"anvil scale = {anvil_scale}: must be > 0")
    n_z = max(1, round(n_r * length / radius))
    tmesh = rod_on_anvil(comm, radius, length, n_r, n_z,
                         3.0 * radius if anvil_radius is None else anvil_radius,
                         2.0 * radius if anvil_depth is None else anvil_depth)
    steel = replace(anvil, E=anvil_scale * anvil.E, density=anvil_scale * anvil.density)
    model = DeformableModel(tmesh, [Body("rod", material), Body("anvil", steel)])
    fixed = [model.facet_dofs("anvil_bottom", 1)] if hold_anvil else []
    sim = Simulation(model, settings, fixed=fixed, initial_velocity={"rod": (0.0, -v0)},
                     policy=FollowingStep(None, t_end, dt, 0.5, dt_interval))
    sim.add_contact(node_to_segment(model, "rod_contact", "anvil_contact"),
                    make_method(method) if isinstance(method, str) else method)
    if repair_every:
        sim.contacts[-1].set_repairing(repair_every)
    sim.scene_figures = track_bar(sim, radius, length, body="rod")
    return sim


def upsetting(settings: Settings, material, radius: float = 5e-3, height: float = 5e-3,
              n_r: int = 8, n_z: int = 8, friction: float = 0.0, method="dme",
              speed: float = 0.5, t_ramp: float = 50e-6, t_end: float = 1e-3,
              cfl: float = 0.5, dt_interval: int = 10,
              comm: MPI.Comm = MPI.COMM_WORLD) -> Simulation:
    """Upsetting at finite strain: a ``material`` cylinder (finite strain; radius, height in
    m, n_r x n_z Q1 cells, the body "billet") standing on the fixed plane z = 0 and
    compressed by a rigid platen on its top face, both faces with Coulomb ``friction``
    (μ, or "stick") by ``method`` (film or dme; a name of :func:`make_method` or a method).

    The platen (the rigid body "platen", starting at rest on the top face) is a testing
    machine's crosshead: a rigid part of prescribed velocity (docs/friction.md 12), v(t)
    ramped linearly from 0 to -V (V = ``speed``, m/s) over ``t_ramp`` (s) and held after,
    whatever the billet pushes back; its stroke is int_0^t v dt and its reaction is
    booked as the motion's external work. The platen's
    candidates are the top face's nodes, g_i = u_platen - u_z,i >= 0 (m; a flat face: the
    rigid kind's friction takes no profile, so a side node folding over onto the platen
    is not caught: the study measures it); the plane's are every boundary
    node, as the Taylor bar's wall. The step
    follows the cells (cfl x the current limit every dt_interval steps) to ``t_end`` (s).
    History: c0_platen_force (N), c0_platen_u (m), c0_platen_v (m/s) and
    c0_platen_reaction (N) from the platen's set (the first)."""
    from .contact.plane import boundary_nodes, plane_below, wall_part
    from .contact.prescribed import crosshead
    from .quad_meshes import quad_rectangle
    from .stepping import FollowingStep

    motion = crosshead("platen", speed, t_ramp)  # refused here, before the mesh is built
    model = DeformableModel(quad_rectangle(comm, 0.0, 0.0, radius, height, n_r, n_z, "billet"),
                            [Body("billet", material)])
    sim = Simulation(model, settings, policy=FollowingStep(None, t_end, None, cfl, dt_interval))
    top = rigid_face(model, "top", radius, "platen")
    platen = RigidBody("platen", math.inf, prescribed=motion)
    chosen = (lambda: make_method(method) if isinstance(method, str) else method)
    sim.add_contact(top, chosen(), rigid=platen)
    nodes = boundary_nodes(model.V, model.n_owned // 2)
    sim.add_contact(plane_below(comm, nodes, model.node_xy, model.offset, 0.0,
                                model.length_scale), chosen(), rigid=wall_part())
    for c in sim.contacts:
        c.set_friction(friction)
    sim.add_probe("r_mid", (radius, 0.5 * height), "r")
    sim.add_probe("r_top", (radius, height), "r")
    return sim


# ------------------------------------------------------------------- the bit with a tied button

def bit_button_rock(settings: Settings, button_material, rock=GRANITE,
                    button_radius: float = 5e-3, button_length: float = 5e-3, n_r: int = 4,
                    rock_radius: float | None = None, rock_depth: float | None = None,
                    bit_mass: float = 0.5, impedance: float = ROD_IMPEDANCE,
                    incident: loads.TimeFunction = loads.Trapezoid(50e3, 2e-6, 8e-6, 1e-5),
                    method="dme", hold_rock: bool = False, t_end: float = 2e-5,
                    dt: float = 2.0 ** -24, dt_interval: int = 10,
                    comm: MPI.Comm = MPI.COMM_WORLD) -> Simulation:
    """One blow of :func:`bit_rock` through a deformable button: the rigid bit (mass in kg,
    one z dof, the rod of impedance Z in kg/s carrying ``incident(t)``, N) is tied by its
    face to the top of a button (a finite-strain ``button_material`` cylinder, radius and
    length in m, n_r x round(n_r length / radius) square Q1 cells, the body "rod" of
    :func:`~.quad_meshes.rod_on_anvil`), whose face meets the ``rock`` (small strain, the
    body "anvil": r <= rock_radius, -rock_depth <= z <= 0, default :func:`rock_extent`
    for t_end, square cells of the button's size) through node-to-segment contact by
    ``method`` (the button's face the slave). The tie (:mod:`.contact.tie`) holds the
    button's top at the bit's u_z and at u_r = 0. ``hold_rock``: the rock's bottom held in
    u_z (free otherwise). The step is the fixed ``dt`` (s) under the step that follows the
    button's cells (checked every ``dt_interval`` steps), to ``t_end`` (s)."""
    from .contact.segments import node_to_segment
    from .contact.tie import Tie, tie_face, tie_radial_dofs
    from .quad_meshes import rod_on_anvil
    from .stepping import FollowingStep

    size = rock_extent(rock, t_end, button_radius)
    n_z = max(1, round(n_r * button_length / button_radius))
    tmesh = rod_on_anvil(comm, button_radius, button_length, n_r, n_z,
                         size if rock_radius is None else rock_radius,
                         size if rock_depth is None else rock_depth)
    model = DeformableModel(tmesh, [Body("rod", button_material), Body("anvil", rock)])
    fixed = [tie_radial_dofs(model, "rod_end", button_radius)]
    if hold_rock:
        fixed.append(model.facet_dofs("anvil_bottom", 1))
    sim = Simulation(model, settings, fixed=fixed,
                     policy=FollowingStep(None, t_end, dt, 0.5, dt_interval))
    bit = RigidBody("bit", bit_mass, impedance=impedance, incident=incident)
    sim.add_contact(tie_face(model, "rod_end", button_radius, "bit"), Tie(), rigid=bit)
    sim.add_contact(node_to_segment(model, "rod_contact", "anvil_contact"),
                    make_method(method) if isinstance(method, str) else method)
    return sim


def rigid_bit_on_rock_block(settings: Settings, method, rock=GRANITE, bit_radius: float = 5e-3,
                            h: float = 1.25e-3, rock_radius: float = 0.05,
                            rock_depth: float = 0.05, bit_mass: float = 0.5,
                            impedance: float = ROD_IMPEDANCE,
                            incident: loads.TimeFunction = loads.Trapezoid(50e3, 2e-6, 8e-6,
                                                                           1e-5),
                            hold_rock: bool = False,
                            comm: MPI.Comm = MPI.COMM_WORLD) -> Simulation:
    """:func:`bit_rock`'s rigid flat bit (radius m) on a structured rock block of square Q1
    cells of side ``h`` (m), r <= rock_radius, -rock_depth <= z <= 0: the rock of
    :func:`bit_button_rock` cell for cell (its anvil), to compare the two blows.
    ``hold_rock``: the bottom held in u_z."""
    from .quad_meshes import quad_rectangle

    m_r, m_z = max(1, round(rock_radius / h)), max(1, round(rock_depth / h))
    model = DeformableModel(quad_rectangle(comm, 0.0, -rock_depth, rock_radius, 0.0, m_r, m_z,
                                           "block"), [Body("block", rock)])
    fixed = [model.facet_dofs("bottom", 1)] if hold_rock else []
    sim = Simulation(model, settings, fixed=fixed)
    bit = RigidBody("bit", bit_mass, impedance=impedance, incident=incident)
    sim.add_contact(rigid_face(model, "top", bit_radius, "bit"), method, rigid=bit)
    return sim
