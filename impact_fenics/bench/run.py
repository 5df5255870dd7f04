"""The command line: options, the parts in their order with the run's metadata, and the
JSON (written by rank 0, replaced atomically), then the headline figures."""
from __future__ import annotations

import argparse
import json
import logging
import os
import time
from pathlib import Path

from mpi4py import MPI

from . import (contact, finite, gain, matrix_format, nts, peers, plastic, scaling, shpb,
               step, whole_run)
from ..output import json_ready
from .common import MODES, Context
from .machine import machine_info
from .tables import summary_lines

PART_FUNCTIONS = {
    "step": step.part_step, "contact": contact.part_contact, "solvers": contact.part_solvers,
    "nts": nts.part_nts, "friction": contact.part_friction,
    "scaling": scaling.part_scaling, "stream": scaling.part_stream, "ranks": scaling.part_ranks,
    "format": matrix_format.part_format, "matfree": peers.part_matfree, "akantu": peers.part_akantu,
    "j2": plastic.part_j2, "finite": finite.part_finite, "taylor": finite.part_taylor,
    "gain": gain.part_gain,
    "whole": whole_run.part_whole_run,
    "shpb": shpb.part_shpb,
}
PARTS = tuple(PART_FUNCTIONS)
SERIAL_ONLY = ("ranks", "gain", "matfree", "akantu")  # launchers and serial prototypes


def parse_args(argv=None) -> argparse.Namespace:
    p = argparse.ArgumentParser(prog="python -m impact_fenics.bench",
                                description="The benchmark harness: where the time of a "
                                            "step goes, and how far it is from the floor.")
    g = p.add_mutually_exclusive_group()
    g.add_argument("--quick", action="store_const", const="quick", dest="mode", help="about a minute")
    g.add_argument("--smoke", action="store_const", const="smoke", dest="mode", help="seconds (tests)")
    g.add_argument("--mode", choices=sorted(MODES), dest="mode")
    p.add_argument("--parts", default=",".join(PARTS), help=f"comma separated, of {', '.join(PARTS)}")
    p.add_argument("--sizes", default=None, help="dofs of the scaling part, comma separated")
    p.add_argument("--out", default="results/bench.json", help="JSON output (default results/bench.json)")
    p.add_argument("--akantu-python", default="/tmp/akantu-venv/bin/python",
                   help="the interpreter of a separate venv with akantu")
    p.add_argument("--install-akantu", action="store_true",
                   help="create that venv with pip install akantu if it is missing")
    p.add_argument("--quiet", action="store_true", help="print nothing")
    p.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    args = p.parse_args(argv)
    args.parts = [s.strip() for s in args.parts.split(",") if s.strip()]
    bad = [s for s in args.parts if s not in PARTS]
    if bad:
        p.error(f"unknown part(s) {', '.join(bad)}; use {', '.join(PARTS)}")
    args.sizes = [int(s) for s in args.sizes.split(",")] if args.sizes else None
    return args


def _header(ctx, meta: dict) -> None:
    ctx.log(f"impact_fenics benchmark ({ctx.mode.name}): {meta['cpu_model']}, "
            f"{meta['cores']} cores, {ctx.comm.size} rank(s), {meta['memory_gb']:.0f} GB; "
            f"dolfinx {meta['dolfinx']}, PETSc {meta['petsc']}, {meta['mpi'].split(',')[0]}, "
            f"numpy {meta['numpy']}, scipy {meta['scipy']}; load average "
            f"{' '.join(f'{x:.2f}' for x in meta['load_average'])}")
    if meta["load_average"][0] > 0.5 * (meta["cores"] or 1) / 2:
        ctx.log(f"   note: the machine is busy (load average {meta['load_average'][0]:.2f} on "
                f"{meta['cores']} cores): timings will be noisy, ratios less so")


def _run_part(ctx, part: str):
    fn = PART_FUNCTIONS[part]
    if part not in SERIAL_ONLY:
        return fn(ctx)
    try:  # one process: a failure here cannot strand other ranks
        return fn(ctx)
    except Exception as exc:  # e.g. no compiler, benchmarks/ not shipped
        ctx.log(f"   {part} failed: {exc}")
        return {"error": f"{type(exc).__name__}: {exc}"}


def run(ctx) -> dict:
    """Every requested part in the order of PARTS; the results with their ``meta``."""
    clock = time.perf_counter
    t0 = clock()
    meta = machine_info(ctx.comm)
    meta.update({"mode": ctx.mode.name, "parts": ctx.parts,
                 "started": time.strftime("%Y-%m-%d %H:%M:%S"),
                 "mode_settings": ctx.mode.__dict__, "part_seconds": {}})
    ctx.results["meta"] = meta
    _header(ctx, meta)
    for part in (p for p in PARTS if p in ctx.parts):
        if part in SERIAL_ONLY and ctx.comm.size > 1:
            ctx.results[part] = {"skipped": "serial-only part (launcher or serial prototype)"}
            continue
        t = clock()
        ctx.results[part] = _run_part(ctx, part)
        meta["part_seconds"][part] = clock() - t
        ctx.log(f"   [{part}: {clock() - t:.1f} s]")
    meta["wall_seconds"] = clock() - t0
    meta["load_average_end"] = os.getloadavg()
    ctx.forget_meshes()
    return ctx.results


def write_json(results: dict, out: Path) -> None:
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_suffix(out.suffix + ".partial")
    with open(tmp, "w") as f:
        json.dump(json_ready(results), f, indent=1, allow_nan=False)
    os.replace(tmp, out)


def main(argv=None) -> dict:
    args = parse_args(argv)
    comm = MPI.COMM_WORLD
    logging.getLogger().setLevel(logging.WARNING)  # the form compiler logs at INFO
    ctx = Context(comm, MODES[args.mode or "full"], args, args.parts)
    results = run(ctx)
    if comm.rank == 0:
        out = Path(args.out)
        write_json(results, out)
        if not ctx.quiet:
            for line in summary_lines(results):
                print(line)
            la = results["meta"]["load_average_end"]
            print(f"\nwrote {out} ({results['meta']['wall_seconds']:.0f} s; load average at the end "
                  f"{la[0]:.2f} {la[1]:.2f} {la[2]:.2f})")
    comm.Barrier()
    return results
