"""Part: the split Hopkinson pressure bar's whole run (scenes/shpb.toml), and how its step
divides between the linear bars and the nonlinear specimen.

The shipped scene (the striker, the incident and the transmitter bar: 19 000 linear
triangles; the J2 specimen: 800), read and built as ``impact-fenics run`` does, with its
outputs into a scratch directory, run to its end (full) or for the first steps only
(quick, smoke: the same loop, fewer steps; no analysis, which needs the whole pulse).
Reported: the whole time (set-up and loop, s), the loop's ns per element-cycle (its wall
time over cells x steps), and each side's internal-force seconds and ns per
element-cycle from the run's per-body timing (the bars' one matrix product against the
specimen's return mapping).
"""
from __future__ import annotations

import os
import tempfile
import time

from mpi4py import MPI

from .common import ROOT

SCENE = ROOT / "scenes" / "shpb.toml"
T_END = {"smoke": 5e-7, "quick": 2.5e-5}  # s, about 20 and 1000 steps; full: the scene's
BARS = ("striker", "incident", "transmitter")


def _scene_text(mode: str) -> str:
    text = SCENE.read_text()
    if mode in T_END:
        old = "t_end = 2.4e-4 "
        assert text.count(old) == 1, "scenes/shpb.toml: its t_end line moved"
        text = text.replace(old, f"t_end = {T_END[mode]!r} ")
    return text


def shpb_run(comm: MPI.Comm, mode: str) -> dict:
    """Run the scene (a scratch directory) and return its cost figures (module docstring)."""
    from .. import scene_file

    with tempfile.TemporaryDirectory() if comm.rank == 0 else _nothing() as scratch:
        scratch = comm.bcast(scratch, root=0)
        path = os.path.join(scratch, "shpb.toml")
        if comm.rank == 0:
            with open(path, "w") as f:
                f.write(_scene_text(mode))
        comm.barrier()
        t0 = time.perf_counter()
        scene = scene_file.read_scene(path)
        sim = scene_file.build(scene, {"out": os.path.join(scratch, "run"), "quiet": True},
                               comm)
        s = sim.run()
        whole = comm.allreduce(time.perf_counter() - t0, op=MPI.MAX)
        comm.barrier()
    bodies = s["bodies"]
    steps = s["stopped_at_step"]
    bars_cells = sum(bodies[b]["n_cells"] for b in BARS)
    bars_f = sum(bodies[b]["f_int_seconds"] for b in BARS)
    spec = bodies["specimen"]
    return {"n_cells": s["n_cells"], "n_steps": steps, "whole_seconds": whole,
            "loop_seconds": s["wall_time"], "ns_per_element_cycle": s["ns_per_element_cycle"],
            "bars": {"n_cells": bars_cells, "f_int_seconds": bars_f,
                     "ns_per_element_cycle": 1e9 * bars_f / (bars_cells * steps)},
            "specimen": {"n_cells": spec["n_cells"], "f_int_seconds": spec["f_int_seconds"],
                         "ns_per_element_cycle": spec["ns_per_element_cycle"]},
            "specimen_share": spec["f_int_seconds"] / (spec["f_int_seconds"] + bars_f)}


class _nothing:
    """A context of no directory (the ranks but 0 take rank 0's)."""

    def __enter__(self):
        return None

    def __exit__(self, *exc):
        return False


def part_shpb(ctx) -> dict:
    r = shpb_run(ctx.comm, ctx.mode.name)
    ctx.log(f"shpb ({'the whole scene' if ctx.mode.name not in T_END else 'its first steps'}): "
            f"{r['n_cells']} cells, {r['n_steps']} steps, whole {r['whole_seconds']:.3g} s, "
            f"loop {r['ns_per_element_cycle']:.3g} ns per element-cycle; internal forces: "
            f"bars {r['bars']['ns_per_element_cycle']:.3g} ns per element-cycle "
            f"({r['bars']['f_int_seconds']:.3g} s), specimen "
            f"{r['specimen']['ns_per_element_cycle']:.3g} ({r['specimen']['f_int_seconds']:.3g}"
            f" s, {r['specimen_share']:.0%} of the force time)")
    return r
