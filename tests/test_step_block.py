"""The compiled steps between events equal the Python steps, bit for bit.

With linear bodies the loop runs its steps as compiled blocks
(impact_fenics/step_block.py): PETSc's MatMultAdd and VecAXPY called by address, the
fused contact step, the contact track, history and per-pair rows, the divergence
check, the output steps' energy sums (their rows made from the blocks' records) and,
on one rank, the frames (into the writer's batch). The oracle is the Python step (``Settings(compiled_steps=False)``),
which the wave, impact and energy tests validated against closed forms: the same
C functions and kernels on the same arrays in the same order, so every number a
run writes must be identical (no tolerance), apart from the CPU-time columns.

Scenes: a rigid punch (penalty, FILM, DME: rigid slot, the penalty's reversals),
two bars with node pairs and a probe, one bar with no contact, and three runs that
fail: a rigid body driven to a non-finite speed, and a step above the stable limit
caught by the runaway speed and by the energy's growth (the energy rows of the blocks'
output steps come from the records the blocks keep).
Under MPI the blocks call the MPI library themselves (the contact set's Allgatherv,
the check's reduction) where the Python step goes through mpi4py: the same
comparisons, on each rank's part.
"""
import os

import numpy as np
import pytest
from mpi4py import MPI

from impact_fenics import meshing, scenes
from impact_fenics.bodies import Body, DeformableModel
from impact_fenics.contact import pair_surfaces
from impact_fenics.errors import UnstableRunError
from impact_fenics.materials import STEEL
from impact_fenics.output import read_pairs
from impact_fenics.simulation import Settings, Simulation
from impact_fenics.xdmf import FieldSeries
from roundoff import ledger, rounding

COMM = MPI.COMM_WORLD
TIMED = ("ns_per_element_cycle", "f_int_seconds")  # body figures that are measured times


def _settings(out, compiled, **kw):
    base = dict(cfl=0.9, n_steps=240, output_every=25, pairs_every=3, quiet=True, plots=False,
                out=out, compiled_steps=compiled)
    base.update(kw)
    return Settings(**base)


@pytest.fixture(scope="module")
def bars_mesh():
    return meshing.coaxial_bars(radius=0.1, striker_length=0.4, target_length=0.4, h=0.04,
                                structured=False)


def _scratch(tmp_path_factory, name):
    path = str(tmp_path_factory.mktemp(name)) if COMM.rank == 0 else None
    return COMM.bcast(path, root=0)


def _written(sim) -> dict:
    """Everything the run wrote that is not a CPU time: the tables, the per-pair rows, the
    frames, the summary's physics and the final state."""
    out = sim.out_dir
    h = sim.history.data()
    got = {f"history.{k}": v for k, v in h.items() if not k.endswith(("cpu_detection",
                                                                       "cpu_solve", "cpu_update"))}
    got.update({f"energy.{k}": v for k, v in sim.energy.data().items()})
    pairs = os.path.join(out, "contact_pairs.h5")
    if os.path.exists(pairs):
        got.update({f"pairs.{k}": v for k, v in read_pairs(pairs).items()})
    if os.path.exists(os.path.join(out, "fields.xdmf")):
        series = FieldSeries(os.path.join(out, "fields.xdmf"))
        got["fields.times"] = np.asarray(series.times)
        for name in series.center:
            for k in range(len(series.times)):
                got[f"fields.{name}.{k}"] = series.values(name, k)
    s = sim.summary
    for key in ("status", "stopped_at_step", "contact", "impact", "energy", "energy_initial",
                "peak_stress"):
        got[f"summary.{key}"] = repr(s.get(key))
    # each body's figures but its time per element per cycle (a measured time)
    got["summary.bodies"] = repr({name: {k: v for k, v in body.items() if k not in TIMED}
                                  for name, body in s["bodies"].items()})
    got["track"] = repr(sim.track.as_dict())  # contact steps, penalty reversals
    integ = sim.integrator
    got["u"], got["v"] = integ.u_owned.copy(), integ.v_owned.copy()
    for c in sim.contacts:
        if c.rigid is not None:
            got["rigid"] = np.array([c.rigid.u, c.rigid.v])
    return got


