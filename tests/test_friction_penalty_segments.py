"""The penalty's Coulomb friction on node to segment on a curved master and re-paired in the
loop (docs/friction.md 4.1, 4.2; contact.friction_segments.carry_elastic_slip).

Oracles:

* μ = 0 with the penalty and re-pairing makes no tangential pass: the run equals the
  frictionless re-paired penalty run, every column, bit for bit (one process, one
  partition; on several ranks within the spread of a one-ulp change of v0);
* (on a flat master without re-pairing the pass is unchanged: tests/test_friction_segments.py
  holds it equal to node pairs on matched faces and to the closed forms of a block on an
  inclined face;)
* a nose (R = 2 cm) on a block (a curved master: the rows couple) and the breathing bars
  (slaves change segments, the rim slave is released), re-paired every step: at every
  step and loaded row the cone |λ_t| <= μ λ_n (1 + 1e-12); at every re-pairing each
  elastic slip is the rule's, recomputed here from the rows' normals before and after
  (kept on the same segment, (t . t') s_e on another, 0 released) and the release loss
  grew, and the stored energy fell, by the energy the projections dropped,
  Σ 1/2 k_t (s_e^2 - s_e'^2) >= 0; the ledger closes (roundoff.ledger);
* a block on an inclined straight face (tests/test_friction_segments.py's) at two soft
  stiffnesses k_t = β m / h^2, β = 0.05 and 0.1: its steady stick differs from FILM's
  (which does not slide) by the spring's stretch (1 - β) F / k_t, falling as 1/k_t up to
  (1 - β);
* refusals in one line: a normal penalty whose bound passes 1 with friction and
  re-pairing (docs/friction.md 4.2).

Every test runs unchanged on 1, 2 and 3 ranks (the set's arrays are replicated).
"""
from __future__ import annotations

import os

import numpy as np
import pytest
from mpi4py import MPI

from impact_fenics.contact import FILM, Penalty
from impact_fenics.contact.friction import RELEASE_LOSS, STORED
from impact_fenics.contact.friction_segments import OFF
from impact_fenics.errors import InputError
from roundoff import assert_runs_agree, ledger, one_ulp, rounding
from test_contact_repair import V0, _bars, _settings
from test_friction_segments import NOSE, _block_on_incline

COMM = MPI.COMM_WORLD


def _history(sim):
    return {k: np.asarray(v) for k, v in sim.history.data().items() if not k.startswith("cpu")}


# ----------------------------------------------------------------------------- μ = 0

def test_zero_friction_penalty_with_repairing_is_the_frictionless_run():
    """friction = 0 with the penalty and re-pairing makes nothing (the set's friction stays
    None) and the run is the frictionless re-paired penalty run: bit for bit on one rank,
    within the one-ulp spread of v0 on several (two runs in one process may be partitioned
    differently)."""
    runs = []
    for friction, v0 in ((False, V0), (True, V0), (False, one_ulp(V0))):
        if v0 != V0 and COMM.size == 1:
            runs.append(None)
            continue
        sim = _bars(Penalty("scaled"))
        c = sim.contacts[0]
        c.set_repairing(1)
        if friction:
            c.set_friction(0.0)
        assert c.friction is None
        sim.run()
        runs.append((_history(sim), {k: np.asarray(v) for k, v in sim.energy.data().items()}))
    ref, got, ulp = runs
    n = sim.n_steps
    for i in (0, 1):
        assert ref[i].keys() == got[i].keys()
        for k in ref[i]:
            assert_runs_agree(got[i][k], ref[i][k], None if ulp is None else ulp[i][k], n,
                              k, None if i == 0 else np.abs(ref[1]["total"]).max())


# ----------------------------------------------------------------------------- a curved master

MU = 0.05  # small enough that the rim of the contact slips
NOSE_REPAIRED = NOSE.replace("h_striker = 0.005", "h_striker = 0.0025").replace(
    "h_block = 0.004", "h_block = 0.0016666666666666668").replace(
    "velocity = [0.0, -20.0]", "velocity = [0.0, -60.0]").replace(
    "t_end = 1e-6", "t_end = 1.2e-5").replace(
    "friction = 0.2", f"friction = {MU}\nrepair_every = 1")


