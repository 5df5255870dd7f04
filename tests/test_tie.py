"""A tie: a deformable face bonded to a rigid part (docs/one_loop.md, "A tie"); serial and
mpirun -n 2.

The scene: a long steel bar (nu = 0) on its axis, z in [0, L], its end face z = L tied
to a rigid mass above it, u_r of the tied nodes fixed. With nu = 0 and u_r = 0 on the
face the bar is one-dimensional: a plane wave runs down it and nothing comes back in
the window (L is longer than half the distance a wave travels in it). Oracle 1 runs in
plane strain too: a strip of one cell's width W and thickness t (nu = 0, its sides free,
the tied face's u_x held), one-dimensional as the bar (with nu = 0 the plane-strain
Hooke's law of u_y(y) has sigma_xx = 0) with A = t W per slab. The oracles do not come
from the code under test:

1. the closed form of a mass M at v0 on a semi-infinite bar of impedance Z = rho c0 A:
   M dv/dt = -Z v, so v = v0 exp(-t / tau), tau = M / Z, and the face stress
   sigma = Z v / A; and the conservation of the momentum of part and bar at every step;
2. a free bar and a free mass translating together at v0: a rigid translation strains
   nothing and the tie, moving both at one velocity, does no work;
3. a tie to a fixed part is the face held: [[fixed]] u_z and u_r, bit for bit;

and the one-line refusals (friction, another set of the part, two deformable bodies).
"""
from dataclasses import dataclass, replace

import numpy as np
import pytest
from mpi4py import MPI

from impact_fenics import meshing
from impact_fenics.bodies import Body, DeformableModel
from impact_fenics.contact import DME, RigidBody, pair_surfaces, rigid_face
from impact_fenics.contact.tie import Tie, tie_face, tie_radial_dofs
from impact_fenics.errors import InputError
from impact_fenics.geometry import PLANE_STRAIN, Geometry
from impact_fenics.materials import STEEL
from impact_fenics.simulation import Settings, Simulation
from roundoff import EPS, ledger

COMM = MPI.COMM_WORLD
H = 0.005  # m, the cell size a
RADIUS = 0.005  # m: one cell across (nu = 0: the bar is 1D)
MASS_RATIO = 100.0  # M / m_face: the face's lumped mass is 1 % of the part's
V0 = -2.0  # m/s: the part moves down, into the bar
BAR = replace(STEEL, nu=0.0)
C0 = float(np.sqrt(BAR.E / BAR.density))  # m/s, the bar wave speed


def _decay_length() -> float:
    """c0 tau (m) for M = MASS_RATIO m_face: m_face = rho A a / 2 and Z = rho c0 A give
    c0 tau = c0 M / Z = MASS_RATIO a / 2."""
    return MASS_RATIO * H / 2.0


WINDOW = 1.5  # the run's length in tau
LENGTH = 1.1 * WINDOW * _decay_length() / 2.0  # m: no wave returns within the window
# (a wave goes down and back, 2 L / c0 = 1.1 x the window; the scheme's lumped chain
# carries no signal faster than c0)


@dataclass(frozen=True)
class Slab:
    """The groups of a long bar's mesh and its geometry: the body's cells, the tied face
    (its far end z = L, y = L in plane strain)."""
    body: str
    face: str
    geometry: Geometry

    def section(self) -> float:
        """A (m^2): pi R^2 of the bar, t W of the strip's slab (W = RADIUS)."""
        if self.geometry.plane:
            return self.geometry.thickness * RADIUS
        return float(np.pi) * RADIUS ** 2


BAR_GROUPS = Slab("bar", "free_end", Geometry())  # meshing.bar: 0 <= r <= RADIUS
# meshing.block: 0 <= x <= RADIUS (W = one cell), its sides free, t = 0.01 m
STRIP_GROUPS = Slab("block", "top", Geometry(PLANE_STRAIN, 0.01))


@pytest.fixture(scope="module")
def bar_mesh():
    return meshing.bar(radius=RADIUS, length=LENGTH, h=H, structured=True, comm=COMM)


