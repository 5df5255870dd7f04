"""The summary's figures of a finite-strain run: its per-body figures are the ledger's, and
a penalty's beta_max is the run's largest.

A copper Taylor bar (one finite-strain body on the FILM wall, 3 us): the body's plastic
work and kinetic energy are the last energy row's (the same terms, reduced over the ranks
in another order), and its strain energy is the stored energy psi(F_bar) at the u^n the
energy row kept, the state its plastic work belongs to (it read 0 before: the per-body
figures counted only the linear and small-strain bodies).
Bounds: the roundings of the sums (an n-term dot product, the reductions over ranks) on
their scale.
"""
import numpy as np
from mpi4py import MPI

from impact_fenics import scenes
from impact_fenics.materials import FiniteJ2
from impact_fenics.simulation import Settings
from roundoff import rounding

COMM = MPI.COMM_WORLD


def test_a_finite_bodys_figures_are_the_ledgers():
    copper = FiniteJ2(E=117e9, nu=0.35, density=8930.0, yield_stress=400e6, hardening=100e6)
    sim = scenes.taylor_bar(Settings(quiet=True, plots=False, timers=False, fields=False),
                            copper, n_r=2, method="film", t_end=3e-6)
    summary = sim.run()
    assert sim.status == "completed"
    body, row = summary["bodies"]["bar"], summary["energy"]
    n = COMM.allreduce(sim.integrator.v_owned.size)
    assert row["plastic_work"] > 0
    assert abs(body["plastic_work"] - row["plastic_work"]) <= rounding(4 * COMM.size,
                                                                       row["plastic_work"])
    assert abs(body["kinetic_energy"] - row["kinetic"]) <= rounding(4 * n, row["kinetic"])
    # psi at the kept u^n: positive, and below the row's strain column, which adds the
    # boundary term 1/2 h v^{n+1/2} . f_int(u^n) (positive while the bar is compressed
    # and still moving into the wall: v and f_int both point down at the impact face)
    assert 0.0 < body["strain_energy"] < row["strain"]


def test_a_penalty_reports_the_runs_largest_beta_under_a_following_step():
    """A penalty of fixed stiffness p on the wall: beta_max = p h h_n / m (a node's S
    diagonal, h h_n / m) falls as the cells flatten and the step with them, so the run's
    largest is the first step's, which the set-up gives (before it re-estimates); the
    summary reports that one, not the last, clipped step's."""
    from impact_fenics.contact import Penalty

    copper = FiniteJ2(E=117e9, nu=0.35, density=8930.0, yield_stress=400e6, hardening=100e6)
    sim = scenes.taylor_bar(Settings(quiet=True, plots=False, timers=False, fields=False),
                            copper, n_r=2, method=Penalty(1e9), t_end=6e-6)
    (c,) = sim.contacts
    first = c.method.info["beta_max"]
    summary = sim.run()
    assert sim.status == "completed"
    dt = summary["dt_range"]
    assert dt[0] < 0.9 * dt[1]  # the step fell: the last step's beta is below the first's
    (entry,) = summary["contacts"] if "contacts" in summary else [summary["contact"]]
    assert entry["method_info"]["beta_max"] == first > 0