class _Watch:
    """Wraps a re-paired set's pass and re-pairing: after each step the cone at every loaded
    row; at each re-pairing the elastic slips against the rule recomputed from the rows'
    normals before and after, and the release loss and stored energy against the drop."""

    def __init__(self, c, mu):
        self.c, self.f, self.mu = c, c.friction, mu
        self.seen = {"rows": 0, "excess": 0.0, "slips": 0, "sticks": 0, "carried": 0,
                     "projected": 0, "released": 0, "drop": 0.0, "coupled": 0}
        self._step, self.f.step = self.f.step, self.checked
        self._repair, c._repair = c._repair, self.watched

    def checked(self) -> float:
        c, f, seen = self.c, self.f, self.seen
        w_t = self._step()
        on = f.state != OFF
        assert np.all(f.lam[~on] == 0.0)
        cone = self.mu * c.force[on]
        assert np.all(np.abs(f.lam[on]) <= cone * (1.0 + 1e-12))
        seen["excess"] = max(seen["excess"],
                             float(np.max(np.abs(f.lam[on]) - cone, initial=-np.inf)))
        seen["rows"] += int(on.sum())
        seen["slips"] += int(np.count_nonzero(f.dsp[on]))
        seen["sticks"] += int(np.count_nonzero(on & (f.dsp == 0.0)))
        seen["coupled"] += int(f.coupled)
        return w_t

    def watched(self) -> None:
        c, f, seen = self.c, self.f, self.seen
        s_before, cc_before = f.s_e.copy(), c.cc.copy()
        seg_before = c.cs[:, 2::2].copy()
        loss_before, stored_before = f.stats[RELEASE_LOSS], f.stats[STORED]
        self._repair()
        # the rule, from the rows' normals: t = (n_z, -n_r) of the slave's entries
        t_old = np.stack([cc_before[:, 1], -cc_before[:, 0]], axis=1)
        t_new = np.stack([c.cc[:, 1], -c.cc[:, 0]], axis=1)
        row = np.any(c.cc[:, :2] != 0.0, axis=1)
        same = np.all(c.cs[:, 2::2] == seg_before, axis=1) & row
        expect = np.where(same, s_before, np.einsum("ij,ij->i", t_old, t_new) * s_before)
        assert np.array_equal(f.s_e[same], s_before[same])  # carried with the segment
        assert np.all(f.s_e[~row] == 0.0)  # released
        # the projection: a dot product of two terms (3 roundings) and its product with s_e
        assert np.all(np.abs(f.s_e - expect) <= rounding(4, np.abs(s_before)))
        drop = 0.5 * f.k_t * (s_before ** 2 - f.s_e ** 2)
        # each drop >= 0 (|t . t'| <= 1 for unit tangents) within its products' roundings
        assert np.all(drop >= -rounding(8, f.k_t * s_before ** 2))
        total = float(drop.sum())
        # booked into the release loss and out of the stored energy: a sum of the rows'
        # terms (8 roundings each, one more per term added) on the energies' scale
        tol = rounding(8 + c.n, float((f.k_t * s_before ** 2).sum()) + abs(loss_before)
                       + abs(stored_before))
        assert abs(f.stats[RELEASE_LOSS] - loss_before - total) <= tol
        assert abs(stored_before - f.stats[STORED] - total) <= tol
        moved = s_before != 0.0
        seen["carried"] += int(np.count_nonzero(moved & same))
        seen["projected"] += int(np.count_nonzero(moved & ~same & row))
        seen["released"] += int(np.count_nonzero(moved & ~row))
        seen["drop"] += total


@pytest.fixture(scope="module")
def nose(tmp_path_factory):
    """The nose on the block, the penalty (scaled) re-paired every step, watched."""
    from impact_fenics.scene_file import build, read_scene

    tmp = COMM.bcast(str(tmp_path_factory.mktemp("nose")) if COMM.rank == 0 else None)
    out = os.path.join(tmp, "nose_penalty")
    text = NOSE_REPAIRED.format(method="penalty") + (
        f'[output]\ndir = "{out}"\nhistory_every = 1\nenergy_every = 1\nfields = false\n'
        'plots = false\n')
    path = os.path.join(tmp, "nose_penalty.toml")
    if COMM.rank == 0:
        with open(path, "w") as fh:
            fh.write(text)
    COMM.barrier()
    sim = build(read_scene(path))
    c = sim.contacts[0]
    assert c.friction.penalty and c.repair_every == 1
    watch = _Watch(c, MU)
    summary = sim.run()
    return sim, watch.seen, summary


@pytest.fixture(scope="module")
def breathing():
    """tests/test_contact_repair.py's breathing bars (the target's face slides along the
    striker's: slaves change segments, the rim slave is released past the master's end),
    the penalty (scaled) with μ = 0.3, re-paired every step, watched."""
    sim = _bars(Penalty("scaled"))
    c = sim.contacts[0]
    c.set_repairing(1)
    c.set_friction(0.3)
    watch = _Watch(c, 0.3)
    summary = sim.run()
    return sim, watch.seen, summary


