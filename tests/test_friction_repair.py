"""Coulomb friction (FILM, DME) on node-to-segment contact re-paired in the time loop
(``ContactSet.set_repairing`` with ``ContactSet.set_friction``; docs/friction.md 10).

Scenes: the bars of tests/test_contact_repair.py (the coaxial nu = 0 bars, two free linear
bodies, the target's face the slave; where the faces must slide the target breathes at a
uniform radial velocity, its face sliding along the striker's, slaves changing segments
and the rim slave released past the master's end and paired again), and the steel and
aluminium bars of tests/test_friction.py as slave/master on matched faces.

Oracles:

* μ = 0 with re-pairing makes no tangential pass: the run equals the frictionless
  re-paired run, every column, bit for bit (one process, one partition);
* matching nu = 0 faces, nothing slides: with friction and re-pairing every step the run
  equals the run with friction without re-pairing within the spread of a one-ulp change
  of v0 (class (c) of tests/roundoff.py, as tests/test_contact_repair.py states it);
* matched steel and aluminium faces under "stick" and μ = 0.3 (no pair changes: the
  faces stay together): the re-paired normals follow the faces' tilt θ (the set-up's stay
  axial), a geometric change: a re-paired row is the set-up's turned by θ, which mixes
  the normal and tangential multipliers by sin θ, so the forces differ by at most
  θ_max (max |F_n| + max |F_t|);
* the breathing bars with μ = 0.3, re-paired every step (slaves change segments): at every
  step and row the cone |λ_t| <= μ λ_n (1 + 1e-12), the slip work of the row
  -h_n λ_t w_t^{n+1/2} >= 0 (the force opposes the slip: exactly on the cone; in stick
  w = 0 within the band solve's round-off), a released slave (no row) has λ_t = 0; the
  balance and z momentum within roundoff.ledger (the r momentum is not conserved on an
  axisymmetric body); nothing compiles in the loop;
* refusals in one line: restitution e > 0 (the penalty's friction with re-pairing:
  tests/test_friction_penalty_segments.py).

Every test runs unchanged on 1, 2 and 3 ranks (the set's arrays are replicated).
"""
import numpy as np
import pytest
from mpi4py import MPI

from impact_fenics import scenes
from impact_fenics.contact import DME, FILM
from impact_fenics.contact.friction_segments import OFF, STICK
from impact_fenics.errors import InputError
from roundoff import assert_runs_agree, assert_within_spread, ledger, one_ulp, rounding
from test_contact_repair import V0, _bars, _settings

COMM = MPI.COMM_WORLD
MU = 0.3
METHODS = {"film": FILM, "dme": lambda: DME(restitution=0.0)}


def _history(sim):
    return {k: np.asarray(v) for k, v in sim.history.data().items() if not k.startswith("cpu")}


def _breathing_bars(method, v0=V0):
    """tests/test_contact_repair.py's breathing bars with the striker at ``v0`` (m/s)."""
    from dataclasses import replace

    from impact_fenics import meshing
    from impact_fenics.bodies import Body, DeformableModel
    from impact_fenics.contact.segments import node_to_segment
    from impact_fenics.materials import STEEL
    from impact_fenics.simulation import Simulation
    from test_contact_repair import A, L, V_R

    tmesh = meshing.coaxial_bars_sized(radius=A, striker_length=L, target_length=L,
                                       h_striker=A / 6, h_target=A / 9)
    material = replace(STEEL, nu=0.0)
    model = DeformableModel(tmesh, [Body("striker", material), Body("target", material)])
    sim = Simulation(model, _settings(),
                     initial_velocity={"striker": (0.0, v0), "target": (V_R, 0.0)})
    sim.add_contact(node_to_segment(model, "target_contact", "striker_contact"), method)
    return sim


def test_zero_friction_with_repairing_is_the_frictionless_run():
    """friction = 0 makes nothing (the set's friction stays None) in either order of the
    calls, and the run is the frictionless re-paired run: bit for bit on one rank
    (roundoff.assert_runs_agree; on several, two runs in one process may be partitioned
    differently, and they agree within the spread of a one-ulp change of v0)."""
    runs = []
    for order, v0 in ((None, V0), ("friction first", V0), ("repairing first", V0),
                      (None, one_ulp(V0))):
        if v0 != V0 and COMM.size == 1:
            runs.append(None)
            continue
        sim = _breathing_bars(FILM(), v0)
        c = sim.contacts[0]
        if order == "friction first":
            c.set_friction(0.0)
        c.set_repairing(1)
        if order == "repairing first":
            c.set_friction(0.0)
        assert c.friction is None
        sim.run()
        runs.append((_history(sim), {k: np.asarray(v) for k, v in sim.energy.data().items()}))
    ref, ulp, n = runs[0], runs[-1], sim.n_steps
    for got in runs[1:3]:
        for i in (0, 1):
            assert ref[i].keys() == got[i].keys()
            for k in ref[i]:
                assert_runs_agree(got[i][k], ref[i][k], None if ulp is None else ulp[i][k], n,
                                  k, None if i == 0 else np.abs(ref[1]["total"]).max())