def _same(make, tmp_path_factory, name, expect_contact=True, frames=None):
    """Run the scene make(out, compiled) both ways; everything written is identical.
    ``frames``: the compiled run's blocks wrote the frames (one rank), if not None."""
    runs = {}
    for compiled in (True, False):
        sim = make(os.path.join(_scratch(tmp_path_factory, name), "run"), compiled)
        sim.run()
        assert sim.compiled_steps == compiled and sim.compiled_in_loop == []
        if frames is not None:
            assert sim.compiled_frames == (compiled and frames and COMM.size == 1)
        runs[compiled] = _written(sim)
    a, b = runs[True], runs[False]
    assert a.keys() == b.keys()
    for key in a:
        assert np.array_equal(a[key], b[key]), key
    if expect_contact:
        assert max(a["history.n_active"]) > 0  # the scene has contact
    return a


@pytest.mark.parametrize("method", ["penalty", "film", "dme"])
def test_punch_compiled_steps_equal_python_steps(punch_mesh, tmp_path_factory, method):
    def make(out, compiled):
        return scenes.punch_indentation(_settings(out, compiled), scenes.make_method(method),
                                        radius=1.0, tmesh=punch_mesh)
    got = _same(make, tmp_path_factory, f"punch_{method}")
    assert "pairs.gap" in got and "fields.sigma_zz.3" in got


@pytest.mark.parametrize("method", ["penalty", "film", "dme"])
def test_a_thrown_punch_compiled_steps_equal_python_steps(punch_mesh, tmp_path_factory,
                                                          method):
    """A rigid punch thrown at the block (v = -5 m/s at t = 0, touching, no force). The
    ledger's E_0 is the initial state, the punch's 1/2 M v^2 exactly (the block at rest),
    and the first row holds the first step, where the punch meets the face's nodes (mass
    m_f, at rest, unloaded: u^0 = 0) and every one of them takes its velocity: a perfectly
    inelastic collision, whose loss 1/2 M v^2 m_f / (M + m_f) the first row books as
    contact work and activation loss (to the roundings of the slots' masses summed, of the
    step's velocities and of the booking: 4 (n_slots + 8) of the loss). (The previous
    ledger began after this step, with E_0 = 1/2 M v^0 v^1: it did not see the loss.) The
    ledger closes to round-off: each row's terms are sums over the dofs, rounded once
    each, over n_steps steps (roundoff.ledger), far below the loss."""
    from impact_fenics.contact import RigidBody, rigid_face

    mass = 1e3  # kg

    def make(out, compiled):
        model = DeformableModel(punch_mesh, [Body("block", STEEL)])
        sim = Simulation(model, _settings(out, compiled), fixed=[model.facet_dofs("bottom", 1)])
        sim.add_contact(rigid_face(model, "surface", 1.0, "punch"), scenes.make_method(method),
                        rigid=RigidBody("punch", mass, v=-5.0))
        return sim
    sims = []
    got = _same(lambda out, compiled: sims.append(make(out, compiled)) or sims[-1],
                tmp_path_factory, f"thrown_{method}")
    kinetic = 0.5 * mass * 5.0 ** 2
    assert got["summary.energy_initial"] == repr(kinetic)  # E_0: the punch's, exactly
    c = sims[-1].contacts[0]
    m_f = float(np.sum(c.mass[:-1]))  # the face's nodes (the slots but the punch's)
    loss = kinetic * m_f / (mass + m_f)
    print("E_0", kinetic, "first row's contact work", got["energy.contact_work"][0],
          "inelastic loss", loss, "balance", got["energy.balance_error"])
    slots = 4 * (c.n_slots + 8) * loss
    assert abs(-got["energy.contact_work"][0] - loss) <= rounding(1, slots)
    assert abs(got["energy.activation_loss"][0] - loss) <= rounding(1, slots)
    bound = ledger(240, 2 * punch_mesh.mesh.geometry.x.shape[0]) * kinetic
    assert np.max(np.abs(got["energy.balance_error"])) < bound


