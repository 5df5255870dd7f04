"""Part: the whole run against its steps, and the cost of one field write against how many
came before.

A run is not its median step: outputs, history rows, energy at outputs and
anything compiled late add to the loop. For the punch Sim3 (610 constraints,
DME, fields every 20 steps, history every step) and the bar impact (FILM, fields
every 25 steps; the demo's mesh, h = 0.02 m, and the same scene at h = 0.01 and
0.005 m: the same 500 steps and output schedule with dt scaled with h, so the
ratios compare the same loop at 4x and 16x the dofs over a shorter physical
time), with the default outputs into a scratch directory, this part
reports the loop's wall time over (steps x median step) and over (steps x a bare
MatMult of K), where the time beyond the median steps went (each phase's total
over the loop minus steps x its median; rest: the loop's own Python; under MPI
the phase totals and medians are the slowest rank's, so rest may read below 0), any
kernel compiled inside the loop, and the set-up by phase (mesh; the
Simulation's stability bound, operators and contact set-up; the run's outputs
before the first step). Then the contact share of the step at Sim3 for DME,
penalty and FILM fast (median contact time of a step over the median step,
without outputs). Between the two, the nonlinear scenes run whole from their scene
files, the whole split by part (whole_nonlinear.py).

Run as a script (``python -m impact_fenics.bench.whole_run``) it prints the same
rows for whatever code is importable, so the figures of an older tree can be taken
the same way.
"""
from __future__ import annotations

import os
import tempfile
import time

import numpy as np
from mpi4py import MPI

from .whole_nonlinear import beyond_median, measure_nonlinear, report as report_nonlinear

PUNCH_DT, PUNCH_STEPS, PUNCH_EVERY = 3.64e-7, 400, 20
BAR_DT, BAR_T_END, BAR_EVERY = 1e-6, 5e-4, 25
BAR_H = 0.02  # the demo's element size (m); BAR_DT is for it
BAR_FINER = (0.01, 0.005)  # finer meshes (m): 4x and 16x the dofs, dt = BAR_DT h / BAR_H


def _matmult_median(integ, comm, repeats: int = 15, inner: int = 100) -> float:
    """Median seconds of one bare K x (the slowest rank's), after a warm-up."""
    x = integ.K.createVecRight()
    y = integ.K.createVecLeft()
    x.setRandom()
    for _ in range(inner):
        integ.K.mult(x, y)
    samples = []
    for _ in range(repeats):
        comm.Barrier()
        t = time.perf_counter()
        for _ in range(inner):
            integ.K.mult(x, y)
        samples.append(comm.allreduce((time.perf_counter() - t) / inner, op=MPI.MAX))
    return float(np.median(samples))


def _scene(kind: str, out: str, comm, h: float = BAR_H, compiled: bool = True):
    """(simulation, set-up seconds by phase) of a scene with its demo's default outputs;
    ``h`` (m) the bars' element size: at a finer one dt shrinks with h and the run keeps
    the demo's number of steps (BAR_T_END / BAR_DT) and output schedule; ``compiled``
    False: the Python step throughout (Settings.compiled_steps)."""
    python_steps = {} if compiled else {"compiled_steps": False}
    from .. import meshing, scenes
    from ..simulation import Settings

    clock = time.perf_counter
    setup = {}
    t = clock()
    if kind == "punch_sim3":
        tmesh = meshing.punch_block(comm=comm)
    else:
        tmesh = meshing.coaxial_bars(radius=0.1, striker_length=0.8, target_length=0.85, h=h,
                                     structured=False, comm=comm)
    setup["mesh"] = clock() - t
    t = clock()
    if kind == "punch_sim3":
        settings = Settings(dt=PUNCH_DT, n_steps=PUNCH_STEPS, out=out, output_every=PUNCH_EVERY,
                            quiet=True, plots=False, **python_steps)
        sim = scenes.punch_indentation(settings, scenes.make_method("dme"),
                                       radius=scenes.PUNCH_RADII[6], tmesh=tmesh, comm=comm)
    else:
        from ..bodies import Body, DeformableModel
        from ..contact import pair_surfaces
        from ..materials import STEEL
        from ..simulation import Simulation

        settings = Settings(dt=BAR_DT * h / BAR_H, n_steps=round(BAR_T_END / BAR_DT), out=out,
                            output_every=BAR_EVERY, quiet=True, plots=False, **python_steps)
        model = DeformableModel(tmesh, [Body("striker", STEEL), Body("target", STEEL)])
        sim = Simulation(model, settings, initial_velocity={"striker": (0.0, 5.0)})
        sim.add_contact(pair_surfaces(model, "striker_contact", "target_contact"),
                        scenes.make_method("film"))
        sim.add_probe("sigma_zz_obs", (0.1, 0.2), "sigma_zz")
    setup["simulation"] = clock() - t
    return sim, setup


