"""The bit-rock scene (percussive drilling): a rigid bit driven by a rod impedance on an
elastic rock, against oracles outside the dynamic code.

- Static indentation stiffness K_h of the mesh (impact_fenics.statics, one MUMPS
  solve with the face nodes held at u_z = -delta): under refinement it tends to the
  half-space value 2 E* a (Boussinesq's flat punch, E* = E/(1 - nu^2)).
- At maximum penetration the bit's velocity and the radiation damping vanish, and the
  dynamic F/delta tends to K_h of the same mesh as the motion slows down. What is
  left is the inertia of the rock's near field: the quasi-static field u ~ delta a/R
  moves rock out to R ~ c/omega, an added mass ~ rho a^2 c/omega, so the relative
  error is ~ omega a/c, first order in the loading frequency. The test slows the
  whole scene down by s = 1, 2, 4 (times x s, masses x s^2, impedance x s: the same
  static problem) and checks that the error halves per doubling and that its
  Richardson extrapolation s -> infinity vanishes within 1e-3 (the next term,
  O((omega a/c)^2), at s = 4).
- A penalty bit: at rest, a penalty step leaves the committed penetrations
  -g = (P^-1 - S) f (S = dt^2 G M^-1 G', the bit's effective mass included), a
  series spring network between the bit and the rock's face flexibility Phi
  (statics.flexibility); its stiffness 1'(P^-1 - S + Phi)^-1 1 is the oracle, with the
  same first-order convergence.
- Wave energies: F_i^2 - F_r^2 = Z w F exactly for the step-averaged velocity w, so
  incident = reflected + delivered to round-off (a count of roundings per step), and the
  energy ledger closes (roundoff.ledger).
- A free rod end (bit mass -> 0) reflects the incident wave as tension, F_r = -F_i;
  a bit too heavy to move reflects it as compression, F_r = F_i.
- Partitions: the run on all ranks equals the run on one within the spread of a
  one-ulp change of the incident wave's peak (the run starts at rest; roundoff.py).
"""
import math

import numpy as np
import pytest
from mpi4py import MPI

from impact_fenics import loads, meshing, scenes, statics
from impact_fenics.bodies import Body, DeformableModel
from impact_fenics.contact import RigidBody, rigid_face
from impact_fenics.operators import assemble_stiffness
from impact_fenics.simulation import Settings
from roundoff import assert_within_spread, ledger, one_ulp, rounding

A = 0.01  # bit radius (m)
E_STAR = scenes.GRANITE.E / (1.0 - scenes.GRANITE.nu ** 2)


def _scene(method, s, comm=MPI.COMM_WORLD, t_end=9e-5, h=A / 5, peak=150e3):
    """The bit-rock scene slowed down by s (the same static problem); ``peak`` (N) the
    incident wave's."""
    settings = Settings(cfl=0.9, t_end=t_end * s, fields=False, quiet=True, plots=False,
                        output_every=10 ** 6)
    return scenes.bit_rock(settings, method, bit_radius=A, bit_mass=0.5 * s * s,
                           impedance=scenes.ROD_IMPEDANCE * s,
                           incident=loads.Trapezoid(peak, 1e-5 * s, 7e-5 * s, 8e-5 * s),
                           h_surface=h, comm=comm)


def _at_max_penetration(sim):
    h = sim.history.data()
    k = int(np.argmin(h["bit_u"]))
    assert 0 < k < h["bit_u"].size - 1  # a maximum inside the run
    assert h["bit_v"][k - 1] < 0.0 < h["bit_v"][k + 1]
    return h["bit_force"][k], -h["bit_u"][k]


def test_static_stiffness_tends_to_boussinesq():
    """K_h / (2 E* a) at h/a = 0.1, 0.05, 0.025 on a block of 200 a (graded mesh): it
    decreases, its error shrinks at least as h^0.5 (the edge singularity of the flat
    punch), and the Richardson extrapolation at the observed rate meets 2 E* a within
    1 % (a block of 200 a on a fixed base is stiffer than the half-space by O(a/200a))."""
    ratios = []
    for h in (0.1, 0.05, 0.025):
        tm = meshing.punch_block(width=200.0, depth=200.0, h_surface=h, grading=0.1, h_max=25.0,
                                 breaks=((1.0, int(round(1 / h))),))
        model = DeformableModel(tm, [Body("block", scenes.GRANITE)])
        c = rigid_face(model, "surface", 1.0, "bit")
        force = statics.rigid_indentation(model, assemble_stiffness(model),
                                          scenes.held_dofs(model), statics.owned(model, c.lower),
                                          1e-3)
        ratios.append(force / 1e-3 / (2 * E_STAR * 1.0))
    e = np.array(ratios) - 1.0
    assert np.all(e > 0) and e[1] < e[0] / math.sqrt(2) and e[2] < e[1] / math.sqrt(2)
    rate = e[1] / e[2]  # observed reduction per halving
    limit = ratios[2] - (ratios[1] - ratios[2]) / (rate - 1.0)
    assert abs(limit - 1.0) < 0.01