@pytest.mark.parametrize("timers", [True, False])
def test_bars_compiled_steps_equal_python_steps(bars_mesh, tmp_path_factory, timers):
    def make(out, compiled):
        model = DeformableModel(bars_mesh, [Body("striker", STEEL), Body("target", STEEL)])
        sim = Simulation(model, _settings(out, compiled, output_every=7, history_every=2,
                                          timers=timers),
                         initial_velocity={"striker": (0.0, 5.0)})
        sim.add_contact(pair_surfaces(model, "striker_contact", "target_contact"),
                        scenes.make_method("film"))
        sim.add_probe("sigma_zz_obs", (0.05, 0.2), "sigma_zz")
        return sim
    got = _same(make, tmp_path_factory, f"bars_{timers}", frames=True)
    assert "history.sigma_zz_obs" in got and "fields.sigma_zz.3" in got


def test_frames_of_a_shallow_batch_equal_python_steps(bars_mesh, tmp_path_factory,
                                                      monkeypatch):
    # a batch of 3 frames and a flush every 8: a block's frames stop where the batch goes
    # to the file, full or flushed, and the next block fills the other batch
    from impact_fenics import xdmf

    mesh = bars_mesh.mesh  # a frame's bytes on one rank (a rank's piece has fewer)
    frame = 8 * (6 * mesh.geometry.x.shape[0] + 5 * mesh.topology.index_map(2).size_local)
    monkeypatch.setattr(xdmf.FieldWriter, "BATCH_LIMIT", 3 * frame + 1)
    depths = []
    init = xdmf.FieldWriter.__init__

    def spy(self, *args, **kw):
        init(self, *args, **kw)
        depths.append((self.depth, self.flush_every))
    monkeypatch.setattr(xdmf.FieldWriter, "__init__", spy)

    def make(out, compiled):
        model = DeformableModel(bars_mesh, [Body("striker", STEEL), Body("target", STEEL)])
        sim = Simulation(model, _settings(out, compiled, output_every=4),
                         initial_velocity={"striker": (0.0, 5.0)})
        sim.add_contact(pair_surfaces(model, "striker_contact", "target_contact"),
                        scenes.make_method("dme"))
        return sim
    got = _same(make, tmp_path_factory, "shallow", frames=True)
    assert "fields.sigma_zz.40" in got
    if COMM.size == 1:
        assert depths == [(3, 8)] * 2


def test_no_contact_compiled_steps_equal_python_steps(bars_mesh, tmp_path_factory):
    def make(out, compiled):
        model = DeformableModel(bars_mesh, [Body("striker", STEEL), Body("target", STEEL)])
        return Simulation(model, _settings(out, compiled, n_steps=60),
                          initial_velocity={"striker": (0.0, 5.0), "target": (0.0, -1.0)})
    _same(make, tmp_path_factory, "free", expect_contact=False)


def _failure(make, tmp_path_factory, name) -> list[str]:
    """Run the failing scene both ways: the messages, and everything written up to the
    failure, identical."""
    messages, runs = [], []
    for compiled in (True, False):
        sim = make(os.path.join(_scratch(tmp_path_factory, name), "run"), compiled)
        with pytest.raises(UnstableRunError) as err:
            sim.run()
        assert sim.compiled_steps == compiled
        messages.append(str(err.value))
        runs.append(_written(sim))
    a, b = runs
    assert a.keys() == b.keys()
    for key in a:
        assert np.array_equal(a[key], b[key]), key
    return messages


