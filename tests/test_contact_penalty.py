"""Penalty contact: the committed penetration, and stability at the derived bound.

Oracles: the algebra of the predictor-corrector (the spring acts on the predicted
penetration, so the predicted penetration is force / p and the committed one
(1 - beta) force / p for an isolated pair with beta = p S_ii), the 1D plateau stress
of the bar impact, the exact eigenvalue of a diagonal-plus-rank-one matrix (dense
LAPACK), and the stability bound beta_max < 4/3 derived in
impact_fenics/contact/penalty.py. Round-off bounds count roundings (tests/roundoff.py).
"""
import math

import numpy as np
import pytest

from impact_fenics import scenes
from impact_fenics.contact import Penalty
from impact_fenics.contact.penalty import STABILITY_BOUND, lambda_max_diag_plus_rank_one
from impact_fenics.errors import InputError
from impact_fenics.simulation import Settings
from roundoff import ledger, rounding

RHO, E = 7850.0, 200e9
C0 = math.sqrt(E / RHO)


def test_rank_one_eigenvalue_matches_dense_solver():
    rng = np.random.default_rng(0)
    for n, kappa in ((1, 0.5), (7, 3.0), (50, 1e3), (200, 1e-3)):
        a = rng.uniform(0.1, 2.0, n)
        z = rng.uniform(0.5, 1.5, n)
        dense = np.linalg.eigvalsh(np.diag(a) + kappa * np.outer(z, z))[-1]
        # LAPACK's eigenvalue errs by O(n) roundings of |A| = lambda_max; the bisection
        # stops between adjacent doubles, where its secular sum of n terms changes sign
        assert abs(lambda_max_diag_plus_rank_one(a, kappa, z) - dense) <= rounding(
            2 * n + 8, dense)


def test_predicted_and_committed_penetration_at_the_plateau():
    p = 1e10  # N/m: every pair (the light axis pair too) below beta = 1
    sim = scenes.bar_impact(Settings(dt=1e-6, n_steps=60, output_every=20, quiet=True),
                            Penalty(p), h=0.02, nu=0.0, radius=0.1, striker_length=0.4,
                            target_length=0.4, observe=None)
    c = sim.contacts[0]
    assert c.method.info["beta_max"] < 1.0
    sim.run()  # ends on the plateau (2 L / c0 = 158 us)
    force, predicted = c.force, -c.gap
    beta = p * c.s_diagonal()
    assert np.all(force > 0)
    # force = p (-g~), then / p: 2 roundings
    assert np.allclose(predicted, force / p, rtol=rounding(2), atol=0)
    committed = -c.committed_gap()
    # the committed gap b + u_up - u_lo after the spring's correction (8 roundings of the
    # displacements, up to v0 t = 3e-4 m) against (1 - beta) f / p (4 of f / p)
    assert np.allclose(committed, (1.0 - beta) * force / p, rtol=rounding(4),
                       atol=rounding(8, 5.0 * 60e-6))
    # and the face carries the 1D contact stress within 1 %
    stress = force.sum() / (math.pi * 0.1 ** 2)
    assert abs(stress / (RHO * C0 * 5.0 / 2) - 1) <= 0.01


def _punch_under_constant_force(beta_target):
    """A light punch (0.1 kg) held on a block by a constant 200 MPa: the light body
    couples every spring, so beta_max = c (1 + kappa sum 1/d) is set by the punch."""
    block = dict(width=1.5, depth=0.3, h_surface=0.02, grading=0.3,
                 breaks=((0.5, 25), (1.0, 25)))
    sim = scenes.punch_indentation(
        Settings(dt=3.64e-7, n_steps=600, output_every=10, quiet=True, energy_growth_limit=1e9,
                 force=beta_target > STABILITY_BOUND),
        Penalty("scaled", beta_target=beta_target), radius=0.5, block=block,
        t_rise=1e-6, t_fall=1.0, t_end=2.0)
    summary = sim.run()
    hist, energy = sim.history.data(), sim.energy.data()
    late = slice(300, None)
    return {
        "n": sim.contacts[0].n,
        "beta_max": sim.contacts[0].method.info["beta_max"],
        "flips_late": int(np.abs(np.diff(hist["n_active"][late])).sum()),
        "punch_ke_late": float((0.5 * 0.1 * hist["punch_v"][late] ** 2).max()),
        "energy": float(np.abs(energy["total"]).max()),
        "balance": summary["energy_balance_error_rel"],
        "ledger": ledger(summary["n_steps"], summary["n_dofs"]),
        "status": summary["status"],
    }


def _beta_round(n: int) -> float:
    """Round-off of beta_max of 'scaled' (n constraints): p = beta_target / (1 + kappa
    sum 1/d) / d (a sum of n terms) and the bisection's secular sum (n more)."""
    return rounding(2 * n + 8)


def test_contact_settles_just_under_the_bound():
    r = _punch_under_constant_force(0.95 * STABILITY_BOUND)
    assert abs(r["beta_max"] - 0.95 * STABILITY_BOUND) <= _beta_round(r["n"])
    assert r["flips_late"] == 0  # the active set holds
    assert r["punch_ke_late"] <= 1e-4 * r["energy"]  # the punch has come to rest on the block
    assert r["balance"] <= r["ledger"]
    assert r["status"] == "completed"  # no chatter, no energy gain reported


def test_contact_chatters_and_gains_energy_just_above_the_bound():
    r = _punch_under_constant_force(1.05 * STABILITY_BOUND)
    assert abs(r["beta_max"] - 1.05 * STABILITY_BOUND) <= _beta_round(r["n"])
    assert r["flips_late"] >= 100  # opens and closes again and again
    # the chattering punch keeps kinetic energy orders above the settled case:
    # energy the non-conservative penalty pumped in (the ledger still balances)
    assert r["punch_ke_late"] >= 1e-2 * r["energy"]
    assert r["balance"] <= r["ledger"]
    # and the run says so in its status (it completes: chatter does not diverge)
    assert r["status"].startswith("completed (penalty chatter") and "contact energy gain" in r["status"]


def test_penalty_above_the_bound_is_refused_unless_forced():
    """beta_max is known before the first step: above 4/3 the run is refused like a dt
    above the stable limit (Settings.force runs it)."""
    block = dict(width=0.3, depth=0.1, h_surface=0.02, grading=0.3, h_max=0.05, breaks=((0.1, 5),))
    settings = Settings(dt=1e-7, n_steps=5, quiet=True)
    with pytest.raises(InputError, match=r"beta_max = 1\.4 is above the stable bound 4/3"):
        scenes.punch_indentation(settings, Penalty("scaled", beta_target=1.4), radius=0.1,
                                 block=block)
    forced = scenes.punch_indentation(Settings(dt=1e-7, n_steps=5, quiet=True, force=True),
                                      Penalty("scaled", beta_target=1.4), radius=0.1, block=block)
    c = forced.contacts[0]
    assert abs(c.method.info["beta_max"] - 1.4) <= _beta_round(c.n)