def test_curved_master_repaired_cone(nose):
    """The cone at every loaded row and step, rows sticking and slipping; the rows couple
    (a curved master: the penalty needs no Tresca iteration)."""
    sim, seen, _ = nose
    c = sim.contacts[0]
    assert c.repairs == sim.n_steps and sim.compiled_in_loop == []
    assert seen["sticks"] > 0 and seen["slips"] > 0 and seen["coupled"] > 0, seen
    if COMM.rank == 0:
        print(f"\nnose penalty re-paired: {seen}; beta_t_max {c.friction.beta_max:.4g}, "
              f"normal beta_max {c.method.info['beta_max']:.4g}")


def test_curved_master_repaired_carry_and_ledger(nose):
    """The elastic slips carried with their segment at every re-pairing (and projected on
    another's tangent when a slave changed segment); the release loss holds every drop;
    the ledger closes within roundoff.ledger."""
    sim, seen, summary = nose
    assert seen["carried"] > 0, seen
    e = sim.energy.data()
    scale = np.abs(np.asarray(e["total"])).max()
    n_dofs = 2 * 2 * 600  # at most: the two bodies' nodes, (r, z) each
    balance = np.abs(np.asarray(e["balance_error"])).max()
    assert balance <= ledger(sim.n_steps, n_dofs) * scale
    h = sim.history.data()
    # R's increments are releases and projection drops (>= 0 each) at a constant step
    # (a rescaling, signed, would need a change of step; docs/friction.md 5.1)
    assert np.all(np.diff(np.asarray(h["release_loss"])) >= 0.0)
    assert np.all(np.diff(np.asarray(h["slip_work"])) >= 0.0)
    if COMM.rank == 0:
        print(f"\nnose penalty re-paired: balance {balance:.3g} J of {scale:.4g} J (bound "
              f"{ledger(sim.n_steps, n_dofs) * scale:.3g} J); {sim.contacts[0].friction.summary()}")


def test_breathing_bars_repaired_carry_and_ledger(breathing):
    """Slaves change segments with their springs loaded (projected) and the rim slave is
    released (its spring dropped), each booked into the release loss; the cone at every
    loaded row and step; the balance and the z momentum within roundoff.ledger."""
    sim, seen, summary = breathing
    assert sim.contacts[0].repairs == sim.n_steps and sim.compiled_in_loop == []
    assert seen["projected"] > 0 and seen["carried"] > 0 and seen["slips"] > 0, seen
    e = sim.energy.data()
    bound = ledger(summary["n_steps"], summary["n_dofs"])
    p = np.asarray(e["momentum_z"])
    assert np.abs(p - p[0]).max() <= bound * abs(p[0])
    assert summary["energy_balance_error_rel"] <= bound
    h = sim.history.data()
    # R's increments: releases and projection drops, >= 0 each at a constant step
    assert np.all(np.diff(np.asarray(h["release_loss"])) >= 0.0)
    if COMM.rank == 0:
        print(f"\nbreathing bars penalty re-paired: {seen}; balance "
              f"{summary['energy_balance_error_rel']:.3g} and z momentum "
              f"{np.abs(p - p[0]).max() / abs(p[0]):.3g} relative (bound {bound:.3g}); "
              f"{sim.contacts[0].friction.summary()}")


# ----------------------------------------------------------------------------- stiffer: FILM

