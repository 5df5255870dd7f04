"""Finite-strain bodies in plane-strain scenes (docs/plane_strain.md): a strip on the wall
against the 1D solution and against the small-strain run, a J2 block between frictionless
platens at 2 sigma_y / sqrt(3), the half model against the full one, and the scene's
outputs.

Oracles, none taken from the code under test:

* the strip (scenes/plane_strain_finite_wall.toml: quad_bar read as the half section
  x in [0, W], symmetry = "x=0", nu = 0, neo-Hookean, 5 m/s on the wall): at nu = 0 the
  strip is exactly one-dimensional, so the wall stress is rho c v for 2 L / c, with the
  tolerances of the small-strain plane-strain test (tests/test_plane_strain_impact.py):
  1 % over the middle 80 % of the contact, the duration within 2 h / c. Against the
  small-strain run on the same mesh and step: the 1D neo-Hookean law at nu = 0 is
  P = mu (lambda - 1/lambda) = E (e - e^2 / 2 + ...) (nominal stress, stretch
  lambda = 1 + e), stiffer in compression, so the wall's front is a shock whose
  Rankine-Hugoniot jump is |P| = rho0 U v with rho0 U^2 = P / e, U = c (1 + |e| / 2)^(1/2):
  |P| = rho c v (1 + eps / 4), eps = v / c. The plateaus differ by eps / 4 of rho c v
  (the order of the strain); the rest is the O(eps^2) of the expansion plus the small
  run's ringing (its plateau's own error d_s) changed by O(eps) over the 2 L / h cells the
  wave crosses: eps^2 + (2 L / h) eps d_s. Step by step the forces differ by at most
  (2 L / h) eps of rho c v: the finite front arrives eps of its travel 2 L / c earlier or
  later and the force rises by rho c v over a cell's transit h / c.
* the J2 block (Hencky J2, perfectly plastic, plane strain, a half model 2 W0 x H0):
  homogeneous flow between frictionless platens with a free side, sigma_xx = 0 there, so
  in Kirchhoff stress |tau_yy - tau_xx| = 2 sigma_y / sqrt(3) (the yield on tau, with
  tau_out halfway once the flow is steady) and sigma = tau / J. The force per thickness
  on the half platen is |sigma_yy| times the current half width w, and with lambda_out = 1,
  J = lambda_x lambda_y, w = W0 lambda_x = W0 J H0 / H:
      F' = (2 / sqrt(3)) sigma_y / J x W0 J H0 / H = (2 / sqrt(3)) sigma_y W0 H0 / H,
  J cancels. The lateral flow's inertia adds to it: v_x = V x / H (incompressible, the
  platen at V) accelerates at a_x = 2 V^2 x / H^2, so sigma_xx = -rho V^2 (w^2 - x^2) / H^2
  and sigma_yy = sigma_xx - 2 sigma_y / (sqrt(3) J): F' gains (2/3) rho V^2 w^3 / H^2
  (2e-4 of F' at 20 % here). Read at 5, 10 and 20 % height reduction (mean over +-0.25 %),
  within the ramp's inertial stress rho H0 V / t_ramp (the platen a crosshead of
  prescribed velocity ramped to V over 58 elastic transit times H0 / c_L: the
  oscillation the ramp leaves is at most its inertial load).
* the half model with symmetry = "x=0" against the full block on x in [-W, W] (nu = 0.3,
  a neo-Hookean strip on the wall, the same cells mirrored): the same displacements, the
  full wall force twice the half's, to round-off (the bound of the small-strain half
  model, tests/test_plane_strain.py: 36 n^2 eps of the largest, doubled for the F-bar
  cell's mean-dilatation sums).
* the wall with friction and with a held face, and two finite-strain bodies node to
  segment: the ledger (and the two bodies' momentum) within tests/roundoff.py's bound.
* 1, 2 and 3 ranks: the run on all ranks equals each rank's own on one within 1e-10 of
  the scale.
* the run's files: the bar's tracked probes named u_y_top, u_y_bottom, u_x_corner, the
  stresses sigma_xx, sigma_out, sigma_yy, sigma_xy in fields.xdmf, the summary's
  geometry and the ledger within its bound.
"""
import json
import math
import os
import xml.etree.ElementTree as ET

