"""Parts "finite" and "taylor": the finite-strain J2 step and the Taylor bar's whole run.

finite   On the benchmark's bar (r in [0, 0.5], z in [0, 1] m, h = dofs^-1/2), in one
         run: the linear step (MatMultAdd + AXPY) and a bare MatMult on the triangle
         mesh, the small-strain J2 step (fused kernel, 3 points per triangle), and the
         finite-strain J2 step (Q1 mean dilatation, 2x2 points, Hencky J2) on the
         quadrilateral mesh of the same nodes (so the same dofs), both in a random
         state that yields most points. The finite step is what the one loop does
         for a finite-strain body each step: ghost update of u, the fused kernel (F,
         J_bar, the return mapping, P and the element force at every point), the reverse
         ghost sum and the min-J allreduce, the trapezoid of the internal work, the
         velocity and the position updates; each piece is timed alone. Goal (issue
         11): finite J2 at most 1.5 x the small-strain J2 step.
taylor   The Taylor bar (scenes/taylor_bar.toml's copper, FILM wall) run whole through
         Simulation (scenes.taylor_bar) without outputs: element-steps per second and
         microseconds per element-step, with the loop's phases; serially the part also launches
         itself on 2 ranks (scripts/mpirun.sh). For scale: Carina.jl's J2 Taylor bar,
         0.65-1.43 us per element-step on 12-64 CPU threads.

    python -m impact_fenics.bench --parts finite,taylor [--quick | --smoke]
"""
from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
from numba import njit

from .. import compat
from .bar import step_fn
from .common import per_dof
from . import roofline
from .plastic import (j2_integrator, linear_floors, linear_reference, small_strain_floor,
                      yielding_steel)

# the Taylor bar of each mode: (cells across the radius, end time in s)
TAYLOR = {"smoke": (2, 4e-6), "quick": (4, 80e-6), "full": (8, 80e-6)}
CARINA_US_PER_ELEMENT_STEP = (0.65, 1.43)  # 12-64 CPU threads


def finite_bar(comm, h: float, yield_stress: float, material=None) -> SimpleNamespace:
    """The benchmark's bar on square quadrilaterals of side h (the nodes of the triangle
    bar), J2 steel yielding at ``yield_stress`` (Pa) or ``material``, in a random state:
    its finite-strain force and the integrator's state (u, v and their vectors), as the
    one loop holds them."""
    from ..bodies import Body, DeformableModel
    from ..integrator import Integrator
    from ..materials.finite_j2 import FiniteJ2
    from ..quad_meshes import one_body, quad_bar
    from ..stepping import FollowingStep

    steel = material or FiniteJ2(E=200e9, nu=0.3, density=7850.0, yield_stress=yield_stress,
                                 hardening=2e9)
    mesh = quad_bar(comm, 0.5, 1.0, max(1, round(0.5 / h)), max(1, round(1.0 / h)))
    model = DeformableModel(one_body(mesh), [Body("body", steel)])
    integ = Integrator(model, None, model.axis_dofs(), policy=FollowingStep(None, 1.0))
    force = integ.finite[0]
    run = SimpleNamespace(comm=comm, force=force, coef=force.coef, n_owned=model.n_owned,
                          u_fn=integ.u_function, u=integ.u_function.x.array,
                          u_owned=integ.u_owned, v=integ.v_owned, u_vec=integ.u_vec,
                          v_vec=integ.v_vec, free=integ.free, dt_limit=force.stable_dt)
    rng = np.random.default_rng(11 + 7919 * comm.rank)
    run.u_owned[:] = np.where(run.free, 1e-6 * rng.standard_normal(run.n_owned), 0.0)
    run.v[:] = np.where(run.free, 1e-3 * rng.standard_normal(run.n_owned), 0.0)
    return run


def finite_floor(ctx, run, kernel: str, seconds: float) -> dict:
    """:func:`.roofline.floor` of the finite-strain step of ``run`` (the rank with the most
    bytes, its points and their yielded fraction now), with its time."""
    local = roofline.finite_strain_bytes(run.force, run.n_owned)
    state = run.force.state
    eps_bar = state[..., 0] if state.shape[-1] > 0 else np.zeros(state.shape[:2])
    most, points, yielded = max(ctx.comm.allgather(
        (local, eps_bar.size, float((eps_bar > 0).mean()) if eps_bar.size else 0.0)))
    return roofline.with_ratio(roofline.floor(
        roofline.machine_rates(ctx), most, roofline.point_arithmetic(kernel, points, yielded)),
        seconds)


