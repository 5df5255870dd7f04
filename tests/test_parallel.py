"""The same numbers for every partition.

Each scene runs twice in one process: on all ranks (COMM_WORLD) and on this
rank alone (COMM_SELF, the serial oracle). Under ``mpirun -n 2`` the two
differ in partition; the histories, energies and final fields must agree to
1e-10 relative. A launcher test also runs the bar impact demo on 1, 2 and 3
ranks and compares the summaries.
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

REL = 1e-10


def _close(a, b, rel=REL, scale=None):
    """|a - b| <= rel * scale, the scale being the largest |a|, |b| unless given."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    if scale is None:
        scale = max(np.abs(a).max(), np.abs(b).max(), 1e-300)
    return np.abs(a - b).max() <= rel * scale


def _run(builder, comm):
    sim = builder(comm)
    sim.run()
    u = np.empty(sim.model.n_owned)
    sim.integrator.displacement(u)
    return sim, gather_field(sim.model, u)


def _compare(builder, columns):
    par, (x_p, u_p) = _run(builder, MPI.COMM_WORLD)
    ser, (x_s, u_s) = _run(builder, MPI.COMM_SELF)
    assert np.allclose(x_p, x_s, rtol=0, atol=1e-12)
    assert _close(u_p, u_s)
    hp, hs = par.history.data(), ser.history.data()
    for col in columns:
        assert _close(hp[col], hs[col]), col
    ep, es = par.energy.data(), ser.energy.data()
    energy = np.abs(es["total"]).max()  # energies compare on the scale of the total
    for col in ("kinetic", "strain", "external_work", "contact_work"):
        assert _close(ep[col], es[col], scale=energy), col
    assert _close(ep["momentum_z"], es["momentum_z"])


def test_wave_same_on_all_partitions():
    def builder(comm):
        sim = scenes.elastic_bar(Settings(dt=1e-6, n_steps=120, output_every=10, quiet=True),
                                 h=0.01, length=0.5, nu=0.3, comm=comm)
        sim.add_probe("s", (0.02, 0.2), "sigma_zz")
        return sim
    _compare(builder, ["s"])


@pytest.mark.parametrize("method", ["penalty", "film", "dme"])
def test_bar_impact_same_on_all_partitions(method):
    def builder(comm):
        return scenes.bar_impact(Settings(dt=1e-6, n_steps=200, output_every=20, quiet=True),
                                 scenes.make_method(method), h=0.025, striker_length=0.2,
                                 target_length=0.25, comm=comm)
    _compare(builder, ["sigma_zz_obs", "contact_force", "min_gap", "n_active"])


def test_punch_same_on_all_partitions():
    block = dict(width=1.5, depth=0.3, h_surface=0.02, grading=0.3,
                 breaks=((0.5, 25), (1.0, 25)))

    def builder(comm):
        return scenes.punch_indentation(Settings(dt=3.64e-7, n_steps=150, output_every=10,
                                                 quiet=True),
                                        scenes.make_method("film"), radius=1.0, block=block,
                                        comm=comm)
    _compare(builder, ["punch_u", "punch_force", "n_active"])


@pytest.mark.skipif(MPI.COMM_WORLD.size > 1, reason="launches mpirun itself: serial run only")
@pytest.mark.parametrize("method", ["film", "dme"])
def test_bar_impact_demo_on_1_2_3_ranks(tmp_path, method):
    root = os.path.join(os.path.dirname(__file__), "..")
    summaries = []
    for n in (1, 2, 3):
        out = tmp_path / f"n{n}"
        cmd = [os.path.join(root, "scripts", "mpirun.sh"), "-n", str(n), sys.executable,
               os.path.join(root, "demos", "bar_impact.py"), "--method", method,
               "--t-end", "2e-4", "--out", str(out), "--quiet"]
        subprocess.run(cmd, check=True, capture_output=True, timeout=300, env=clean_mpi_env())
        with open(out / "summary.json") as f:
            summaries.append(json.load(f))
    for s in summaries[1:]:
        for key in ("contact_duration", "velocity_striker_final", "velocity_target_final"):
            assert _close(s[key], summaries[0][key]), key
        energy = abs(summaries[0]["energy"]["total"])
        for key in ("kinetic", "strain", "contact_work"):
            assert _close(s["energy"][key], summaries[0]["energy"][key], scale=energy), key
    for s in summaries:  # round-off quantities: small on every partition
        assert s["momentum_error_rel"] <= 1e-12 and s["max_penetration"] <= 1e-15
