"""Parts 6 and 7: what else could do the step. A compiled matrix-free CST K u
(benchmarks/matfree_cst.py) against MatMult of K, and Akantu's explicit
lumped-mass step (benchmarks/akantu_peer.py, in a venv of its own) against ours on
the same plane-strain mesh, material, time step and initial state."""
from __future__ import annotations

import importlib
import math
import os
import subprocess
import sys
import tempfile
import time

import numpy as np

from .bar import bar_integrator, bar_mesh, matrix_bytes, step_fn, vectors
from ..materials import STEEL
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


AKANTU_SPEED = 1.0  # m/s: the scale of the random initial velocity of both codes
AKANTU_HARDENING = 2e9  # Pa: the J2 hardening modulus H of both codes
NEVER_YIELDS = 1e15  # Pa: a yield stress that no point of the comparison reaches


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


def time_steps(step, steps: int, repeats: int) -> float:
    """Median seconds per step over ``repeats`` blocks of ``steps`` calls of ``step``: the
    timing of benchmarks/akantu_peer.py, so that both codes are timed alike."""
    samples = []
    for _ in range(repeats):
        t = time.perf_counter()
        for _ in range(steps):
            step()
        samples.append((time.perf_counter() - t) / steps)
    return float(np.median(samples))


def akantu_j2(yield_stress: float):
    """The J2 steel of the comparison (linear isotropic hardening H = AKANTU_HARDENING)."""
    from ..materials.j2 import J2

    return J2(E=STEEL.E, nu=STEEL.nu, density=STEEL.density, yield_stress=yield_stress,
              hardening=AKANTU_HARDENING)


def akantu_yield_stress(dt: float, h: float) -> float:
    """sigma_y (Pa) half the stress scale E v dt / h of the first step from the random
    velocity (v ~ AKANTU_SPEED): most points yield in the first steps, at any mesh size."""
    return 0.5 * STEEL.E * AKANTU_SPEED * dt / h


def ours_run(tmesh, material, geometry, dt: float, v0: np.ndarray, steps: int,
             repeats: int) -> tuple[dict, np.ndarray]:
    """Our integrator on ``tmesh`` (one body of ``material``, in ``geometry``; the axis held in
    axisymmetry), u = 0 and v = ``v0`` at t = 0: ``steps`` steps of dt (or of 0.9 x the
    element bound if smaller), u then (the physics check), then :func:`time_steps`.
    Serial (the part is). Returns (record, u after the check steps)."""
    from ..bodies import Body, DeformableModel
    from ..integrator import Integrator
    from ..stability import critical_dt, element_omega_bound

    model = DeformableModel(tmesh, [Body("bar", material)], geometry=geometry)
    bound = critical_dt(element_omega_bound(model, model.axis_dofs(owned=False)))
    integ = Integrator(model, min(dt, 0.9 * bound), model.axis_dofs())
    integ.set_initial(None, v0)
    step = step_fn(integ)
    for _ in range(steps):
        step()
    u = integ.displacement(np.empty(model.n_owned))
    n_cells = int(model.cell_dofs.shape[0])
    rec = {"n_dofs": int(model.n_global), "n_cells": n_cells, "dt": integ.dt,
           "stable_dt": bound, "points_per_cell": None, "yielded_fraction": None}
    if integ.nonlinear:
        eps_bar = integ.nonlinear[0].qs.state[..., 0]
        rec["points_per_cell"] = int(eps_bar.shape[1])
        rec["yielded_fraction"] = float((eps_bar > 0).mean())
    rec["step_seconds"] = time_steps(step, steps, repeats) if repeats else None
    return rec, u


def _run_akantu(ctx, py: str, work: str, material: str, dt: float, yield_stress: float,
                label: str = "", timed: bool = True) -> dict:
    """benchmarks/akantu_peer.py on the mesh and velocity written in ``work``; ``material``
    'elastic' or 'j2' (plastic_linear_isotropic_hardening); its u after the check steps
    under "u"; not ``timed``: the check steps alone."""
    mode = ctx.mode
    label = label or material
    out = os.path.join(work, f"akantu_{label}.json")
    cmd = [py, str(BENCHMARKS / "akantu_peer.py"), "--mesh", os.path.join(work, "bar.msh"),
           "--velocity", os.path.join(work, "v0.npy"), "--dt", repr(dt),
           "--check-steps", str(mode.akantu_steps), "--steps", str(mode.akantu_steps),
           "--repeats", str(mode.repeats if timed else 0), "--out", out,
           "--material", material, "--label", label,
           "--E", repr(STEEL.E), "--nu", repr(STEEL.nu), "--rho", repr(STEEL.density)]
    if material == "j2":
        cmd += ["--yield-stress", repr(yield_stress), "--hardening", repr(AKANTU_HARDENING)]
    rec = run_json(cmd, out, child_env("PYTHON", OMP_NUM_THREADS="1"), work, timeout=600)
    rec["u"] = np.load(os.path.join(work, f"u_akantu_{label}.npy")).ravel()
    return rec


