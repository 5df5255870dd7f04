"""The Taylor bar on 1, 2 and 3 ranks: the same numbers, to the spread of round-off.

The coarse mesh (n_r = 2: 2 x 20 quadrilaterals, 63 nodes) run 10 us through
`impact-fenics run`: serially in this process, then on 2 and on 3 ranks launched
with scripts/mpirun.sh (3 ranks oversubscribe the 2 cores: OpenMPI's
--oversubscribe, which mpirun.sh passes). Why 10 us is enough: from the first step
the face is on the wall and the plastic zone grows under it (eps_bar_p passes 1 by
10 us), the step is re-estimated 11 times from flattening cells (dt falls), and
the wall's active set changes many times (face nodes leave and return; 0 to 3
nodes active): every decision a partition could change (the gathered wall, the
min-J and dt reductions, the ghost sums of f_int at partition boundaries crossing
the plastic zone) is taken again and again. A run that took one of them
differently would differ by far more than round-off.

The comparison (class (c) of tests/roundoff.py): every column of history.csv (but the
timers) and of energy.csv at every row (one row every step) and the summary's shape and
energies. The partitions
sum in another order at every step, and a difference of one rounding grows through
the wall's switches and the plastic steps; the bound is the steps x the spread of the
serial run under a one-ulp change of the impact velocity (a fourth run). The
ledger's residual columns (balance_error, work_gap), round-off themselves, take the
initial kinetic energy as their scale. It launches processes, so it runs in the
serial pass only (under mpirun it is skipped).
"""
import json
import os

import numpy as np
import pytest
from mpi4py import MPI

from impact_fenics import cli
from roundoff import assert_within_spread, one_ulp
from test_finite_scene import TAYLOR, V0
from scene_texts import replace, run_on_ranks

serial_only = pytest.mark.skipif(MPI.COMM_WORLD.size > 1, reason="launches processes: serial only")
SCENE = replace(replace(replace(TAYLOR, "t_end = 8e-6", "t_end = 10e-6"), "history_every = 3",
                        "history_every = 1"), "output_every = 25", "output_every = 1000000\n"
                                                                     "fields = false\nplots = false")
KEYS = ("final_length", "final_face_radius", "eps_p_max", "plastic_work", "stored_elastic",
        "kinetic", "activation_loss", "strain", "dt_min", "dt_max", "t_end")
SCENE = replace(SCENE, "history_every = 1", "history_every = 1\nenergy_every = 1")


def _read(out):
    """The summary's figures (KEYS), and the columns and rows of history.csv (but the
    timers: cpu_*) beside those of energy.csv."""
    with open(os.path.join(out, "summary.json")) as f:
        s = json.load(f)
    s.update(s["energy"])
    s["dt_min"], s["dt_max"] = s["dt_range"]
    head, rows = [], []
    for name in ("history.csv", "energy.csv"):
        with open(os.path.join(out, name)) as f:
            cols = f.readline().strip().split(",")
        h = np.loadtxt(os.path.join(out, name), delimiter=",", skiprows=1, ndmin=2)
        keep = [k for k, c in enumerate(cols) if not c.startswith("cpu_")]
        head += [f"{name}:{cols[k]}" for k in keep]
        rows.append(h[:, keep])
    n = min(r.shape[0] for r in rows)  # (energy.csv has the row of step 0 too)
    return s, head, np.hstack([r[-n:] for r in rows])


