"""Re-pairing node-to-segment contact in the time loop (``ContactSet.set_repairing``).

Scenes: the coaxial nu = 0 bars of tests/test_contact_nts.py, two free linear bodies
(no dof held in z), with the target's face the slave. Where the faces must slide, the
target starts with a uniform radial velocity (it breathes: its face slides along the
striker's, its rim past the striker's and back, amplitude about v_r R / c0).

Oracles:

* pairs: at every re-pairing of a run whose faces slide, the positions the set used
  are X + u^n of the owners (the owned displacements gathered in the test, the same
  addition: equal), and its pairs and rows of G are those of a brute-force projection
  of every slave onto every segment (O(N M), tests/test_contact_nts_search.py) at
  those positions, restricted to the re-pairing's reach: equal, since both run the
  same arithmetic on the same candidates in the same order;
* matching faces, nothing slides: with re-pairing every step the run equals the
  node-pair run and the run without re-pairing within the spread of a one-ulp change
  of v0 (class (c) of tests/roundoff.py: a re-pairing computes g0 = g(X + u^n) - G u^n,
  the set-up's constant by another expression, so each step differs by roundings that
  the run carries); at t = 0 the rows are the node pairs' to the round-off of a
  normal from mesh coordinates;
* momentum: z momentum to the round-off of a ledger (roundoff.ledger: the contact
  forces G' lam are equal and opposite only up to their roundings), and the energy
  balance within the same bound;
* release: the rim slave, once beyond the end of the master face, has no row and no
  force, stays in the set, and is paired again (a row, in contact) when it comes back.

Every test runs unchanged on 1, 2 and 3 ranks (the set's arrays are replicated).
"""
import math
from dataclasses import replace

import numpy as np
import pytest

from impact_fenics import meshing, scenes
from impact_fenics.bodies import Body, DeformableModel
from impact_fenics.contact import DME, FILM, Penalty
from impact_fenics.contact.segments import node_to_segment, repair_reach
from impact_fenics.materials import STEEL
from impact_fenics.simulation import Settings, Simulation
from roundoff import assert_within_spread, ledger, one_ulp, rounding
from test_contact_nts_search import _brute_force, _current_normals, _end_rule

RHO, E = 7850.0, 200e9
C0 = math.sqrt(E / RHO)
V0, L, A = 5.0, 0.2, 0.05
V_R = 20.0  # m/s, the target's initial radial velocity where the faces slide


def _settings():
    return Settings(cfl=0.9, t_end=3 * L / C0, output_every=10, quiet=True)


def _bars(method, n_striker=6, n_target=9, v_r=V_R):
    """The bars with the target (finer face, slave) breathing at v_r (m/s)."""
    tmesh = meshing.coaxial_bars_sized(radius=A, striker_length=L, target_length=L,
                                       h_striker=A / n_striker, h_target=A / n_target)
    material = replace(STEEL, nu=0.0)
    model = DeformableModel(tmesh, [Body("striker", material), Body("target", material)])
    sim = Simulation(model, _settings(),
                     initial_velocity={"striker": (0.0, V0), "target": (v_r, 0.0)})
    sim.add_contact(node_to_segment(model, "target_contact", "striker_contact"), method)
    return sim


def _owned_u(sim):
    """u (m) of every global dof, from the owners, on every rank."""
    return np.concatenate(sim.comm.allgather(sim.integrator.u_owned.copy()))


