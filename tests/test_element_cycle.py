"""The time per element per cycle a run reports (summary.json, the console) is the loop's wall
time over cells x steps, from the summary's own numbers; each body's is its own force's time
over its cells x steps where the bodies have forces of their own (a linear and a J2 body),
else its share of the f_int phase by its cells.

No timed assertion: only that the figures are there, positive, and the quotients of the
summary's other figures. Serial and under MPI (the summary is the same on every rank).
"""
from mpi4py import MPI

from impact_fenics import scenes
from impact_fenics.contact import Penalty
from impact_fenics.report import console_lines
from impact_fenics.simulation import Settings
from roundoff import rounding

# 1e9 * wall / (cells * steps) computed twice in another order: a product and a division or
# two, each rounding once (4 roundings of a number of the result's size)
QUOTIENT = rounding(4)


def _close(a: float, b: float) -> bool:
    return abs(a - b) <= QUOTIENT * abs(b)


def test_two_bodies_report_the_time_per_element_per_cycle():
    sim = scenes.bar_impact(Settings(dt=1e-6, n_steps=30, output_every=10, quiet=True),
                            Penalty(1e10), h=0.04, nu=0.0, radius=0.1, striker_length=0.4,
                            target_length=0.4, observe=None)
    s = sim.run()
    steps, cells = s["stopped_at_step"], s["n_cells"]
    assert steps == 30 and cells > 0
    whole = s["ns_per_element_cycle"]
    assert whole > 0 and _close(whole, 1e9 * s["wall_time"] / (cells * steps))
    f_int = s["time_per_step_total"]["f_int"]
    assert sum(s["bodies"][b]["n_cells"] for b in ("striker", "target")) == cells
    for name in ("striker", "target"):
        b = s["bodies"][name]
        assert b["n_cells"] > 0 and b["ns_per_element_cycle"] > 0
        assert _close(b["ns_per_element_cycle"], 1e9 * f_int / (cells * steps))
    if MPI.COMM_WORLD.rank == 0:
        assert any(line.startswith("cost: ") and "ns per element per cycle" in line
                   for line in console_lines(s))


def test_bodies_with_forces_of_their_own_are_timed_apart(tmp_path):
    """The plastic bar impact (an elastic striker, a J2 target): two forces, each timed on
    its own; each body's figure is its force's time over its cells x steps."""
    import os

    from impact_fenics import scene_file
    from scene_texts import ROOT

    scene = scene_file.read_scene(os.path.join(ROOT, "scenes", "plastic_bar_impact.toml"))
    sim = scene_file.build(scene, {"quiet": True, "n_steps": 20, "t_end": None,
                                   "plots": False})
    assert len(sim.integrator.forces) == 2
    assert sim.integrator.force_bodies == [["striker"], ["target"]]  # linear, then J2
    s = sim.run()
    steps = s["stopped_at_step"]
    for name in ("striker", "target"):
        b = s["bodies"][name]
        assert b["f_int_seconds"] > 0 and b["n_cells"] > 0
        assert _close(b["ns_per_element_cycle"], 1e9 * b["f_int_seconds"] / (b["n_cells"] * steps))


def test_a_finite_strain_run_reports_the_time_per_element_per_cycle():
    """The Taylor bar (2 x 20 Q1 cells, no wall, 2 us under the step that follows its
    cells) through Simulation: its body's figure is its force's time over cells x steps."""
    from impact_fenics import scenes
    from impact_fenics.materials import FiniteJ2

    copper = FiniteJ2(E=117e9, nu=0.35, density=8930.0, yield_stress=400e6, hardening=100e6)
    sim = scenes.taylor_bar(Settings(quiet=True, plots=False, fields=False), copper, n_r=2,
                            method=None, t_end=2e-6)
    s = sim.run()
    steps, cells = s["stopped_at_step"], s["n_cells"]
    assert steps > 0 and cells == 2 * 20
    whole = s["ns_per_element_cycle"]
    assert whole > 0 and _close(whole, 1e9 * s["wall_time"] / (cells * steps))
    b = s["bodies"]["bar"]
    assert b["f_int_seconds"] > 0 and b["n_cells"] == 2 * 20
    assert _close(b["ns_per_element_cycle"], 1e9 * b["f_int_seconds"] / (b["n_cells"] * steps))
