"""A rigid part of prescribed velocity (docs/friction.md 12): serial and mpirun -n 2, 3.

The scene: the coarse punch block, free but for its axis, under a flat rigid face of
radius 1 m (penalty, FILM and DME). The oracles do not come from the code under test:

(a) exact equivalences: a prescribed velocity 0 is the fixed part bit for bit (the same
    expressions: h/m = m/h = 0 at its slot, v = 0 added); and Galilean invariance: the
    punch driven down at V against the block at rest is, relative to the punch, the
    fixed punch hit by the block moving up at V. The two runs differ by round-off at
    every step (K u of the drifting state, the positions' sums), compared by the
    project's whole-run rule (tests/roundoff.py, assert_within_spread: the spread of a
    one-ulp change of V, plus a step's 32 roundings of the quantity, times the steps);
(b) the energy ledger closes with the motion's work booked, to the ledger's bound
    (roundoff.ledger, drifting: the block is pushed away);
(c) conservation of momentum: the reaction impulse sum h R^n on the punch is minus the
    block's momentum change, and the motion's work is V times it.
"""
import numpy as np
import pytest

from mpi4py import MPI

from impact_fenics.bodies import Body, DeformableModel
from impact_fenics.contact import DME, FILM, Penalty, RigidBody, rigid_face
from impact_fenics.contact.prescribed import PrescribedVelocity, crosshead, prescribed_velocity
from impact_fenics.errors import InputError
from impact_fenics.materials import STEEL
from impact_fenics.simulation import Settings, Simulation
from roundoff import EPS, assert_within_spread, ledger, one_ulp

V = 2.0  # m/s, the punch's speed
N_STEPS = 40
COMM = MPI.COMM_WORLD
METHODS = {"penalty": lambda: Penalty("scaled", beta_target=0.9), "film": FILM, "dme": DME}


def _run(mesh, method: str, body_v: float, punch: RigidBody, separate: bool = False,
         friction: float = 0.0):
    """The block (initial z velocity ``body_v``) under ``punch``; (sim, summary).
    ``separate``: the step as three calls with the part in Python (use_separate_calls);
    ``friction``: Coulomb's mu on the punch's face."""
    model = DeformableModel(mesh, [Body("block", STEEL)])
    sim = Simulation(model, Settings(cfl=0.9, n_steps=N_STEPS, output_every=1,
                                     quiet=True, plots=False),
                     initial_velocity={"block": (0.0, body_v)} if body_v else None)
    c = sim.add_contact(rigid_face(model, "surface", 1.0, "punch"), METHODS[method](),
                        rigid=punch)
    if separate:
        c.use_separate_calls()
    if friction:
        c.set_friction(friction)
    return sim, sim.run()


def _prescribed(v: float) -> RigidBody:
    return RigidBody("punch", np.inf, prescribed=prescribed_velocity("punch", v))


def _z(sim) -> np.ndarray:
    return sim.model.body_dofs("block", 1)


@pytest.mark.parametrize("method", list(METHODS))
def test_a_prescribed_velocity_0_is_the_fixed_part_bit_for_bit(punch_mesh, method):
    fixed, s_fixed = _run(punch_mesh, method, V, RigidBody("punch", 1.0, fixed=True))
    still, s_still = _run(punch_mesh, method, V, _prescribed(0.0))
    assert s_fixed["status"] == s_still["status"] == "completed"
    assert fixed.contacts[0].any_active or fixed.track.first is not None  # contact was made
    for a, b in ((fixed.integrator.u_owned, still.integrator.u_owned),
                 (fixed.integrator.v_owned, still.integrator.v_owned)):
        assert np.array_equal(a, b)
    e_fixed, e_still = fixed.energy.data(), still.energy.data()
    assert list(e_fixed) == list(e_still)  # a prescribed part keeps no momentum column
    for name in e_fixed:
        assert np.array_equal(e_fixed[name], e_still[name]), name
    h = still.history.data()
    assert np.all(h["punch_u"] == 0.0) and np.all(h["punch_v"] == 0.0)
    assert s_still["rigid_bodies"]["punch"]["prescribed"] is True


