"""Part whole, the nonlinear scenes: each run whole, as ``impact-fenics run`` runs it, against
its steps.

The shipped scene files, read and built as the command does, with their default outputs
(fields, history, energy rows, the history plots) into a scratch directory: the plastic
bar impact (scenes/plastic_bar_impact.toml, J2 target, DME), the bit-rock blow
(scenes/bit_rock.toml with the Drucker-Prager granite that its comment names, taken from
scenes/wedge_rock.toml's [materials.granite] without the plane-strain match) and the
Taylor bar (scenes/taylor_bar.toml, finite-strain J2, FILM wall). Full: the scene's
t_end; quick and smoke: a fraction of it (the same loop, fewer steps).

Reported per scene: the whole wall time W (read the scene, build it, run it, publish the
directory), the steps n, the median step m and W / (n m) against the goal 1.3, beside the
loop alone over n m (the linear rows' figure); W split into its parts, each from the
run's own clocks (Simulation.setup_time, the summary's wall_time) or from this module's
around read_scene, build and run:

    read      read_scene and its checks
    build     scene_file.build less the Simulation's own set-up below (mesh, model,
              loads, probes)
    stability, operators, contact set-up     Simulation.setup_time
    outputs   the output directory, the tables and the first frame (setup_time)
    kernels   the compiled step blocks' set-up (setup_time)
    loop      the time loop (summary wall_time); split further as the linear rows are:
              each phase's total over the loop less n x its median, and the loop's rest
    checks    the scene's checks after the loop (the run's ``extra``: contact duration,
              the Taylor bar's length and radius)
    publish   after the checks: the history plots, summary.json, the directory moved
    other     run() less the above: before the loop the set-up's objects collected
              (gc.collect, then frozen), the ledger and the timers set up; after it the
              tables and the field writer closed, the summary's reductions

The parts are disjoint intervals of one rank's clock, so they sum to W with ``other``
>= 0 up to the clock's resolution; the figures are those of the rank whose W is the
largest (under MPI the loop's phase totals and medians are the slowest rank's, as in the
summary). In quick and full modes each scene first runs a few steps untimed in the same
process (kernels and the plotting library loaded: what is timed is the run's own work,
as in a process that has run a scene before); that first run's W less its loop is kept
as ``cold_setup``.
"""
from __future__ import annotations

import math
import os
import tempfile
import time
import tomllib

from mpi4py import MPI

from .common import ROOT

SCENES = ROOT / "scenes"
GOAL = 1.3  # whole / (steps x median step)
# (label, scene file, the Drucker-Prager rock swapped in)
NONLINEAR = (("plastic bar impact", "plastic_bar_impact.toml", False),
             ("bit-rock, Drucker-Prager rock", "bit_rock.toml", True),
             ("Taylor bar", "taylor_bar.toml", False))
T_END_FRACTION = {"smoke": 0.02, "quick": 0.25}  # of the scene's t_end; full: all of it
WARM_FRACTION = T_END_FRACTION["smoke"]  # the untimed first run: the smoke run
SETUP_KEYS = ("stability", "operators", "contact", "converged_dt")
PARTS = ("read", "build", "stability", "operators", "contact", "converged_dt", "outputs",
         "kernels", "loop", "checks", "publish", "other")


def drucker_prager_rock(base: str = str(SCENES)):
    """The [materials.granite] of scenes/wedge_rock.toml without its plane-strain match:
    the Drucker-Prager rock that scenes/bit_rock.toml's comment gives, as a MaterialSpec."""
    from ..scene_materials import read_material

    with open(os.path.join(base, "wedge_rock.toml"), "rb") as f:
        granite = tomllib.load(f)["materials"]["granite"]
    granite.pop("match", None)  # axisymmetric: the cone's default match
    return read_material("granite", granite, base)


def read(name: str, rock: bool, fraction: float | None):
    """The checked scene ``name`` of scenes/, its rock Drucker-Prager if ``rock``, its end
    (t_end or n_steps) times ``fraction`` (None: the scene's)."""
    from ..scene_file import read_scene

    scene = read_scene(str(SCENES / name))
    if rock:
        scene.materials["granite"] = drucker_prager_rock()
    if fraction is not None:
        t = scene.time
        if t.get("t_end") is not None:
            t["t_end"] *= fraction
        else:
            t["n_steps"] = max(1, round(t["n_steps"] * fraction))
    return scene


def beyond_median(summary: dict) -> dict:
    """The loop beyond its median steps by phase (s): each phase's total less steps x its
    median; ``rest`` the loop's wall time less every phase's total (its own Python)."""
    n = summary["stopped_at_step"]
    totals = summary.get("time_per_step_total", {})
    medians = summary.get("time_per_step_median", {})
    beyond = {k: totals[k] - n * medians.get(k, 0.0) for k in totals}
    beyond["rest"] = summary["wall_time"] - sum(totals.values())
    return beyond


class _nothing:
    """A context of no directory (the ranks but 0 take rank 0's)."""

    def __enter__(self):
        return None

    def __exit__(self, *exc):
        return False


