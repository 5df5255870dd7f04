"""The one compiled call of a contact step equals the three separate calls, bit for bit.

Penalty, FILM (fast) and DME run their whole contact step (detection, the method,
the commit and the contact-work booking) as one compiled call
(impact_fenics/contact/fused.py). The oracle is the step as three separate
calls (detection, the method's correct(), the commit), which the contact tests
validated against closed-form impacts: the same kernels on the same arrays in
the same order, so every number must be identical (no tolerance). The scenes
cover a rigid punch (rigid slot, cluster DME, coupled FILM), node pairs of two
bars (pair DME with restitution) and a rigid bit driven by a rod (impedance,
wave bookkeeping), in serial and under MPI (each comparison on one partition).

Also exact: no numba kernel compiles inside the loop (the summary's
``compiled_in_loop``, from the kernels' signatures before and after), and
``pairs_every`` records the same per-pair rows at its steps as every step does.
"""
import os

import numpy as np
import pytest
from mpi4py import MPI

from impact_fenics import meshing, scenes
from impact_fenics.errors import InputError
from impact_fenics.output import read_pairs
from impact_fenics.simulation import Settings

METHODS = ("penalty", "film", "dme")


def _settings(**kw):
    base = dict(cfl=0.9, n_steps=150, output_every=25, quiet=True, plots=False, fields=False)
    base.update(kw)
    return Settings(**base)


def _state(sim):
    c = sim.contacts[0]
    integ = sim.integrator
    out = [integ.u_owned.copy(), integ.v_owned.copy(), c.stats.copy(), c.force.copy(),
           c.active.astype(float),
           np.array([c.contact_work, c.activation_loss, c.rigid_external_work])]
    if c.rigid is not None:
        r = c.rigid
        out.append(np.array([r.u, r.v, r.wave_incident, r.wave_reflected, r.wave_delivered]))
    e = sim.energy.data()
    out += [e[k] for k in sorted(e)]
    return out


class _OneAssembly:
    """The stiffness assembled once for two runs built one after the other: the second
    build gets copies of the first build's matrices, call by call. PETSc adds the
    entries other ranks send to a row in the order they arrive; from 3 ranks on a row
    can receive from two, so two assemblies may differ in the last bit, and two runs
    compared bit for bit must share one."""

    NAMES = ("impact_fenics.internal_force.linear.assemble_stiffness",
             "impact_fenics.simulation.assemble_stiffness")

    def __init__(self):
        from impact_fenics.operators import assemble_stiffness

        self.assemble, self.first, self.replay = assemble_stiffness, [], None

    def __call__(self, *args, **kwargs):
        if self.replay is None:
            self.first.append(self.assemble(*args, **kwargs))
            return self.first[-1].copy()
        return self.replay.pop(0).copy()

    def second_build(self) -> None:
        self.replay = list(self.first)


def _same(make):
    """Run the scene made by make() fused and with separate calls; every number equal."""
    from unittest import mock

    one = _OneAssembly()
    with mock.patch(one.NAMES[0], one), mock.patch(one.NAMES[1], one):
        fused = make()
        one.second_build()
        separate = make()
        assert not one.replay  # the second build assembled what the first did
    for c in separate.contacts:
        c.use_separate_calls()
    assert fused.contacts[0]._fused is not None and separate.contacts[0]._fused is None
    fused.run()
    separate.run()
    assert fused.summary["contact"]["max_penetration"] == separate.summary["contact"]["max_penetration"]
    assert max(fused.history.data()["n_active"]) > 0  # the scene has contact
    for a, b in zip(_state(fused), _state(separate)):
        assert np.array_equal(a, b)


@pytest.mark.parametrize("name", METHODS)
def test_punch_fused_equals_separate_calls(punch_mesh, name):
    _same(lambda: scenes.punch_indentation(_settings(), scenes.make_method(name), radius=1.0,
                                           tmesh=punch_mesh))


@pytest.mark.parametrize("name", METHODS)
def test_bars_fused_equals_separate_calls(name):
    tmesh = meshing.coaxial_bars(radius=0.1, striker_length=0.4, target_length=0.4, h=0.04,
                                 structured=False)

    def make():
        from impact_fenics.bodies import Body, DeformableModel
        from impact_fenics.contact import pair_surfaces
        from impact_fenics.materials import STEEL
        from impact_fenics.simulation import Simulation

        model = DeformableModel(tmesh, [Body("striker", STEEL), Body("target", STEEL)])
        sim = Simulation(model, _settings(dt=1e-6, cfl=None),
                         initial_velocity={"striker": (0.0, 5.0)})
        sim.add_contact(pair_surfaces(model, "striker_contact", "target_contact"),
                        scenes.make_method(name, restitution=0.3))
        return sim

    _same(make)


def test_rod_driven_bit_fused_equals_separate_calls():
    s = dict(dt=2e-8, cfl=None, n_steps=None, t_end=4e-6)
    tmesh = scenes.bit_rock(_settings(**s), scenes.make_method("dme"), h_surface=0.002).model.tmesh
    _same(lambda: scenes.bit_rock(_settings(**s), scenes.make_method("dme"), tmesh=tmesh))


def test_nothing_compiles_in_the_loop_and_pairs_every(tmp_path_factory, punch_mesh):
    """A run with history rows (a probe, so the block kernel of the probes runs at the
    first table flush, 256 rows in), per-pair rows and fields: no kernel compiles in the
    loop; per-pair rows every 7 steps are the rows of a run that records every step, at
    the steps n = 0, 7, 14, ... and the last (the state after them)."""
    base = MPI.COMM_WORLD.bcast(str(tmp_path_factory.mktemp("fused")), root=0)
    runs = {}
    for every in (1, 7):
        out = os.path.join(base, f"every{every}")
        sim = scenes.punch_indentation(_settings(n_steps=300, out=out, output_every=100,
                                                 pairs_every=every),
                                       scenes.make_method("dme"), radius=1.0, tmesh=punch_mesh)
        sim.add_probe("szz", (0.3, -0.1), "sigma_zz")
        summary = sim.run()
        assert summary["timing"]["compiled_in_loop"] == []
        runs[every] = read_pairs(os.path.join(sim.out_dir, "contact_pairs.h5"))
    all_rows, some = runs[1], runs[7]
    n_steps = 300
    rows = np.union1d(np.arange(0, n_steps, 7), [n_steps - 1])
    assert np.array_equal(all_rows["step"], np.arange(1, n_steps + 1))
    assert np.array_equal(some["step"], all_rows["step"][rows])
    for key in ("time", "gap", "force", "active"):
        assert np.array_equal(some[key], all_rows[key][rows])
    assert some["active"].any()


@pytest.mark.parametrize("bad", [0, -3, 2.5, True])
def test_pairs_every_must_be_a_positive_integer(punch_mesh, bad):
    with pytest.raises(InputError, match="pairs_every"):
        scenes.punch_indentation(_settings(pairs_every=bad), scenes.make_method("dme"),
                                 radius=1.0, tmesh=punch_mesh)