@serial_only
def test_taylor_bar_on_1_2_and_3_ranks(tmp_path):
    scene = tmp_path / "taylor.toml"
    scene.write_text(SCENE)
    ulp = tmp_path / "ulp.toml"
    ulp.write_text(replace(SCENE, f"velocity = [0.0, -{V0!r}]",
                           f"velocity = [0.0, {one_ulp(-V0)!r}]"))
    assert cli.main(["run", str(scene), "--out", str(tmp_path / "n1"), "--quiet"]) == 0
    assert cli.main(["run", str(ulp), "--out", str(tmp_path / "ulp"), "--quiet"]) == 0
    s1, head, h1 = _read(tmp_path / "n1")
    su, _, hu = _read(tmp_path / "ulp")
    assert su["n_steps"] == s1["n_steps"]
    assert s1["eps_p_max"] > 1.0 and s1["contact"]["method"] == "film"
    n_act = h1[:, head.index("history.csv:n_active")]
    assert n_act.max() >= 2 and np.count_nonzero(np.diff(n_act)) >= 10  # the active set moves
    run_on_ranks(scene, {n: tmp_path / f"n{n}" for n in (2, 3)})
    for n in (2, 3):
        s, head_n, h = _read(tmp_path / f"n{n}")
        assert s["n_ranks"] == n and head_n == head
        steps = s1["n_steps"]
        assert s["n_steps"] == steps and h.shape == h1.shape
        for key in KEYS:
            assert_within_spread(s[key], s1[key], su[key], steps, f"{n} ranks: {key}")
        for k, name in enumerate(head):
            # the ledger's residuals are round-off themselves: on the scale of the energy
            scale = (s1["energy_initial"] if name.split(":")[1] in
                     ("balance_error", "balance_error_rel", "work_gap") else None)
            assert_within_spread(h[:, k], h1[:, k], hu[:, k], steps, f"{n} ranks: {name}", scale)


def test_the_step_follows_the_same_cells_on_every_partition():
    """A bar flying free with a radial velocity (its cells grow, so the limit min L / c
    is re-estimated from moving cells, some on a partition's boundary): the run on every
    rank of COMM_WORLD equals the same run on one rank (each rank runs it on COMM_SELF)
    in its number of steps, and in its final length, radius and step range to the spread
    of round-off (class (c), the serial run after a one-ulp change of v_r as the
    perturbed one). The limit must read u^n on the ghost nodes too: estimated from
    ghosts one step old, the steps of 2 ranks differed from the serial run's (326 and
    323 here) and the length by 4e-7 of itself."""
    from impact_fenics.bodies import Body, DeformableModel
    from impact_fenics.materials import FiniteJ2
    from impact_fenics.quad_meshes import one_body, quad_bar
    from impact_fenics.simulation import Settings, Simulation
    from impact_fenics.stepping import FollowingStep

    R, L = 3.2e-3, 32.4e-3

    def run(comm, v_r):
        material = FiniteJ2(E=117e9, nu=0.35, density=8930.0, yield_stress=400e6,
                            hardening=100e6)
        model = DeformableModel(one_body(quad_bar(comm, R, L, 4, 40), "bar"),
                                [Body("bar", material)])
        # energy rows every 3 steps: a row keeps u^n, so not all the limit's steps (every
        # 10) come after a row's own refresh of the ghosts
        sim = Simulation(model, Settings(quiet=True, plots=False, timers=False, fields=False,
                                         energy_every=3, history_every=3),
                         initial_velocity={"bar": (v_r, -227.0)},
                         policy=FollowingStep(None, 20e-6, None, 0.5, 10))
        for name, point, quantity in (("top", (0.0, L), "u_z"), ("bottom", (0.0, 0.0), "u_z"),
                                      ("corner", (R, 0.0), "u_r")):
            sim.add_probe(name, point, quantity)
        s = sim.run()
        h = sim.history.data()
        s["final_length"] = (L + h["top"][-1]) - h["bottom"][-1]
        s["final_face_radius"] = R + h["corner"][-1]
        s["dt_min"], s["dt_max"] = s["dt_range"]
        return s

    s_n = run(MPI.COMM_WORLD, 5.0)
    s_1 = run(MPI.COMM_SELF, 5.0)
    s_u = run(MPI.COMM_SELF, one_ulp(5.0))
    steps = s_1["n_steps"]
    assert s_n["n_steps"] == steps == s_u["n_steps"]
    for key in ("final_length", "final_face_radius", "dt_min", "dt_max", "t_end"):
        assert_within_spread(s_n[key], s_1[key], s_u[key], steps, key)
