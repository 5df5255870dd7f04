"""The summary an impact researcher reads first, against the 1D impact of two equal nu = 0
bars (nu = 0 admits exact plane waves, d'Alembert's solution): contact stress
rho c0 v0 / 2 for 2 L / c0, then the velocities exchanged (the striker stops: it
rebounds at ~0 m/s; the target leaves at v0; the coefficient of restitution of the
pair is 1).

Tolerances: body masses are exact (the lumped mass integrates rho 2 pi r
exactly) to a count of roundings; the impulse is the striker's momentum change to
the round-off of a ledger (the contact force is the only force on it, and a history
row every step makes sum F dt exact; tests/roundoff.py); the 1D figures carry the
element-scale errors of
the 1D impact: velocities within h / 2L of v0 (one element's share of the bar),
the time in contact within 3 h / c0 as in test_contact_bars, and the peak force the overshoot of the wave front on the CST mesh
(within 10 % of the 1D plateau, which the middle of the contact meets to 1 %).
"""
import json
import math
import os

import numpy as np
import pytest
from mpi4py import MPI

from impact_fenics import scenes
from impact_fenics.contact import FILM
from impact_fenics.simulation import Settings
from roundoff import ledger, rounding

RHO, E = 7850.0, 200e9
C0 = math.sqrt(E / RHO)
V0, L, A, H = 5.0, 0.2, 0.05, 0.01
# the exchanged velocities carry an error of about one element over the bar's length
# (the CST end rows spread the 1D field): within h / 2L of v0 (measured 2.1 % at h/L = 5 %)
VEL = H / (2 * L)


@pytest.fixture(scope="module")
def bars(tmp_path_factory):
    base = MPI.COMM_WORLD.bcast(str(tmp_path_factory.mktemp("summary")), root=0)
    out = os.path.join(base, "bars")
    sim = scenes.bar_impact(Settings(cfl=0.9, t_end=3 * L / C0, output_every=25, out=out,
                                     quiet=True, plots=False),
                            FILM(), h=H, nu=0.0, v0=V0, radius=A, striker_length=L,
                            target_length=L, structured=True, observe=None)
    sim.run()
    with open(os.path.join(out, "summary.json")) as f:
        return json.load(f), sim


def test_masses_and_provenance(bars):
    s, sim = bars
    mass = RHO * math.pi * A ** 2 * L
    n_nodes = s["n_dofs"] // 2  # a node's mass: about 30 roundings; the sum: one a node
    for name in ("striker", "target"):
        assert abs(s["bodies"][name]["mass"] - mass) <= rounding(30 + n_nodes, mass)
    assert s["version"] and s["date"] and "command_line" in s
    assert s["stopped_at_step"] == s["n_steps"]
    assert set(s["setup_time"]) >= {"stability", "operators", "contact", "outputs"}
    shares = [p["share"] for p in s["timing"]["phases"].values()]
    # the shares: each phase's time over the loop's (1 rounding), summed (1 each)
    assert all(0 <= x <= 1 for x in shares)
    assert sum(shares) + s["timing"]["rest_share"] <= 1 + rounding(2 * (len(shares) + 1))


def test_impact_figures_of_the_1d_solution(bars):
    s, sim = bars
    (c,) = s["impact"]
    assert (c["lower"], c["upper"]) == ("striker", "target")
    mass = s["bodies"]["striker"]["mass"]
    plateau = RHO * C0 * V0 / 2 * math.pi * A ** 2
    assert abs(c["peak_force"] - plateau) <= 0.10 * plateau
    # impulse = the striker's momentum change, exactly; and m v0 in 1D
    dp = mass * (s["bodies"]["striker"]["velocity_z_initial"] - s["bodies"]["striker"]["velocity_z_final"])
    assert abs(c["impulse"] - dp) <= ledger(s["n_steps"], s["n_dofs"]) * mass * V0
    assert abs(c["impulse"] - mass * V0) <= VEL * mass * V0
    assert c["separated_at_end"] and c["n_separations"] == 1
    assert abs(c["time_in_contact"] - 2 * L / C0) <= 3 * H / C0
    # velocities exchanged: the striker stops (rebounds at ~0), the target leaves at v0
    # the striker's mean velocity while it moves as one: each step's internal forces
    # cancel to round-off, the mean sums its nodes (a ledger's count)
    assert abs(c["velocity_lower_before"] - V0) <= ledger(s["n_steps"], s["n_dofs"]) * V0
    assert abs(c["velocity_lower_after"]) <= VEL * V0
    assert abs(c["velocity_upper_after"] - V0) <= VEL * V0
    assert abs(c["restitution"] - 1.0) <= 2 * VEL


