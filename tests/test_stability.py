"""Stability against a converged omega_max: the modified Euler scheme is stable for
dt < 2 / omega_max of M^-1 K.

The oracle is SLEPc's largest eigenvalue of M^-1 K (fixed dofs removed),
converged to 1e-10: a forced run slightly above 2 / omega_max must blow up,
one slightly below must not. The element bound used to refuse input must lie
on the safe side of it. The ledger closes to the round-off of a ledger
(tests/roundoff.py).
"""
import pytest

from impact_fenics import scenes
from impact_fenics.errors import InputError, UnstableRunError
from impact_fenics.simulation import Settings
from roundoff import ledger

BAR = dict(h=0.02, length=0.4, nu=0.3, peak=50e6, structured=False, clamp_far_end=True)


@pytest.fixture(scope="module")
def dt_limits():
    sim = scenes.elastic_bar(Settings(dt=1e-9, n_steps=1, converged_dt=True, quiet=True), **BAR)
    return sim.dt_converged, sim.dt_critical


def test_element_bound_is_conservative(dt_limits):
    converged, bound = dt_limits
    assert bound <= converged
    assert bound >= 0.5 * converged  # and not uselessly so


def test_run_just_above_the_limit_is_detected_unstable(dt_limits):
    converged, _ = dt_limits
    sim = scenes.elastic_bar(Settings(dt=1.05 * converged, n_steps=2000, output_every=20,
                                      force_dt=True, quiet=True), **BAR)
    with pytest.raises(UnstableRunError, match="diverged at step"):
        sim.run()
    assert sim.status == "diverged"


def test_run_just_below_the_limit_is_stable(dt_limits):
    converged, _ = dt_limits
    sim = scenes.elastic_bar(Settings(dt=0.95 * converged, n_steps=2000, output_every=20,
                                      force_dt=True, quiet=True), **BAR)
    summary = sim.run()
    e = sim.energy.data()
    bound = ledger(summary["n_steps"], summary["n_dofs"])
    assert summary["status"] == "completed"
    # no growth: starting at rest, the energy is the work put in, to the ledger's round-off
    assert e["total"].max() <= (1.0 + bound) * e["external_work"].max()
    assert summary["energy_balance_error_rel"] <= bound


def test_dt_above_the_element_bound_is_refused(dt_limits):
    _, bound = dt_limits
    with pytest.raises(InputError, match="above the stable limit"):
        scenes.elastic_bar(Settings(dt=1.01 * bound, n_steps=10, quiet=True), **BAR)
