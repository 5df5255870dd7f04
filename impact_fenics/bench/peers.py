"""Parts 6 and 7: what else could do the step. A compiled matrix-free CST K u
(benchmarks/matfree_cst.py) against MatMult of K, and Akantu's explicit
lumped-mass step (benchmarks/akantu_peer.py, in a venv of its own)."""
from __future__ import annotations

import importlib
import math
import os
import subprocess
import sys
import tempfile

import numpy as np

from .bar import (bar_integrator, bar_mesh, bar_simulation, matrix_bytes, random_state, step_fn,
                  vectors)
from .common import ROOT, child_env, ns_per_dof, run_json

BENCHMARKS = ROOT / "benchmarks"
MATFREE = BENCHMARKS / "matfree_cst.py"
AKANTU_VENV = ("'/usr/bin/python3 -m venv /tmp/akantu-venv && /tmp/akantu-venv/bin/pip "
               "install akantu'")


def load_benchmark(name: str):
    """Import benchmarks/<name>.py (once per process)."""
    sys.path.insert(0, str(BENCHMARKS))
    try:
        return importlib.import_module(name)
    finally:
        sys.path.pop(0)


def matfree_record(ctx, model, integ) -> dict:
    """The prototype's f = K u (batched and plain) against MatMult of the integrator's K."""
    mf = load_benchmark("matfree_cst").MatrixFreeCST(model)
    K = integ.K
    with vectors(K, integ.u_vec.array) as (x, y):
        xa = x.array.copy()
        f = np.empty_like(xa)
        K.mult(x, y)
        scale = np.abs(y.array).max()
        err = max(float(np.abs(mf.force(xa, f, batched) - y.array).max() / scale)
                  for batched in (False, True))
        return {"rel_diff_to_K_u": err,
                "force": ctx.median(lambda: mf.force(xa, f, True)),
                "force_plain": ctx.median(lambda: mf.force(xa, f, False)),
                "K_matmult": ctx.median(lambda: K.mult(x, y)),
                "n_cells": mf.n_cells}


def part_matfree(ctx) -> dict:
    tmesh, _ = ctx.mesh(ctx.mode.step_dofs)
    model, integ = bar_integrator(tmesh)
    N = int(model.n_global)
    rec = matfree_record(ctx, model, integ)
    rec["n_dofs"] = N
    rec["ns_per_dof"] = {"matfree": ns_per_dof(rec["force"], N),
                         "matfree_plain": ns_per_dof(rec["force_plain"], N),
                         "K_matmult": ns_per_dof(rec["K_matmult"], N)}
    rec["matfree_over_matmult"] = rec["force"] / rec["K_matmult"]
    bytes_per_dof = load_benchmark("matfree_cst").matfree_bytes_per_dof
    rec["bytes_per_dof"] = {"matfree": bytes_per_dof(rec["n_cells"], N),
                            "K_matmult": matrix_bytes(integ.K, N)["matmult_bytes_per_dof"]}
    by_size = [(r["n_dofs"], r["matfree"]) for r in ctx.results.get("scaling", []) if "matfree" in r]
    rows = [[f"{n:,}", f"{ns_per_dof(r['K_matmult'], n):.2f}",
             f"{ns_per_dof(r['force_plain'], n):.2f}", f"{ns_per_dof(r['force'], n):.2f}",
             f"{r['force'] / r['K_matmult']:.2f}", f"{r['rel_diff_to_K_u']:.1e}"]
            for n, r in [(N, rec)] + [(n, r) for n, r in by_size if n != N]]
    ctx.table("6. Matrix-free axisymmetric CST K u (benchmarks/matfree_cst.py: C via cffi, gcc -O3 "
              "-march=native, serial) against MatMult of K; "
              f"~{rec['bytes_per_dof']['matfree']:.0f} B/dof against "
              f"{rec['bytes_per_dof']['K_matmult']:.0f} B/dof",
              ["dofs", "MatMult ns/dof", "plain loop", "batched (SIMD)", "batched/MatMult",
               "rel. diff"], rows)
    return rec


def _akantu_missing(ctx, py: str) -> str | None:
    """Why there is no Akantu interpreter at ``py`` (None once there is one)."""
    if os.path.exists(py):
        return None
    if not ctx.args.install_akantu:
        reason = (f"no Akantu interpreter at {py}: create it with {AKANTU_VENV} "
                  "or pass --install-akantu")
        ctx.log("   akantu: skipped, " + reason)
        return reason
    venv = os.path.dirname(os.path.dirname(py))
    ctx.log(f"   installing akantu into {venv} (pip, a separate venv)")
    try:
        base = getattr(sys, "_base_executable", None) or "/usr/bin/python3"
        subprocess.run([base, "-m", "venv", venv], check=True, capture_output=True, timeout=120)
        subprocess.run([os.path.join(venv, "bin", "pip"), "install", "-q", "akantu"],
                       check=True, capture_output=True, timeout=480)
    except (subprocess.SubprocessError, OSError) as exc:
        return f"akantu did not install: {exc}"
    return None