def test_energy_row_and_peak_stresses_are_the_written_outputs(bars):
    """Exact equivalences with the files: the summary's energy is the last row of
    energy.csv (17 digits read back as the same float64); the row's total z momentum is
    the two bodies' (the bars share no node), to the round-off of summing the z dofs'
    m v (all of one sign) in another order: one rounding a dof of m v0; the peak
    stresses are the extremes of
    the frames written to fields.xdmf, at the time of the first frame that reaches them."""
    from impact_fenics.xdmf import FieldSeries

    s, sim = bars
    energy = sim.energy.data()
    for key, value in s["energy"].items():
        assert energy[key][-1] == value, key
    p = s["bodies"]["striker"]["mass"] * V0
    both = energy["momentum_z_striker"] + energy["momentum_z_target"]
    assert np.abs(energy["momentum_z"] - both).max() <= rounding(s["n_dofs"], p)
    series = FieldSeries(os.path.join(sim.out_dir, "fields.xdmf"))
    frames = range(len(series.times))
    von_mises = np.array([series.values("von_mises", k).max() for k in frames])
    zz_max = np.array([series.values("sigma_zz", k).max() for k in frames])
    zz_min = np.array([series.values("sigma_zz", k).min() for k in frames])
    peaks = s["peak_stress"]
    for key, per_frame, extreme in (("von_mises", von_mises, von_mises.max()),
                                    ("sigma_zz_max", zz_max, zz_max.max()),
                                    ("sigma_zz_min", zz_min, zz_min.min())):
        assert peaks[key] == extreme, key
        assert peaks[f"{key}_time"] == series.times[np.flatnonzero(per_frame == extreme)[0]], key


def test_plastic_work_and_strain_in_the_summary_and_console(tmp_path, capsys):
    """A J2 target yielding under the tiny pair's impact (with a load on its far end): the
    console's energy line shows every term of the ledger that is not zero, kinetic +
    strain + plastic work = total = initial + work of loads + contact work (to the
    printed digits); the target's plastic work is the ledger's (the only plastic body:
    the same points' works, >= 0, summed in another order, a rounding a point); eps_p_max
    is the largest
    equivalent plastic strain at a point at the end, so at least every cell mean of the
    last frame."""
    from scene_texts import PAIR, replace

    from impact_fenics import cli, plotting

    comm = MPI.COMM_WORLD
    base = comm.bcast(str(tmp_path) if comm.rank == 0 else None, root=0)
    scene = os.path.join(base, f"plastic{comm.rank}.toml")
    with open(scene, "w") as f:
        f.write(replace(PAIR, '[bodies.target]\nmaterial = "steel"',
                        '[bodies.target]\nmaterial = "soft"\n\n[materials.soft]\nmodel = "j2"\n'
                        'E = 200e9\nnu = 0.3\ndensity = 7850.0\nyield_stress = 1e6\n'
                        'hardening = 1e9'))
    out = os.path.join(base, "out")
    capsys.readouterr()
    assert cli.main(["run", scene, "--out", out]) == 0
    text = capsys.readouterr().out
    with open(os.path.join(out, "summary.json")) as f:
        s = json.load(f)
    e = s["energy"]
    assert e["plastic_work"] > 0 and e["external_work"] != 0
    # the pairs touch at t = 0 and the first step's impact is in E_0 = 1/2 v^0 M v^1: the
    # contact's work after it is round-off here (4 to 90 EPS of the total, by the
    # partition), shown only above the console's round-off threshold
    from impact_fenics.report import ROUND_OFF

    noise = ROUND_OFF * max(abs(e[k]) for k in ("kinetic", "strain", "plastic_work", "total",
                                                 "external_work", "contact_work"))
    # the initial energy closes the balance: E_n - E_0 - W_n is the balance error (the
    # ledger's expression, evaluated again on the same floats)
    assert e["total"] - s["energy_initial"] - e["external_work"] - e["contact_work"] == \
        e["balance_error"]
    n_points = 3 * s["n_cells"]  # the degree-2 rule of the stiffness: 3 points a cell
    assert s["bodies"]["target"]["plastic_work"] == pytest.approx(e["plastic_work"],
                                                                  rel=rounding(n_points))
    assert "plastic_work" not in s["bodies"]["striker"]
    last = plotting.read_xdmf(os.path.join(out, "fields.xdmf"))
    eps = last.values("eps_p_eq", last.fields["eps_p_eq"].times.size - 1)
    assert 0 < eps.max() <= s["eps_p_max"]
    if comm.rank != 0:
        return
    (line,) = [ln for ln in text.splitlines() if ln.startswith("energy: ")]
    assert f"plastic work {e['plastic_work']:.6g} J" in line
    assert f"work of loads {e['external_work']:.4g} J" in line
    assert (f"contact work {e['contact_work']:.4g} J" in line) == (abs(e["contact_work"]) > noise)
    stored = e["kinetic"] + e["strain"] + e["plastic_work"]
    assert f"= {stored:.6g} J = initial {s['energy_initial']:.6g} J + " in line
    assert f"largest equivalent plastic strain {s['eps_p_max']:.4g}" in text