def measure(kind: str, comm: MPI.Comm, h: float = BAR_H, compiled: bool = True) -> dict:
    """One whole run of scene ``kind`` ('punch_sim3' or 'bars', the bars at element size
    ``h``, m; ``compiled`` False: with the Python step throughout): its ratios and set-up."""
    scratch = tempfile.mkdtemp(prefix="ifx_whole_") if comm.rank == 0 else None
    scratch = comm.bcast(scratch, root=0)
    sim, setup = _scene(kind, os.path.join(scratch, kind), comm, h, compiled)
    t = time.perf_counter()
    summary = sim.run()
    total = comm.allreduce(time.perf_counter() - t, op=MPI.MAX)
    wall = summary["wall_time"]
    n = summary["stopped_at_step"]
    median = summary["step_time_median"]
    matmult = _matmult_median(sim.integrator, comm)
    setup.update(summary.get("setup_time", {}))
    setup["run_outside_loop"] = total - wall
    totals = summary.get("time_per_step_total", {})
    medians = summary.get("time_per_step_median", {})
    # the loop beyond its median steps, by phase (s): total - steps x median; the rest is
    # what no phase timer holds (timers, progress, checks, the loop's Python)
    beyond = beyond_median(summary)
    label = kind if kind != "bars" or h == BAR_H else f"bars h={h:g}"
    if not compiled:
        label += " (Python steps)"
    res = {"scene": label, "h": h if kind == "bars" else None, "n_ranks": comm.size, "n_steps": n, "n_dofs": summary["n_dofs"],
           "loop_wall": wall, "step_median": median, "matmult": matmult,
           "wall_over_steps_median": wall / (n * median),
           "wall_over_steps_matmult": wall / (n * matmult),
           "setup": setup, "phase_totals": totals, "phase_medians": medians,
           "beyond_median": beyond,
           "ns_per_element_cycle": summary.get("ns_per_element_cycle"),
           "ns_per_element_cycle_bodies": {k: b.get("ns_per_element_cycle")
                                           for k, b in summary.get("bodies", {}).items()},
           "compiled_in_loop": summary.get("timing", {}).get("compiled_in_loop"),
           "compiled_steps": summary.get("timing", {}).get("compiled_steps", False),
           "compiled_frames": summary.get("timing", {}).get("compiled_frames", False)}
    if comm.rank == 0:
        import shutil
        shutil.rmtree(scratch, ignore_errors=True)
    return res