@pytest.fixture(scope="module", params=["axisymmetric", "plane_strain"])
def long_bar(request):
    """(mesh, groups) of the bar on its axis, or of the plane-strain strip: the same cells
    (squares of side H, two triangles of alternating diagonals), W = RADIUS, 0 <= z <= L."""
    if request.param == "axisymmetric":
        return request.getfixturevalue("bar_mesh"), BAR_GROUPS
    return meshing.block(RADIUS, LENGTH, h=H, comm=COMM), STRIP_GROUPS


def _run(mesh, part: RigidBody, bar_v: float = 0.0, tie: bool = True, n_steps=None,
         t_end=None, fixed_face: bool = False, groups: Slab = BAR_GROUPS):
    """The bar (initial z velocity ``bar_v``), its face z = L tied to ``part`` (``tie``),
    or held in u_z and u_r (``fixed_face``). (sim, summary)."""
    model = DeformableModel(mesh, [Body(groups.body, BAR)], geometry=groups.geometry)
    fixed = [tie_radial_dofs(model, groups.face, RADIUS)]
    if fixed_face:
        fixed.append(model.facet_dofs(groups.face, 1))
    sim = Simulation(model, Settings(cfl=0.9, n_steps=n_steps, t_end=t_end, output_every=1,
                                     fields=False, quiet=True, plots=False),
                     fixed=fixed,
                     initial_velocity={groups.body: (0.0, bar_v)} if bar_v else None)
    if tie:
        sim.add_contact(tie_face(model, groups.face, RADIUS, part.name), Tie(), rigid=part)
    return sim, sim.run()


def _face_and_bar_mass(mesh, groups: Slab = BAR_GROUPS) -> tuple[float, float]:
    """(m_face, the bar's mass) (kg) from the lumped masses (the section's convention)."""
    model = DeformableModel(mesh, [Body(groups.body, BAR)], geometry=groups.geometry)
    sim = Simulation(model, Settings(cfl=0.9, n_steps=1, quiet=True, plots=False))
    mass = sim.integrator.mass
    face = COMM.allreduce(float(mass[model.facet_dofs(groups.face, 1)].sum()))
    return face, sim.body_mass[groups.body]