import numpy as np
import pytest
from mpi4py import MPI

from impact_fenics import scene_file
from roundoff import ledger
from scene_texts import ROOT, launch, read_history, replace

COMM = MPI.COMM_WORLD
SCENE = os.path.join(ROOT, "scenes", "plane_strain_finite_wall.toml")
TEXT = open(SCENE).read()
RHO, E, V0 = 7850.0, 200e9, 5.0
C = math.sqrt(E / RHO)
EPS_V = V0 / C  # the strain of the 1D impact
W, T, H, L = 0.01, 0.01, 0.0025, 0.05  # m: half width, thickness, cell, length
DT = 3e-7  # s, the scene's fixed step for both kinematics (the limit h / c is 4.95e-7 s)


def _shared(tmp_path):
    return type(tmp_path)(COMM.bcast(str(tmp_path)))


def _run(text: str, tmp_path, method: str = "film", comm: MPI.Comm = COMM):
    """Build and run a scene text on ``comm`` (every rank of it): (summary, history)."""
    path = _shared(tmp_path) / "scene.toml"
    if COMM.rank == 0:
        path.parent.mkdir(exist_ok=True)
        path.write_text(text)
    COMM.barrier()
    scene = scene_file.read_scene(str(path))
    scene.set_method(method)
    sim = scene_file.build(scene, {"out": None, "quiet": True, "plots": False}, comm=comm)
    return sim.run(), sim.history.data()


def _plateau(hist, one_d):
    """(the mean wall force over the middle 80 % of the contact, the contact's duration to
    where the force last exceeds half ``one_d``) (N, s)."""
    steps = np.flatnonzero(hist["n_active"] > 0)
    t0, in_contact = steps[0] * DT, (steps[-1] - steps[0] + 1) * DT
    t = hist["time"]
    window = (t > t0 + 0.1 * in_contact) & (t < t0 + 0.9 * in_contact)
    pressing = np.flatnonzero(hist["wall_force"] > 0.5 * one_d)
    return float(hist["wall_force"][window].mean()), (pressing[-1] + 1) * DT - t0


FIXED_STEP = TEXT  # (the scene's dt is DT)
SMALL = replace(replace(replace(FIXED_STEP, 'strain = "finite"\n', ""),
                        'model = "neo_hookean"\n', ""),
                "dt_interval = 10        # steps between checks of the step against the "
                "cells' limit\n", "")
FOLLOWING = replace(TEXT, "dt = 3e-7 ", "cfl = 0.9 ")  # the step following the cells


@pytest.mark.parametrize("method", ["film", "dme"])
def test_strip_on_the_wall_against_1d_and_small_strain(method, tmp_path):
    one_d = RHO * C * V0 * W * T  # N, rho c v on the half slab
    s_f, h_f = _run(FIXED_STEP, tmp_path / "finite", method)
    s_s, h_s = _run(SMALL, tmp_path / "small", method)
    f_f, duration = _plateau(h_f, one_d)
    f_s, _ = _plateau(h_s, one_d)
    d_s = abs(f_s / one_d - 1)
    predicted = EPS_V / 4
    n = min(h_f["wall_force"].size, h_s["wall_force"].size)
    step_gap = float(np.abs(h_f["wall_force"][:n] - h_s["wall_force"][:n]).max()) / one_d
    print(f"{method}: finite wall stress {f_f / (W * T):.6g} Pa against rho c v = "
          f"{RHO * C * V0:.6g} Pa ({f_f / one_d - 1:+.2e}); duration {duration:.4g} s against "
          f"2 L / c = {2 * L / C:.4g} s; finite - small plateau {(f_f - f_s) / one_d:.4e} of "
          f"rho c v against eps / 4 = {predicted:.4e}; step by step within {step_gap:.3e} "
          f"(bound {2 * L / H * EPS_V:.3e}); ledger {s_f['energy_balance_error_rel']:.2e}")
    assert abs(f_f / one_d - 1) <= 0.01
    assert abs(duration - 2 * L / C) <= 2 * H / C
    assert abs((f_f - f_s) / one_d - predicted) <= EPS_V ** 2 + 2 * L / H * EPS_V * d_s
    assert step_gap <= 2 * L / H * EPS_V
    assert s_f["energy_balance_error_rel"] <= ledger(s_f["n_steps"], s_f["n_dofs"])