@pytest.mark.parametrize("method", list(METHODS))
def test_the_separate_calls_drive_the_part_as_the_fused_call(punch_mesh, method):
    """The fused call and the three separate calls (the part predicted and committed in
    Python, RigidBody.predict/advance) evaluate the same expressions: equal bit for bit,
    state, reaction and every energy column, under a table that changes v each step."""
    law = [(0.0, 0.0), (5e-5, -V)]
    runs = [_run(punch_mesh, method, 0.0, RigidBody("punch", np.inf, prescribed=
                                                     prescribed_velocity("punch", law)),
                 separate=separate)[0] for separate in (False, True)]
    fused, separate = runs
    assert np.array_equal(fused.integrator.u_owned, separate.integrator.u_owned)
    assert np.array_equal(fused.integrator.v_owned, separate.integrator.v_owned)
    for table in ("energy", "history"):
        a, b = getattr(fused, table).data(), getattr(separate, table).data()
        for name in a:
            if not name.startswith("cpu_"):
                assert np.array_equal(a[name], b[name]), (table, name)
    assert fused.history.data()["punch_reaction"].max() > 0.0


@pytest.mark.parametrize("mu", [0.0, 0.3], ids=["frictionless", "mu0.3"])
@pytest.mark.parametrize("method", list(METHODS))
def test_galilean_invariance_and_the_ledger(punch_mesh, method, mu):
    """With friction too: the tangential (r) law sees the relative r velocity and the
    normal force, both the same in the two frames (the platen squeezing a cylinder)."""
    lab, s_lab = _run(punch_mesh, method, 0.0, _prescribed(-V), friction=mu)
    frame, _ = _run(punch_mesh, method, V, _prescribed(0.0), friction=mu)
    nudged, _ = _run(punch_mesh, method, one_ulp(V), _prescribed(0.0), friction=mu)
    if mu:  # the face spreads under the punch and friction holds it: rows stick and slip
        rows = lab.history.data()
        assert rows["tangential_force"].max() > 0.0 and rows["n_slip"].max() > 0.0
        assert rows["n_stick"].max() > 0.0
    assert s_lab["status"] == "completed"
    punch = lab.contacts[0].rigid
    # the punch moved by -V t exactly per step (a constant: v^{n+1/2} = V, u += h V)
    t_end = lab.integrator.t
    assert abs(punch.u + V * t_end) <= N_STEPS * EPS * V * t_end  # a rounding a step
    assert punch.v == -V
    z = _z(lab)
    for name, got, ref, pert, shift in (
            ("u", lab.integrator.u_owned, frame.integrator.u_owned, nudged.integrator.u_owned,
             punch.u),
            ("v", lab.integrator.v_owned, frame.integrator.v_owned, nudged.integrator.v_owned,
             punch.v)):
        rel = got.copy()
        rel[z] -= shift  # relative to the punch
        # the quantity's scale is the lab's (|u| ~ V t, |v| ~ V): its roundings are on it
        assert_within_spread(rel, ref, pert, N_STEPS, f"{method} {name} relative to the punch",
                             scale=float(np.abs(got).max()) + abs(shift))
    # (b) the ledger closes with the motion's work booked (as the punch's external work)
    e = lab.energy.data()
    assert e["external_work"][-1] > 0.0  # the punch does work on the block
    assert np.all(np.abs(e["balance_error_rel"]) <= ledger(N_STEPS, s_lab["n_dofs"],
                                                            drifting=True))
    # (c) momentum: sum h R^n = -(p^N - p^0) of the block. Each step's K u sums to zero
    # over the z dofs in exact arithmetic (a translation strains nothing); in floats the
    # roundings are the ledger's (roundoff.ledger, drifting: a row of K on |K| |u|, |u|
    # growing as n h |v|, its impulse h |K u| within (omega h)^2 = 4 of m |v| n), counted
    # on the momentum scale sum m |v| instead of the energy's
    h = lab.history.data()  # a row after each step (1 ... N), h["dt"] its step
    impulse = float(np.sum(h["dt"] * h["punch_reaction"]))
    p_block = e["momentum_z_block"]  # the block starts at rest: p^0 = 0
    mv = lab.comm.allreduce(float(np.dot(lab.integrator.mass[z],
                                         np.abs(lab.integrator.v_owned[z]))))
    tol = ledger(N_STEPS, s_lab["n_dofs"], drifting=True) * mv
    assert p_block[-1] < 0.0
    assert abs(impulse + p_block[-1]) <= tol, (impulse, p_block[-1], tol)
    # the motion's work, -sum h 1/2 (v^{n-1/2} + v^{n+1/2}) R^n at v = -V: V times the impulse
    assert abs(e["external_work"][-1] - V * impulse) <= rounding_of_sum(h, V)
    assert s_lab["rigid_bodies"]["punch"] == {"prescribed": True, "u": punch.u, "v": -V,
                                              "reaction": punch.reaction}


