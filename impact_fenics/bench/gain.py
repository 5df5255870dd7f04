"""Part 4c: the nonlinear steps on 2 ranks against 1, each step's gain over the STREAM
triad's gain from the second rank in the same run."""
from __future__ import annotations

from . import finite, plastic
from .scaling import STREAM_OPS, launch, part_stream

# the steps of the nonlinear parts whose gain from the second rank is measured, by part
GAIN_STEPS = {"j2": ("linear_step", "j2_fast_elastic", "j2_fast", "dp_fast"),
              "finite": ("j2_small_strain", "j2_finite_strain", "jc_finite_strain",
                         "nh_finite_strain")}


def part_gain(ctx) -> dict:
    """Part 4c: the nonlinear steps on 2 ranks against 1. Each step's gain t1 / t2 (the
    median step on one rank over that on two, the same global mesh), and that gain over
    the STREAM triad's gain from the second rank in the same run (the compiled triad of
    the roofline; PETSc's VecWAXPY gain beside it, whose one-rank figure falls well below
    the compiled triad's on some machines): a step bound by memory
    traffic can gain what the shared bus gives, so 1 means it does; a step bound by
    arithmetic can gain up to 2 / triad gain. The one-rank figures are this run's j2,
    finite and stream parts (made here if they were not asked for)."""
    one = {"j2": ctx.results.get("j2") or plastic.part_j2(ctx),
           "finite": ctx.results.get("finite") or finite.part_finite(ctx)}
    stream1 = ctx.results.get("stream") or part_stream(ctx)
    child = launch(ctx, 2, ["j2", "finite", "stream"], ctx.mode.rank_sizes)
    if "error" in child:
        ctx.log(f"   the 2-rank run failed: {child['error']}")
        return {"error": child["error"]}
    # the STREAM triad a = b + s c compiled (the roofline's: each rank's own arrays, all
    # ranks at once, the slowest rank's GB/s): the two ranks' sum over one rank's
    triad_gbs = {"1": one["j2"]["machine_rates"]["triad_gbs"],
                 "2": child["j2"]["machine_rates"]["triad_gbs"]}  # one rank's, GB/s
    triad = 2.0 * (triad_gbs["2"] / triad_gbs["1"])
    waxpy = child["stream"]["waxpy_triad"]["gbs"] / stream1["waxpy_triad"]["gbs"]
    res = {"triad_gain": triad, "triad_gbs": triad_gbs, "waxpy_gain": waxpy,
           "triad": "the compiled STREAM triad a = b + s c (roofline.machine_rates' "
                    "triad_gbs, one rank's with all ranks at once) on 2 ranks, summed, over "
                    "1 rank's; waxpy_gain: PETSc's VecWAXPY (part stream) likewise",
           "steps": {}, "meta_two_ranks": child.get("meta", {}),
           "stream_gbs": {str(n): {op: s[op]["gbs"] for op in STREAM_OPS}
                          for n, s in ((1, stream1), (2, child["stream"]))}}
    rows = []
    for part, keys in GAIN_STEPS.items():
        t1, t2 = one[part]["timings"], child[part]["timings"]
        for k in keys:
            if k not in t1 or k not in t2:
                continue
            gain = t1[k] / t2[k]
            res["steps"][k] = {"ms_1": 1e3 * t1[k], "ms_2": 1e3 * t2[k], "gain": gain,
                               "over_triad": gain / triad}
            rows.append([k, f"{1e3 * t1[k]:.3f}", f"{1e3 * t2[k]:.3f}", f"{gain:.2f}",
                         f"{gain / triad:.2f}"])
    ctx.table(f"4c. Nonlinear steps, 2 ranks against 1 (STREAM triad gain {triad:.2f} in "
              f"this run, compiled; PETSc VecWAXPY {waxpy:.2f})",
              ["step", "ms 1 rank", "ms 2 ranks", "gain t1/t2", "/ triad gain"],
              rows)
    return res