def test_a_mass_on_a_long_bar(long_bar):
    """Oracle 1 on the bar and on the plane-strain strip: Z = rho c0 A with A = pi R^2,
    or t W per slab."""
    mesh, groups = long_bar
    m_face, m_bar = _face_and_bar_mass(mesh, groups)
    area = groups.section()  # m^2
    z = BAR.density * C0 * area  # kg/s
    M = MASS_RATIO * m_face
    tau = M / z
    part = RigidBody("mass", M, v=V0)
    sim, summary = _run(mesh, part, t_end=WINDOW * tau, groups=groups)
    assert summary["status"] == "completed"
    # the lumped masses hold rho A L: their sum over the dofs rounds (n - 1) EPS relative,
    # each mass a few more (its cells' quadrature shares), the quotient two
    assert abs(m_bar / (BAR.density * LENGTH * area) - 1.0) <= 8 * summary["n_dofs"] * EPS
    e, h = sim.energy.data(), sim.history.data()
    n = len(h["time"])
    # momentum of part + bar, every step: the tie merges it exactly and K u sums to zero
    # over the z dofs; the roundings are the ledger's (roundoff.ledger: per step a dof's
    # 32, each sum over the dofs one a term), counted on the momentum's scale
    # sum m |v| <= (M + m_bar) |v0| (no speed exceeds |v0| in the compressed bar)
    p = e["momentum_z"]
    p0 = (M + m_face) * V0
    tol = ledger(n, summary["n_dofs"]) * (M + m_bar) * abs(V0)
    assert np.abs(p - p0).max() <= tol, (np.abs(p - p0).max(), tol)
    # the decay: log v against t (v^{n+1/2} at t^n + h/2) fitted past the first cells'
    # transient (the front leaves the face within a few a / c0)
    t_mid = h["time"] - 0.5 * h["dt"]
    v = h["mass_v"]
    keep = t_mid >= 5.0 * H / C0
    slope, intercept = np.polyfit(t_mid[keep], np.log(v[keep] / V0), 1)
    tau_fit = -1.0 / slope
    amp = float(np.exp(intercept))
    # the amplitude's bound: the bar's lumped chain, ended by a node of half a cell's
    # mass, has the impedance Z (1 + O((omega a / c0)^2)) (no added mass to first order),
    # so the face's own mass m_face, at v0 with the part at t = 0, is momentum the bar
    # carries away beside the part's: A v0 M = (M + m_face) v0 gives the amplitude
    # A = 1 + m_face / M (the impulse of v = A v0 exp(-t / tau) through Z is A v0 Z tau);
    # and the front, carried by waves of the mesh's speed c_p (the lumped chain's at the
    # shortest wave 2 a: c_p = 2 c0 / pi) instead of c0, leaves the face late or early by
    # |c_p / c0 - 1| a / c0 per cell it crosses, and the fit of exp(-t / tau) through it
    # moves by that time over tau, twice (the front's lead and its tail)
    c_p = 2.0 * C0 / np.pi
    amp_tol = 2.0 * abs(c_p / C0 - 1.0) * (H / C0) / tau + m_face / M
    # the face stress: sigma = -(total tie force) / A (the force is compressive-positive),
    # the force of step n (its impulse takes v^{n-1/2} to v^{n+1/2}) at t^n. The face
    # rings at the lumped chain's highest frequency (a step's front excites it and the
    # scheme does not damp it), 10 to 25 per cent about the mean: the amplitude is the
    # least-squares one of the closed form's shape, sum sigma s / sum s s with
    # s = exp(-t / tau), which the ringing, changing sign every few steps, averages out of
    sigma = -h["mass_force"] / area
    shape = np.exp(-(h["time"] - h["dt"])[keep] / tau)
    s_amp = float(np.dot(sigma[keep], shape) / np.dot(shape, shape)) / (z * V0 / area)
    if COMM.rank == 0:
        print(f"\ntie, mass on a bar ({groups.geometry.kind}): tau = {tau:.6g} s, fitted "
              f"{tau_fit:.6g} s ({tau_fit / tau - 1:+.3%}); v amplitude {amp:.5f}, sigma amplitude "
              f"{s_amp:.5f} (tolerance {amp_tol:.3%}); momentum drift "
              f"{np.abs(p - p0).max():.3g} kg m/s (tolerance {tol:.3g}); {n} steps")
    assert abs(tau_fit / tau - 1.0) <= 0.01
    assert abs(amp - 1.0) <= amp_tol
    assert abs(s_amp - 1.0) <= amp_tol
    # the ledger closes (the tie's work booked as a contact's)
    assert np.all(np.abs(e["balance_error_rel"]) <= ledger(n, summary["n_dofs"]))


def test_a_mass_driven_by_a_rod_on_a_long_bar(bar_mesh):
    """The mass with a rod of impedance Z_rod = Z above it (no incident wave): the rod
    takes -Z_rod v, the bar -Z v, so M dv/dt = -(Z + Z_rod) v and tau = M / (Z + Z_rod).
    The tie merges the part's slot mass M + Z_rod h/2 (the rod's implicit half) with
    the face. The amplitude's bound is the first test's: the impulse through Z + Z_rod
    is A v0 (Z + Z_rod) tau = A v0 M, the momentum (M + m_face) v0, so again
    A = 1 + m_face / M, plus the front's term over the new tau. The ledger closes with
    the rod's waves booked."""
    m_face, m_bar = _face_and_bar_mass(bar_mesh)
    area = m_bar / (BAR.density * LENGTH)
    z = BAR.density * C0 * area
    M = MASS_RATIO * m_face
    z_rod = z
    tau = M / (z + z_rod)
    part = RigidBody("mass", M, v=V0, impedance=z_rod)
    sim, summary = _run(bar_mesh, part, t_end=WINDOW * M / z)  # the window of the bar
    e, h = sim.energy.data(), sim.history.data()
    n = len(h["time"])
    t_mid = h["time"] - 0.5 * h["dt"]
    keep = t_mid >= 5.0 * H / C0
    slope, intercept = np.polyfit(t_mid[keep], np.log(h["mass_v"][keep] / V0), 1)
    c_p = 2.0 * C0 / np.pi
    amp_tol = 2.0 * abs(c_p / C0 - 1.0) * (H / C0) / tau + m_face / M
    amp = float(np.exp(intercept))
    if COMM.rank == 0:
        print(f"\ntie, mass with a rod: tau = {tau:.6g} s, fitted {-1.0 / slope:.6g} s "
              f"({-1.0 / slope / tau - 1:+.3%}); v amplitude {amp:.5f} (tolerance "
              f"{amp_tol:.3%}); {n} steps")
    assert abs(-1.0 / slope / tau - 1.0) <= 0.01
    assert abs(amp - 1.0) <= amp_tol
    assert np.all(np.abs(e["balance_error_rel"]) <= ledger(n, summary["n_dofs"]))