def _run_akantu(ctx, py: str, material: str = "elastic", yield_stress: float = 0.0) -> dict:
    """benchmarks/akantu_peer.py on the bar of ``akantu_dofs`` dofs, in a scratch folder;
    ``material`` 'elastic' or 'j2' (plastic_linear_isotropic_hardening, sigma_y in Pa)."""
    mode = ctx.mode
    work = tempfile.mkdtemp(prefix="bench_akantu_")
    mesh = os.path.join(work, "bar.msh")
    load_benchmark("akantu_peer").write_mesh(mesh, radius=0.5, length=1.0,
                                             h=1.0 / math.sqrt(mode.akantu_dofs))
    out = os.path.join(work, "akantu.json")
    cmd = [py, str(BENCHMARKS / "akantu_peer.py"), "--mesh", mesh, "--steps",
           str(mode.akantu_steps), "--repeats", str(max(3, mode.repeats // 2)), "--out", out,
           "--material", material]
    if material == "j2":
        cmd += ["--yield-stress", repr(yield_stress), "--hardening", "2e9"]
    return run_json(cmd, out, child_env("PYTHON", OMP_NUM_THREADS="1"), work, timeout=300)


def part_akantu(ctx) -> dict:
    py = ctx.args.akantu_python
    reason = _akantu_missing(ctx, py)
    if reason:
        return {"skipped": reason}
    try:
        rec = _run_akantu(ctx, py)
    except (subprocess.SubprocessError, OSError, ValueError, RuntimeError) as exc:
        ctx.log(f"   akantu: the run failed: {exc}")
        return {"skipped": f"akantu run failed: {exc}"}
    # ours on the same size, the same kind of measurement (integrator step)
    from .plastic import j2_integrator, yielding_steel

    tmesh, h = bar_mesh(ctx.comm, ctx.mode.akantu_dofs)
    sim = bar_simulation(tmesh, n_steps=10)
    random_state(sim.integrator)
    N = int(sim.model.n_global)
    rec["ours_step_ns_per_dof"] = ns_per_dof(ctx.median(step_fn(sim.integrator)), N)
    rec["ours_n_dofs"] = N
    rec["akantu_over_ours"] = rec["ns_per_dof_per_step"] / rec["ours_step_ns_per_dof"]
    rows = [[f"akantu {rec.get('version', '')}", "elastic", f"{rec['n_dofs']:,}",
             f"{rec['ns_per_dof_per_step']:.1f}"],
            ["impact_fenics", "elastic", f"{N:,}", f"{rec['ours_step_ns_per_dof']:.2f}"]]
    # J2 (linear isotropic hardening) on both, yield stress scaled to the random state
    steel = yielding_steel(h)
    try:
        rec["j2"] = _run_akantu(ctx, py, "j2", steel.yield_stress)
    except (subprocess.SubprocessError, OSError, ValueError, RuntimeError) as exc:
        rec["j2"] = {"skipped": f"akantu J2 run failed: {exc}"}
    _, integ = j2_integrator(tmesh, "fast", sim.integrator.dt, steel)
    step = step_fn(integ)
    step()
    rec["ours_j2_step_ns_per_dof"] = ns_per_dof(ctx.median(step), N)
    if "ns_per_dof_per_step" in rec["j2"]:
        rec["akantu_over_ours_j2"] = (rec["j2"]["ns_per_dof_per_step"]
                                      / rec["ours_j2_step_ns_per_dof"])
        rows.append([f"akantu {rec.get('version', '')}", "J2 (plastic_linear_isotropic_hardening)",
                     f"{rec['j2']['n_dofs']:,}", f"{rec['j2']['ns_per_dof_per_step']:.1f}"])
    rows.append(["impact_fenics", "J2 (fused cell kernel)", f"{N:,}",
                 f"{rec['ours_j2_step_ns_per_dof']:.2f}"])
    ctx.table("7. Peer: Akantu explicit lumped-mass step (plane strain CST, OMP_NUM_THREADS=1) "
              "against ours (axisymmetric CST)",
              ["code", "material", "dofs", "ns/dof/step"], rows)
    return rec