def write_cost(comm: MPI.Comm, n_writes: int = 200, every: int = 50) -> dict:
    """Seconds per field write, in blocks of ``every`` writes (rounded down to whole flushes:
    a write may only copy its frame into the writer's batch, so a block holds its flushes,
    and its mean is a write's cost with the batch's rows and the XML amortised), on the
    punch mesh: flat when the cost does not depend on the writes before. (With the
    writer's worker thread, writes back to back leave it no steps to run beside: a write
    waits for the batch before it, so this is the rows' throughput, more than a run's
    loop pays for a write.)"""
    from .. import meshing
    from ..bodies import Body, DeformableModel
    from ..materials import STEEL

    from ..cell_fields import STRESS_NAMES
    from ..xdmf import FieldWriter

    tmesh = meshing.punch_block(comm=comm)
    model = DeformableModel(tmesh, [Body("block", STEEL)])
    scratch = tempfile.mkdtemp(prefix="ifx_write_") if comm.rank == 0 else None
    scratch = comm.bcast(scratch, root=0)
    writer = FieldWriter(os.path.join(scratch, "fields.xdmf"), model, cell_fields=STRESS_NAMES)
    every = max(1, every // writer.flush_every) * writer.flush_every
    rng = np.random.default_rng(comm.rank)
    u = writer.ghosted(rng.standard_normal(model.n_owned) * 1e-6, 0)
    v = writer.ghosted(rng.standard_normal(model.n_owned), 1)
    cells = {k: rng.standard_normal(writer.n_cells) for k in STRESS_NAMES}
    blocks = []
    for b in range(n_writes // every):
        comm.Barrier()
        t = time.perf_counter()
        for k in range(every):
            writer.write((b * every + k) * 1e-6, b * every + k, u, v, cells)
        blocks.append(comm.allreduce((time.perf_counter() - t) / every, op=MPI.MAX))
    writer.close()
    if comm.rank == 0:
        import shutil
        shutil.rmtree(scratch, ignore_errors=True)
    return {"every": every, "batch_depth": writer.depth, "asynchronous": writer.asynchronous,
            "seconds_per_write_by_block": blocks,
            "growth_last_over_first": blocks[-1] / blocks[0]}


def row_cost(kind: str, comm: MPI.Comm, rows: int = 200, repeats: int = 30) -> dict:
    """Seconds per history row of scene ``kind``: filling it (without and with the per-pair
    record) and, per row, writing a block of rows to history.csv."""
    import gc

    from .. import rundir
    from ..outputs import momentum_columns, open_tables, record_pairs
    from ..probes import Probes

    scratch = tempfile.mkdtemp(prefix="ifx_rows_") if comm.rank == 0 else None
    scratch = comm.bcast(scratch, root=0)
    sim, _ = _scene(kind, os.path.join(scratch, "run"), comm)
    staging = rundir.prepare_directory(os.path.join(scratch, "run"), comm)
    probes = Probes(sim.model, sim._probe_specs) if sim._probe_specs else None
    tables, history_row, pair_tables = open_tables(
        staging, probes, sim.contacts, sim.integrator, sim.settings.dt,
        momentum_columns(sim.model.bodies, sim.contacts),
        sim.n_steps // sim.settings.pairs_every + 2, comm)
    sim.integrator.predict()
    for c in sim.contacts:
        c.step()
    sim.integrator.advance()
    gc.collect()
    clock = time.perf_counter
    table = tables["history"]
    res = {"columns": len(table.columns), "probes": len(sim._probe_specs),
           "pairs": sum(c.n for c in sim.contacts)}
    for label, pairs in (("fill", False), ("fill_with_pairs", True)):
        samples = []
        for _ in range(repeats):
            table._n = 0
            for _, pt in pair_tables:
                pt._n, pt._rows = 0, 0
            t = clock()
            for _ in range(rows):
                history_row()
                if pairs:
                    record_pairs(pair_tables, sim.integrator.n, sim.settings.dt)
            samples.append((clock() - t) / rows)
        res[label] = float(np.median(samples))
    samples = []
    for _ in range(repeats // 3):
        table._n = table._buf.shape[0]
        t = clock()
        table.flush()
        samples.append((clock() - t) / table._buf.shape[0])
    res["block_write_per_row"] = float(np.median(samples))
    samples = []
    for _, pt in pair_tables:  # rank 0: a block of per-pair rows into contact_pairs.h5
        for _ in range(repeats // 3):
            pt._n, pt._rows = pt._clock.shape[0], 0
            t = clock()
            pt.flush()
            samples.append((clock() - t) / pt._clock.shape[0])
    res["pairs_block_write_per_row"] = comm.bcast(float(np.median(samples)) if samples else 0.0)
    for tbl in tables.values():
        tbl.close()
    if comm.rank == 0:
        import shutil
        shutil.rmtree(scratch, ignore_errors=True)
    return res


def contact_share(comm: MPI.Comm, steps: int = PUNCH_STEPS) -> list[dict]:
    """Median contact time of a step (detection + solve + update) over the median step at
    Sim3 (610 constraints) for DME, penalty and FILM fast, without outputs."""
    from .. import meshing, scenes
    from ..simulation import Settings

    tmesh = meshing.punch_block(comm=comm)
    out = []
    for name in ("dme", "penalty", "film"):
        settings = Settings(dt=PUNCH_DT, n_steps=steps, out=None, fields=False, quiet=True,
                            plots=False)
        sim = scenes.punch_indentation(settings, scenes.make_method(name),
                                       radius=scenes.PUNCH_RADII[6], tmesh=tmesh, comm=comm)
        s = sim.run()
        contact, step = s["contact_cpu_time_per_step_median"], s["step_time_median"]
        out.append({"method": "film fast" if name == "film" else name,
                    "n_constraints": sim.contacts[0].n, "contact": contact, "step": step,
                    "share": contact / step,
                    "compiled_in_loop": s["timing"]["compiled_in_loop"]})
    return out


def part_whole_run(ctx) -> dict:
    """The whole-run table (both scenes), the nonlinear scenes' whole runs
    (whole_nonlinear.py), the contact share at Sim3 and the cost per field write and
    history row."""
    res, runs = {}, []
    for kind, h, compiled in _RUNS:
        r = measure(kind, ctx.comm, h, compiled)
        res[r["scene"]] = r
        runs.append(r)
    ctx.table(f"Whole run vs its steps ({ctx.comm.size} rank(s); default outputs; the finer "
              "bars: the demo's 500 steps, dt scaled with h)", HEADERS, [_row(r) for r in runs])
    ctx.table("   where the loop went beyond steps x median (ms), by phase; set-up (s) by phase",
              BEYOND_HEADERS, [_beyond_row(r) for r in runs])
    res["nonlinear"] = measure_nonlinear(ctx.comm, ctx.mode.name)
    report_nonlinear(ctx, res["nonlinear"])
    res["contact_share"] = contact_share(ctx.comm)
    ctx.table("Contact share of the step at Sim3 (punch R_z = 6 m, no outputs; medians in us)",
              ["method", "constraints", "contact", "step", "share", "compiled in loop"],
              [[r["method"], r["n_constraints"], f"{1e6 * r['contact']:.1f}",
                f"{1e6 * r['step']:.1f}", f"{100 * r['share']:.1f} %",
                ", ".join(r["compiled_in_loop"]) or "none"] for r in res["contact_share"]])
    for kind in ("bars", "punch_sim3"):
        rc = res[f"rows_{kind}"] = row_cost(kind, ctx.comm)
        rc["row"] = rc["fill"] + rc["block_write_per_row"]
        ctx.log(f"   history row ({kind}, {rc['columns']} columns, {rc['probes']} probe(s)): "
                f"{1e6 * rc['row']:.2f} us (target < 2) = fill {1e6 * rc['fill']:.2f} + block "
                f"write {1e6 * rc['block_write_per_row']:.2f}; a per-pair row ({rc['pairs']} "
                f"pairs, every pairs_every steps) adds {1e6 * (rc['fill_with_pairs'] - rc['fill']):.2f}"
                f" + block write {1e6 * rc['pairs_block_write_per_row']:.2f}")
    res["write_cost"] = write_cost(ctx.comm)
    wc = res["write_cost"]
    if "seconds_per_write_by_block" in wc:
        thread = ", rows by the worker thread" if wc.get("asynchronous") else ""
        ctx.log("   field write (punch mesh, batch depth "
                f"{wc.get('batch_depth', 1)}{thread}), ms per write with its flushes in blocks of "
                f"{wc['every']}: " + ", ".join(f"{1e3 * s:.2f}" for s in wc["seconds_per_write_by_block"]))
    return res


# (scene, the bars' element size in m, compiled steps) of the whole-run table: the demo's
# bars also with the Python step throughout, the ratio the compiled steps gain
_RUNS = ((("punch_sim3", BAR_H, True), ("bars", BAR_H, True), ("bars", BAR_H, False))
         + tuple(("bars", h, True) for h in BAR_FINER))


HEADERS = ["scene", "dofs", "steps", "loop (s)", "median step (us)", "MatMult (us)",
           "wall/(n x step)", "wall/(n x MatMult)", "ns/element/cycle", "steps between events",
           "set-up (s): mesh, sim, run"]


BEYOND_HEADERS = ["scene", "f_int", "contact", "history", "output", "rest", "rest/step (us)",
                  "compiled in loop", "stability", "operators", "contact set-up", "outputs",
                  "kernels"]


def _beyond_row(r: dict) -> list:
    b, s = r["beyond_median"], r["setup"]
    contact = sum(b.get(k, 0.0) for k in ("contact_detection", "contact_solve", "contact_update"))
    return [r["scene"]] + [f"{1e3 * v:.1f}" for v in (b.get("f_int", 0.0), contact,
                                                      b.get("history", 0.0), b.get("output", 0.0),
                                                      b["rest"])] + \
        [f"{1e6 * b['rest'] / r['n_steps']:.2f}", ", ".join(r["compiled_in_loop"] or []) or "none"] + \
        [f"{s.get(k, 0.0):.2f}" for k in ("stability", "operators", "contact", "outputs",
                                          "kernels")]


def _row(r: dict) -> list:
    s = r["setup"]
    return [r["scene"], r["n_dofs"], r["n_steps"], f"{r['loop_wall']:.3f}", f"{1e6 * r['step_median']:.1f}",
            f"{1e6 * r['matmult']:.1f}", f"{r['wall_over_steps_median']:.2f}",
            f"{r['wall_over_steps_matmult']:.2f}",
            f"{r['ns_per_element_cycle']:.0f}" if r.get("ns_per_element_cycle") else "-",
            ("compiled, frames too" if r.get("compiled_frames") else "compiled")
            if r.get("compiled_steps") else "Python",
            f"{s['mesh']:.2f}, {s['simulation']:.2f}, {s['run_outside_loop']:.2f}"]


if __name__ == "__main__":
    import json
    import sys

    comm = MPI.COMM_WORLD
    results = [measure(k, comm, h) for k, h, compiled in _RUNS if compiled]
    if comm.rank == 0:
        from .tables import format_table

        print(format_table(f"Whole run ({comm.size} rank(s))", HEADERS, [_row(r) for r in results]))
        if len(sys.argv) > 1:
            with open(sys.argv[1], "w") as f:
                json.dump(results, f, indent=1)
