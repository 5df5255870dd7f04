"""Two finite-strain J2 bodies in node-to-segment contact, re-paired as their faces spread.

Scene: a copper striker (z in [-4R, 0]) at v0 onto a copper target at rest (z in [0, 4R]),
R = 3.2 mm, both finite-strain J2 (total Lagrangian, Q1 quadrilaterals), contact faces of
4 and 4 intervals (matched) or 4 and 6 (non-matching; the finer face the slave), FILM or
DME, re-paired every 5 steps. The step follows the cells: a fixed dt checked against the
current cells' limit at every re-estimate, dt = 2^-24 s (a power of two: t = n dt is exact,
the last step is not clipped, so runs compared dof by dof take the same steps), or cfl x
that limit re-estimated every 10 steps (the step varies as the cells deform).

Oracles:

* z momentum: no external force acts (no dof held, no load), so it stays its initial
  value to the round-off of a ledger (roundoff.ledger: the contact forces G' lam are
  equal and opposite only up to their roundings, the finite force's rows sum to zero
  only up to theirs);
* the ledger: kinetic + strain + plastic + work_gap - contact work = E_0, the kinetic
  identity of the half-step scheme, exact for any forces, within roundoff.ledger at
  every row;
* the same under the step that follows the cells (cfl 0.5, re-estimated every 10 steps):
  momentum and the ledger within roundoff.ledger, every re-pairing the brute force's;
* re-pairing: at every re-pairing the pairs and rows of G equal a brute-force
  projection of every slave onto every segment (test_contact_repair._Watch, the same
  arithmetic: equal), and slaves change segments as the faces spread (counted);
* matched faces: FILM and DME (e = 0, mass-weighted positions) are the same
  M-projection while a constraint stays closed: the runs agree within the spread of a
  one-ulp change of v0 (class (c) of tests/roundoff.py), with the same active set at
  every step;
* low speed, nu = 0, elastic: the finite-strain run equals the small-strain run (J2 on
  Q1, B-bar, the same bodies, contact and step) to the order of the strain
  eps = v0 / c0. The two differ in the stress by O(eps) relative (Hencky's log strain
  against the linear one, the current against the reference configuration): the wave
  speed by O(eps) relative, so a front that has run c0 t arrives eps c0 t earlier or
  later; spread over a cell h it changes u and v by at most eps c0 t / h of their
  largest value. And the difference is first order: halving v0 halves it, within the
  same O(eps) factor.

* the scene file: the 4/6 bodies through `impact-fenics run` close energy.csv's balance
  and keep its z momentum within the same bound, with a fixed dt and with cfl (a varying
  step); a triangle mesh is refused in one line.

Every test runs unchanged on 1, 2 and 3 ranks (the compared arrays gathered).
"""
import math

import numpy as np
import pytest
from mpi4py import MPI

from impact_fenics import meshing, scenes
from impact_fenics.bodies import Body, DeformableModel
from impact_fenics.contact.segments import node_to_segment
from impact_fenics.materials import J2, FiniteJ2
from impact_fenics.simulation import Settings, Simulation
from impact_fenics.stepping import FollowingStep
from roundoff import assert_within_spread, ledger, one_ulp
from scene_texts import COPPER_J2, FILM_SEGMENTS_100_STEPS, Q1_BARS_MESH
from test_contact_repair import _Watch

COMM = MPI.COMM_WORLD
R = 3.2e-3  # m, the bodies' radius; each is 4 R long
E, RHO = 117e9, 8930.0  # Pa, kg/m^3: copper
C0 = math.sqrt(E / RHO)  # m/s, the bar wave speed
DT = 2.0 ** -24  # s (6.0e-8: 0.72 of the 4/6 mesh's limit at set-up, 0.78 of its
# smallest at 100 m/s; the following step checks it at every re-estimate and stops the run)
EVERY = 5  # steps between re-pairings