def whole_run(comm: MPI.Comm, name: str, rock: bool, fraction: float | None) -> dict:
    """One whole run of scene ``name`` (module docstring): W, its parts (s) and the summary's
    step figures, the slowest rank's."""
    from .. import scene_file
    from ..cli import _scene_checks

    clock = time.perf_counter
    marks = {}

    def checks(sim) -> dict:
        marks["checks"] = clock()
        extra = _scene_checks(sim, str(SCENES / name))
        marks["publish"] = clock()
        return extra

    with tempfile.TemporaryDirectory() if comm.rank == 0 else _nothing() as scratch:
        scratch = comm.bcast(scratch, root=0)
        comm.barrier()
        t0 = clock()
        scene = read(name, rock, fraction)
        t1 = clock()
        sim = scene_file.build(scene, {"out": os.path.join(scratch, "run"), "quiet": True},
                               comm)
        t2 = clock()
        s = sim.run(extra=checks)
        t3 = clock()
        comm.barrier()
    setup = s["setup_time"]
    parts = {"read": t1 - t0,
             "build": t2 - t1 - sum(setup.get(k, 0.0) for k in SETUP_KEYS),
             **{k: setup.get(k, 0.0) for k in SETUP_KEYS},
             "outputs": setup.get("outputs", 0.0), "kernels": setup.get("kernels", 0.0),
             "loop": s["wall_time"], "checks": marks["publish"] - marks["checks"],
             "publish": t3 - marks["publish"]}
    parts["other"] = (t3 - t2) - sum(parts[k] for k in ("outputs", "kernels", "loop",
                                                         "checks", "publish"))
    whole = t3 - t0
    whole, parts = max(comm.allgather((whole, parts)), key=lambda w: w[0])
    n, median = s["stopped_at_step"], s["step_time_median"]
    timing = s.get("timing", {})
    return {"whole": whole, "parts": parts, "n_steps": n, "n_cells": s["n_cells"],
            "n_dofs": s["n_dofs"], "n_ranks": comm.size, "t_end": s["t_end"],
            "status": s["status"], "step_median": median,
            "whole_over_steps_median": whole / (n * median) if n * median > 0 else math.inf,
            "loop_over_steps_median": parts["loop"] / (n * median) if n * median > 0 else math.inf,
            "ns_per_element_cycle_whole": 1e9 * whole / (s["n_cells"] * n) if n else math.inf,
            "ns_per_element_cycle_loop": s.get("ns_per_element_cycle"),
            "beyond_median": beyond_median(s), "phase_totals": s.get("time_per_step_total", {}),
            "phase_medians": s.get("time_per_step_median", {}),
            "compiled_in_loop": timing.get("compiled_in_loop", []),
            "compiled_steps": timing.get("compiled_steps", False),
            "eps_p_max": s.get("eps_p_max")}


def measure_nonlinear(comm: MPI.Comm, mode: str) -> list[dict]:
    """The whole runs of the NONLINEAR scenes in ``mode`` (smoke, quick or full)."""
    fraction = T_END_FRACTION.get(mode)
    out = []
    for label, name, rock in NONLINEAR:
        cold = None
        if mode != "smoke":  # the untimed first run: kernels and plotting loaded
            warm = whole_run(comm, name, rock, WARM_FRACTION)
            cold = warm["whole"] - warm["parts"]["loop"]
        r = whole_run(comm, name, rock, fraction)
        r.update({"scene": label, "scene_file": f"scenes/{name}", "cold_setup": cold,
                  "goal": GOAL, "t_end_fraction": fraction or 1.0})
        out.append(r)
    return out


HEADERS = ["scene", "cells", "steps", "whole (s)", "median step (us)", "whole/(n x step)",
           "loop/(n x step)", "ns/element/cycle whole", "ns/element/cycle loop"]
PART_HEADERS = ["scene", "read", "build", "stability", "operators", "contact set-up",
                "outputs", "kernels", "loop", "checks", "publish", "other", "cold set-up"]
LOOP_HEADERS = ["scene", "n x median", "f_int", "contact", "history", "output", "rest",
                "compiled in loop"]


def row(r: dict) -> list:
    return [r["scene"], f"{r['n_cells']:,}", r["n_steps"], f"{r['whole']:.2f}",
            f"{1e6 * r['step_median']:.1f}",
            f"{r['whole_over_steps_median']:.1f} (goal {r['goal']:g})",
            f"{r['loop_over_steps_median']:.2f}", f"{r['ns_per_element_cycle_whole']:.0f}",
            f"{r['ns_per_element_cycle_loop']:.0f}" if r.get("ns_per_element_cycle_loop")
            else "-"]


def part_row(r: dict) -> list:
    p = r["parts"]
    return [r["scene"]] + [f"{p[k]:.3f}" for k in ("read", "build", "stability", "operators",
                                                   "contact", "outputs", "kernels", "loop",
                                                   "checks", "publish", "other")] + \
        [f"{r['cold_setup']:.2f}" if r.get("cold_setup") is not None else "-"]


def loop_row(r: dict) -> list:
    b = r["beyond_median"]
    contact = sum(b.get(k, 0.0) for k in ("contact_detection", "contact_solve", "contact_update"))
    return [r["scene"], f"{1e3 * r['n_steps'] * r['step_median']:.1f}"] + \
        [f"{1e3 * v:.1f}" for v in (b.get("f_int", 0.0), contact, b.get("history", 0.0),
                                    b.get("output", 0.0), b["rest"])] + \
        [", ".join(r["compiled_in_loop"] or []) or "none"]


def report(ctx, runs: list[dict]) -> None:
    """The three tables of the nonlinear whole runs."""
    ctx.table(f"Whole runs of the nonlinear scenes ({ctx.comm.size} rank(s); default outputs; "
              "whole: read, build, run, publish)", HEADERS, [row(r) for r in runs])
    ctx.table("   the whole by part (s; 'other': run() less its timed parts)", PART_HEADERS,
              [part_row(r) for r in runs])
    ctx.table("   the loop beyond steps x median (ms), by phase", LOOP_HEADERS,
              [loop_row(r) for r in runs])