def test_ranks_agree_with_one(tmp_path):
    """The scene on every rank against each rank's own run on one (COMM_SELF), the step
    following the cells (cfl): the same steps, the wall force and the tracked nodes within
    1e-10 of their largest values (the sums reorder across ranks; round-off is ~1e-15)."""
    _, world = _run(FOLLOWING, tmp_path / "world")
    _, one = _run(FOLLOWING, tmp_path / "one", comm=MPI.COMM_SELF)
    assert np.array_equal(world["step"], one["step"])
    # (u_x at the corner is zero at nu = 0 but for round-off: scaled by the displacement)
    for name, of in (("dt", "dt"), ("wall_force", "wall_force"), ("u_y_top", "u_y_top"),
                     ("u_x_corner", "u_y_top")):
        scale = float(np.abs(one[of]).max())
        gap = float(np.abs(world[name] - one[name]).max())
        print(f"{name}: {COMM.size} ranks against 1 within {gap:.2e} of {scale:.4g}")
        assert gap <= 1e-10 * scale


@pytest.mark.parametrize("method", ["film", "dme"])
def test_wall_with_friction_and_a_held_face(method, tmp_path):
    """The other wall conditions of a finite-strain body (nu = 0.3, so the face spreads):
    Coulomb friction (mu = 0.2) on the contact face, and the held face (u_y = 0 on y = 0
    from t = 0, free in x): the ledger, friction's dissipation included, within its bound;
    the slipping face does positive slip work."""
    spread = replace(TEXT, "nu = 0.0                # the strip stays one-dimensional\n",
                     "nu = 0.3\n")
    rubbing = replace(spread, "[wall]\n", "[wall]\nfriction = 0.2\n")
    s, _ = _run(rubbing, tmp_path / "friction", method)
    print(f"{method}: friction ledger {s['energy_balance_error_rel']:.2e}")
    assert s["energy_balance_error_rel"] <= ledger(s["n_steps"], s["n_dofs"])
    assert s["friction"][0]["slip_work"] > 0.0
    held = replace(rubbing, "[wall]\n", '[wall]\nface = "held"\n')
    s, _ = _run(held, tmp_path / "held", method)
    assert s["energy_balance_error_rel"] <= ledger(s["n_steps"], s["n_dofs"])


def test_two_finite_bodies_node_to_segment(tmp_path):
    """Two finite-strain J2 strips node to segment in plane strain (the axisymmetric
    scene of tests/test_two_finite_bodies.py as a half model): only the contact acts, so
    the y momentum is constant, and the ledger closes, each within the ledger's bound."""
    from test_two_finite_bodies import TWO_BODIES

    text = 'geometry = "plane_strain"\nthickness = 0.01\nsymmetry = "x=0"\n' + TWO_BODIES
    path = _shared(tmp_path) / "scene.toml"
    if COMM.rank == 0:
        path.write_text(text)
    COMM.barrier()
    sim = scene_file.build(scene_file.read_scene(str(path)),
                           {"out": None, "quiet": True, "plots": False})
    s = sim.run()
    p = sim.energy.data()["momentum_z"]
    bound = ledger(s["n_steps"], s["n_dofs"])
    drift = float(np.abs(p - p[0]).max() / abs(p[0]))
    print(f"two finite strips: momentum drift {drift:.2e}, ledger "
          f"{s['energy_balance_error_rel']:.2e} (bound {bound:.2e})")
    assert drift <= bound
    assert s["energy_balance_error_rel"] <= bound


# ----------------------------------------------------------------- the J2 block, platens

SY, NU_J2 = 200e6, 0.3  # Pa, -
W0 = H0 = 0.01  # m: the half width and the height
V_PLATEN, T_RAMP = 2.0, 100e-6  # m/s, s: the crosshead's speed and ramp
READINGS, HALF_WINDOW = (0.05, 0.10, 0.20), 0.0025


