"""The study (demos/paper_study.py --quick on tiny meshes): physics, not just existence.

Oracles: the definition of the Pareto front (an exact property, checked against
brute force); the stability bound of the penalty (beta_max < 4/3, derived in
contact/penalty.py) against FILM and DME, which are stable up to the converged
dt_crit; the exact equality of FILM and DME while the active set holds (whole runs:
within the spread of a one-ulp change of their start, tests/roundoff.py); the energy
ledgers of the long runs; and the mesh convergence of the reference.
No timing is asserted.
"""
import copy
import os
import shutil
import tempfile

import numpy as np
import pytest
from mpi4py import MPI

from conftest import load_demo
from impact_fenics.contact import FILM
from impact_fenics.study.bars import run_bar, window_time
from impact_fenics.study.common import BETA_BOUND, dominated, pareto_front, rel_l2, settings
from impact_fenics.study.config import QUICK
from impact_fenics.study.punch import run_punch
from roundoff import LIBM, STEP_ROUNDINGS, ledger, one_ulp, rounding


def test_pareto_front_is_exactly_the_non_dominated_set():
    rng = np.random.default_rng(3)
    for n in (1, 2, 7, 40):
        pts = [tuple(p) for p in rng.integers(0, 6, size=(n, 2)).astype(float)]  # many ties
        front = set(pareto_front(pts))
        for i in range(n):
            assert (i in front) == (not dominated(pts, i)), (pts, i)


def test_relative_l2_of_a_history():
    t = np.linspace(0.0, 1.0, 101)
    y = np.sin(3 * t) + 2
    assert rel_l2(t, y, t, y, (0.0, 1.0)) == 0.0
    # 1.1 y - y rounds on 1.1 y (11 roundings of the difference's size), each trapezoid
    # sums 101 squared terms, then a ratio and a sqrt
    n = 11 + 2 * (t.size + 2) + LIBM
    assert abs(rel_l2(t, 1.1 * y, t, y, (0.0, 1.0)) - 0.1) <= rounding(n, 0.1)
    assert rel_l2(t[:50], y[:50], t, y, (0.0, 1.0)) == float("inf")  # stopped early


@pytest.fixture(scope="module")
def quick():
    comm = MPI.COMM_WORLD
    folder = tempfile.mkdtemp(prefix="study_quick_") if comm.rank == 0 else None
    folder = comm.bcast(folder, root=0)
    study = load_demo("paper_study")
    out = study.main(["--quick", "--out", folder])
    files = sorted(os.listdir(folder)) if comm.rank == 0 else None
    report = open(os.path.join(folder, "results.md")).read() if comm.rank == 0 else None
    files, report = comm.bcast((files, report), root=0)
    comm.barrier()
    if comm.rank == 0:
        shutil.rmtree(folder, ignore_errors=True)
    return out["results"], files, report


def test_every_figure_has_its_numbers(quick):
    _, files, report = quick
    pngs = {f[:-4] for f in files if f.endswith(".png")}
    jsons = {f[:-5] for f in files if f.endswith(".json")}
    assert pngs and pngs <= jsons
    assert "| claim" in report.lower()


def test_reference_changes_decrease_under_refinement(quick):
    ref = quick[0]["bars_reference"]
    changes = ref["changes"]
    assert len(changes) >= 2
    assert all(b < a for a, b in zip(changes[:-1], changes[1:]))


def test_pareto_front_of_the_accuracy_study(quick):
    acc = quick[0]["accuracy"]
    pts = acc["points"]
    assert len({p["h"] for p in pts}) >= 2
    for cost, front in (("cpu_run", acc["front_cpu_run"]), ("cpu_contact", acc["front_cpu_contact"])):
        finite = [i for i, p in enumerate(pts) if np.isfinite(p["err_sigma"])]
        xy = [(pts[i][cost], pts[i]["err_sigma"]) for i in finite]
        for j, i in enumerate(finite):
            assert (i in front) == (not dominated(xy, j))


def test_exact_methods_keep_the_constraint_and_converge(quick):
    pts = quick[0]["accuracy"]["points"]
    # the committed gap b + u_up - u_lo (2 roundings) after the correction that closed it
    # (6 more), on displacements up to v0 t_end
    bars = QUICK["bars"]
    gap_round = rounding(8, bars["v0"] * bars["t_end"])
    for method in ("film", "dme_e0"):
        rows = sorted((p for p in pts if p["method"] == method), key=lambda p: -p["h"])
        assert all(p["max_penetration"] <= gap_round for p in rows)
        assert rows[-1]["err_sigma"] < rows[0]["err_sigma"]  # finer mesh, closer to the reference