def _mesh(n_striker, n_target):
    return meshing.coaxial_bars_sized(radius=R, striker_length=4 * R, target_length=4 * R,
                                      h_striker=R / n_striker, h_target=R / n_target,
                                      quadrilaterals=True, comm=COMM)


def _bodies(n_striker, n_target, v0, n_steps, method, nu=0.35, finite=True, repair=True,
            tmesh=None, dt=DT):
    """The striker at v0 (m/s, +z) onto the target, n_steps of DT (to n_steps DT at 0.5 x
    the current limit with ``dt`` None: finite strain only); node to segment with the
    finer face the slave, re-paired every EVERY steps (``repair``); ``tmesh``: the mesh
    built already (runs compared dof by dof share it: one partition, one numbering)."""
    if tmesh is None:
        tmesh = _mesh(n_striker, n_target)
    material = (FiniteJ2 if finite else J2)(E=E, nu=nu, density=RHO, yield_stress=400e6,
                                            hardening=100e6)
    model = DeformableModel(tmesh, [Body("striker", material), Body("target", material)])
    settings = Settings(quiet=True, plots=False, timers=False, fields=False, energy_every=1)
    if finite:  # a finite-strain body takes the step that follows its cells (or a fixed dt)
        policy = FollowingStep(None, n_steps * DT, dt, 0.5, 10)
    else:
        settings.dt, settings.n_steps, policy = DT, n_steps, None
    sim = Simulation(model, settings, initial_velocity={"striker": (0.0, v0)}, policy=policy)
    slave, master = ("target_contact", "striker_contact")
    if n_striker > n_target:
        slave, master = master, slave
    sim.add_contact(node_to_segment(model, slave, master), scenes.make_method(method))
    if repair:
        sim.contacts[0].set_repairing(EVERY)
    active = []  # the active set's size after each step
    step = sim.contacts[0].step

    def step_and_count():
        step()
        active.append(int(sim.contacts[0].active.sum()))

    sim.contacts[0].step = step_and_count
    sim.active_counts = active
    return sim


def _gathered(sim):
    """(u, v) of every global dof (m, m/s), from the owners, on every rank."""
    integ = sim.integrator
    return (np.concatenate(COMM.allgather(integ.u_owned.copy())),
            np.concatenate(COMM.allgather(integ.v_owned.copy())))


# ----------------------------------------------------------------------------- momentum, ledger

@pytest.mark.parametrize("faces", [(4, 4), (4, 6)], ids=["matched", "non-matching"])
@pytest.mark.parametrize("method", ["film", "dme"])
def test_momentum_ledger_and_repairing(faces, method):
    """100 m/s, 300 steps (18 us: the waves cross each body twice; the striker's foot
    yields and spreads): momentum and the ledger to round-off, every re-pairing the brute
    force's, slaves changing segments."""
    sim = _bodies(*faces, 100.0, 300, method)
    watch = _Watch(sim)
    summary = sim.run()
    assert sim.status == "completed" and sim.n_steps == 300
    e = sim.energy.data()
    n_dofs = COMM.allreduce(sim.model.n_owned)
    bound = ledger(sim.n_steps, n_dofs)
    p = e["momentum_z"]
    assert np.abs(p - p[0]).max() <= bound * abs(p[0])
    assert np.abs(e["balance_error"]).max() <= bound * sim.ledger.E0
    assert e["plastic_work"][-1] > 0.1 * sim.ledger.E0  # finite strain: the foot yields
    c = sim.contacts[0]
    assert len(watch.steps) == c.repairs == 300 // EVERY  # steps 0, 5, ..., 295
    assert watch.changed > 0  # the faces spread: slaves moved to other segments
    assert summary["n_steps"] == 300