def _platen_run(n: int = 8):
    """The half block (quad_bar n x n, symmetry x = 0) on a frictionless base (u_y = 0 on
    y = 0, x free), a rigid platen on its top, a crosshead of prescribed velocity ramped
    from 0 to V_PLATEN over T_RAMP and held (the same acceleration V / t_ramp, so the same
    inertial bound, as the heavy platen's force ramp it replaced): the history (time,
    platen_force, platen_u, platen_v)."""
    from impact_fenics.bodies import Body, DeformableModel
    from impact_fenics.contact import DME, RigidBody, rigid_face
    from impact_fenics.contact.prescribed import crosshead
    from impact_fenics.geometry import PLANE_STRAIN, Geometry
    from impact_fenics.materials.finite_j2 import FiniteJ2
    from impact_fenics.quad_meshes import quad_bar, tag_rectangle
    from impact_fenics.simulation import Settings, Simulation
    from impact_fenics.stepping import FollowingStep

    t_end = T_RAMP / 2 + (max(READINGS) + 2 * HALF_WINDOW) * H0 / V_PLATEN
    tmesh = tag_rectangle(quad_bar(COMM, W0, H0, n, n), "block")
    material = FiniteJ2(E=E, nu=NU_J2, density=RHO, yield_stress=SY, hardening=0.0)
    model = DeformableModel(tmesh, [Body("block", material)],
                            geometry=Geometry(PLANE_STRAIN, T, "x=0"))
    platen = RigidBody("platen", math.inf, prescribed=crosshead("platen", V_PLATEN, T_RAMP))
    sim = Simulation(model, Settings(quiet=True, plots=False, fields=False, timers=False,
                                     out=None, t_end=t_end, history_every=1),
                     fixed=[model.facet_dofs("bottom", 1)],
                     policy=FollowingStep(None, t_end, None, 0.5, 10))
    sim.add_contact(rigid_face(model, "top", W0, "platen"), DME(), rigid=platen)
    summary = sim.run()
    return summary, sim.history.data()


def test_j2_block_between_platens_flows_at_2_sigma_y_over_sqrt3():
    summary, hist = _platen_run()
    u = -hist["platen_u"]  # m, the platen's travel (the top's, in contact)
    height = H0 - u
    v = -hist["platen_v"]
    w = W0 * H0 / height  # m, the current half width
    k = 2 / math.sqrt(3) * SY
    oracle = (k * W0 * H0 / height + 2 / 3 * RHO * v ** 2 * w ** 3 / height ** 2) * T
    ratio = hist["platen_force"] / oracle
    reduction = u / H0
    tol = RHO * H0 * V_PLATEN / T_RAMP / k  # the ramp's inertial stress over the flow stress
    for at in READINGS:
        window = np.abs(reduction - at) < HALF_WINDOW
        assert window.sum() > 20
        mean = float(ratio[window].mean())
        spread = float(ratio[window].max() - ratio[window].min())
        inertia = float((oracle[window] / (k * W0 * H0 / height[window] * T)).mean()) - 1
        print(f"at {at:.0%} reduction: F' / ((2/sqrt3) sigma_y W0 H0 / H + inertia) - 1 = "
              f"{mean - 1:+.2e} (ringing spread {spread:.1e}, tolerance {tol:.1e}; the "
              f"lateral inertia {inertia:.1e})")
        assert abs(mean - 1) <= tol
    assert summary["energy_balance_error_rel"] <= ledger(summary["n_steps"], summary["n_dofs"])


# ------------------------------------------------------------ half against full model

N_HALF = 60  # steps of the half/full comparison (the front reaches the top and back)