@pytest.mark.parametrize("method", ["film", "dme"])
def test_matching_faces_repaired_every_step_with_friction(method):
    """Matching 5/5 nu = 0 faces (flat, matched, nothing slides): friction with re-pairing
    every step against friction without it, within the spread of a one-ulp change of v0;
    the same stick and slip counts."""
    make = METHODS[method]

    def run(repair=0, v0=V0):
        sim = scenes.bar_impact_sized(_settings(), make(), n_striker=5, n_target=5, v0=v0)
        c = sim.contacts[0]
        if repair:
            c.set_repairing(repair)
        c.set_friction(MU)
        sim.run()
        assert sim.compiled_in_loop == []
        return sim

    on, off, ulp = run(repair=1), run(), run(v0=one_ulp(V0))
    n = on.n_steps
    assert on.contacts[0].repairs == n
    ho, hr, hu = on.history.data(), off.history.data(), ulp.history.data()
    assert np.array_equal(ho["n_active"], hr["n_active"])
    assert np.array_equal(ho["n_stick"], hr["n_stick"])
    assert np.array_equal(ho["n_slip"], hr["n_slip"])
    assert ho["n_stick"].max() > 0  # the pass ran on loaded rows
    for col in ("contact_force", "tangential_force"):
        assert_within_spread(ho[col], hr[col], hu[col], n, col,
                             np.abs(hr["contact_force"]).max())
    eo, er, eu = on.energy.data(), off.energy.data(), ulp.energy.data()
    scale = np.abs(er["total"]).max()
    for col in ("kinetic", "strain", "contact_work"):
        assert_within_spread(eo[col], er[col], eu[col], n, col, scale)




def _steel_alu(method, law, repair):
    import os
    import tempfile

    from test_friction import SCENE
    from test_friction_segments import PAIRS, SEGMENTS

    from impact_fenics.scene_file import build, read_scene

    text = SCENE.format(method=method, friction=f"friction = {law}", v0=5.0).replace(
        PAIRS, SEGMENTS)
    if repair:  # through the scene file: its refusal is lifted for film and dme
        text = text.replace('method = "', f'repair_every = {repair}\nmethod = "')
    tmp = COMM.bcast(tempfile.mkdtemp() if COMM.rank == 0 else None)
    path = os.path.join(tmp, "bars.toml")
    if COMM.rank == 0:
        with open(path, "w") as fh:
            fh.write(text)
    COMM.barrier()
    sim = build(read_scene(path), {"quiet": True, "fields": False, "plots": False})
    c = sim.contacts[0]
    seen = {"tilt": 0.0, "changed": 0}
    if repair:
        assert c.repair_every == repair and c.friction is not None
        repair_ = c._repair
        seg0 = c.constraints.seg.copy()

        def watched():
            repair_()
            seen["tilt"] = max(seen["tilt"], float(np.abs(c.cc[:, 0]).max()))
            seen["changed"] += int(np.count_nonzero(c._repairing.pairs.seg != seg0))
        c._repair = watched
    sim.run()
    return sim.history.data(), seen


@pytest.mark.parametrize("law", ["0.3", '"stick"'])
@pytest.mark.parametrize("method", ["film", "dme"])
def test_matched_steel_aluminium_follows_the_tilt(method, law):
    """Matched faces, nu = 0.3 on 0.33 (the faces want to slide radially): re-paired every
    step, no slave changes segment; the rows turn with the faces by theta_max, so the
    normal and tangential forces differ from the fixed rows' by at most
    theta_max (max |F_n| + max |F_t|) (a frame turned by theta mixes them by sin theta);
    the same stick and slip counts."""
    (on, seen), (off, _) = _steel_alu(method, law, 1), _steel_alu(method, law, 0)
    assert seen["changed"] == 0
    assert 0.0 < seen["tilt"] < 1e-3
    assert np.array_equal(on["n_stick"], off["n_stick"])
    assert np.array_equal(on["n_slip"], off["n_slip"])
    bound = seen["tilt"] * (np.abs(off["contact_force"]).max()
                            + np.abs(off["tangential_force"]).max())
    for col in ("contact_force", "tangential_force"):
        assert np.abs(on[col] - off[col]).max() <= bound, col


