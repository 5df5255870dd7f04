"""The benchmark harness (impact_fenics.bench) runs and its comparisons compare like with like.

No timed assertion: only that the smoke run writes the expected keys with
positive, finite figures, that the SciPy CSR loop it times is the integrator's
update to round-off, and that the matrix-free prototype computes K u. Serial and
MPI-safe: under mpirun the launcher and serial-only parts are skipped by the
harness itself.
"""
import json
import math
import os

import pytest
from mpi4py import MPI

from impact_fenics.bench import main
from impact_fenics.bench.contact import CONTACT_METHODS
from impact_fenics.bench.step import scipy_equivalence
from roundoff import STEP_ROUNDINGS, rounding

# akantu needs a venv of its own that CI does not have: left out here
PARTS = "step,contact,friction,solvers,scaling,stream,ranks,format,matfree,j2,finite,gain,shpb"
TIMING_KEYS = ("median", "gbs", "step", "matmult", "multadd", "axpy", "contact", "fast", "force",
               "numba_call_floor")


def _numbers(obj, path=""):
    """(path, value) of every number in a JSON tree."""
    if isinstance(obj, dict):
        for k, v in obj.items():
            yield from _numbers(v, f"{path}/{k}")
    elif isinstance(obj, list):
        for i, v in enumerate(obj):
            yield from _numbers(v, f"{path}/{i}")
    elif isinstance(obj, (int, float)) and not isinstance(obj, bool):
        yield path, obj


@pytest.fixture(scope="module")
def smoke(tmp_path_factory):
    comm = MPI.COMM_WORLD
    path = str(tmp_path_factory.mktemp("bench") / "bench.json") if comm.rank == 0 else None
    path = comm.bcast(path, root=0)
    main(["--smoke", "--quiet", "--parts", PARTS, "--out", path])
    with open(path) as f:
        return json.load(f)