def _same_problem(ak: dict, ours: dict, u: np.ndarray) -> dict:
    """Akantu's u after the check steps (taken out of ``ak``) against ours ``u``: the largest
    difference over max |u|, and whether the dofs and cells are the same."""
    scale = float(np.abs(u).max())
    return {"u_max": scale, "u_rel_diff": float(np.abs(ak.pop("u") - u).max()) / scale,
            "same_dofs": ak["n_dofs"] == ours["n_dofs"],
            "same_cells": ak["n_elements"] == ours["n_cells"]}


def _row(code: str, geometry: str, material: str, rec: dict, seconds: float, points: int | None,
         n_cells: int, akantu_seconds: float) -> list[str]:
    per_point = (f"{1e9 * seconds / (n_cells * points):.2f}" if points else "(matrix)")
    return [code, geometry, material, f"{rec['n_dofs']:,}", str(points or "-"),
            f"{ns_per_dof(seconds, rec['n_dofs']):.2f}", per_point,
            f"{akantu_seconds / seconds:.2f}"]


def part_akantu(ctx) -> dict:
    """Akantu's explicit step against ours on the same plane-strain mesh (the same nodes and
    triangles written for both), material, dt, number of steps and initial state (u = 0, a
    random velocity), elastic and J2; ours axisymmetric on the same mesh as a third row.
    Both first advance the same steps from the same state: u after them is the check that
    they solved the same problem."""
    from ..geometry import PLANE_STRAIN, Geometry

    load_start = os.getloadavg()
    py = ctx.args.akantu_python
    reason = _akantu_missing(ctx, py)
    if reason:
        return {"skipped": reason}
    mode = ctx.mode
    steps, repeats = mode.akantu_steps, mode.repeats
    tmesh, h = bar_mesh(ctx.comm, mode.akantu_dofs)
    plane, axi = Geometry(PLANE_STRAIN), Geometry()
    # the time step: 0.9 x our element bound in plane strain, used by both codes
    from ..bodies import Body, DeformableModel
    from ..stability import critical_dt, element_omega_bound

    model = DeformableModel(tmesh, [Body("bar", STEEL)], geometry=plane)
    dt = 0.9 * critical_dt(element_omega_bound(model, model.axis_dofs(owned=False)))
    v0 = AKANTU_SPEED * np.random.default_rng(5).standard_normal(model.n_owned)
    work = tempfile.mkdtemp(prefix="bench_akantu_")
    load_benchmark("akantu_peer").write_msh(os.path.join(work, "bar.msh"), model.node_xy,
                                            model.cell_dofs)
    np.save(os.path.join(work, "v0.npy"), v0.reshape(-1, 2))
    n_cells = int(model.cell_dofs.shape[0])
    del model
    sigma_y = akantu_yield_stress(dt, h)
    rec = {"n_cells": n_cells, "h": h, "dt": dt, "steps": steps, "repeats": repeats,
           "speed": AKANTU_SPEED, "yield_stress": sigma_y, "hardening": AKANTU_HARDENING,
           "load_average_start": load_start, "started": time.strftime("%Y-%m-%d %H:%M"),
           "akantu": {}, "ours": {}, "check": {}}
    # the timed runs, and J2 below its yield stress (the check alone): both codes' plastic
    # materials on the elastic branch of their return mappings, the same problem again
    runs = {"elastic": ("elastic", sigma_y, True), "j2": ("j2", sigma_y, True),
            "j2_elastic_range": ("j2", NEVER_YIELDS, False)}
    for label, (material, stress, timed) in runs.items():
        try:
            rec["akantu"][label] = _run_akantu(ctx, py, work, material, dt, stress, label, timed)
        except (subprocess.SubprocessError, OSError, ValueError, RuntimeError) as exc:
            ctx.log(f"   akantu: the {label} run failed: {exc}")
            return {"skipped": f"akantu {label} run failed: {exc}",
                    "load_average_start": load_start}
    rec["version"] = rec["akantu"]["elastic"].get("version", "?")
    materials = {"elastic": STEEL, "j2": akantu_j2(sigma_y)}
    for geometry, name in ((plane, "plane_strain"), (axi, "axisymmetric")):
        for material, mat in materials.items():
            ours, u = ours_run(tmesh, mat, geometry, dt, v0, steps, repeats)
            rec["ours"][f"{name}_{material}"] = ours
            if name == "plane_strain":  # the same discrete problem as Akantu's
                rec["check"][material] = _same_problem(rec["akantu"][material], ours, u)
    ours, u = ours_run(tmesh, akantu_j2(NEVER_YIELDS), plane, dt, v0, steps, 0)
    rec["check"]["j2_elastic_range"] = _same_problem(rec["akantu"]["j2_elastic_range"], ours, u)
    ak_el, ak_j2 = (rec["akantu"][m]["step_seconds"] for m in ("elastic", "j2"))
    o = {k: v["step_seconds"] for k, v in rec["ours"].items()}
    rec["akantu_over_ours"] = ak_el / o["plane_strain_elastic"]
    rec["akantu_over_ours_j2"] = ak_j2 / o["plane_strain_j2"]
    p_ak = rec["akantu"]["j2"]["points_per_element"]
    p_pl = rec["ours"]["plane_strain_j2"]["points_per_cell"]
    p_ax = rec["ours"]["axisymmetric_j2"]["points_per_cell"]
    rec["akantu_over_ours_j2_per_point"] = (ak_j2 / p_ak) / (o["plane_strain_j2"] / p_pl)
    rec["axisymmetric_over_plane_strain"] = {
        m: o[f"axisymmetric_{m}"] / o[f"plane_strain_{m}"] for m in materials}
    per_dof = {f"akantu_{m}": ns_per_dof(a["step_seconds"], a["n_dofs"])
               for m, a in rec["akantu"].items() if a["step_seconds"] is not None}
    per_dof.update({k: ns_per_dof(v, rec["ours"][k]["n_dofs"]) for k, v in o.items()})
    rec["ns_per_dof_per_step"] = per_dof
    rec["load_average_end"] = os.getloadavg()
    version = rec["version"]
    rows = [_row(f"Akantu {version}", "plane strain", "elastic", rec["akantu"]["elastic"], ak_el,
                 rec["akantu"]["elastic"]["points_per_element"], n_cells, ak_el),
            _row("impact_fenics", "plane strain", "elastic", rec["ours"]["plane_strain_elastic"],
                 o["plane_strain_elastic"], None, n_cells, ak_el),
            _row("impact_fenics", "axisymmetric", "elastic", rec["ours"]["axisymmetric_elastic"],
                 o["axisymmetric_elastic"], None, n_cells, ak_el),
            _row(f"Akantu {version}", "plane strain", "J2", rec["akantu"]["j2"], ak_j2, p_ak,
                 n_cells, ak_j2),
            _row("impact_fenics", "plane strain", "J2", rec["ours"]["plane_strain_j2"],
                 o["plane_strain_j2"], p_pl, n_cells, ak_j2),
            _row("impact_fenics", "axisymmetric", "J2", rec["ours"]["axisymmetric_j2"],
                 o["axisymmetric_j2"], p_ax, n_cells, ak_j2)]
    ctx.table(f"7. Peer: Akantu's explicit lumped-mass step against ours on the same "
              f"{n_cells:,} triangles, dt = {dt:.3e} s, {steps} steps a block, "
              "OMP_NUM_THREADS=1, 1 rank",
              ["code", "geometry", "material", "dofs", "points/cell", "ns/dof/step",
               "ns/point/step", "Akantu / this"], rows)
    c = rec["check"]
    ctx.log(f"   the same problem: u after {steps} steps from u = 0 and the same random velocity "
            f"differs by {c['elastic']['u_rel_diff']:.1e} (elastic) and "
            f"{c['j2']['u_rel_diff']:.1e} (J2; below yield "
            f"{c['j2_elastic_range']['u_rel_diff']:.1e}) of max |u|; points yielded: Akantu "
            f"{rec['akantu']['j2'].get('yielded_fraction') or 0:.0%}, ours plane strain "
            f"{rec['ours']['plane_strain_j2']['yielded_fraction']:.0%}, axisymmetric "
            f"{rec['ours']['axisymmetric_j2']['yielded_fraction']:.0%}; Akantu's own stable "
            f"step {rec['akantu']['elastic']['stable_dt']:.3e} s")
    ctx.log(f"   load average {' '.join(f'{x:.2f}' for x in load_start)} at the start, "
            f"{' '.join(f'{x:.2f}' for x in rec['load_average_end'])} at the end")
    return rec