def test_node_to_segment_summary_names_the_bodies_below_and_above(tmp_path):
    """Node to segment with the finer target face (above) as slave and the striker (below,
    moving up) as master: the summary says lower = striker, upper = target (the master's
    outward normals point up to the slave), names the slave and the master, and gives the
    1D impact's rebound: the velocities exchanged, restitution 1 (within h / 2L each, as
    the node-pair bars above)."""
    from impact_fenics.contact import DME

    out = MPI.COMM_WORLD.bcast(str(tmp_path / "nts") if MPI.COMM_WORLD.rank == 0 else None,
                               root=0)
    sim = scenes.bar_impact_sized(Settings(cfl=0.9, t_end=3 * L / C0, output_every=25,
                                           out=out, quiet=True, plots=False, fields=False),
                                  DME(), n_striker=6, n_target=9, v0=V0, radius=A,
                                  striker_length=L, target_length=L)
    s = sim.run()
    (c,) = s["impact"]
    assert (c["slave"], c["master"]) == ("target", "striker")
    assert (c["lower"], c["upper"]) == ("striker", "target")
    assert c["separated_at_end"]
    # the striker moving as one: a ledger's round-off, as above
    assert abs(c["velocity_lower_before"] - V0) <= ledger(s["n_steps"], s["n_dofs"]) * V0
    assert abs(c["velocity_lower_after"]) <= VEL * V0
    assert abs(c["velocity_upper_after"] - V0) <= VEL * V0
    assert abs(c["restitution"] - 1.0) <= 2 * VEL


def test_results_line_says_what_was_written(tmp_path, capsys):
    """'open fields.xdmf in ParaView' only when the run wrote it; with [output] fields =
    false the line lists the files the run wrote instead."""
    from scene_texts import PAIR, replace

    from impact_fenics import cli

    comm = MPI.COMM_WORLD
    base = comm.bcast(str(tmp_path) if comm.rank == 0 else None, root=0)
    for fields in (True, False):
        text = PAIR if fields else replace(PAIR, "output_every = 10",
                                           "output_every = 10\nfields = false")
        scene = os.path.join(base, f"pair{int(fields)}_{comm.rank}.toml")
        with open(scene, "w") as f:
            f.write(text)
        out = os.path.join(base, f"out{int(fields)}")
        capsys.readouterr()
        assert cli.main(["run", scene, "--out", out]) == 0
        lines = capsys.readouterr().out.splitlines()
        if comm.rank != 0:
            continue
        (line,) = [ln for ln in lines if ln.startswith("results in ")]
        written = sorted(n for n in os.listdir(out) if not n.startswith("."))
        if fields:
            assert "fields.xdmf" in written and "open fields.xdmf in ParaView" in line
        else:
            assert "fields.xdmf" not in written and "ParaView" not in line
            assert line == (f"results in {out}/: {', '.join(written)} (no fields.xdmf: "
                            "[output] fields = false)")