def test_a_prescribed_part_is_a_piston(bar_mesh):
    """A tie to a part of prescribed velocity V0 (a piston) on the bar at rest: the bar's
    momentum grows at Z |V0| (d'Alembert: the piston sets rho c0 A of bar in motion at V0
    a second, the face force Z |V0|), and the tied face moves at exactly V0."""
    import math

    from impact_fenics.contact.prescribed import prescribed_velocity

    area = BAR_GROUPS.section()
    z = BAR.density * C0 * area  # kg/s
    m_face, m_bar = _face_and_bar_mass(bar_mesh)
    window = WINDOW * _decay_length() / C0  # s: the front stays on the bar (oracle 1's)
    part = RigidBody("piston", math.inf, prescribed=prescribed_velocity("piston", V0))
    sim, summary = _run(bar_mesh, part, t_end=window)
    assert summary["status"] == "completed"
    h, e = sim.history.data(), sim.energy.data()
    assert np.all(h["piston_v"] == V0)
    # the bar's momentum is the face's m_face V0 (set at the start) plus the tie's
    # impulse, -sum h F (F compressive-positive): the momentum balance, to the ledger's
    # roundings on (m_face + m_bar) |V0|
    impulse = np.cumsum(h["dt"] * h["piston_force"])  # N s (a constant step: h_n = dt)
    p = e["momentum_z"]
    tol = ledger(len(h["time"]), summary["n_dofs"]) * (m_face + m_bar) * abs(V0)
    assert abs(p[-1] - (m_face * V0 - impulse[-1])) <= tol
    # the impulse's slope is Z |V0|: in the lumped chain the momentum behind the front is
    # rho A V0 (c0 t + a bounded offset): its spread about the straight line is at most the
    # momentum of a cell, m_cell |V0| = 2 m_face |V0|, at each end of the fit, so the slope
    # over the window T (past the first five cells' transient) moves by at most
    # 2 x 2 m_face |V0| / T, relative to Z |V0|: 4 m_face / (Z T)
    t = h["time"]
    keep = t >= 5.0 * H / C0
    slope = np.polyfit(t[keep], impulse[keep], 1)[0]
    bound = 4.0 * m_face / (z * (t[-1] - t[keep][0]))
    if COMM.rank == 0:
        print(f"\ntie to a piston at {V0} m/s: impulse slope {slope:.6g} N against Z |V0| = "
              f"{z * abs(V0):.6g} N ({slope / (z * abs(V0)) - 1:+.3%}, bound {bound:.2%})")
    assert abs(slope / (z * abs(V0)) - 1.0) <= bound


def test_a_free_bar_and_a_free_mass_translate_as_one(bar_mesh):
    """Both at v0: the tie moves them at one velocity, so the bar translates rigidly
    (strain energy 0) and the tie does no work. In floats K u of the translating bar
    rounds on |K| |u| with |u| = |v0| t growing: the ledger's drifting bound
    (roundoff.ledger, drifting=True) on the kinetic energy bounds both."""
    m_face, _ = _face_and_bar_mass(bar_mesh)
    part = RigidBody("mass", MASS_RATIO * m_face, v=V0)
    n_steps = 60
    sim, summary = _run(bar_mesh, part, bar_v=V0, n_steps=n_steps)
    e = sim.energy.data()
    bound = ledger(n_steps, summary["n_dofs"], drifting=True) * float(e["kinetic"][0])
    if COMM.rank == 0:
        print(f"\ntie, free translation: strain {np.abs(e['strain']).max():.3g} J, tie work "
              f"{np.abs(e['contact_work']).max():.3g} J (bound {bound:.3g} J)")
    assert np.abs(e["strain"]).max() <= bound
    assert np.abs(e["contact_work"]).max() <= bound
    assert abs(part.v - V0) <= bound / abs(part.mass * V0)  # (an energy bound over M |v0|)
    assert abs(part.u - V0 * sim.integrator.t) <= n_steps * 4 * np.finfo(float).eps * abs(
        V0 * sim.integrator.t)  # u += h v: a few roundings a step on |u|