def test_flat_bit_force_over_penetration_tends_to_static_stiffness():
    """DME (case 1) at s = 1, 2, 4: |F/delta / K_h - 1| halves per doubling of s and
    extrapolates to zero (see the module docstring)."""
    errors = []
    for s in (1.0, 2.0, 4.0):
        sim = _scene(scenes.make_method("dme"), s)
        sim.run()
        force, delta = _at_max_penetration(sim)
        errors.append(force / delta / scenes.static_stiffness(sim) - 1.0)
    e = np.array(errors)
    ratios = e[1:] / e[:-1]
    assert np.all((ratios > 0.4) & (ratios < 0.6)), ratios  # first order in omega a / c
    assert abs(2 * e[2] - e[1]) < 1e-3  # Richardson: the s -> infinity limit is K_h


def test_penalty_bit_adds_a_series_spring():
    """A soft penalty (p = 1e8 N/m a node): F/delta tends to the series network
    1'(P^-1 - S + Phi)^-1 1, about a quarter of K_h here."""
    errors = []
    for s in (1.0, 2.0):
        method = scenes.make_method("penalty", penalty=1e8)
        sim = _scene(method, s)
        sim.run()
        force, delta = _at_max_penetration(sim)
        c, model = sim.contacts[0], sim.model
        assert method.info["beta_max"] < 4.0 / 3.0
        phi = statics.flexibility(model, sim.integrator.K, scenes.held_dofs(model),
                                  c.constraints.lower)
        compliance = np.diag(1.0 / method.p - c.d) - c.kappa + phi
        k_series = np.linalg.solve(compliance, np.ones(c.n)).sum()
        assert k_series < 0.5 * scenes.static_stiffness(sim)  # the spring is felt
        errors.append(force / delta / k_series - 1.0)
    assert 0.4 < errors[1] / errors[0] < 0.6
    assert abs(2 * errors[1] - errors[0]) < 1e-3


@pytest.mark.parametrize("method", ["dme", "film", "penalty"])
def test_wave_energies_balance_and_ledger_closes(method):
    """incident = reflected + delivered to round-off (an identity of the booking), and
    the ledger (the rod's force as external work on the bit) closes to round-off."""
    sim = _scene(scenes.make_method(method), 1.0, t_end=6e-5)
    sim.settings.output_every = 50
    summary = sim.run()
    bit = sim.contacts[0].rigid
    n = sim.n_steps
    assert bit.wave_incident > 0 and bit.wave_delivered > 0
    # a step books dt F_i^2 / Z, dt F_r^2 / Z and dt (2 F_i - Z w) w from F_r = F_i - Z w:
    # about 15 roundings on terms within 12 x the incident energy (|F_r|, |Z w| <= 2 |F_i|
    # here), and each of the three running sums rounds once a step
    assert abs(bit.wave_incident - bit.wave_reflected - bit.wave_delivered) \
        <= rounding(3 * n + 15 * 12, bit.wave_incident)
    # the incident energy of the pulse in closed form (trapezoid, rectangle rule in dt):
    # the same F_i(n dt), a term rounded 3 times in the run and once here, n terms summed
    # in both, dt / Z applied once here (2)
    pulse = loads.Trapezoid(150e3, 1e-5, 7e-5, 8e-5)
    dt = sim.settings.dt
    exact = sum(pulse(k * dt) ** 2 for k in range(n)) * dt / scenes.ROD_IMPEDANCE
    assert bit.wave_incident == pytest.approx(exact, rel=rounding(2 * n + 6))
    assert summary["energy_balance_error_rel"] <= ledger(n, summary["n_dofs"])


def _rod_end(mass, n=400, dt=1e-7, z=3e4):
    """A bit alone (no rock) under the rod: returns the per-step F_i and F_r."""
    pulse = loads.Trapezoid(1e5, 5e-6, 2e-5, 3e-5)
    bit = RigidBody("bit", mass, impedance=z, incident=pulse)
    f_i, f_r = np.empty(n), np.empty(n)
    for k in range(n):
        t = k * dt
        v_now = bit.v
        u, v = bit.predict(t, dt)
        bit.advance(t, dt, u, v)
        f_i[k] = pulse(t)
        f_r[k] = f_i[k] + z * 0.5 * (v_now + v)  # F_i - Z w with w = -v averaged
    return bit, f_i, f_r


def test_rod_end_reflections():
    """Free end (m -> 0): F_r = -F_i (tension back), all energy reflected, to first order
    in m / (Z dt / 2) (the bit's mass against the rod's damping in a step; exact at m = 0)
    plus the round-off of F_r = F_i + Z w (|Z w| <= 2 |F_i|: a few roundings of 2 F_i).
    A bit far heavier than Z t_pulse: F_r = F_i to O(Z t / m)."""
    m, dt, z = 1e-12, 1e-7, 3e4
    bit, f_i, f_r = _rod_end(m, dt=dt, z=z)
    first_order = 2 * m / (z * dt)
    np.testing.assert_allclose(f_r, -f_i, atol=(first_order + rounding(8, 2)) * f_i.max())
    assert bit.wave_reflected == pytest.approx(bit.wave_incident, rel=2 * first_order)
    bit, f_i, f_r = _rod_end(1e6, dt=dt, z=z)
    z_t_over_m = z * 4e-5 / 1e6
    np.testing.assert_allclose(f_r, f_i, atol=2 * z_t_over_m * f_i.max())
    # the booking's identity, as in the scene's run (400 steps)
    assert abs(bit.wave_incident - bit.wave_reflected - bit.wave_delivered) \
        <= rounding(3 * 400 + 15 * 12, bit.wave_incident)


