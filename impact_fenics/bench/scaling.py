"""Parts 3, 4a and 4b: step and MatMult time per dof over mesh sizes, a STREAM-like
bandwidth, and both again on 2 ranks (this harness launched under mpirun)."""
from __future__ import annotations

import os
import subprocess
import sys
import tempfile

from ..compat import mpi_launcher
from .bar import bar_integrator, matrix_bytes, measure_step_variants
from .common import ROOT, child_env, per_dof, run_json
from .peers import MATFREE, matfree_record

STEP_OPS = ("step", "matmult", "multadd", "axpy")
STREAM_OPS = ("copy", "axpy", "waxpy_triad", "dot")


def _scaling_record(ctx, target: int, with_matfree: bool) -> dict:
    tmesh, h = ctx.mesh(target, keep=(target == ctx.mode.step_dofs))
    model, integ = bar_integrator(tmesh)
    N = int(model.n_global)
    rec = {"target_dofs": target, "n_dofs": N, "h": h, "ranks": ctx.comm.size}
    rec.update(matrix_bytes(integ.A, N))
    rec["timings"] = measure_step_variants(ctx, integ)
    t = {k: v["median"] for k, v in rec["timings"].items()}
    if with_matfree:
        rec["matfree"] = matfree_record(ctx, model, integ)
        t["matfree"] = rec["matfree"]["force"]
        t["K_matmult"] = rec["matfree"]["K_matmult"]
    rec["ns_per_dof"] = per_dof(t, N)
    rec["step_over_matmult"] = t["step"] / t["matmult"]
    integ.A.destroy()
    integ.K.destroy()
    return rec


def part_scaling(ctx, sizes=None) -> list:
    """The bar at each size (``sizes``, else --sizes, else the mode's)."""
    sizes = tuple(sizes or ctx.args.sizes or ctx.mode.sizes)
    with_matfree = "matfree" in ctx.parts and ctx.comm.size == 1 and MATFREE.exists()
    out = [_scaling_record(ctx, target, with_matfree) for target in sizes]
    rows = [[f"{r['n_dofs']:,}", f"{r['nnz_per_row']:.1f}"]
            + [f"{r['ns_per_dof'][k]:.2f}" for k in STEP_OPS]
            + [f"{r['step_over_matmult']:.2f}",
               f"{r['step_bytes_per_dof'] / r['ns_per_dof']['step']:.1f}"]
            + ([f"{r['ns_per_dof']['matfree']:.2f}"] if with_matfree else []) for r in out]
    ctx.table(f"3. Scaling over dofs on {ctx.comm.size} rank(s): ns per dof per step",
              ["dofs", "nnz/row", "step", "MatMult", "MultAdd", "AXPY", "step/MatMult",
               "step GB/s"] + (["matfree Ku"] if with_matfree else []), rows)
    return out


def part_stream(ctx) -> dict:
    from petsc4py import PETSc

    comm, n = ctx.comm, ctx.mode.stream_n
    x = PETSc.Vec().createMPI(n, comm=comm)
    y, w = x.duplicate(), x.duplicate()
    x.set(1.0), y.set(2.0), w.set(0.0)
    # (call, bytes per entry as STREAM counts them, bytes with the write-allocate of
    # a written vector that is not read)
    ops = {"copy": (lambda: x.copy(y), 16, 24), "axpy": (lambda: y.axpy(1e-9, x), 24, 24),
           "waxpy_triad": (lambda: w.waxpy(1e-9, x, y), 24, 32),
           "dot": (lambda: x.dot(y), 16, 16)}
    res = {"n": n, "ranks": comm.size, "vector_mb": 8 * n / 2 ** 20}
    for k, (fn, b, b_wa) in ops.items():
        t = ctx.median(fn)
        res[k] = {"seconds": t, "bytes_per_entry": b, "gbs": b * n / t / 1e9,
                  "bytes_per_entry_write_allocate": b_wa, "gbs_write_allocate": b_wa * n / t / 1e9}
    res["best_gbs"] = max(res[k]["gbs_write_allocate"] for k in ops)
    for v in (x, y, w):
        v.destroy()
    ctx.table(f"4a. STREAM-like bandwidth on {comm.size} rank(s), vectors of "
              f"{res['vector_mb']:.0f} MB (PETSc Vec ops; BLAS: see meta)",
              ["op", "B/entry", "GB/s", "B/entry w/ write-alloc", "GB/s w/ write-alloc"],
              [[k, res[k]["bytes_per_entry"], f"{res[k]['gbs']:.1f}",
                res[k]["bytes_per_entry_write_allocate"], f"{res[k]['gbs_write_allocate']:.1f}"]
               for k in ops])
    return res