def other_finite_materials(steel):
    """{key: (label, material)} of the other finite-strain materials the part times on the
    same bar: Johnson-Cook with the steel's elastic constants and its yield stress as A
    (rate and temperature terms at their defaults), and neo-Hookean (elastic)."""
    from ..materials import JohnsonCook, NeoHookean

    return {"jc_finite_strain": ("Johnson-Cook finite strain, Q1 F-bar",
                                 JohnsonCook(E=200e9, nu=0.3, density=7850.0,
                                             A=steel.yield_stress, B=2e9)),
            "nh_finite_strain": ("neo-Hookean finite strain, Q1 F-bar",
                                 NeoHookean(E=200e9, nu=0.3, density=7850.0))}


def finite_step(run, dt: float):
    """One step of a finite-strain body in the one loop (no wall, no history): see the
    module docstring."""
    force = run.force
    force.set_step(dt, dt)

    def step():
        run.u_fn.x.scatter_forward()
        force.velocity_increment(run.u_owned, run.v, dt)
        run.u_vec.axpy(dt, run.v_vec)
    return step


@njit(cache=True)
def _copy_update(F, state, params, dt, tau, work) -> float:
    """No material: tau = (F_rr, F_tt, F_zz, F_rz) (a stand-in that costs nothing)."""
    tau[0], tau[1], tau[2], tau[3] = F[0], F[4], F[3], F[1]
    return 0.0


@njit(cache=True)
def _no_energy(F, state, params, work) -> float:
    return 0.0


def _finite_split(ctx, run, dt: float) -> dict:
    """Median seconds of the pieces of the finite step, each timed alone; the fused kernel
    also with a material that does nothing (the kernel's own work: F at the points, J_bar,
    F_bar, tau_eff, P and the scatter)."""
    from mpi4py import MPI

    from ..internal_force.finite import trapezoid_work, velocity_update
    from ..internal_force.finite import kernels

    force, g = run.force, run.force.geometry
    f = force.f.x.array
    fo = force.f_owned
    comm = run.comm
    bare, _ = kernels(_copy_update, _no_energy, force.state.shape[-1])
    state, tau = force.state.copy(), force.tau.copy()

    def kernel(fn, state, tau):
        return lambda: fn(force.params, dt, g.dofs, g.dxi, g.N, g.inv_R, g.w, g.volume,
                          run.u, f, state, tau, force._Fq, force._Jq, force._fbar, force._work,
                          force._point_state, force._point_tau)
    return {
        "ghost_forward": ctx.median(lambda: run.u_fn.x.scatter_forward()),
        "zero_f": ctx.median(lambda: f.fill(0.0)),
        "fused_kernel": ctx.median(kernel(force._force, force.state, force.tau)),
        "kernel_without_material": ctx.median(kernel(bare, state, tau)),
        "ghost_reverse": ctx.median(lambda: compat.scatter_add(force.f.x)),
        "j_min_allreduce": ctx.median(lambda: comm.allreduce(1.0, op=MPI.MIN)),
        "trapezoid_work": ctx.median(lambda: trapezoid_work(fo, run.u_owned, run.force._f_prev,
                                                            run.force._u_prev)),
        "velocity_update": ctx.median(lambda: velocity_update(run.coef, fo, run.v, dt)),
        "position_update": ctx.median(lambda: run.u_vec.axpy(dt, run.v_vec)),
    }