def test_penalty_goes_unstable_before_film_and_dme(quick):
    dt = quick[0]["stability"]["dt"]
    for scene in ("bars", "punch"):
        first = dt[scene]["first_unstable"]
        rows = dt[scene]["rows"]
        for exact in ("film", "dme_e0" if scene == "bars" else "dme"):
            # stable below the converged limit, unstable above it
            assert first[exact]["first_unstable"] is not None and first[exact]["first_unstable"] > 1.0
            assert first[exact]["last_stable"] < 1.0
        pen = [r for r in rows if r["method"] == "p_paper"]
        over = [r["ratio"] for r in pen if r["beta_max"] > BETA_BOUND]
        assert over and min(over) < 1.0  # the fixed penalty crosses 4/3 below dt_crit ...
        assert first["p_paper"]["first_unstable"] < first["film"]["first_unstable"]  # ... and fails there
        for r in pen:  # every run above the bound fails; below beta = 1 and dt_crit none does
            if r["beta_max"] > BETA_BOUND or r["ratio"] > 1.0:
                assert r["state"] != "stable", r
            elif r["beta_max"] <= 1.0:
                assert r["state"] == "stable", r


def test_penalty_fails_where_the_coupled_beta_crosses_the_bound(quick):
    sweep = quick[0]["penalty_sweep"]
    for res in sweep["radii"].values():
        for r in res["rows"]:
            if r["beta_max"] > 1.2 * BETA_BOUND:
                assert r["state"] != "stable", r
            if r["beta_max"] < 1.0:
                assert r["state"] == "stable", r
        scaled = {r["value"]: r for r in res["rows"] if r["family"] == "mass_scaled"}
        # p proportional to the ring masses: every pair far below 4/3, yet it fails with the punch
        assert scaled[2.0]["beta_ii_rim"] < 0.1 and scaled[2.0]["state"] != "stable"
        assert scaled[1.0]["state"] == "stable"


def test_film_and_dme_agree_on_the_punch_and_bars(quick):
    """FILM's dense solver and its fast one, and DME (e = 0) and FILM on the bars, are the
    same motion by other expressions: whole runs, within the steps x (the spread (the
    same relative L2 difference) of the reference run under a one-ulp change of its start
    (the punch's load peak, the striker's v0) + a step's roundings; tests/roundoff.py)."""
    p = QUICK["punch"]
    window = (0.0, p["pulse"]["t_end"])
    for sim in quick[0]["punch"]["radii"].values():
        assert sim["methods"]["dme"]["err_u"] <= 1e-3
        ref = sim["methods"]["film_fast"]["series"]
        rec = run_punch(QUICK, FILM("fast"), sim["radius"],
                        pulse=dict(p["pulse"], peak=one_ulp(p["pulse"]["peak"])))
        spread = rel_l2(rec["history"]["time"], rec["history"]["punch_u"], ref["time"],
                        ref["punch_u"], window)
        assert sim["methods"]["film_dense"]["err_u"] <= p["n_steps"] * (
            spread + rounding(STEP_ROUNDINGS))
    # node pairs: with e = 0 and mass-weighted positions DME moves a closed pair exactly as
    # FILM does (an exact equivalence, round-off only)
    bars = QUICK["bars"]
    film = quick[0]["bars"]["methods"]["film"]["series"]
    cfg = copy.deepcopy(QUICK)
    cfg["bars"]["v0"] = one_ulp(bars["v0"])
    rec = run_bar(cfg, FILM(), bars["h"], bars["t_end"], output_every=25)
    spread = rel_l2(rec["history"]["time"], rec["history"]["sigma_zz_obs"], film["time"],
                    film["sigma"], (0.0, window_time(QUICK)))
    n_steps = round(bars["t_end"] / bars["dt"])
    assert quick[0]["bars"]["film_vs_dme_e0_sigma"] <= n_steps * (spread
                                                                    + rounding(STEP_ROUNDINGS))


def test_energy_balance_of_long_runs(quick):
    """The ledgers of the long runs close to the round-off of a ledger (tests/roundoff.py);
    the bars separate and fly apart, drifting rigidly for most of the run."""
    from impact_fenics import scenes

    runs = quick[0]["stability"]["long"]["runs"]
    n = QUICK["stability"]["long_steps"]
    clamped = scenes.elastic_bar(settings(cfl=0.9, n_steps=1), h=QUICK["bars"]["h"], length=0.5,
                                 nu=0.3, peak=50e6, structured=False, clamp_far_end=True)
    assert runs["clamped_bar"]["balance_max"] <= ledger(n, clamped.model.n_global)
    bars = scenes.bar_impact(settings(dt=QUICK["bars"]["dt"], n_steps=1), FILM(),
                             h=QUICK["bars"]["h"], nu=0.3, radius=QUICK["bars"]["radius"],
                             striker_length=QUICK["bars"]["striker_length"],
                             target_length=QUICK["bars"]["target_length"], observe=None)
    for key in ("film", "dme_e0", "p_scaled"):
        assert runs[key]["balance_max"] <= ledger(n, bars.model.n_global, drifting=True)