def test_a_tie_to_a_fixed_part_is_the_face_held(bar_mesh):
    """The bar moving up at |v0| into its face z = L, held by a tie to a fixed part, or by
    fixed u_z and u_r on the face: the tie sets the face's v to the part's 0 and its u to
    the part's u + 0 = 0, the values the fixed dofs keep, and books no work (v = 0 on
    both sides of every step). Equal bit for bit."""
    n_steps = 60
    tied, _ = _run(bar_mesh, RigidBody("seat", 1.0, fixed=True), bar_v=-V0, n_steps=n_steps)
    held, _ = _run(bar_mesh, None, bar_v=-V0, n_steps=n_steps, tie=False, fixed_face=True)
    assert np.array_equal(tied.integrator.u_owned, held.integrator.u_owned)
    assert np.array_equal(tied.integrator.v_owned, held.integrator.v_owned)
    a, b = tied.energy.data(), held.energy.data()
    for name in ("kinetic", "strain", "momentum_z"):
        assert np.array_equal(a[name], b[name]), name
    assert np.all(a["contact_work"] == 0.0)
    assert tied.history.data()["seat_force"].max() > 0.0  # the face was loaded


def _tie_set_up(mesh):
    model = DeformableModel(mesh, [Body("bar", BAR)])
    sim = Simulation(model, Settings(cfl=0.9, n_steps=2, quiet=True, plots=False),
                     fixed=[tie_radial_dofs(model, "free_end", RADIUS)])
    return model, sim


def _one_line(err) -> str:
    text = str(err.value)
    assert "\n" not in text
    return text


def test_friction_on_a_tie_is_refused(bar_mesh):
    model, sim = _tie_set_up(bar_mesh)
    c = sim.add_contact(tie_face(model, "free_end", RADIUS, "mass"), Tie(),
                        rigid=RigidBody("mass", 1.0))
    with pytest.raises(InputError) as err:
        c.set_friction(0.3)
    assert "a tie takes no friction" in _one_line(err)
    with pytest.raises(InputError) as err:
        c.set_repairing(1)
    assert "a tie does not re-pair" in _one_line(err)


@pytest.mark.parametrize("fixed", [False, True], ids=["moving", "fixed"])
@pytest.mark.parametrize("tie_first", [True, False], ids=["tie_first", "contact_first"])
def test_a_tied_part_in_another_set_is_refused(bar_mesh, tie_first, fixed):
    """A fixed part may be in several contact sets, but not when one is a tie."""
    model, sim = _tie_set_up(bar_mesh)
    part = RigidBody("mass", 1.0, fixed=fixed)
    sets = [(tie_face(model, "free_end", RADIUS, "mass"), Tie()),
            (rigid_face(model, "loaded_end", RADIUS, "mass"), DME())]
    if not tie_first:
        sets.reverse()
    sim.add_contact(*sets[0], rigid=part)
    with pytest.raises(InputError) as err:
        sim.add_contact(*sets[1], rigid=part)
    assert "is in a tie and in another contact set" in _one_line(err)
    assert len(sim.contacts) == 1


@pytest.mark.parametrize("tie_first", [True, False], ids=["tie_first", "contact_first"])
def test_a_tied_face_in_another_set_is_refused(bar_mesh, tie_first):
    """A tied node is bonded: a second set on the same face (another part's contact) is
    refused, whichever comes first."""
    model, sim = _tie_set_up(bar_mesh)
    sets = [(tie_face(model, "free_end", RADIUS, "mass"), Tie(), RigidBody("mass", 1.0)),
            (rigid_face(model, "free_end", RADIUS, "other"), DME(), RigidBody("other", 1.0))]
    if not tie_first:
        sets.reverse()
    sim.add_contact(sets[0][0], sets[0][1], rigid=sets[0][2])
    with pytest.raises(InputError) as err:
        sim.add_contact(sets[1][0], sets[1][1], rigid=sets[1][2])
    assert "a tied node belongs to its tie alone" in _one_line(err)
    assert len(sim.contacts) == 1