def _run_scene(tmp_path, name: str, text: str):
    """``impact-fenics run`` of scene ``text`` (written as NAME.toml): (the process, the
    run directory, its history.csv)."""
    from scene_texts import launch, read_history

    scene = tmp_path / f"{name}.toml"
    scene.write_text(text)
    out = tmp_path / f"{name}_out"
    proc = launch(["run", scene, "--out", out], timeout=600)
    assert proc.returncode == 0, proc.stderr[-2000:]
    return proc, out, read_history(out)


def rounding_of_sum(h, v) -> float:
    """The two sums of v h R over the N steps (the ledger's running sums, the history's
    np.sum) round each term (3: the ledger's products 1/2 h (v + v) R) and each partial sum
    (at most N a sum, each within the sum of the |terms|): EPS (2 N + 3) v sum |h R|."""
    return (2 * N_STEPS + 3) * EPS * v * float(np.sum(np.abs(h["dt"] * h["punch_reaction"])))


def test_the_table_moves_the_part_by_its_integral():
    """v linear between points, held after the last: the step's mean is the exact integral
    (trapezoids of a linear v), so sum h v^{n+1/2} telescopes to int_0^t v dt."""
    law = PrescribedVelocity("p", points=[(0.0, 0.0), (1e-3, -2.0), (3e-3, -2.0), (4e-3, 1.0)])
    t, u, h = 0.0, 0.0, 0.37e-3
    for _ in range(20):  # steps that straddle the points, and past the last
        u += h * law.mean(t, h)
        t += h
    # int_0^t v: 1/2 (1e-3)(-2) + (2e-3)(-2) + 1/2 (1e-3)(-2 + 1) + (t - 4e-3)(1)
    exact = -1e-3 - 4e-3 - 0.5e-3 + (t - 4e-3)
    assert abs(u - exact) <= 20 * 8 * EPS * 1e-2  # 8 roundings a step on |u|, |h v| <= 1e-2 m
    assert law(2e-3) == -2.0 and law(5e-3) == 1.0 and law(0.5e-3) == -1.0


def test_refusals():
    law = prescribed_velocity("punch", -1.0)
    for kw in (dict(v=1.0), dict(impedance=1e3), dict(v_x=1.0), dict(fixed=True)):
        with pytest.raises(InputError, match="a prescribed velocity takes no"):
            RigidBody("punch", np.inf, prescribed=law, **kw)
    with pytest.raises(InputError, match="increase strictly"):
        PrescribedVelocity("p", points=[(0.0, 1.0), (0.0, 2.0)])
    for speed, t_ramp in ((0.0, 1e-6), (1.0, 0.0), (-1.0, 1e-6)):
        with pytest.raises(InputError, match="crosshead's speed"):
            crosshead("platen", speed, t_ramp)


def test_crosshead_is_the_ramp_table():
    """A crosshead (speed 2 m/s, ramp 1e-4 s) is the table [(0, 0), (1e-4, -2)]: -V t / t_r
    on the ramp, -V after, and its stroke -V t^2 / (2 t_r), then -V (t - t_r / 2), in
    closed form to at most five roundings (on the ramp the interpolation's two and the
    trapezoid's product, the closed form's two; after it fewer), each within EPS / 2 of
    the stroke: 2.5 EPS, 4 EPS allowed."""
    law, table = crosshead("platen", 2.0, 1e-4), prescribed_velocity("p", [(0.0, 0.0),
                                                                          (1e-4, -2.0)])
    for t in (0.0, 2.5e-5, 1e-4, 3e-4):
        assert law(t) == table(t) and law.displacement(t) == table.displacement(t)
        stroke = -t * t / 1e-4 if t <= 1e-4 else -2.0 * (t - 0.5e-4)
        assert abs(law.displacement(t) - stroke) <= 4 * EPS * abs(stroke)
    assert law(5e-5) == -1.0 and law(1.0) == -2.0


