# # The paper's studies, speed against accuracy, and where each method goes unstable
#
# One command regenerates every figure under docs/figures/ (PNG, with its numbers
# as JSON beside it) and the write-up docs/results.md:
#
#     scripts/mpirun.sh -n 2 .venv/bin/python demos/paper_study.py        # or: make study
#     .venv/bin/python demos/paper_study.py --quick --out results/study_quick
#
# ``--quick`` runs every part on tiny meshes (well under a minute): the smoke
# version the tests use. ``--report-only`` rewrites docs/results.md from the JSON
# files already in the figures folder.
#
# The study code lives in impact_fenics/study/, one module per part, so that it
# can be tested; this driver only sequences it.

import argparse
import logging
import os
import time

from mpi4py import MPI

from impact_fenics.errors import user_errors
from impact_fenics.study import accuracy, bars, config, modelling, punch, report, stability
from impact_fenics.study.common import Writer, log

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)


def run(cfg: dict, out: str, report_path: str | None, comm=MPI.COMM_WORLD) -> dict:
    """Every part of the study with the sizes ``cfg``; figures and JSON in ``out``."""
    writer = Writer(out, comm)
    t_start = time.perf_counter()
    timings = {}
    results = {}

    def part(name, func, *args):
        t0 = time.perf_counter()
        log(f"[{name}]")
        results[name] = func(*args)
        timings[name] = comm.allreduce(time.perf_counter() - t0, op=MPI.MAX)
        log(f"[{name}] {timings[name]:.1f} s")

    # ## 1. The rigid punch: Sim1, Sim2, Sim3 with every method
    #
    # FILM (the exact O(n log n) solver and the dense factorisation the paper
    # timed), DME, and penalty with the paper's 6e9 N/m, the same value for
    # per-radian masses (x 2 pi), both readings of "auto" and the
    # stability-scaled choice. Punch penetration, contact force and the contact
    # CPU time of each step.
    part("punch", punch.paper_runs, cfg, writer)

    # ## 2. Why the penalty fails on the wide interface
    #
    # A uniform p from 1e7 to 1e11 N/m and a p proportional to the ring masses
    # at coupled beta_max on both sides of 4/3, on every radius.
    part("penalty_sweep", punch.penalty_sweep, cfg, writer)

    # ## 3. The bars: per-pair gaps and forces, sigma_zz against a converged reference
    part("bars_reference", bars.reference, cfg, writer)
    part("bars", bars.paper_runs, cfg, writer, results["bars_reference"])

    # ## 4. Speed against accuracy: every method on three meshes, with the Pareto front
    part("accuracy", accuracy.study, cfg, writer, results["bars_reference"])

    # ## 5. Stability: dt / dt_crit, the penalty against its bound, 1e5 steps
    part("stability", stability.study, cfg, writer)

    # ## 6. Model no more than the scene needs: domain, mesh, rigid or deformable punch
    part("modelling", modelling.study, cfg, writer)

    total = comm.allreduce(time.perf_counter() - t_start, op=MPI.MAX)
    meta = {"config": cfg["name"], "ranks": comm.size, "wall_time_total": total, "parts": timings,
            "load_average_end": os.getloadavg()[0], "cpu_count": os.cpu_count()}
    writer.json("study_run", meta)
    log(f"study ({cfg['name']}) done in {total:.0f} s on {comm.size} rank(s); figures in {out}")
    # ## 7. The write-up: docs/results.md, with the claims table, from the JSON files
    if report_path and comm.rank == 0:
        report.write(out, report_path)
        log(f"report: {report_path}")
    comm.barrier()
    return {"results": results, "meta": meta}


@user_errors
def main(argv=None):
    parser = argparse.ArgumentParser(description="Reproduce the paper's studies (docs/results.md).")
    parser.add_argument("--quick", action="store_true", help="tiny meshes: a smoke run")
    parser.add_argument("--out", default=None, help="figures folder (default docs/figures, "
                                                    "results/study_quick with --quick)")
    parser.add_argument("--report", default=None, help="results markdown (default docs/results.md; "
                                                       "with --quick: OUT/results.md)")
    parser.add_argument("--report-only", action="store_true",
                        help="only rewrite the report from the JSON files in the figures folder")
    args = parser.parse_args(argv)
    logging.getLogger().setLevel(logging.WARNING)  # the form compiler logs at INFO
    cfg = config.QUICK if args.quick else config.FULL
    out = args.out or os.path.join(ROOT, "results/study_quick" if args.quick else "docs/figures")
    report_path = args.report or (os.path.join(out, "results.md") if args.quick
                                  else os.path.join(ROOT, "docs/results.md"))
    if args.report_only:
        if MPI.COMM_WORLD.rank == 0:
            report.write(out, report_path)
        return None
    return run(cfg, out, report_path)


if __name__ == "__main__":
    main()