def test_a_runaway_rigid_body_stops_both_at_the_same_step(punch_mesh, tmp_path_factory):
    def make(out, compiled):
        sim = scenes.punch_indentation(_settings(out, compiled), scenes.make_method("dme"),
                                       radius=1.0, tmesh=punch_mesh)
        body = sim.contacts[0].rigid
        body.force = lambda t: np.inf if t > 40 * sim.settings.dt else 0.0
        return sim
    a, b = _failure(make, tmp_path_factory, "runaway")
    assert a == b and "rigid body" in a


def test_a_diverging_run_stops_both_at_the_same_step(bars_mesh, tmp_path_factory):
    def make(out, compiled):
        model = DeformableModel(bars_mesh, [Body("striker", STEEL), Body("target", STEEL)])
        return Simulation(model, _settings(out, compiled, cfl=3.0, force_dt=True,
                                           n_steps=2000, output_every=500),
                          initial_velocity={"striker": (0.0, 5.0)})
    a, b = _failure(make, tmp_path_factory, "diverged")
    assert a == b and "a node moves at" in a


def test_an_energy_growing_run_stops_both_at_the_same_step(bars_mesh, tmp_path_factory):
    # above the stable step the energy grows by a factor every step: checked at every
    # output step (here every 5th, in the compiled blocks' records), it passes the growth
    # limit long before a speed passes the runaway limit (checked every 64 steps)
    def make(out, compiled):
        model = DeformableModel(bars_mesh, [Body("striker", STEEL), Body("target", STEEL)])
        sim = Simulation(model, _settings(out, compiled, cfl=3.0, force_dt=True,
                                          n_steps=2000, output_every=5),
                         initial_velocity={"striker": (0.0, 5.0)})
        sim.add_contact(pair_surfaces(model, "striker_contact", "target_contact"),
                        scenes.make_method("film"))
        return sim
    a, b = _failure(make, tmp_path_factory, "grew")
    assert a == b and "grew beyond" in a


def test_the_divergence_message_names_the_limit_it_checked(bars_mesh, tmp_path_factory):
    """'a node moves at V m/s, beyond the runaway speed L m/s': L is the limit the run
    checked against, fixed at its start (the steel's dilatational speed: 10 x the initial
    5 m/s is below it), not one recomputed from the diverged speeds, and V passed it;
    the same from the compiled and the Python steps."""
    import re

    def make(out, compiled):
        model = DeformableModel(bars_mesh, [Body("striker", STEEL), Body("target", STEEL)])
        return Simulation(model, _settings(out, compiled, cfl=3.0, force_dt=True,
                                           n_steps=2000, output_every=500),
                          initial_velocity={"striker": (0.0, 5.0)})
    for message in _failure(make, tmp_path_factory, "runaway_limit"):
        found = re.search(r"a node moves at (\S+) m/s, beyond the runaway speed (\S+) m/s",
                          message)
        assert found, message
        speed, limit = map(float, found.groups())
        assert limit == float(f"{STEEL.wave_speed():.4g}") and speed > limit, message


def test_energy_rows_on_their_own_cadence_equal_python_steps(bars_mesh, tmp_path_factory):
    """energy_every = 4 with frames every 25 steps and history rows every 3: the energy
    rows come at steps 0, 4, 8, ... and the last one (the schedule of every cadence), the
    frames at t = 0 and every 25 steps; the compiled blocks (whose output steps are the
    energy rows) and the Python steps write the same files."""
    def make(out, compiled):
        model = DeformableModel(bars_mesh, [Body("striker", STEEL), Body("target", STEEL)])
        sim = Simulation(model, _settings(out, compiled, energy_every=4, history_every=3),
                         initial_velocity={"striker": (0.0, 5.0)})
        sim.add_contact(pair_surfaces(model, "striker_contact", "target_contact"),
                        scenes.make_method("film"))
        return sim
    got = _same(make, tmp_path_factory, "energy_every", frames=True)
    n = 240  # _settings' n_steps
    assert got["energy.step"].tolist() == list(range(0, n - 1, 4)) + [n - 1]
    assert len(got["fields.times"]) == 1 + -(-n // 25)