class _Watch:
    """Checks every re-pairing of a run against the brute force, and records, per
    re-pairing, the step, which slaves have a row and their forces after the step."""

    def __init__(self, sim):
        self.sim, self.c = sim, sim.contacts[0]
        self.steps, self.rows, self.changed = [], [], 0
        self.u_n = None  # u^0 = 0 until the first step's end
        integ = sim.integrator
        advance, repair = integ.advance, self.c._repair

        def advance_and_record():
            advance()
            self.u_n = _owned_u(sim)

        def checked_repair():
            repair()
            self._check()

        integ.advance = advance_and_record
        self.c._repair = checked_repair
        self.seg0 = self.c.constraints.seg.copy()

    def _check(self):
        c = self.c
        cons = c.constraints
        u_n = np.zeros(int(cons.dofs.max()) + 1) if self.u_n is None else self.u_n
        # the positions: X + u^n of the owners, the same addition
        for x, xy0, dofs in ((c._slave_x, cons.slave_xy, cons.slave_dofs),
                             (c._master_x, cons.master_xy, cons.master_dofs)):
            assert np.array_equal(x[:, 0], xy0[:, 0] + u_n[dofs[:, 0]])
            assert np.array_equal(x[:, 1], xy0[:, 1] + u_n[dofs[:, 1]])
        # the pairs: the brute force within the re-pairing's reach
        p, reach = c._repairing.pairs, c._repairing.reach
        seg, xi, normal, g, kind, dist = _brute_force(cons, c._slave_x, c._master_x,
                                                      _current_normals(cons, c._master_x))
        near = dist <= reach
        released, kind, normal, g = _end_rule(cons, np.where(near, seg, -1), xi, kind, normal,
                                              g, c._slave_x, c._master_x,
                                              c._repairing.end_tol)
        assert np.array_equal(p.seg[~near], np.full((~near).sum(), -1))
        for name, got, want in (("seg", p.seg, seg), ("xi", p.xi, xi),
                                ("normal", p.normal, normal), ("gap", p.gap, g),
                                ("kind", p.kind, kind)):
            assert np.array_equal(got[near], want[near]), name
        rows = ~released
        assert np.array_equal(p.active, rows)
        # the rows of G the step uses: (n, -N_a n, -N_b n) on (slave, a, b); none else
        ns = cons.slave_xy.shape[0]
        a, b = cons.segments[seg[rows], 0], cons.segments[seg[rows], 1]
        k = np.flatnonzero(rows)
        want_cs = np.stack([2 * k, 2 * k + 1, 2 * (ns + a), 2 * (ns + a) + 1, 2 * (ns + b),
                            2 * (ns + b) + 1], axis=1)
        na, nb = 1.0 - xi[rows], xi[rows]
        nr, nz = normal[rows, 0], normal[rows, 1]
        want_cc = np.stack([nr, nz, -na * nr, -na * nz, -nb * nr, -nb * nz], axis=1)
        assert np.array_equal(c.cs[rows], want_cs)
        assert np.array_equal(c.cc[rows], want_cc)
        assert np.all(c.cc[~rows] == 0.0)
        self.changed += int(np.count_nonzero(p.seg != self.seg0))
        self.steps.append(self.sim.integrator.n)
        self.rows.append(rows.copy())


@pytest.fixture(scope="module", params=["film", "dme", "penalty"])
def sliding(request):
    """A run whose faces slide, re-paired every step, every re-pairing checked."""
    method = {"film": FILM, "dme": lambda: DME(restitution=0.0),
              "penalty": lambda: Penalty("scaled")}[request.param]()
    sim = _bars(method)
    sim.contacts[0].set_repairing(1)
    watch = _Watch(sim)
    forces = []
    step = sim.contacts[0].step

    def step_and_record():
        step()
        forces.append(sim.contacts[0].force.copy())

    sim.contacts[0].step = step_and_record
    summary = sim.run()
    return sim, watch, np.array(forces), summary


def test_pairs_are_the_brute_force_at_every_repairing(sliding):
    sim, watch, _, _ = sliding
    assert len(watch.steps) == sim.n_steps == sim.contacts[0].repairs  # every step
    assert watch.changed > 0  # the faces slid: slaves changed segments