def test_smoke_run_writes_the_expected_figures(smoke):
    comm = MPI.COMM_WORLD
    meta = smoke["meta"]
    for key in ("cpu_model", "cores", "ranks", "dolfinx", "petsc", "mode", "wall_seconds"):
        assert key in meta, key
    assert meta["ranks"] == comm.size and meta["mode"] == "smoke"

    step = smoke["step"]
    for k in ("step", "simulation", "matmult", "multadd", "axpy"):
        assert step["ns_per_dof"][k] > 0 and step["ratio_to_matmult"][k] > 0, k
    assert step["nnz_per_row"] > 0 and step["step_bytes_per_dof"] > step["matrix_bytes_per_dof"]
    assert step["simulation"]["ns_per_element_cycle"] > 0

    assert {r["method"] for r in smoke["contact"]["rigid"]} == set(CONTACT_METHODS)
    for kind in ("rigid", "pairs"):
        for rec in smoke["contact"][kind]:
            assert rec["status"] == "completed", rec
            for k in ("contact_detection", "contact_solve", "contact_update", "contact", "step"):
                assert rec[k] > 0, (kind, rec["method"], k)
            assert rec["n_active_median"] > 0  # the scenes keep contact closed
    assert all(c["fast"] > 0 and c["dense"] > 0 for c in smoke["solvers"]["cases"])

    for rec in smoke["scaling"]:
        assert all(v > 0 for v in rec["ns_per_dof"].values())
    assert smoke["stream"]["best_gbs"] > 0
    assert set(smoke["format"]) == {"aij", "baij"}
    for variant in ("aij", "baij"):
        assert all(v > 0 for v in smoke["format"][variant]["ns_per_dof"].values())
    assert smoke["format"]["baij"]["block_size"] == 2
    # the same operator in another format, times a random x: a row's 18 products summed in
    # another order, 18 roundings of sum_j |A_ij x_j| (within sqrt(18) of max |A x| for a
    # random x)
    assert smoke["format"]["baij"]["same_A_as_aij"] <= rounding(18 * math.sqrt(18))

    if comm.size == 1:
        for k in ("scipy_plain", "scipy_inplace"):
            assert step["ns_per_dof"][k] > 0
        ranks = smoke["ranks"]
        assert "error" not in ranks, ranks.get("error")
        assert ranks["two_ranks"]["meta"]["ranks"] == 2
        for s in ranks["speedup"]:
            assert all(v > 0 for v in s["speedup"].values())
        mf = smoke["matfree"]
        # another assembly: each path an element matrix from quadrature (about 26
        # roundings an entry) and a row of 18 products, on sum_j |K_ij u_j| (within
        # sqrt(18) of max |K u| for the random u)
        assert mf["rel_diff_to_K_u"] <= rounding(2 * (26 + 18) * math.sqrt(18))
        assert mf["ns_per_dof"]["matfree"] > 0
        gain = smoke["gain"]  # every nonlinear step timed on 2 ranks beside its 1-rank time
        assert "error" not in gain, gain.get("error")
        assert gain["meta_two_ranks"]["ranks"] == 2 and gain["triad_gain"] > 0
        # the compiled triad's gain: the two ranks' sum over one rank's (a product and a
        # quotient: 2 roundings); PETSc's VecWAXPY gain beside it
        gbs = gain["triad_gbs"]
        triad = gain["triad_gain"]
        assert abs(triad - 2.0 * gbs["2"] / gbs["1"]) <= rounding(2) * triad
        assert gain["waxpy_gain"] > 0
        assert {"j2_fast", "dp_fast", "j2_finite_strain"} <= set(gain["steps"])
        for k, r in gain["steps"].items():
            # gain = t1 / t2; the ms columns are 1e3 t each: 3 more roundings
            assert r["gain"] > 0, k
            assert abs(r["gain"] - r["ms_1"] / r["ms_2"]) <= rounding(4) * r["gain"], k
    else:
        for part in ("ranks", "gain", "matfree"):
            assert "skipped" in smoke[part]

    j2 = smoke["j2"]
    for k in ("j2_fast", "j2_generic", "j2_fast_elastic", "linear_step", "matmult"):
        assert j2["ns_per_dof"][k] > 0 and j2["ratio_to_linear_step"][k] > 0, k
    assert j2["yielded_fraction_fast"] > 0.1  # the J2 row times real return mappings

    fin = smoke["finite"]
    for k in ("j2_finite_strain", "j2_small_strain", "linear_step", "matmult"):
        assert fin["ns_per_dof"][k] > 0 and fin["ratio_to_linear_step"][k] > 0, k
    assert fin["n_dofs_quadrilateral"] == fin["n_dofs"]  # the same nodes, quadrilaterals
    assert fin["yielded_fraction_finite"] > 0.1 and fin["split_finite"]["fused_kernel"] > 0

    # the roofline: every timed step of the J2 and finite parts has its floor, the larger of
    # its memory and compute terms, and its time over it; and its time per element per cycle
    for part, steps in ((j2, ("matmult", "linear_step", "j2_fast_elastic", "j2_fast",
                              "j2_generic", "dp_fast")),
                        (fin, ("matmult", "linear_step", "j2_small_strain", "j2_finite_strain",
                               "jc_finite_strain", "nh_finite_strain"))):
        rates = part["machine_rates"]
        assert rates["triad_gbs"] > 0 and rates["gflops"] > 0
        for k in steps:
            f = part["floor"][k]
            assert f["floor_seconds"] == max(f["memory_seconds"], f["compute_seconds"]) > 0, k
            assert f["over_floor"] == f["seconds"] / f["floor_seconds"], k
            assert f["bound"] in ("memory", "compute") and part["ns_per_element_cycle"][k] > 0
    assert fin["floor"]["j2_finite_strain"]["arithmetic"]["log"] > 0
    # per element: a quadrilateral for the finite-strain rows, a triangle for the others
    for k, ns in fin["ns_per_element_cycle"].items():
        cells = fin["n_cells_quadrilateral"] * (1 if k.endswith("_finite_strain") else 2)
        assert ns == 1e9 * fin["timings"][k] / cells, k

    for path, value in _numbers(smoke):
        assert math.isfinite(value), path
        if path.rsplit("/", 1)[-1] in TIMING_KEYS:
            assert value > 0, path


def test_scipy_loop_is_the_integrator_update():
    """Same u and v after a few steps, loads included (each rank on its own mesh): each of
    the 8 steps rounds about 32 times (a row of K and the update, the ledger's count of
    tests/roundoff.py), and the stable linear step carries the earlier errors along
    without growth, so the two stay within 32 x 8 roundings."""
    steps = 8
    e = scipy_equivalence(MPI.COMM_SELF, dofs=3000, steps=steps)
    assert e["load_steps"] > 0 and e["u_max"] > 0
    for k in ("plain_u_rel", "plain_v_rel", "inplace_u_rel", "inplace_v_rel"):
        assert e[k] <= rounding(32 * steps), (k, e[k])