def _strip_on_wall(full: bool):
    """A neo-Hookean strip (nu = 0.3) at 5 m/s on the wall, FILM, fixed DT: the half
    x in [0, W] with symmetry = "x=0", or the full x in [-W, W] (the same cells mirrored).
    Returns (the node coordinates, their displacements, the wall force history)."""
    from impact_fenics.bodies import Body, DeformableModel
    from impact_fenics.contact import FILM
    from impact_fenics.contact.plane import boundary_nodes, plane_below, wall_part
    from impact_fenics.geometry import PLANE_STRAIN, Geometry
    from impact_fenics.materials.neo_hookean import NeoHookean
    from impact_fenics.quad_meshes import quad_bar, tag_rectangle
    from impact_fenics.simulation import Settings, Simulation
    from impact_fenics.stepping import FollowingStep

    mesh = quad_bar(COMM, 2 * W if full else W, L, 8 if full else 4, 20)
    if full:
        mesh.geometry.x[:, 0] -= W
    tmesh = tag_rectangle(mesh, "strip")
    material = NeoHookean(E=E, nu=0.3, density=RHO)
    geometry = Geometry(PLANE_STRAIN, T, None if full else "x=0")
    model = DeformableModel(tmesh, [Body("strip", material)], geometry=geometry)
    t_end = N_HALF * DT
    sim = Simulation(model, Settings(quiet=True, plots=False, fields=False, timers=False,
                                     out=None, t_end=t_end, history_every=1),
                     fixed=[model.axis_dofs()] if not full else [],
                     initial_velocity={"strip": (0.0, -V0)},
                     policy=FollowingStep(None, t_end, DT, 0.9, 10))
    nodes = boundary_nodes(model.V, model.n_owned // 2)
    sim.add_contact(plane_below(COMM, nodes, model.node_xy, model.offset, 0.0,
                                model.length_scale), FILM(), rigid=wall_part())
    sim.run()
    owned = model.n_owned // 2
    xy = np.concatenate(COMM.allgather(model.node_xy[:owned]))
    u = np.concatenate(COMM.allgather(sim.integrator.u_owned.reshape(-1, 2)))
    return xy, u, sim.history.data()["wall_force"]


def test_half_model_equals_the_full_one():
    xy_h, u_h, f_h = _strip_on_wall(False)
    xy_f, u_f, f_f = _strip_on_wall(True)
    key = lambda xy: np.round(xy / (1e-3 * H)).astype(np.int64)  # noqa: E731 (node lookup)
    index = {tuple(k): i for i, k in enumerate(key(xy_f))}
    rows = np.array([index[tuple(k)] for k in key(xy_h)])
    scale = float(np.abs(u_f).max())
    bound = 72 * N_HALF ** 2 * np.finfo(float).eps
    gap = float(np.abs(u_f[rows] - u_h).max()) / scale
    force_gap = float(np.abs(f_f - 2 * f_h).max() / np.abs(f_f).max())
    print(f"half against full: u within {gap:.2e} of {scale:.3e} m, wall force (full = 2 half) "
          f"within {force_gap:.2e} of {np.abs(f_f).max():.4g} N (bound {bound:.1e})")
    assert gap <= bound
    assert force_gap <= bound


# ------------------------------------------------------------------------ the files

@pytest.mark.skipif(COMM.size > 1, reason="launches a process: serial only")
def test_scene_outputs(tmp_path):
    out = tmp_path / "out"
    proc = launch(["run", SCENE, "--out", out])
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert "x of the corner at y = 0" in proc.stdout
    hist = read_history(out)
    for name in ("u_y_top", "u_y_bottom", "u_x_corner", "wall_force"):
        assert name in hist
    summary = json.loads((out / "summary.json").read_text())
    assert summary["geometry"]["kind"] == "plane_strain"
    assert summary["geometry"]["thickness"] == T
    assert summary["energy_balance_error_rel"] <= ledger(summary["n_steps"], summary["n_dofs"])
    # the final length from the tracked nodes: L plus the two ends' last u_y
    assert summary["final_length"] == pytest.approx(
        L + hist["u_y_top"][-1] - hist["u_y_bottom"][-1], rel=1e-12)
    assert (out / "energy.csv").exists()
    names = {a.get("Name") for a in ET.parse(out / "fields.xdmf").iter("Attribute")}
    assert {"sigma_xx", "sigma_out", "sigma_yy", "sigma_xy", "displacement"} <= names
    assert not any(n.startswith("sigma_r") or n == "sigma_zz" for n in names)
