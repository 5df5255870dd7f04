"""The same numbers for every partition: a rank's share of a run changes only the order
of its sums.

Each scene runs in one process on all ranks (COMM_WORLD) and on this rank alone
(COMM_SELF, the serial oracle). On one rank the two evaluate the same expressions:
equal. Under ``mpirun -n 2`` they differ in partition, so in the order of the sums at
every step: the histories, energies and final fields must agree within the steps x
the spread of the serial run under a one-ulp change of its start (its initial
velocity, or the peak of the load that drives it from rest: class (c) of
tests/roundoff.py). A launcher test also runs the bar impact demo on 1, 2 and 3
ranks and compares the summaries the same way.
"""
import json
import os
import subprocess
import sys

import numpy as np
import pytest
from mpi4py import MPI

from conftest import clean_mpi_env, gather_field
from impact_fenics import scenes
from impact_fenics.simulation import Settings
from roundoff import assert_runs_agree, assert_within_spread, ledger, one_ulp, rounding

SERIAL = MPI.COMM_WORLD.size == 1


def _run(builder, comm, ulp=False):
    sim = builder(comm, ulp)
    sim.run()
    u = np.empty(sim.model.n_owned)
    sim.integrator.displacement(u)
    return sim, gather_field(sim.model, u)


def _compare(builder, columns):
    """``builder(comm, ulp)``: the scene on ``comm``, its start moved by one ulp if ``ulp``."""
    par, (x_p, u_p) = _run(builder, MPI.COMM_WORLD)
    ser, (x_s, u_s) = _run(builder, MPI.COMM_SELF)
    ulp, (_, u_u) = (None, (None, None)) if SERIAL else _run(builder, MPI.COMM_SELF, True)
    n = ser.n_steps
    # dof coordinates: the cell's map at a vertex through whichever cell the rank has
    # (sum_i phi_i x_i over 3 vertices: 6 roundings of the coordinates)
    assert np.abs(x_p - x_s).max() <= rounding(6, np.abs(x_s).max())
    assert_runs_agree(u_p, u_s, u_u, n, "u")
    hp, hs = par.history.data(), ser.history.data()
    hu = None if ulp is None else ulp.history.data()
    for col in columns:
        assert_runs_agree(hp[col], hs[col], None if hu is None else hu[col], n, col)
    ep, es = par.energy.data(), ser.energy.data()
    eu = None if ulp is None else ulp.energy.data()
    energy = np.abs(es["total"]).max()  # energies compare on the scale of the total
    for col in ("kinetic", "strain", "external_work", "contact_work", "momentum_z"):
        assert_runs_agree(ep[col], es[col], None if eu is None else eu[col], n, col,
                          None if col == "momentum_z" else energy)


def test_wave_same_on_all_partitions():
    def builder(comm, ulp):
        sim = scenes.elastic_bar(Settings(dt=1e-6, n_steps=120, output_every=10, quiet=True),
                                 h=0.01, length=0.5, nu=0.3, comm=comm,
                                 peak=one_ulp(100e6) if ulp else 100e6)
        sim.add_probe("s", (0.02, 0.2), "sigma_zz")
        return sim
    _compare(builder, ["s"])


@pytest.mark.parametrize("method", ["penalty", "film", "dme"])
def test_bar_impact_same_on_all_partitions(method):
    def builder(comm, ulp):
        return scenes.bar_impact(Settings(dt=1e-6, n_steps=200, output_every=20, quiet=True),
                                 scenes.make_method(method), h=0.025, striker_length=0.2,
                                 target_length=0.25, comm=comm,
                                 v0=one_ulp(5.0) if ulp else 5.0)
    _compare(builder, ["sigma_zz_obs", "contact_force", "min_gap", "n_active"])


def test_punch_same_on_all_partitions():
    block = dict(width=1.5, depth=0.3, h_surface=0.02, grading=0.3,
                 breaks=((0.5, 25), (1.0, 25)))

    def builder(comm, ulp):
        return scenes.punch_indentation(Settings(dt=3.64e-7, n_steps=150, output_every=10,
                                                 quiet=True),
                                        scenes.make_method("film"), radius=1.0, block=block,
                                        comm=comm, peak=one_ulp(200e6) if ulp else 200e6)
    _compare(builder, ["punch_u", "punch_force", "n_active"])


@pytest.mark.skipif(MPI.COMM_WORLD.size > 1, reason="launches mpirun itself: serial run only")
@pytest.mark.parametrize("method", ["film", "dme"])
def test_bar_impact_demo_on_1_2_3_ranks(tmp_path, method):
    from conftest import load_demo

    root = os.path.join(os.path.dirname(__file__), "..")
    # the spread (class (c) of tests/roundoff.py): the demo in this process, serially, with
    # its striker one ulp faster
    demo = load_demo("bar_impact")
    demo.V0 = one_ulp(demo.V0)
    ulp, _ = demo.run(method, None, t_end=2e-4)
    summaries = []
    for n in (1, 2, 3):
        out = tmp_path / f"n{n}"
        cmd = [os.path.join(root, "scripts", "mpirun.sh"), "-n", str(n), sys.executable,
               os.path.join(root, "demos", "bar_impact.py"), "--method", method,
               "--t-end", "2e-4", "--out", str(out), "--quiet"]
        subprocess.run(cmd, check=True, capture_output=True, timeout=300, env=clean_mpi_env())
        with open(out / "summary.json") as f:
            summaries.append(json.load(f))
    one = summaries[0]
    n = one["n_steps"]
    for s in summaries[1:]:
        for key in ("contact_duration", "velocity_striker_final", "velocity_target_final"):
            assert_within_spread(s[key], one[key], ulp[key], n, key)
        energy = abs(one["energy"]["total"])
        for key in ("kinetic", "strain", "contact_work"):
            assert_within_spread(s["energy"][key], one["energy"][key], ulp["energy"][key], n,
                                 key, energy)
    for s in summaries:  # round-off quantities: small on every partition
        assert s["momentum_error_rel"] <= ledger(s["n_steps"], s["n_dofs"])
        # the committed gap b + u_up - u_lo (2 roundings) after the correction that closed
        # it (a few more) on displacements up to v0 t_end
        assert s["max_penetration"] <= rounding(8, 5.0 * 2e-4)