def test_a_tie_between_two_deformable_bodies_is_refused():
    mesh = meshing.coaxial_bars_sized(radius=0.01, striker_length=0.02, target_length=0.02,
                                      h_striker=0.01, h_target=0.01, comm=COMM)
    model = DeformableModel(mesh, [Body("striker", BAR), Body("target", BAR)])
    sim = Simulation(model, Settings(cfl=0.9, n_steps=2, quiet=True, plots=False))
    with pytest.raises(InputError) as err:
        sim.add_contact(pair_surfaces(model, "striker_contact", "target_contact"), Tie())
    assert "not two deformable bodies" in _one_line(err)


def test_a_tie_without_its_face_held_radially_is_refused(bar_mesh):
    model = DeformableModel(bar_mesh, [Body("bar", BAR)])
    sim = Simulation(model, Settings(cfl=0.9, n_steps=2, quiet=True, plots=False))
    with pytest.raises(InputError) as err:
        sim.add_contact(tie_face(model, "free_end", RADIUS, "mass"), Tie(),
                        rigid=RigidBody("mass", 1.0))
    assert "must be fixed" in _one_line(err)


def _scene_text(mass: float) -> str:
    return f"""\
[mesh]
generator = "bar"
radius = {RADIUS!r}
length = {LENGTH!r}
h = {H!r}

[materials.steel]
E = {BAR.E!r}
nu = 0.0
density = {BAR.density!r}

[bodies.bar]
material = "steel"

[rigid.mass]
mass = {mass!r}
velocity = {V0!r}

[[tie]]
surface = "free_end"
rigid = "mass"
radius = {RADIUS!r}

[time]
cfl = 0.9
n_steps = 40
"""


def test_the_scene_tie_is_the_python_tie(bar_mesh, tmp_path_factory):
    """A [[tie]] builds the Python route's set (the face selected as a rigid [[contact]]'s,
    its u_r held, its nodes at the part's velocity): the same run bit for bit."""
    from impact_fenics.scene_file import build, read_scene
    from scene_texts import scene_on_every_rank

    m_face, _ = _face_and_bar_mass(bar_mesh)
    M = MASS_RATIO * m_face
    _, path = scene_on_every_rank(tmp_path_factory, "tie", _scene_text(M))
    from_file = build(read_scene(path), {"out": None, "quiet": True, "plots": False,
                                         "fields": False, "timers": False})
    summary = from_file.run()
    built, _ = _run(from_file.model.tmesh, RigidBody("mass", M, v=V0), n_steps=40)
    assert np.array_equal(from_file.integrator.u_owned, built.integrator.u_owned)
    assert np.array_equal(from_file.integrator.v_owned, built.integrator.v_owned)
    assert from_file.contacts[0].rigid.v == built.contacts[0].rigid.v != V0
    # the console names it a tie, without a contact's time in contact and separations
    from impact_fenics.report import console_lines

    if COMM.rank == 0:
        line = next(x for x in console_lines(summary) if "free_end/mass" in x)
        assert line.startswith("tie free_end/mass: peak force") and "separation" not in line


@pytest.mark.parametrize("change, expected", [
    (("radius = 0.005\n\n[time]", 'radius = 0.005\nfriction = 0.3\n\n[time]'),
     "[tie #1] unknown key 'friction'"),
    (("[time]", '[[contact]]\nsurface = "loaded_end"\nrigid = "mass"\nradius = 0.005\n'
                'method = "dme"\n\n[time]'),
     "[rigid.mass] a rigid body must be in exactly one [[contact]] or [[tie]] (it is in 2"),
], ids=["friction", "another_set"])
def test_the_scene_refuses(tmp_path_factory, change, expected):
    from impact_fenics.scene_file import read_scene
    from scene_texts import replace, scene_on_every_rank

    _, path = scene_on_every_rank(tmp_path_factory, "tie_refused",
                                  replace(_scene_text(1.0), *change))
    with pytest.raises(InputError) as err:
        read_scene(path)
    assert _one_line(err).startswith(expected)