def part_finite(ctx) -> dict:
    comm = ctx.comm
    tmesh, h, N, lin, t = linear_reference(ctx)
    steel = yielding_steel(h)
    _, integ = j2_integrator(tmesh, "fast", lin.dt, steel)
    step = step_fn(integ)
    step()  # the first step yields most points of the random state
    t["j2_small_strain"] = ctx.median(step)
    floors = linear_floors(ctx, lin, N, t)
    floors["j2_small_strain"] = small_strain_floor(ctx, integ, "j2_small_strain",
                                                   t["j2_small_strain"])
    small = integ.nonlinear[0]
    small_yielded = comm.allreduce(int((small.qs.state[..., 0] > 0).sum())) / max(
        comm.allreduce(int(small.qs.state[..., 0].size)), 1)
    del integ, small
    run = finite_bar(comm, h, steel.yield_stress)
    N_q = comm.allreduce(run.n_owned)
    dt = 0.5 * run.dt_limit()
    fstep = finite_step(run, dt)
    fstep()
    t["j2_finite_strain"] = ctx.median(fstep)
    floors["j2_finite_strain"] = finite_floor(ctx, run, "j2_finite_strain", t["j2_finite_strain"])
    split = _finite_split(ctx, run, dt)
    others = sum(v for k, v in split.items()
                 if k not in ("zero_f", "fused_kernel", "kernel_without_material"))
    split["fused_kernel_by_difference"] = t["j2_finite_strain"] - others
    state = run.force.state[..., 0]
    yielded = comm.allreduce(int((state > 0).sum())) / max(comm.allreduce(int(state.size)), 1)
    n_cells = comm.allreduce(int(run.force.geometry.dofs.shape[0]))
    del run, fstep
    labels_other, yielded_other = {}, {}
    for key, (label, material) in other_finite_materials(steel).items():
        other = finite_bar(comm, h, steel.yield_stress, material)
        ostep = finite_step(other, 0.5 * other.dt_limit())
        ostep()
        t[key] = ctx.median(ostep)
        floors[key] = finite_floor(ctx, other, key, t[key])
        st = other.force.state
        yielded_other[key] = (comm.allreduce(int((st[..., 0] > 0).sum())) / max(
            comm.allreduce(int(st[..., 0].size)), 1)) if st.shape[-1] > 0 else 0.0
        labels_other[key] = label
        del other, ostep
    res = {"n_dofs": N, "n_dofs_quadrilateral": N_q, "h": h, "n_cells_quadrilateral": n_cells,
           "yield_stress": steel.yield_stress, "yielded_fraction_small": small_yielded,
           "yielded_fraction_finite": yielded, "timings": t, "split_finite": split,
           "ns_per_dof": per_dof(t, N),
           "ratio_to_linear_step": {k: v / t["linear_step"] for k, v in t.items()},
           "ratio_to_matmult": {k: v / t["matmult"] for k, v in t.items()},
           "finite_over_small_strain_j2": t["j2_finite_strain"] / t["j2_small_strain"],
           "goal_finite_over_small_strain_j2": 1.5, "floor": floors,
           "yielded_fraction_other": yielded_other,
           # per element: a quadrilateral for the finite step, a triangle for the others
           "ns_per_element_cycle": {k: 1e9 * v / (n_cells if k.endswith("_finite_strain")
                                                  else 2 * n_cells) for k, v in t.items()},
           "machine_rates": roofline.machine_rates(ctx)}
    labels = {"matmult": "MatMult K u", "linear_step": "linear step (MatMultAdd + AXPY)",
              "j2_small_strain": "J2 small strain, fused kernel (3 points per triangle)",
              "j2_finite_strain": "J2 finite strain, Q1 mean dilatation (2x2 points per quad)",
              **labels_other}
    rows = [[label, f"{1e3 * t[k]:.3f}", f"{res['ns_per_dof'][k]:.2f}",
             f"{res['ratio_to_matmult'][k]:.2f}", f"{res['ratio_to_linear_step'][k]:.2f}",
             roofline.floor_cell(floors.get(k))]
            for k, label in labels.items()]
    ctx.table(f"9. Finite-strain J2 against small-strain J2 and the linear step: {N:,} dofs "
              f"({n_cells:,} quadrilaterals or {2 * n_cells:,} triangles on the same nodes), "
              f"{comm.size} rank(s); yielded points {small_yielded:.0%} small, {yielded:.0%} "
              "finite", ["what", "ms/step", "ns/dof/step", "/ MatMult", "/ linear step",
                        "x the floor"], rows)
    ctx.log(roofline.rates_line(res["machine_rates"]))
    points = max(4 * n_cells / comm.size, 1)
    share = split["fused_kernel_by_difference"] / t["j2_finite_strain"]
    material = max(split["fused_kernel"] - split["kernel_without_material"], 0.0)
    res["kernel_share_of_step"] = share
    res["material_share_of_kernel"] = material / split["fused_kernel"]
    ctx.log(f"   finite / small-strain J2 step = {res['finite_over_small_strain_j2']:.2f} "
            f"(goal <= 1.5)")
    ctx.log("   finite step (ms): " + ", ".join(f"{k} {1e3 * v:.3f}" for k, v in split.items()))
    ctx.log(f"   the fused kernel is {share:.0%} of the step (the step minus the other pieces); "
            f"timed alone {1e9 * split['fused_kernel'] / points:.0f} ns per point, of which the "
            f"kernel's own work {1e9 * split['kernel_without_material'] / points:.0f} and the "
            f"Hencky J2 update {1e9 * material / points:.0f}")
    return res