@pytest.mark.skipif(COMM.size > 1, reason="launches its own runs")
def test_scene_key_prescribed_velocity(tmp_path):
    """[rigid.NAME] prescribed_velocity: a table drives the punch into the block from the
    command line; the history has its u, v and reaction, the summary says it is
    prescribed, its stroke is the table's integral (a rounding a step: the step's mean
    times h into a running sum), the ledger closes (the run's own check). A mass with it,
    a bad table and a force on it are refused in one line."""
    import json

    from scene_texts import RIGID, assert_refused, replace

    base = RIGID[:RIGID.index("[[loads]]")] + RIGID[RIGID.index("[time]"):]  # no force
    text = replace(base, "mass = 0.1\n", "prescribed_velocity = [[0.0, 0.0], [1e-6, -1.0]]\n")
    proc, out, h = _run_scene(tmp_path, "drive", text)
    t = h["time"]
    stroke = np.where(t <= 1e-6, -0.5 * t ** 2 / 1e-6, -0.5e-6 - (t - 1e-6))  # int_0^t v dt
    assert np.all(np.abs(h["punch_u"] - stroke) <= 8 * EPS * np.arange(1, t.size + 1) * 1e-6)
    assert h["punch_v"][-1] == -1.0 and h["punch_reaction"].max() > 0.0
    end = json.loads((out / "summary.json").read_text())["rigid_bodies"]["punch"]
    assert end["prescribed"] is True and end["u"] == h["punch_u"][-1]
    assert "rigid punch: prescribed" in proc.stdout
    # in plane strain (y), a constant: v^{n+1/2} = V, u^n = -V t^n to a rounding a step
    plane = replace(replace(replace(base, "mass = 0.1\n", "prescribed_velocity = -1.0\n"),
                            "radius = 0.1\n", "half_width = 0.1\n"),
                    'components = ["z"]', 'components = ["y"]')
    _, _, h = _run_scene(tmp_path, "plane", 'geometry = "plane_strain"\nthickness = 0.01\n'
                         + plane)
    assert np.all(h["punch_v"] == -1.0) and h["punch_reaction"].max() > 0.0
    assert np.all(np.abs(h["punch_u"] + h["time"]) <= 2 * EPS * h["step"]
                  * h["time"])
    for old, new, expected in (
            ("mass = 0.1\n", "mass = 0.1\nprescribed_velocity = -1.0\n",
             "error: [rigid.punch] mass with prescribed_velocity"),
            ("mass = 0.1\n", "prescribed_velocity = [[1.0]]\n",
             "error: [rigid.punch] prescribed_velocity = [[1.0]]: give a velocity")):
        bad = tmp_path / "bad.toml"
        bad.write_text(replace(base, old, new))
        assert_refused(["run", bad, "--out", tmp_path / "bad_out"], expected,
                       tmp_path / "bad_out")
    bad.write_text(replace(RIGID, "mass = 0.1\n", "prescribed_velocity = -1.0\n"))
    assert_refused(["run", bad, "--out", tmp_path / "bad_out"],
                   "error: [loads #1] rigid = \"punch\": [rigid.punch] has a prescribed_velocity",
                   tmp_path / "bad_out")


@pytest.mark.skipif(COMM.size > 1, reason="launches its own runs")
def test_a_finite_strain_upsetting_under_a_varying_step(tmp_path):
    """scenes/upsetting_finite.toml (its platen driven by a table: ramp to 0.5 m/s over
    50 us, then held), run short: the step follows the cells
    (varying), and the platen's stroke is the table's integral at every history row to a
    few roundings a step (the mean's integrals and h v: 8 on |u|; the history's time, a
    sum of the steps, 1 on t, times |v|), the reaction compressive, the ledger closed to
    its bound (the run's own check and the table's column)."""
    import json
    import os

    from scene_texts import ROOT, replace

    with open(os.path.join(ROOT, "scenes", "upsetting_finite.toml")) as f:
        text = f.read()
    # the table the stroke below integrates
    assert text.count("prescribed_velocity = [[0.0, 0.0], [50e-6, -0.5]]") == 1
    text = replace(replace(text, "t_end = 1e-3            # s", "t_end = 8e-5  # s"),
                   "n_r = 8", "n_r = 4")
    _, out, h = _run_scene(tmp_path, "upsetting", text)
    t, n = h["time"], h["step"]
    assert np.ptp(h["dt"]) > 0.0  # the step varied
    stroke = np.where(t <= 50e-6, -0.5 * 0.5 * t ** 2 / 50e-6, -12.5e-6 - 0.5 * (t - 50e-6))
    assert np.all(np.abs(h["c0_platen_u"] - stroke)
                  <= n * EPS * (8 * np.abs(stroke) + 0.5 * t))
    assert np.all(h["c0_platen_reaction"][t > 0.0] >= 0.0)  # the billet pushes it up
    e = np.genfromtxt(out / "energy.csv", delimiter=",", names=True)
    assert "momentum_z_platen" not in e.dtype.names
    n_dofs = json.loads((out / "summary.json").read_text())["n_dofs"]
    assert np.all(np.abs(e["balance_error_rel"]) <= ledger(int(n[-1]), n_dofs))
