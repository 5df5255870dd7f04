"""The plane-strain impact of two strips at nu = 0 (scenes/plane_strain_impact.toml, a half
model with symmetry = "x=0", node pairs) and of a strip on the wall, against the 1D
solution (docs/plane_strain.md).

At nu = 0 a strip whose sections move as one is exactly one-dimensional (no lateral
strain, no shear): the bar speed c = sqrt(E / rho), the contact stress rho c v / 2 of two
equal impedances (rho c v on a rigid wall) for 2 L_s / c (L_s the striker's length), and
the same stress carried through the target. The mesh only converges to this (the front
rings over a few elements), so, as for the axisymmetric bars (tests/test_contact_bars.py):

* the contact force over the middle 80 % of the contact, per slab (w t), within 1 % of
  the 1D stress (the plateau of a 1D wave is exact; only the front's ringing reaches
  into the window), and the target's sigma_yy at its middle over the middle 80 % of the
  pulse's passage within 2 % (a cell's stress rings more than a face's force sum);
* the contact's duration, to where the force falls for good below half the 1D force (the
  unloading front's centre, not its ringing tail), within 2 h / c of 2 L_s / c: the
  front's centre is placed to an element after its travel through the striker and
  back, and its half-force sample to one more element of ringing;
* the momentum (two strips) constant and the energy ledger balanced to round-off
  (tests/roundoff.py's ledger bound: the steps' roundings, summed).
"""
import math
import os

import numpy as np
import pytest

from impact_fenics import scene_file
from roundoff import LIBM, ledger, rounding
from scene_texts import ROOT, replace

SCENE = os.path.join(ROOT, "scenes", "plane_strain_impact.toml")
RHO, E, V0 = 7850.0, 200e9, 5.0
C = math.sqrt(E / RHO)
W, T, H = 0.01, 0.01, 0.0025  # m: the half width, the thickness, the element size
L_S, L_T = 0.05, 0.1  # m: the striker's and the target's lengths


def _run(text: str, tmp_path, method: str):
    """Build and run a scene text in this process (every rank): (summary, history, energy,
    dt)."""
    path = tmp_path / "scene.toml"
    from mpi4py import MPI

    if MPI.COMM_WORLD.rank == 0:
        path.write_text(text)
    MPI.COMM_WORLD.barrier()
    scene = scene_file.read_scene(str(path))
    scene.set_method(method)
    sim = scene_file.build(scene, {"out": None, "quiet": True, "plots": False})
    summary = sim.run()
    return summary, sim.history.data(), sim.energy.data(), sim.settings.dt


def _shared_tmp(tmp_path):
    from mpi4py import MPI

    return type(tmp_path)(MPI.COMM_WORLD.bcast(str(tmp_path)))


def _contact_window(hist, dt, force, one_d):
    """The contact's duration (s) to where ``force`` (N) last exceeds half ``one_d`` (N),
    and a mask of the middle 80 % of the steps in contact."""
    steps = np.flatnonzero(hist["n_active"] > 0)
    t0, in_contact = steps[0] * dt, (steps[-1] - steps[0] + 1) * dt
    pressing = np.flatnonzero(force > 0.5 * one_d)
    t = hist["time"]
    return ((pressing[-1] + 1) * dt - t0,
            (t > t0 + 0.1 * in_contact) & (t < t0 + 0.9 * in_contact))


@pytest.fixture(scope="module", params=["film", "dme"])
def strips(request, tmp_path_factory):
    with open(SCENE) as f:
        text = f.read()
    return _run(text, _shared_tmp(tmp_path_factory.mktemp("strips")), request.param)


def test_strips_press_at_rho_c_v_over_2(strips):
    summary, hist, energy, dt = strips
    one_d = RHO * C * V0 / 2
    duration, window = _contact_window(hist, dt, hist["contact_force"], one_d * W * T)
    stress = float(hist["contact_force"][window].mean()) / (W * T)
    print(f"contact stress {stress:.6g} Pa against rho c v / 2 = {one_d:.6g} Pa "
          f"({stress / one_d - 1:+.2e}); duration {duration:.4g} s against 2 L / c = "
          f"{2 * L_S / C:.4g} s")
    assert abs(stress / one_d - 1) <= 0.01
    assert abs(duration - 2 * L_S / C) <= 2 * H / C


def test_the_target_carries_the_plateau(strips):
    _, hist, _, dt = strips
    steps = np.flatnonzero(hist["n_active"] > 0)
    t0 = steps[0] * dt
    arrive = t0 + 0.5 * L_T / C  # the probe at the target's middle
    t = hist["time"]
    window = (t > arrive + 0.1 * 2 * L_S / C) & (t < arrive + 0.9 * 2 * L_S / C)
    assert window.sum() > 10
    plateau = float(hist["sigma_yy_target"][window].mean())
    one_d = -RHO * C * V0 / 2
    print(f"target sigma_yy plateau {plateau:.6g} Pa against -rho c v / 2 = {one_d:.6g} Pa "
          f"({plateau / one_d - 1:+.2e})")
    assert abs(plateau / one_d - 1) <= 0.02