def taylor_rate(comm, n_r: int, t_end: float) -> dict:
    """The Taylor bar (n_r x 10 n_r, FILM; scenes.taylor_bar) to t_end without outputs: its
    rate and phases."""
    from ..materials.finite_j2 import FiniteJ2
    from ..scenes import taylor_bar
    from ..simulation import Settings

    copper = FiniteJ2(E=117e9, nu=0.35, density=8930.0, yield_stress=400e6, hardening=100e6)
    sim = taylor_bar(Settings(quiet=True, plots=False, fields=False, history_every=20),
                     copper, n_r=n_r, method="film", t_end=t_end, comm=comm)
    s = sim.run(extra=sim.scene_figures)
    n_steps = s["stopped_at_step"]
    rate = s["n_cells"] * n_steps / s["wall_time"]
    return {"n_r": n_r, "t_end": t_end, "n_cells": s["n_cells"], "n_steps": n_steps,
            "n_ranks": comm.size, "wall_time": s["wall_time"], "element_steps_per_second": rate,
            "us_per_element_step": 1e6 / rate,
            "ns_per_element_cycle": s["ns_per_element_cycle"],
            "us_per_element_step_median_step": 1e6 * s["step_time_median"] / s["n_cells"],
            "final_length": s["final_length"],
            "final_face_radius": s["final_face_radius"],
            "phase_share": {k: v["share"] for k, v in s["timing"]["phases"].items()},
            "step_time_median": s["step_time_median"]}


def part_taylor(ctx) -> dict:
    from .scaling import launch

    n_r, t_end = TAYLOR[ctx.mode.name]
    taylor_rate(ctx.comm, n_r, min(t_end, 1e-6))  # compile the kernels outside the timing
    here = taylor_rate(ctx.comm, n_r, t_end)
    res = {"runs": [here], "carina_us_per_element_step": list(CARINA_US_PER_ELEMENT_STEP)}
    if ctx.comm.size == 1 and not ctx.args.child:
        child = launch(ctx, 2, ["taylor"], [ctx.mode.step_dofs])
        if "error" in child:
            res["two_ranks_error"] = child["error"]
            ctx.log(f"   the 2-rank run failed: {child['error']}")
        else:
            res["runs"] += child["taylor"]["runs"]
    if ctx.args.child:
        return res
    rows = [[r["n_ranks"], f"{r['n_cells']:,}", f"{r['n_steps']:,}", f"{r['wall_time']:.2f}",
             f"{r['element_steps_per_second']:,.0f}", f"{r['us_per_element_step']:.3f}",
             f"{r['us_per_element_step_median_step']:.3f}",
             ", ".join(f"{k} {v:.0%}" for k, v in r["phase_share"].items() if v >= 0.005)]
            for r in res["runs"]]
    ctx.table(f"10. The Taylor bar's whole run (n_r = {n_r}, {1e6 * t_end:g} us, FILM, no "
              "outputs); Carina.jl: 0.65-1.43 us per element-step on 12-64 threads",
              ["ranks", "cells", "steps", "wall s", "element-steps/s", "us/element-step",
               "median step", "where the loop's time goes"], rows)
    ctx.log("   us/element-step: the loop's wall time over cells x steps; median step: the "
            "median step's time over the cells (what a step costs when the machine lets it run)")
    if len(res["runs"]) == 2:
        res["speedup_2_ranks"] = res["runs"][0]["wall_time"] / res["runs"][1]["wall_time"]
        ctx.log(f"   2 ranks / 1 rank speed-up {res['speedup_2_ranks']:.2f}; the same shape: "
                f"length {1e3 * res['runs'][0]['final_length']:.6f} / "
                f"{1e3 * res['runs'][1]['final_length']:.6f} mm")
    return res


if __name__ == "__main__":  # pragma: no cover - a quick look without the harness
    import sys

    from mpi4py import MPI

    n_r = int(sys.argv[1]) if len(sys.argv) > 1 else 4
    r = taylor_rate(MPI.COMM_WORLD, n_r, 80e-6)
    if MPI.COMM_WORLD.rank == 0:
        print(r, math.isfinite(r["us_per_element_step"]))