@pytest.mark.parametrize("method", ["film", "dme", "penalty"])
def test_repairing_compiles_nothing_in_the_loop(method):
    """Every kernel of a re-pairing is loaded at set-up (set_repairing)."""
    make = {"film": FILM, "dme": lambda: DME(restitution=0.0),
            "penalty": lambda: Penalty("scaled")}[method]
    sim = _bars(make())
    sim.contacts[0].set_repairing(3)
    sim.run()
    assert sim.compiled_in_loop == []
    assert sim.contacts[0].repairs == -(-sim.n_steps // 3)  # steps 0, 3, 6, ...


def test_momentum_and_ledger_with_repairing(sliding):
    sim, _, _, summary = sliding
    energy = sim.energy.data()
    p = energy["momentum_z"]
    bound = ledger(summary["n_steps"], summary["n_dofs"])
    assert np.abs(p - p[0]).max() <= bound * abs(p[0])
    assert summary["energy_balance_error_rel"] <= bound
    method = sim.contacts[0].method
    if method.name == "penalty":  # p bounded over every row: the rows used stay stable
        assert method.info["beta_max"] < method.info["beta_bound"]


def test_a_slave_past_the_end_is_released_and_paired_again(sliding):
    sim, watch, forces, _ = sliding
    c = sim.contacts[0]
    rows = np.array(watch.rows)  # (steps, slaves)
    rim = int(np.argmax(c.constraints.slave_xy[:, 0]))  # the target's rim node
    out = ~rows[:, rim]
    assert out.any()  # it slid past the striker's rim
    assert np.all(forces[out, rim] == 0.0)  # no row, no force
    back = np.flatnonzero(rows[:, rim] & (np.cumsum(out) > 0))
    assert back.size  # paired again after a release
    assert np.any(forces[back, rim] > 0.0)  # and in contact again
    assert rows.shape[1] == c.n  # kept: the set's slaves never change


# ----------------------------------------------------------------------------- no sliding

def _penalty_for_both():
    """A penalty stiffness (N/m) that both the re-pairing and the fixed set accept: the
    smallest of the fixed set's scaled choice (each row at beta_ii <= 1)."""
    sim = scenes.bar_impact_sized(_settings(), Penalty("scaled"), n_striker=5, n_target=5)
    return float(np.min(sim.contacts[0].method.p))


METHODS = {"film": FILM, "dme": lambda: DME(restitution=0.0)}


@pytest.mark.parametrize("method", ["film", "dme"])
def test_matching_faces_repaired_every_step(method):
    """Matching 5/5 faces with nu = 0, FILM and DME: the gaps are closed exactly, the faces
    stay flat and matched (nothing slides, nothing tilts), so re-pairing every step
    changes the arithmetic only: against the same run without re-pairing and against
    node pairs, within the spread of a one-ulp change of v0."""
    make = METHODS[method]

    def run(node_to_node=False, repair=0, v0=V0):
        sim = scenes.bar_impact_sized(_settings(), make(), n_striker=5, n_target=5,
                                      node_to_node=node_to_node, v0=v0)
        if repair:
            sim.contacts[0].set_repairing(repair)
            first = sim.contacts[0]
            first._repair()  # the rows at t = 0 (the run's first step makes them again)
            _assert_node_pairs(first)
        sim.run()
        return sim

    on, off, nn = run(repair=1), run(), run(node_to_node=True)
    off_ulp, nn_ulp = run(v0=one_ulp(V0)), run(node_to_node=True, v0=one_ulp(V0))
    n = on.n_steps
    assert on.contacts[0].repairs == n + 1
    assert np.all(on.contacts[0].has_row)
    ho, eo = on.history.data(), on.energy.data()
    for ref, ulp in ((off, off_ulp), (nn, nn_ulp)):
        hr, hu = ref.history.data(), ulp.history.data()
        assert np.array_equal(ho["n_active"], hr["n_active"])
        assert_within_spread(ho["contact_force"], hr["contact_force"], hu["contact_force"], n,
                             "contact_force")
        er, eu = ref.energy.data(), ulp.energy.data()
        scale = np.abs(er["total"]).max()
        for col in ("kinetic", "strain", "contact_work"):
            assert_within_spread(eo[col], er[col], eu[col], n, col, scale)


def test_matching_faces_penalty_follows_the_tilt():
    """The penalty on the same faces: a uniform p lets nodes of unequal mass penetrate
    unequally, so the master face tilts by theta ~ (difference of penetrations) / h and
    the re-paired normals follow it (the set-up's stay axial): a geometric change, not
    round-off. A gap differs from the fixed rows' by the tilt times the slave's offset
    from its contact point (zero on matched nodes) plus (1 - cos theta) times the
    penetration, so the force of a step differs at most by theta of the force; the run
    stays within theta_max (the largest sin theta a re-pairing made) of the largest
    force, and the set's activation is the same."""
    p = _penalty_for_both()

    def run(repair):
        sim = scenes.bar_impact_sized(_settings(), Penalty(p), n_striker=5, n_target=5)
        tilt = [0.0]
        if repair:
            c = sim.contacts[0]
            c.set_repairing(repair)
            repair_ = c._repair

            def watched():
                repair_()
                tilt[0] = max(tilt[0], float(np.abs(c.cc[:, 0]).max()))
            c._repair = watched
        sim.run()
        return sim, tilt[0]

    (on, theta), (off, _) = run(1), run(0)
    ho, hf = on.history.data(), off.history.data()
    assert 0.0 < theta < 1e-2  # the faces tilt, a little
    assert np.array_equal(ho["n_active"], hf["n_active"])
    scale = np.abs(hf["contact_force"]).max()
    assert np.abs(ho["contact_force"] - hf["contact_force"]).max() <= theta * scale


def _assert_node_pairs(c):
    """At t = 0 on matching faces each slave's row is a node pair's: xi snapped to a
    segment end, n = (0, 1) (out of the striker, up into the target's face) up to the
    round-off of a normal from coordinates (a difference of r and z of size A over a
    segment's length A/5, its square root: about 8 roundings of 1), and g0 zero up to a
    gap's roundings on coordinates of size A (6 products and sums: 12)."""
    assert np.all(c.has_row)
    xi = c._repairing.pairs.xi
    assert np.all((xi == 0.0) | (xi == 1.0))
    one = np.where(xi == 0.0, 1, 2)  # the column pair of the master node the slave sits on
    rows = np.arange(c.n)
    normal = c.cc[:, :2]
    assert np.abs(normal[:, 0]).max() <= rounding(8)
    assert np.abs(normal[:, 1] - 1.0).max() <= rounding(8)
    assert np.array_equal(c.cc[rows, 2 * one], -normal[:, 0])
    assert np.array_equal(c.cc[rows, 2 * one + 1], -normal[:, 1])
    assert np.abs(c.g0).max() <= rounding(12, A)


def test_repairing_refuses_bad_input():
    from impact_fenics.errors import InputError

    sim = scenes.bar_impact_sized(_settings(), FILM(), n_striker=5, n_target=5)
    with pytest.raises(InputError, match="repair_every = -1"):
        sim.contacts[0].set_repairing(-1)
    sim = scenes.bar_impact_sized(_settings(), FILM(solver="dense"), n_striker=5, n_target=5)
    with pytest.raises(InputError, match="band solver"):
        sim.contacts[0].set_repairing(1)
    nn = scenes.bar_impact_sized(_settings(), FILM(), n_striker=5, n_target=5,
                                 node_to_node=True)
    with pytest.raises(InputError, match="node-to-segment"):
        nn.contacts[0].set_repairing(1)


def test_repair_reach_is_two_segments():
    sim = scenes.bar_impact_sized(_settings(), FILM(), n_striker=6, n_target=9)
    assert repair_reach(sim.contacts[0].constraints) == pytest.approx(2 * A / 6, rel=1e-12)


@pytest.mark.parametrize("method", ["film", "dme"])
def test_equal_radius_rims_stay_paired(method):
    """Non-matching 6/9 faces of equal radius, nothing breathing: the rims meet at a corner,
    and the tilted re-paired normals move the slave rim node radially by about 1e-8 m,
    past the master's end vertex by far less than the end tolerance (1 % of a segment,
    8e-5 m): it stays on the face's continuation at every re-pairing (no slave ever
    loses its row), and the run follows the fixed rows'. A re-paired row differs from
    the set-up's by the tilt theta of its normal (and the slave's offset from its
    contact point times theta), so the multipliers, which solve S lam = -g~ with S and
    g~ changed by O(theta) relative, and the force of a step differ by at most theta_max
    (the largest sin theta a re-pairing made) of the largest force."""
    make = METHODS[method]

    def run(repair):
        sim = _bars(make(), v_r=0.0)
        c = sim.contacts[0]
        seen = {"tilt": 0.0, "without_row": 0}
        if repair:
            c.set_repairing(repair)
            repair_ = c._repair

            def watched():
                repair_()
                seen["tilt"] = max(seen["tilt"], float(np.abs(c.cc[:, 0]).max()))
                seen["without_row"] += int(np.count_nonzero(~c.has_row))
            c._repair = watched
        sim.run()
        return sim.history.data(), seen

    (on, seen), (off, _) = run(1), run(0)
    assert seen["without_row"] == 0
    assert 0.0 < seen["tilt"] < 1e-2
    assert np.array_equal(on["n_active"], off["n_active"])
    scale = np.abs(off["contact_force"]).max()
    assert np.abs(on["contact_force"] - off["contact_force"]).max() <= seen["tilt"] * scale


def _scene_with(tmp_path, extra):
    """scenes/nts_bars.toml with ``extra`` added to its [[contact]], written by rank 0."""
    import os

    from mpi4py import MPI

    from scene_texts import ROOT

    text = open(os.path.join(ROOT, "scenes", "nts_bars.toml")).read()
    path = os.path.join(MPI.COMM_WORLD.bcast(str(tmp_path)), "repaired.toml")
    if MPI.COMM_WORLD.rank == 0:
        with open(path, "w") as f:
            f.write(text.replace('restitution = 0.0 ', f'{extra}\nrestitution = 0.0 '))
    MPI.COMM_WORLD.barrier()
    return path


def test_scene_file_repair_every(tmp_path):
    """`repair_every = 3` in a node-to-segment [[contact]]: the set re-pairs every third
    step of the run (the scene reader calls set_repairing), and the ledger balances to
    round-off as the Python route's does."""
    from impact_fenics import scene_file

    scene = scene_file.read_scene(_scene_with(tmp_path, "repair_every = 3"))
    assert scene.contacts[0].repair_every == 3
    sim = scene_file.build(scene, {"quiet": True, "t_end": 2e-5})
    c = sim.contacts[0]
    assert c.repair_every == 3
    sim.run()
    assert c.repairs == -(-sim.n_steps // 3)  # steps 0, 3, 6, ...
    s = sim.energy.data()
    n_dofs = sim.comm.allreduce(sim.integrator.mass.size)
    assert abs(s["balance_error_rel"][-1]) <= ledger(sim.n_steps, n_dofs)


@pytest.mark.parametrize("value", ["0", "-1", "1.5", '"often"'])
def test_scene_file_repair_every_refused(tmp_path, value):
    """A count >= 1, else one line naming the key."""
    from impact_fenics import scene_file
    from impact_fenics.errors import InputError

    with pytest.raises(InputError, match=r"\[contact #1\] repair_every.*integer >= 1"):
        scene_file.read_scene(_scene_with(tmp_path, f"repair_every = {value}"))