def test_momentum_and_energy_balance(strips):
    summary, _, energy, _ = strips
    bound = ledger(summary["n_steps"], summary["n_dofs"])
    p = energy["momentum_z"]
    drift = float(np.abs(p - p[0]).max() / abs(p[0]))
    print(f"momentum drift {drift:.3g}, energy balance {summary['energy_balance_error_rel']:.3g}"
          f" (bound {bound:.3g})")
    assert drift <= bound
    assert summary["energy_balance_error_rel"] <= bound
    # the striker's momentum is half the slab's m v (a half model: the masses are the half's)
    assert p[0] == pytest.approx(RHO * W * L_S * T * V0, rel=bound)


# The striker alone on the wall y = 0, moving down: the stress rho c v for 2 L_s / c.
WALL = """\
title = "strip on the wall"
geometry = "plane_strain"
thickness = 0.01
symmetry = "x=0"

[mesh]
generator = "block"
width = 0.01
height = 0.05
h = 0.0025

[materials.steel]
E = 200e9
nu = 0.0
density = 7850.0

[bodies.block]
material = "steel"
velocity = [0.0, -5.0]

[wall]
z = 0.0
method = "film"

[time]
cfl = 0.9
t_end = 2.5e-5

[output]
history_every = 1
"""


@pytest.mark.parametrize("method", ["film", "dme"])
def test_strip_on_the_wall_presses_at_rho_c_v(method, tmp_path):
    summary, hist, energy, dt = _run(WALL, _shared_tmp(tmp_path), method)
    duration, window = _contact_window(hist, dt, hist["wall_force"], RHO * C * V0 * W * T)
    stress = float(hist["wall_force"][window].mean()) / (W * T)
    print(f"wall stress {stress:.6g} Pa against rho c v = {RHO * C * V0:.6g} Pa; duration "
          f"{duration:.4g} s against {2 * L_S / C:.4g} s")
    assert abs(stress / (RHO * C * V0) - 1) <= 0.01
    assert abs(duration - 2 * L_S / C) <= 2 * H / C
    assert summary["energy_balance_error_rel"] <= ledger(summary["n_steps"], summary["n_dofs"])


# A rigid punch of half-width 5 mm (the half model: x in [0, 5 mm], 11 surface nodes of
# 0.5 mm) pushed into a block by 200 MPa on the half face (area b t), its bottom held in y.
PUNCH = """\
title = "plane-strain punch"
geometry = "plane_strain"
thickness = 0.01
symmetry = "x=0"

[mesh]
generator = "punch_block"
width = 0.02
depth = 0.01
h_surface = 0.0005
grading = 0.3
h_max = 0.002
breaks = [[0.005, 10]]

[materials.steel]
E = 200e9
nu = 0.3
density = 7850.0

[bodies.block]
material = "steel"

[rigid.punch]
mass = 0.01

[[fixed]]
facet = "bottom"
components = ["y"]

[[contact]]
surface = "surface"
rigid = "punch"
half_width = 0.005
method = "film"

[[loads]]
rigid = "punch"
peak = 200e6
area = 5e-5
t_rise = 2e-6
t_fall = 1.0
t_end = 2.0

[time]
cfl = 0.9
n_steps = 60
"""


@pytest.mark.parametrize("method", ["film", "dme"])
def test_rigid_punch_scene(method, tmp_path):
    """half_width in a scene: the 11 nodes of x in [0, b] constrained, the punch moving
    down along y, the ledger closing within its round-off bound."""
    summary, hist, energy, dt = _run(PUNCH, _shared_tmp(tmp_path), method)
    print(f"punch scene, {method}: {summary['contact']}, ledger "
          f"{summary['energy_balance_error_rel']:.3g}")
    assert summary["energy_balance_error_rel"] <= ledger(summary["n_steps"], summary["n_dofs"])
    assert float(hist["n_active"].max()) == 11


def test_cylinder_button_gaps(tmp_path):
    """button = R_s in plane strain: a cylinder, the gap R_s - sqrt(R_s^2 - x^2) under each
    node of |x| <= b (x^2, R_s^2, -, sqrt, -: 4 + LIBM roundings, the last subtraction
    cancelling R_s / gap of its digits)."""
    text = replace(PUNCH, "half_width = 0.005\n", "half_width = 0.005\nbutton = 0.02\n")
    path = _shared_tmp(tmp_path) / "button.toml"
    from mpi4py import MPI

    if MPI.COMM_WORLD.rank == 0:
        path.write_text(text)
    MPI.COMM_WORLD.barrier()
    sim = scene_file.build(scene_file.read_scene(str(path)),
                           {"out": None, "quiet": True, "plots": False})
    c = sim.contacts[0]
    x = np.linspace(0.0, 0.005, 11)
    gap = 0.02 - np.sqrt(0.02 ** 2 - x ** 2)
    assert c.b.shape == gap.shape and c.b[0] == 0.0
    assert np.allclose(c.b[1:], gap[1:], rtol=rounding((4 + LIBM) * 0.02 / gap[1]), atol=0)