def launch(ctx, n_ranks: int, parts: list[str], sizes) -> dict:
    """This harness on ``n_ranks`` ranks in a fresh mpirun (MPI variables scrubbed)."""
    runner = mpi_launcher(ROOT)
    fd, path = tempfile.mkstemp(prefix="bench_child_", suffix=".json")
    os.close(fd)
    cmd = runner + ["-n", str(n_ranks), sys.executable, "-m", "impact_fenics.bench",
                    "--mode", ctx.mode.name, "--parts", ",".join(parts), "--child",
                    "--sizes", ",".join(str(s) for s in sizes), "--out", path]
    ctx.log(f"   launching: {' '.join(cmd[-12:])}")
    try:
        return run_json(cmd, path, child_env(), str(ROOT), timeout=600)
    except (subprocess.SubprocessError, OSError, ValueError, RuntimeError) as exc:
        return {"error": str(exc)}
    finally:
        if os.path.exists(path):
            os.remove(path)


def _speedup_row(a: dict, b: dict) -> tuple[dict, list]:
    """The speed-up record and table row of one size, 1 rank (a) against 2 ranks (b)."""
    su = {k: a["timings"][k]["median"] / b["timings"][k]["median"] for k in STEP_OPS}
    rec = {"target_dofs": a["target_dofs"], "n_dofs": a["n_dofs"], "speedup": su,
           "step_ns_per_dof": {"1": a["ns_per_dof"]["step"], "2": b["ns_per_dof"]["step"]},
           "matmult_ns_per_dof": {"1": a["ns_per_dof"]["matmult"], "2": b["ns_per_dof"]["matmult"]}}
    row = [f"{a['n_dofs']:,}", f"{a['ns_per_dof']['step']:.2f}", f"{b['ns_per_dof']['step']:.2f}",
           f"{su['step']:.2f}", f"{a['ns_per_dof']['matmult']:.2f}",
           f"{b['ns_per_dof']['matmult']:.2f}", f"{su['matmult']:.2f}", f"{su['axpy']:.2f}"]
    return rec, row


def part_ranks(ctx) -> dict:
    sizes = ctx.mode.rank_sizes
    one = {r["target_dofs"]: r for r in ctx.results.get("scaling", []) if r["target_dofs"] in sizes}
    missing = [s for s in sizes if s not in one]
    if missing:
        one.update((r["target_dofs"], r) for r in part_scaling(ctx, missing))
    stream1 = ctx.results.get("stream") or part_stream(ctx)
    child = launch(ctx, 2, ["scaling", "stream"], sizes)
    res = {"sizes": list(sizes), "one_rank": {"scaling": [one[s] for s in sizes], "stream": stream1}}
    if "error" in child:
        res["error"] = child["error"]
        ctx.log(f"   the 2-rank run failed: {child['error']}")
        return res
    res["two_ranks"] = {"scaling": child["scaling"], "stream": child["stream"],
                        "meta": child.get("meta", {})}
    two = {r["target_dofs"]: r for r in child["scaling"]}
    bw = {k: child["stream"][k]["gbs"] / stream1[k]["gbs"] for k in STREAM_OPS}
    res["bandwidth_ratio"] = bw
    pairs = [_speedup_row(one[s], two[s]) for s in sizes]
    res["speedup"] = [rec for rec, _ in pairs]
    ctx.table("4b. 1 rank against 2 ranks (ns per dof per step, wall clock; speed-up = t1/t2)",
              ["dofs", "step 1r", "step 2r", "speed-up", "MatMult 1r", "MatMult 2r",
               "speed-up", "AXPY sp-up"], [row for _, row in pairs])
    ctx.log("   STREAM 2 ranks / 1 rank: " + ", ".join(f"{k} {v:.2f}" for k, v in bw.items())
            + f"  ({stream1['waxpy_triad']['gbs']:.1f} -> "
              f"{child['stream']['waxpy_triad']['gbs']:.1f} GB/s triad)")
    return res