class _Rows:
    """Wraps the set's tangential pass: after each step, per row, the cone and the slip
    work's sign, and which rows a re-pairing released."""

    def __init__(self, c):
        self.c, self.f = c, c.friction
        self.step, self.f.step = self.f.step, self.checked
        self.rows = self.sticks = self.slips = self.released = 0
        self.d_min = 0.0

    def checked(self) -> float:
        c, f = self.c, self.f
        w_t = self.step()
        lam, state = f.lam, f.state
        on = state != OFF
        assert np.all(lam[~on] == 0.0)
        assert np.all(lam[~c.has_row] == 0.0)  # a released slave: no row, no force
        assert np.all(np.abs(lam[on]) <= MU * c.force[on] * (1.0 + 1e-12))
        # the slip work of each row, -h_n λ_t w_t^{n+1/2}: >= 0 on the cone (the box's clip
        # and the pivoting's sign test) and in stick within the round-off of w = 0, a band
        # solve (4 (bw + 1) roundings) and T v (12 on its terms |t_k| |v_k|)
        d = -c.h_avg * lam * f.w_next
        tv = (np.abs(f.ct) * np.abs(c.v[c.cs])).sum(axis=1)
        stick = state == STICK
        tol = c.h_avg * np.abs(lam) * rounding(4 * (f.bw + 1) + 12, tv)
        assert np.all(d[on & ~stick] >= 0.0)
        assert np.all(d[stick] >= -tol[stick])
        self.d_min = min(self.d_min, float(d.min(initial=0.0)))
        self.rows += int(on.sum())
        self.sticks += int(stick.sum())
        self.slips += int((on & ~stick).sum())
        self.released += int((~c.has_row).sum())
        return w_t


@pytest.fixture(scope="module", params=["film", "dme"])
def breathing(request):
    """The breathing bars with μ = 0.3, re-paired every step, every row checked."""
    sim = _bars(METHODS[request.param]())
    c = sim.contacts[0]
    c.set_repairing(1)
    c.set_friction(MU)
    seg0 = c.constraints.seg.copy()
    changed = [0]
    repair_ = c._repair

    def watched():
        repair_()
        changed[0] += int(np.count_nonzero(c._repairing.pairs.seg != seg0))
    c._repair = watched
    rows = _Rows(c)
    summary = sim.run()
    return sim, rows, summary, changed[0]


def test_breathing_bars_cone_and_slip_work(breathing):
    sim, rows, _, changed = breathing
    assert sim.contacts[0].repairs == sim.n_steps
    assert changed > 0  # slaves changed segments
    assert rows.released > 0  # the rim slave left the master face
    assert rows.sticks > 0 and rows.slips > 0
    h = sim.history.data()
    assert np.all(np.diff(np.asarray(h["slip_work"])) >= 0.0)
    assert sim.compiled_in_loop == []


def test_breathing_bars_momentum_and_ledger(breathing):
    sim, _, summary, _ = breathing
    e = sim.energy.data()
    bound = ledger(summary["n_steps"], summary["n_dofs"])
    p = np.asarray(e["momentum_z"])
    assert np.abs(p - p[0]).max() <= bound * abs(p[0])
    assert summary["energy_balance_error_rel"] <= bound
    assert sim.history.data()["slip_work"][-1] > 0.0


def test_restitution_with_friction_and_repairing_is_refused():
    sim = _bars(DME(restitution=0.5))
    c = sim.contacts[0]
    c.set_repairing(1)
    with pytest.raises(InputError, match="re-pairing and restitution e > 0 is not built"):
        c.set_friction(MU)


# ----------------------------------------------------------------------------- finite strain

@pytest.mark.parametrize("method", ["film", "dme"])
def test_taylor_rod_on_an_elastic_anvil_with_friction(method):
    """The Taylor rod (finite-strain J2) at 227 m/s on the free elastic anvil
    (tests/test_taylor_anvil.py's scene: node to segment re-paired every 5 steps), μ = 0.2,
    400 steps (3 us: the rim yields and spreads): z momentum and the ledger within
    roundoff.ledger; the face's rim radius below the frictionless run's (friction holds
    the foot back) and above R (it still spreads); the slip work positive."""
    from test_taylor_anvil import R, _anvil

    runs = {}
    for mu in (0.0, 0.2):
        sim = _anvil(400, 227.0, method)
        if mu:
            sim.contacts[0].set_friction(mu)
        summary = sim.run(extra=sim.scene_figures)
        assert sim.status == "completed" and summary["n_steps"] == 400
        assert sim.compiled_in_loop == []
        e = sim.energy.data()
        bound = ledger(sim.n_steps, COMM.allreduce(sim.model.n_owned))
        p = np.asarray(e["momentum_z"])
        assert np.abs(p - p[0]).max() <= bound * abs(p[0])
        assert np.abs(np.asarray(e["balance_error"])).max() <= bound * sim.ledger.E0
        runs[mu] = summary, sim
    (free, _), (rough, sim) = runs[0.0], runs[0.2]
    assert R < rough["final_face_radius"] < free["final_face_radius"]
    if COMM.rank == 0:  # the figures of docs/friction.md 10
        print(f"\n{method}: face radius {free['final_face_radius']:.6e} m (mu = 0), "
              f"{rough['final_face_radius']:.6e} m (mu = 0.2); "
              f"{sim.contacts[0].friction.figures()}; {sim.contacts[0].friction.info}")
    assert sim.contacts[0].friction.figures()["slip_work"] > 0.0