@pytest.mark.parametrize("faces", [(4, 4), (4, 6)], ids=["matched", "non-matching"])
@pytest.mark.parametrize("method", ["film", "dme"])
def test_a_step_that_follows_the_cells(faces, method):
    """100 m/s to 300 DT (18 us) at 0.5 x the current cells' limit, re-estimated every 10
    steps: the step varies; momentum and the ledger to round-off, every re-pairing the
    brute force's, the foot yields."""
    sim = _bodies(*faces, 100.0, 300, method, dt=None)
    watch = _Watch(sim)
    summary = sim.run()
    assert sim.status == "completed"
    h = sim.history.data()["dt"]
    assert len(set(h[:-1].tolist())) > 10  # re-estimated as the cells deform (the last clipped)
    e = sim.energy.data()
    n_dofs = COMM.allreduce(sim.model.n_owned)
    bound = ledger(sim.n_steps, n_dofs)
    p = e["momentum_z"]
    print(faces, method, sim.n_steps, "steps, dt", h.min(), h.max(), "momentum",
          np.abs(p - p[0]).max() / abs(p[0]), "balance",
          np.abs(e["balance_error"]).max() / sim.ledger.E0, "bound", bound)
    assert np.abs(p - p[0]).max() <= bound * abs(p[0])
    assert np.abs(e["balance_error"]).max() <= bound * sim.ledger.E0
    assert e["plastic_work"][-1] > 0.1 * sim.ledger.E0
    c = sim.contacts[0]
    assert len(watch.steps) == c.repairs == -(-sim.n_steps // EVERY)
    assert summary["n_steps"] == sim.n_steps


# ----------------------------------------------------------------------------- FILM = DME

@pytest.mark.parametrize("faces, repair", [((4, 4), True), ((4, 6), False)],
                         ids=["matched", "non-matching-unpaired"])
def test_film_equals_dme_where_every_closed_gap_is_zero(faces, repair):
    """100 m/s, 200 steps: DME (e = 0) against FILM within the spread of a one-ulp change
    of v0, the same active set at every step. They are equal wherever each active
    constraint was closed at step n (docs/node_to_segment.md): on matched faces, re-paired
    (a slave sits on a master node, where its re-paired gap stays 0), and on 4/6 faces
    kept on their first pairing. (Re-paired, 4/6 faces start a re-paired constraint from
    the exact gap of its new pairing, up to 2.8e-8 m here; FILM closes it with a velocity,
    DME without one: they differ by that gap.)"""
    runs, tmesh = {}, _mesh(*faces)
    for key, method, v0 in (("film", "film", 100.0), ("dme", "dme", 100.0),
                            ("ulp", "film", one_ulp(100.0))):
        sim = _bodies(*faces, v0, 200, method, tmesh=tmesh, repair=repair)
        sim.run()
        runs[key] = sim
    assert runs["film"].active_counts == runs["dme"].active_counts
    (uf, vf), (ud, vd), (uu, vu) = (_gathered(runs[k]) for k in ("film", "dme", "ulp"))
    n = runs["film"].n_steps
    assert_within_spread(ud, uf, uu, n, "u")
    assert_within_spread(vd, vf, vu, n, "v")


# ----------------------------------------------------------------------------- low speed

@pytest.mark.parametrize("faces", [(4, 4), (4, 6)], ids=["matched", "non-matching"])
def test_low_speed_finite_equals_small_strain(faces):
    """nu = 0, v0 = 1 and 0.5 m/s (stress about rho c0 v0 / 2 = 16 MPa, far below the
    400 MPa yield), 200 steps: the finite-strain run against the small-strain one within
    eps c0 t / h of the largest |u| and |v|, eps = v0 / c0, h the finer face's cell; the
    difference halves with v0 within the same factor."""
    n_steps, h = 200, R / max(faces)
    amplification = C0 * n_steps * DT / h  # fronts' travel over a cell (about 80)
    rel, tmesh = {}, _mesh(*faces)
    for v0 in (1.0, 0.5):
        (uf, vf), (us, vs) = (_gathered(_run(faces, v0, n_steps, finite, tmesh))
                              for finite in (True, False))
        eps = v0 / C0
        rel[v0] = (np.abs(uf - us).max() / np.abs(us).max(),
                   np.abs(vf - vs).max() / np.abs(vs).max())
        assert 0.0 < rel[v0][0] <= eps * amplification
        assert 0.0 < rel[v0][1] <= eps * amplification
    eps = 1.0 / C0
    for k in (0, 1):  # first order in the strain: the remainder is O(eps) of it
        assert abs(rel[1.0][k] / rel[0.5][k] / 2.0 - 1.0) <= eps * amplification


def _run(faces, v0, n_steps, finite, tmesh):
    sim = _bodies(*faces, v0, n_steps, "film", nu=0.0, finite=finite, tmesh=tmesh)
    sim.run()
    assert sim.n_steps == n_steps
    e = sim.energy.data()
    assert not e["plastic_work"].any()  # elastic
    return sim


# ----------------------------------------------------------------------------- the scene file

TWO_BODIES = ("""
title = "two finite-strain bars"

"""
              + Q1_BARS_MESH
              + """
"""
              + COPPER_J2
              + """
[bodies.striker]
material = "copper"
velocity = [0.0, 100.0]
strain = "finite"

[bodies.target]
material = "copper"
strain = "finite"

"""
              + FILM_SEGMENTS_100_STEPS)


def _scene(tmp_path, text):
    import os

    base = COMM.bcast(str(tmp_path), root=0)
    path = os.path.join(base, "two.toml")
    if COMM.rank == 0:
        with open(path, "w") as f:
            f.write(text)
    COMM.barrier()
    return path, os.path.join(base, "run")


FIXED_DT = "dt = 5.9604644775390625e-08     # s, 2^-24 (exact)\n"


@pytest.mark.parametrize("step", ["dt", "cfl"])
def test_the_scene_file_runs_two_finite_bodies(tmp_path, step):
    """The 4/6 bodies through `impact-fenics run`, with the fixed dt (100 steps) or cfl = 0.5
    (the step re-estimated from the cells every 10 steps, clipped to t_end): the ledger and
    z momentum of energy.csv within roundoff.ledger, the set re-paired every 5 steps, the
    foot yields, nothing compiled in the loop."""
    import json
    import os

    from impact_fenics import cli

    text = TWO_BODIES if step == "dt" else TWO_BODIES.replace(FIXED_DT, "cfl = 0.5\n")
    path, out = _scene(tmp_path, text)
    assert cli.main(["run", path, "--out", out, "--quiet"]) == 0
    with open(os.path.join(out, "summary.json")) as f:
        s = json.load(f)
    assert s["status"] == "completed"
    assert s["timing"]["compiled_in_loop"] == []  # a new step rebuilds S with loaded kernels
    if step == "dt":
        assert s["n_steps"] == 100
    else:  # 0.5 x the limit against the fixed dt's 0.72 x: more steps, and they vary
        h = np.genfromtxt(os.path.join(out, "history.csv"), delimiter=",", names=True)["dt"]
        assert s["n_steps"] > 100 and len(set(h[:-1].tolist())) > 1
    e = np.genfromtxt(os.path.join(out, "energy.csv"), delimiter=",", names=True)
    bound = ledger(s["n_steps"], s["n_dofs"])
    e0 = e["total"][0]
    assert np.abs(e["balance_error"]).max() <= bound * e0
    p = e["momentum_z"]
    assert np.abs(p - p[0]).max() <= bound * abs(p[0])
    assert e["plastic_work"][-1] > 0.0


@pytest.mark.parametrize("edit, message", [
    (("quadrilaterals = true\n", ""), 'a finite-strain body needs generator = "quad_bar" or '
     '"rod_on_anvil", or quadrilaterals = true'),
])
def test_the_scene_file_refuses(tmp_path, capsys, edit, message):
    from impact_fenics import cli

    path, out = _scene(tmp_path, TWO_BODIES.replace(*edit))
    with pytest.raises(SystemExit) as stop:
        cli.main(["run", path, "--out", out, "--quiet"])
    assert stop.value.code == 2
    err = capsys.readouterr().err
    if COMM.rank == 0:
        assert message in err and "Traceback" not in err
