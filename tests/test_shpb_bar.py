"""The bar alone: a striker of the bar's steel and diameter on the incident bar, no
specimen, read by a strain gauge and a section on the bar (docs/shpb.md, "Checked
against").

Oracles:

* the 1D theory of the impact of two bars of one impedance: the bar carries the strain
  v / (2 c0) (the stress rho c0 v / 2) for 2 L_s / c0. The gauge's mean over the middle
  half of the pulse within 1 % of it, and its duration at half amplitude within 2 % of
  2 L_s / c0 (the bounds docs/shpb.md sets the bar: what the Pochhammer-Chree ringing of a 10 mm
  radius, nu = 0.29 bar may leave of the 1D wave over a 40 us pulse, 20 cells across the
  radius; the rise and ringing themselves are physical, the 3D pulse at the gauge about
  1 % longer than the 1D one);
* momentum, exact: the section's impulse h sum F_s equals the change of z momentum of
  the bar's nodes at and above its plane (nothing else acts on them), to the round-off
  bound of tests/test_section_force.py; and the striker's loss m_s (v0 - v_end) is the
  bar's whole gain (the contact's impulse), to the round-off of the momentum sums. The
  bar's part below the plane keeps the rest: the ringing that trails the pulse. The
  section's impulse equals m_s (v0 - v_end) only up to that part's momentum (printed;
  it is not round-off: equality to round-off would need the part below at rest).
"""
import json
import math
import os

import numpy as np
from mpi4py import MPI

from roundoff import rounding
from scene_texts import scene_on_every_rank
from test_section_force import momentum_bound, part_momentum

COMM = MPI.COMM_WORLD
E, NU, RHO, V0 = 200e9, 0.29, 7850.0, 10.0
C0 = math.sqrt(E / RHO)
RADIUS, H, L_S, L_BAR = 0.01, 0.0005, 0.1, 0.3  # m: 20 cells across the radius
Z_GAUGE = 0.15  # m on the bar, a node row (the section's plane)

SCENE = f"""title = "SHPB striker on the incident bar"
[mesh]
generator = "coaxial_bars"
radius = {RADIUS}
striker_length = {L_S}
target_length = {L_BAR}
h = {H}
structured = true
[materials.bar_steel]
E = {E}
nu = {NU}
density = {RHO}
[bodies.striker]
material = "bar_steel"
velocity = [0.0, {V0}]
[bodies.target]
material = "bar_steel"
[[contact]]
lower = "striker_contact"
upper = "target_contact"
method = "dme"
[time]
cfl = 0.9
t_end = 7.5e-5
[output]
fields = false
history_every = 1
[[probes]]
name = "gauge"
quantity = "strain_gauge"
z = {Z_GAUGE}
[[probes]]
name = "section"
quantity = "section"
z = {Z_GAUGE}
"""
# t_end: the pulse has passed the gauge ((Z_GAUGE + 2 L_S) / c0 = 69 us) and the free
# end's reflection has not come back to it ((2 L_BAR - Z_GAUGE) / c0 = 89 us)


def _crossings(t: np.ndarray, y: np.ndarray, level: float, width: float) -> tuple[float, float]:
    """The first upward crossing of ``level``, and the first downward one at least
    ``width`` / 2 after it (the ringing behind the fall may come back above the level);
    linear interpolation between the samples."""
    i = int(np.argmax(y >= level))
    up = t[i - 1] + (level - y[i - 1]) * (t[i] - t[i - 1]) / (y[i] - y[i - 1])
    j = int(np.argmax((t > up + 0.5 * width) & (y < level)))
    down = t[j - 1] + (level - y[j - 1]) * (t[j] - t[j - 1]) / (y[j] - y[j - 1])
    return float(up), float(down)


def test_bar_alone(tmp_path_factory):
    from impact_fenics import scene_file

    base, path = scene_on_every_rank(tmp_path_factory, "shpb_bar", SCENE)
    scene = scene_file.read_scene(path)
    out = os.path.join(base, "run")
    sim = scene_file.build(scene, {"out": out, "quiet": True}, COMM)
    sim.run()
    COMM.barrier()
    d = np.genfromtxt(os.path.join(sim.out_dir, "history.csv"), delimiter=",", names=True)
    with open(os.path.join(sim.out_dir, "summary.json")) as f:
        summary = json.load(f)
    t, strain = d["time"], -d["gauge"]  # compression positive
    exact = V0 / (2.0 * C0)
    duration = 2.0 * L_S / C0
    up, down = _crossings(t, strain, 0.5 * exact, duration)
    middle = (t > up + 0.25 * duration) & (t < up + 0.75 * duration)
    plateau = float(np.mean(strain[middle]))
    if COMM.rank == 0:
        print(f"bar alone: plateau {plateau * E / 1e6:.5g} MPa against rho c0 v / 2 = "
              f"{exact * E / 1e6:.5g} MPa ({plateau / exact - 1:+.2%}); duration at half "
              f"amplitude {(down - up) * 1e6:.4g} us against 2 L_s / c0 = "
              f"{duration * 1e6:.4g} us ({(down - up) / duration - 1:+.2%})")
    assert abs(plateau / exact - 1.0) <= 0.01
    assert abs((down - up) / duration - 1.0) <= 0.02

    h, n = summary["dt"], summary["n_steps"]
    # rows hold u^1 .. u^n; the steps' forces are F_s(u^0 .. u^{n-1}), F_s(u^0) = 0
    impulse = h * float(np.sum(d["section"][:-1]))
    above = part_momentum(sim, Z_GAUGE)  # the bar's nodes at and above the plane, at rest at t = 0
    # the discrete wave's particle speed stays below 2 V0 (the striker starts at V0)
    bound = momentum_bound(sim, n, 2.0 * V0)
    striker = summary["bodies"]["striker"]
    loss = striker["mass"] * (striker["velocity_z_initial"] - striker["velocity_z_final"])
    target = summary["bodies"]["target"]
    gain = target["mass"] * target["velocity_z_final"]
    if COMM.rank == 0:
        print(f"section impulse {impulse:.15e} N s, momentum above it {above:.15e} "
              f"(difference {impulse - above:.3g}, bound {bound:.3g}); striker's loss "
              f"m_s (v0 - v_end) {loss:.15e}, the bar's gain {gain:.15e}; the part below "
              f"the plane keeps {loss - impulse:.3g} N s ({(loss - impulse) / loss:.2%})")
    assert abs(impulse - above) <= bound
    # the ledger's momentum: two sums over the dofs of M v (each a rounding per dof)
    assert abs(loss - gain) <= rounding(2 * sim.model.n_global, (striker["mass"]
                                                                  + target["mass"]) * V0)
