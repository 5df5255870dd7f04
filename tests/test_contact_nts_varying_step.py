"""Node-to-segment contact under a varying step (docs/node_to_segment.md, "A varying step").

With h_{n+1/2} the step from t^n to t^{n+1} and h_n = 1/2 (h_{n-1/2} + h_{n+1/2}), a
multiplier lam moves the velocities by h_n M^-1 G' lam and the positions by h_{n+1/2}
times that, so the predicted gaps by S lam with S = h_{n+1/2} h_n G M^-1 G'; the set's
``set_step`` rebuilds S's band in place and tells its method.

Oracles:

* S itself: after ``set_step(h, h_n)`` the band equals h h_n G M^-1 G' formed here densely
  from the rows of G (numpy, another order of the sums: to the round-off of a row's
  products); back at the set-up's step it is the set-up's band to the bit, in the same
  storage (nothing allocated), and m / h_n is rewritten with it.
* Reduction: on matching faces (5/5) the segment kind applies the node pairs' forces by
  other expressions, under any step as under a constant one; under a step sequence that
  ramps down geometrically and then alternates, the node-to-segment run equals the
  node-pair run under the same steps within the spread of a one-ulp change of v0 (class
  (c) of tests/roundoff.py), the same active set at every step; FILM and DME.
* The ledger and momentum: on non-matching faces (6/9) under the same steps, the energy
  balance (the kinetic identity, exact for any sequence of steps) within
  roundoff.ledger at every row and z momentum (no external z force: the axis holds u_r
  only) within the same relative bound; FILM, DME and the penalty; the same with
  Coulomb friction (mu = 0.3, nu = 0.3 bars whose faces slide radially).
* The penalty's beta under the steps: a stiffness in N/m checked at every step the run
  takes (refused in one line above 4/3), a scaled one keeping its beta.

Every test runs unchanged on 1, 2 and 3 ranks.
"""
import math
from dataclasses import replace

import numpy as np
import pytest
from mpi4py import MPI

from impact_fenics import meshing, scenes
from impact_fenics.bodies import Body, DeformableModel
from impact_fenics.contact import Penalty
from impact_fenics.contact.banded import dense_s
from impact_fenics.contact.pairing import pair_surfaces
from impact_fenics.contact.segments import node_to_segment
from impact_fenics.errors import InputError
from impact_fenics.materials import STEEL
from impact_fenics.simulation import Settings, Simulation
from impact_fenics.stepping import StepSequence
from roundoff import assert_within_spread, ledger, one_ulp, rounding
from test_varying_step import _limit

COMM = MPI.COMM_WORLD
RHO, E = 7850.0, 200e9
C0 = math.sqrt(E / RHO)
V0, L, A = 5.0, 0.2, 0.05
T_END = 3 * L / C0  # s: the contact lasts 2 L / c0, then the bars part


def _model(n_striker, n_target, comm=COMM, nu=0.0):
    tmesh = meshing.coaxial_bars_sized(radius=A, striker_length=L, target_length=L,
                                       h_striker=A / n_striker, h_target=A / n_target,
                                       structured=True, comm=comm)
    steel = replace(STEEL, nu=nu)
    return DeformableModel(tmesh, [Body("striker", steel), Body("target", steel)])


def _steps(limit: float) -> list[float]:
    """A geometric ramp from 0.9 to 0.45 of the limit over 20 steps, then steps alternating
    between 0.85 and 0.5 of it, until t passes T_END."""
    ramp = [0.9 * 0.5 ** (k / 19) for k in range(20)]
    steps, k = [], 0
    while sum(steps) < T_END:
        f = ramp[k] if k < len(ramp) else (0.85 if k % 2 else 0.5)
        steps.append(f * limit)
        k += 1
    return steps


def _bars(method, n_striker, n_target, node_to_node=False, v0=V0, nu=0.0, friction=None):
    """The bars (striker below at v0 in +z; nu = 0 unless given) under _steps, node to
    segment with the finer face the slave, or node pairs on matching faces; Coulomb
    ``friction`` on the set if given."""
    model = _model(n_striker, n_target, nu=nu)
    steps = _steps(_limit(model))
    sim = Simulation(model, Settings(energy_every=1, output_every=len(steps), quiet=True,
                                     plots=False, fields=False),
                     initial_velocity={"striker": (0.0, v0)}, policy=StepSequence(steps))
    if node_to_node:
        constraints = pair_surfaces(model, "striker_contact", "target_contact")
    elif n_target >= n_striker:
        constraints = node_to_segment(model, "target_contact", "striker_contact")
    else:
        constraints = node_to_segment(model, "striker_contact", "target_contact")
    c = sim.add_contact(constraints, scenes.make_method(method))
    if friction is not None:
        c.set_friction(friction)
    return sim


def _final_u(sim):
    return np.concatenate(COMM.allgather(sim.integrator.u_owned.copy()))


# ----------------------------------------------------------------------------- S at a new step