def test_penalty_stick_approaches_film_as_one_over_k_t():
    """The block on the inclined face (tan θ = μ/4, μ = 0.5: it sticks with the cone at four
    times the load, above the soft springs' transient overshoot, at most 2 F) at
    k_t = β m/h^2, β = 0.05 and 0.1 (the scaled k_t is β = 1), and under FILM, whose stick
    is w = 0: its slide t . u stays 0. The penalty settles at s_e = -(1 - β) F / k_t
    (docs/friction.md 4) with |z| = sqrt(1 - β) per step (below 1e-16 after 1500 steps),
    so the difference of the two sticks is (1 - β) F / k_t: falling as 1/k_t, by the ratio
    (1 - β1) β2 / ((1 - β2) β1) = 19/9 when k_t doubles. Round-off: s_e settles within a
    step's roundings (32) of F / k_t; the slide t . u is another accumulator, which drifts
    from s_e by the roundings of u += h v each step (2, on |u| <= 2 F / k_t with the
    transient's overshoot) and FILM's slide by n steps' roundings of h^2 g (its step's
    displacement); the ratio by the two differences' relative errors."""
    mu, n = 0.5, 1500
    theta = np.arctan(0.25 * mu)
    m, g, h = 2.0, 10.0, 1e-3
    F = m * g * np.sin(theta)
    _, film, _, _, _ = _block_on_incline(theta, mu, "scaled", n, FILM())
    film_slide = film[-1, 3]
    assert abs(film_slide) <= rounding(32 * n, h * h * g)
    diffs, tols = {}, {}
    for beta in (0.05, 0.1):
        k_t = beta * m / h ** 2
        c, rows, _, _, _ = _block_on_incline(theta, mu, k_t, n)
        ln, lt, _, slide, s_e, _ = rows.T
        assert np.all(np.abs(lt) < mu * ln)  # stick at every step
        assert abs(c.friction.beta_max - beta) <= rounding(8, beta)
        assert abs(s_e[-1] + (1.0 - beta) * F / k_t) <= rounding(32, F / k_t)
        diff = slide[-1] - film_slide
        tols[beta] = (rounding(32, F / k_t) + rounding(2 * n, 2 * F / k_t)
                      + rounding(32 * n, h * h * g))
        assert abs(diff + (1.0 - beta) * F / k_t) <= tols[beta]
        diffs[beta] = abs(diff)
    ratio = diffs[0.05] / diffs[0.1]
    assert abs(ratio - 19.0 / 9.0) <= ratio * sum(tols[b] / diffs[b] for b in diffs) + \
        rounding(2, ratio)
    if COMM.rank == 0:
        print(f"\npenalty stick - FILM stick: {diffs[0.05]:.6e} m at beta 0.05, "
              f"{diffs[0.1]:.6e} m at beta 0.1: ratio {ratio:.6f} for k_t doubled "
              f"(closed form 19/9 = {19 / 9:.6f}; 1/k_t alone: 2)")


# ----------------------------------------------------------------------------- refusals

@pytest.mark.parametrize("order", ["friction first", "repairing first"])
def test_normal_bound_past_one_with_repairing_is_refused(order):
    """A normal penalty at beta 1.2 (within its own 4/3) with friction and re-pairing: the
    sequential update is stable only with the normal bound at most 1 (docs/friction.md
    4.2): refused in one line, either order of the calls; accepted when forced."""
    sim = _bars(Penalty("scaled", beta_target=1.2))
    c = sim.contacts[0]
    first, second = ((lambda: c.set_friction(0.3), lambda: c.set_repairing(1))
                     if order == "friction first" else
                     (lambda: c.set_repairing(1), lambda: c.set_friction(0.3)))
    first()
    with pytest.raises(InputError, match="passes 1, the bound under which the penalty's "
                                         "friction is stable"):
        second()
    sim = _bars(Penalty("scaled", beta_target=1.2))
    c = sim.contacts[0]
    c.set_repairing(1)
    c.set_friction(0.3, force=True)
    assert c.friction.penalty and c.friction.repairing


# ----------------------------------------------------------------------------- finite strain

def test_taylor_rod_on_an_elastic_anvil_penalty_friction():
    """The Taylor rod (finite-strain J2) at 227 m/s on the free elastic anvil
    (tests/test_taylor_anvil.py's scene, node to segment re-paired every 5 steps), the
    penalty with μ = 0.2, 400 steps (the rim yields and spreads, the rod's face segments
    turn): the cone at every loaded row and step, every re-pairing's elastic slips the
    rule's (carried with a turning segment, projected on another's), z momentum and the
    ledger within roundoff.ledger, the slip work positive."""
    from test_taylor_anvil import _anvil

    sim = _anvil(400, 227.0, "penalty")
    c = sim.contacts[0]
    c.set_friction(0.2)
    watch = _Watch(c, 0.2)
    summary = sim.run(extra=sim.scene_figures)
    assert sim.status == "completed" and summary["n_steps"] == 400
    assert sim.compiled_in_loop == []
    seen = watch.seen
    assert seen["carried"] > 0 and seen["sticks"] > 0 and seen["slips"] > 0, seen
    e = sim.energy.data()
    bound = ledger(sim.n_steps, COMM.allreduce(sim.model.n_owned))
    p = np.asarray(e["momentum_z"])
    assert np.abs(p - p[0]).max() <= bound * abs(p[0])
    assert np.abs(np.asarray(e["balance_error"])).max() <= bound * sim.ledger.E0
    assert c.friction.figures()["slip_work"] > 0.0
    if COMM.rank == 0:
        print(f"\ntaylor anvil penalty: {seen}; {c.friction.summary()}; face radius "
              f"{summary['final_face_radius']:.6e} m, length {summary['final_length']:.6e} m; "
              f"z momentum {np.abs(p - p[0]).max() / abs(p[0]):.3g}, balance "
              f"{np.abs(np.asarray(e['balance_error'])).max() / sim.ledger.E0:.3g} relative "
              f"(bound {bound:.3g})")
