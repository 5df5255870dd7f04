"""Part 5: AIJ against BAIJ (block size 2) for MatMult and the whole step.

Both matrices are what the core builds: operators.assemble_stiffness creates K in
its final format (fem.petsc.create_matrix + assemble_matrix, no MatConvert), and
the Integrator forms A = -dt M^-1 K from a second such assembly, scaled in place
with zero rows on the fixed dofs (no Mat.copy). "build s" is the Simulation's
whole set-up (stable dt, both assemblies, the lumped mass)."""
from __future__ import annotations

import time

import numpy as np
from mpi4py import MPI

from .bar import (bar_simulation, matrix_bytes, measure_step_variants, random_state, time_matmult,
                  vectors)
from .common import per_dof

VARIANTS = ("aij", "baij")


def same_operator(comm, A, ref) -> float:
    """max |A x - ref x| / max |ref x| for a random x (0 for the reference itself)."""
    if ref is None:
        return 0.0
    x0 = np.random.default_rng(2 + comm.rank).standard_normal(A.getLocalSize()[1])
    with vectors(A, x0) as (x, y), vectors(ref, x0) as (_, z):
        A.mult(x, y)
        ref.mult(x, z)
        diff = comm.allreduce(float(np.abs(y.array - z.array).max(initial=0.0)), op=MPI.MAX)
        scale = comm.allreduce(float(np.abs(z.array).max(initial=0.0)), op=MPI.MAX)
    return diff / scale


def _variant(ctx, tmesh, variant: str, ref) -> tuple[dict, object]:
    """The record of one format, and its A (the reference of the next)."""
    comm, mode = ctx.comm, ctx.mode
    t_build = time.perf_counter()
    sim = bar_simulation(tmesh, n_steps=mode.sim_steps, matrix_type=variant)
    integ = sim.integrator
    t_build = comm.allreduce(time.perf_counter() - t_build, op=MPI.MAX)
    N = int(sim.model.n_global)
    u0, v0 = random_state(integ)
    rec = {"matrix_type": integ.A.getType(), "block_size": integ.A.getBlockSize(),
           "n_dofs": N, "build_seconds": t_build}
    rec.update(matrix_bytes(integ.A, N))
    rec["same_A_as_aij"] = same_operator(comm, integ.A, ref)
    rec["timings"] = measure_step_variants(ctx, integ, ("step", "matmult"))
    rec["K_matmult"] = time_matmult(ctx, integ.K, integ.u_vec.array)
    integ.set_initial(u0, v0)
    s = sim.run()
    rec["simulation_step_median"] = s["step_time_median"]
    rec["ns_per_dof"] = per_dof({"step": rec["timings"]["step"]["median"],
                                 "matmult": rec["timings"]["matmult"]["median"],
                                 "simulation": s["step_time_median"],
                                 "K_matmult": rec["K_matmult"]}, N)
    return rec, ref or integ.A


def part_format(ctx) -> dict:
    tmesh, _ = ctx.mesh(ctx.mode.step_dofs)
    out, ref = {}, None
    for variant in VARIANTS:
        out[variant], ref = _variant(ctx, tmesh, variant, ref)
    rows = [[v, r["matrix_type"], f"{r['matrix_bytes_per_dof']:.0f}", f"{r['build_seconds']:.2f}"]
            + [f"{r['ns_per_dof'][k]:.2f}" for k in ("K_matmult", "matmult", "step", "simulation")]
            for v, r in out.items()]
    ctx.table(f"5. Matrix format, {out['aij']['n_dofs']:,} dofs, {ctx.comm.size} rank(s): ns per dof "
              "per step. K and A = -dt M^-1 K each assembled in the format (create_matrix + "
              "assemble_matrix; A scaled in place, no convert, no copy); build s = Simulation set-up",
              ["variant", "type", "matrix B/dof", "build s", "K MatMult", "A MatMult", "step",
               "Simulation"], rows)
    return out