def test_unknown_part_is_refused():
    with pytest.raises(SystemExit):
        main(["--smoke", "--quiet", "--parts", "step,nonsense"])


def test_small_strain_bytes_are_the_hand_count():
    """The bytes of a small-strain J2 step on a few cells against a count by hand: per
    triangle 3 points of 9 float64 (plastic strain 4, equivalent plastic strain 1, stress 4)
    read and written (432 B), its geometry read (3 int32 dofs, dN/dr, dN/dz, 1/r and w at 3
    values each: 12 + 96 B); per local dof u gathered and f zeroed, summed into and read
    back (32 B); per owned dof the velocity update (72 B) and the position update (24 B)."""
    from impact_fenics.bench.bar import bar_mesh
    from impact_fenics.bench.plastic import J2_ELASTIC, j2_integrator
    from impact_fenics.bench.roofline import small_strain_bytes

    tmesh, _ = bar_mesh(MPI.COMM_WORLD, 200)
    model, integ = j2_integrator(tmesh, "fast", 1e-7, J2_ELASTIC)
    force = integ.nonlinear[0]
    cells = force.qs.state.shape[0]
    n_local, n_owned = force.f.x.array.size, model.n_owned
    assert force.geometry.dofs.dtype.itemsize == 4 and force.qs.state.shape[1:] == (3, 1)
    assert small_strain_bytes(force, n_owned) == (432 + 108) * cells + 32 * n_local + 96 * n_owned


def test_smoke_shpb_splits_the_scene_into_bars_and_specimen(smoke):
    """The SHPB part's cells are the scene's (the generator's structured triangles: the
    striker, the incident and the transmitter bar of 20 mm at 1 mm, 2 x 10 x length / h
    each; the specimen 2 x 20 x 20), its figures positive and its shares a split."""
    r = smoke["shpb"]
    bars = 2 * 10 * round((0.2 + 0.5 + 0.25) / 0.001)
    assert r["bars"]["n_cells"] == bars and r["specimen"]["n_cells"] == 2 * 20 * 20
    assert r["n_cells"] == bars + 800 and r["n_steps"] > 0
    for v in (r["whole_seconds"], r["loop_seconds"], r["ns_per_element_cycle"],
              r["bars"]["ns_per_element_cycle"], r["specimen"]["ns_per_element_cycle"]):
        assert math.isfinite(v) and v > 0
    assert 0.0 < r["specimen_share"] < 1.0


def test_smoke_friction_times_each_method_with_and_without_friction(smoke):
    """The friction part: for each method a run with mu = 0 and one with mu > 0 on the same
    constraints, every time positive, the ratios those of the medians, and the page renders
    it (docs_pages)."""
    from impact_fenics import docs_pages

    r = smoke["friction"]
    assert r["mu"] > 0
    runs = {(x["method"], x["mu"] > 0): x for x in r["runs"]}
    for method in ("penalty", "film", "dme"):
        off, on = runs[method, False], runs[method, True]
        assert off["n_constraints"] == on["n_constraints"] > 0
        for v in (off["contact"], on["contact"], off["step"], on["step"]):
            assert math.isfinite(v) and v > 0
        assert on["contact_ratio"] == on["contact"] / off["contact"]
    assert any(line.startswith("## Friction") for line in docs_pages._friction(r, smoke))


AKANTU_PYTHON = "/tmp/akantu-venv/bin/python"  # the harness's default --akantu-python


@pytest.mark.skipif(not os.path.exists(AKANTU_PYTHON),
                    reason=f"no Akantu venv at {AKANTU_PYTHON} (python -m impact_fenics.bench "
                           "--install-akantu makes it)")