def test_same_on_all_partitions():
    """The scene on all ranks against this rank alone. On one rank the two evaluate the
    same expressions: equal. On more, the sums over ranks round in another order at every
    step: within the steps x the spread of the serial run under a one-ulp change of the
    incident wave's peak (the run starts at rest; tests/roundoff.py, class (c))."""
    serial = MPI.COMM_WORLD.size == 1
    runs = []
    for comm, peak in ((MPI.COMM_WORLD, 150e3), (MPI.COMM_SELF, 150e3)) + (
            () if serial else ((MPI.COMM_SELF, one_ulp(150e3)),)):
        sim = _scene(scenes.make_method("dme"), 1.0, comm=comm, t_end=4e-5, peak=peak)
        sim.run()
        runs.append((sim.history.data(), sim.contacts[0].rigid, sim.n_steps))
    (hp, bp, n), (hs, bs, _) = runs[:2]
    cols = ("bit_u", "bit_v", "bit_force")
    names = ("wave_incident", "wave_reflected", "wave_delivered")
    if serial:
        for col in cols:
            assert np.array_equal(hp[col], hs[col]), col
        for name in names:
            assert getattr(bp, name) == getattr(bs, name), name
        return
    hq, bq, _ = runs[2]
    for col in cols:
        assert_within_spread(hp[col], hs[col], hq[col], n, col)
    for name in names:
        assert_within_spread(getattr(bp, name), getattr(bs, name), getattr(bq, name), n, name)


SCENE = """\
title = "tiny bit"
[mesh]
generator = "punch_block"
width = 0.06
depth = 0.06
h_surface = 0.002
grading = 0.2
h_max = 0.01
breaks = [[0.01, 5]]
[materials.granite]
E = 60e9
nu = 0.25
density = 2600.0
[bodies.block]
material = "granite"
[rigid.bit]
mass = 0.5
impedance = 31866.9
[[fixed]]
facet = "bottom"
components = ["z"]
[[contact]]
surface = "surface"
rigid = "bit"
radius = 0.01
button = 0.02
method = "film"
[[loads]]
rigid = "bit"
incident = true
peak = 150e3
t_rise = 1e-5
t_fall = 7e-5
t_end = 8e-5
[time]
cfl = 0.9
n_steps = 150
[output]
fields = false
plots = false
"""


def test_scene_file_keys(tmp_path):
    """impedance, incident and button build the same run as the Python API (same mesh)."""
    from impact_fenics import scene_file

    path = tmp_path / "bit.toml"
    path.write_text(SCENE)
    scene = scene_file.read_scene(str(path))
    sim_file = scene_file.build(scene, {"out": None, "quiet": True, "plots": False})
    sim_file.run()
    settings = Settings(dt=sim_file.settings.dt, n_steps=150, quiet=True, fields=False,
                        plots=False)
    sim_api = scenes.bit_rock(settings, scenes.make_method("film"), bit_radius=0.01,
                              button_radius=0.02, impedance=31866.9,
                              incident=loads.Trapezoid(150e3, 1e-5, 7e-5, 8e-5),
                              tmesh=sim_file.model.tmesh)
    sim_api.run()
    np.testing.assert_array_equal(sim_file.history.data()["bit_u"], sim_api.history.data()["bit_u"])
    # b(r) = R_s - sqrt(R_s^2 - r^2) at the bit's edge: r^2, R_s^2, -, sqrt, - (4 + LIBM
    # roundings), the last subtraction cancelling R_s / b = 7.5 of its digits
    b = 0.02 - math.sqrt(0.02 ** 2 - 0.01 ** 2)
    assert sim_api.contacts[0].b[-1] == pytest.approx(b, rel=rounding((4 + 4) * 0.02 / b))
    assert sim_file.summary["rod_waves"]["bit"]["incident"] == sim_api.contacts[0].rigid.wave_incident


@pytest.mark.parametrize("old, new, words", [
    ("impedance = 31866.9", "impedance = -1.0", "impedance"),
    ("impedance = 31866.9", "", "impedance"),
    ("button = 0.02", "button = 0.005", "button"),
    ("incident = true", "incident = true\narea = 1.0", "area"),
])
def test_scene_file_bad_keys(tmp_path, old, new, words):
    from impact_fenics import scene_file
    from impact_fenics.errors import InputError

    path = tmp_path / "bit.toml"
    path.write_text(SCENE.replace(old, new))
    with pytest.raises(InputError, match=words):
        scene_file.read_scene(str(path))