def test_set_step_rebuilds_s_in_place():
    """S = h h_n G M^-1 G' after set_step, formed densely here; the set-up's band to the bit
    when the step comes back; the same storage throughout."""
    model = _model(6, 9)
    dt = 0.5 * _limit(model)
    sim = Simulation(model, Settings(dt=dt, n_steps=1, quiet=True, plots=False, fields=False))
    c = sim.add_contact(node_to_segment(model, "target_contact", "striker_contact"),
                        scenes.make_method("film"))
    band, start = c.band, c.band.copy()
    G = np.zeros((c.n, c.n_slots))
    for i in range(c.n):
        G[i, c.cs[i]] += c.cc[i]
    unit = (G * c.minv) @ G.T  # G M^-1 G' (1/kg)
    size = (np.abs(G) * c.minv) @ np.abs(G).T  # the magnitudes of its products
    for h, h_avg in ((0.7 * dt, 0.85 * dt), (1.3 * dt, 1.15 * dt)):
        c.set_step(h, h_avg)
        assert c.band is band
        # each entry: at most 6 x 6 products of three factors summed (54 roundings a row),
        # then times h h_n (2), against numpy's (as many): 112 on the products' magnitudes
        bound = rounding(112, h * h_avg * size)
        assert np.all(np.abs(dense_s(c.band, c.bw) - h * h_avg * unit) <= bound)
        assert np.array_equal(c.m_over_dt, c.mass / h_avg)
    c.set_step(dt, dt)
    assert c.band is band and np.array_equal(c.band, start)
    assert np.array_equal(c.m_over_dt, c.mass / dt)


# ----------------------------------------------------------------------------- reduction

@pytest.mark.parametrize("method", ["film", "dme"])
def test_matching_faces_reproduce_node_pairs_under_varying_steps(method):
    """Matching 5/5 faces: node to segment against node pairs under the same steps, within
    the steps x the spread of the node-pair run under a one-ulp change of v0."""
    nn, nts = _bars(method, 5, 5, node_to_node=True), _bars(method, 5, 5)
    ulp = _bars(method, 5, 5, node_to_node=True, v0=one_ulp(V0))
    for sim in (nn, nts, ulp):
        assert sim.run()["status"].startswith("completed")
    n = nn.n_steps
    hn, hs, hu = nn.history.data(), nts.history.data(), ulp.history.data()
    assert len(set(hs["dt"].tolist())) > 10  # the step varied
    assert np.array_equal(hn["dt"], hs["dt"])
    assert np.array_equal(hn["n_active"], hs["n_active"])
    assert hn["n_active"].max() == 6
    assert_within_spread(hs["contact_force"], hn["contact_force"], hu["contact_force"], n,
                         "contact_force")
    assert_within_spread(_final_u(nts), _final_u(nn), _final_u(ulp), n, "u")
    en, es, eu = nn.energy.data(), nts.energy.data(), ulp.energy.data()
    scale = np.abs(en["total"]).max()
    for col in ("kinetic", "strain", "contact_work"):
        assert_within_spread(es[col], en[col], eu[col], n, col, scale)


# ----------------------------------------------------------------------------- the ledger

@pytest.mark.parametrize("friction", [None, 0.3], ids=["frictionless", "mu=0.3"])
@pytest.mark.parametrize("method", ["film", "dme", "penalty"])
def test_non_matching_faces_keep_the_ledger_and_momentum_under_varying_steps(method, friction):
    """6/9 faces under the steps: the balance and z momentum within roundoff.ledger; the
    bars meet and part. With friction (nu = 0.3: the faces expand radially and slide on
    each other), the tangential pass's work is in the balance: it closes the same."""
    sim = _bars(method, 6, 9, nu=0.0 if friction is None else 0.3, friction=friction)
    summary = sim.run()
    assert summary["status"].startswith("completed")
    e, h = sim.energy.data(), sim.history.data()
    n, n_dofs = sim.n_steps, summary["n_dofs"]
    assert len(set(h["dt"].tolist())) > 10
    assert h["n_active"].max() > 0 and h["n_active"][-1] == 0  # met and parted
    if friction is not None:
        assert h["slip_work"][-1] > 0.0  # the faces slid
    bound = ledger(n, n_dofs)
    print(method, "balance", np.abs(e["balance_error_rel"]).max(), "momentum",
          np.abs(e["momentum_z"] - e["momentum_z"][0]).max() / abs(e["momentum_z"][0]),
          "bound", bound)
    assert np.abs(e["balance_error_rel"]).max() <= bound
    p = e["momentum_z"]
    assert np.abs(p - p[0]).max() <= bound * abs(p[0])


def _penalty_bars(p, factors):
    model = _model(6, 9)
    limit = _limit(model)
    sim = Simulation(model, Settings(quiet=True, plots=False, fields=False),
                     initial_velocity={"striker": (0.0, V0)},
                     policy=StepSequence([f * limit for f in factors]))
    sim.add_contact(node_to_segment(model, "target_contact", "striker_contact"), Penalty(p))
    return sim


def test_a_given_penalty_is_checked_at_every_step_the_run_takes():
    """beta = the Gershgorin bound of P^1/2 S P^1/2 grows with h h_n: a p in N/m that gives
    beta = 1 at 0.4 x the limit is accepted under that step alone and refused at set-up,
    in one line, when the sequence later takes 0.9 x the limit (beta about 5); a 'scaled'
    p keeps beta at its target under every step."""
    beta_1 = _penalty_bars(1e9, [0.4] * 5).contacts[0].method.info["beta_max"]
    p = 1e9 / beta_1  # beta is linear in p
    assert _penalty_bars(p, [0.4] * 5).contacts[0].method.info["beta_max"] <= 4.0 / 3.0
    with pytest.raises(InputError, match="beta_max = .* is above the stable bound"):
        _penalty_bars(p, [0.4] * 3 + [0.9] * 3)
    c = _penalty_bars("scaled", [0.4] * 3 + [0.9] * 3).contacts[0]
    # beta = 1 at set-up, to the roundings of Gershgorin's row sums (2 bw + 1 terms of 4
    # roundings each, bw <= 3 here) and of p's scaling (2); at another step p h h_n is the
    # set-up's but for the rescaling's and the band's roundings (4 more a term): 64 in all
    assert abs(c.method.info["beta_max"] - 1.0) <= rounding(64)