def test_smoke_akantu_runs_our_problem(tmp_path_factory):
    """The akantu part runs Akantu's step and ours on the same plane-strain problem: the same
    dofs and triangles, one point per triangle in both with J2 (three in our axisymmetric
    row), and for the elastic body the same u after the steps from the same state to
    round-off (the same P1 stiffness and lumped mass; Akantu's central differences and our
    leapfrog give the same positions from u = 0), and so for J2 below its yield stress (both
    return mappings on their elastic branch). Each code rounds a dof's quantities about
    32 times a step (tests/roundoff.py) and the stable linear step carries the earlier
    roundings along without growth: two codes over n steps stay within 2 x 32 x n roundings
    of max |u|. Timings are only positive and finite; the page renders the part. Under
    mpirun the part is serial-only and the harness skips it."""
    from impact_fenics import docs_pages

    comm = MPI.COMM_WORLD
    path = str(tmp_path_factory.mktemp("akantu") / "bench.json") if comm.rank == 0 else None
    path = comm.bcast(path, root=0)
    main(["--smoke", "--quiet", "--parts", "akantu", "--out", path])
    with open(path) as f:
        bench = json.load(f)
    ak = bench["akantu"]
    if comm.size > 1:
        assert "skipped" in ak
        return
    assert "skipped" not in ak and "error" not in ak, ak
    for material in ("elastic", "j2"):
        a, ours = ak["akantu"][material], ak["ours"][f"plane_strain_{material}"]
        assert a["n_dofs"] == ours["n_dofs"] and a["n_elements"] == ours["n_cells"] == ak["n_cells"]
        assert a["dt"] == ours["dt"] == ak["dt"] and a["check_steps"] == ak["steps"]
        for v in (a["step_seconds"], ours["step_seconds"],
                  ak["ours"][f"axisymmetric_{material}"]["step_seconds"]):
            assert math.isfinite(v) and v > 0
    assert ak["akantu"]["j2"]["points_per_element"] == 1
    assert ak["ours"]["plane_strain_j2"]["points_per_cell"] == 1
    assert ak["ours"]["axisymmetric_j2"]["points_per_cell"] == 3
    assert ak["ours"]["plane_strain_j2"]["yielded_fraction"] > 0.5  # J2 times return mappings
    for check in ("elastic", "j2_elastic_range"):  # J2 below yield: the elastic branch
        assert ak["check"][check]["u_max"] > 0
        assert ak["check"][check]["u_rel_diff"] <= rounding(2 * STEP_ROUNDINGS * ak["steps"])
    assert any(line.startswith("## A peer: Akantu") for line in docs_pages._akantu(ak, bench))


def test_smoke_whole_nonlinear_scenes_split_their_whole_run():
    """The nonlinear scenes of part whole (bench/whole_nonlinear.py) in smoke mode: a row
    per scene, run to the shortened end, and the whole W split into disjoint intervals of
    one rank's clock. Each part that is a difference of intervals (build: build() less the
    Simulation's own set-up within it; other: run() less its timed parts) is >= 0 up to the
    clock: at most 2 reads per interval, 6 intervals each, so 12 x the clock's resolution,
    plus the float rounding of the ~12 additions (16 eps W). The parts sum to W to that
    rounding. The plastic bar steps dt = 1e-6 s to 0.02 x t_end = 4e-6 s: 4 steps exactly.
    The page renders a row per scene (docs_pages)."""
    import sys
    import time

    from impact_fenics import docs_pages
    from impact_fenics.bench.whole_nonlinear import NONLINEAR, PARTS as WHOLE_PARTS
    from impact_fenics.bench.whole_nonlinear import measure_nonlinear

    runs = measure_nonlinear(MPI.COMM_WORLD, "smoke")
    assert [r["scene"] for r in runs] == [label for label, _, _ in NONLINEAR]
    resolution = time.get_clock_info("perf_counter").resolution
    for r in runs:
        assert r["status"].startswith("completed") and r["n_steps"] >= 1
        parts, whole = r["parts"], r["whole"]
        assert set(parts) == set(WHOLE_PARTS)
        rounding_w = 16 * sys.float_info.epsilon * whole
        assert min(parts.values()) >= -(12 * resolution + rounding_w), parts
        assert abs(sum(parts.values()) - whole) <= rounding_w + 12 * resolution
        assert parts["loop"] <= whole
        for key in ("whole_over_steps_median", "loop_over_steps_median",
                    "ns_per_element_cycle_whole", "ns_per_element_cycle_loop"):
            assert math.isfinite(r[key]) and r[key] > 0
    assert runs[0]["n_steps"] == 4
    text = "\n".join(docs_pages._whole({"nonlinear": runs}, {}))
    assert all(f"| {label} |" in text for label, _, _ in NONLINEAR)
