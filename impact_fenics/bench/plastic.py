"""Part 8: the J2 step (state at three points per cell) against the linear step and MatMult.

On the benchmark's bar, in one run: the linear integrator step (one MatMultAdd
and one AXPY), a bare MatMult of K, and the J2 step by the fused cell kernel
("fast") and by dolfinx ("generic": Expression at the points, the point loop,
assemble_vector), each split into where its time goes.
"""
from __future__ import annotations

import numpy as np

from .. import compat
from ..materials.j2 import J2
from . import roofline
from .bar import bar_integrator, matrix_bytes, random_state, step_fn, time_matmult
from .common import per_dof

J2_ELASTIC = J2(E=200e9, nu=0.3, density=7850.0, yield_stress=1e15)  # never yields


def yielding_steel(h: float) -> J2:
    """J2 steel whose yield stress is twice the scale E |u| / h of the random state
    (|u| ~ 1e-6 m, :func:`.bar.random_state`): most points yield, at any mesh size."""
    return J2(E=200e9, nu=0.3, density=7850.0, yield_stress=2.0 * 200e9 * 1e-6 / h, hardening=2e9)


def j2_integrator(tmesh, path: str, dt: float, material: J2):
    """(model, integrator) of the bar made of ``material``, axis fixed, in a random state."""
    from ..bodies import Body, DeformableModel
    from ..integrator import Integrator

    model = DeformableModel(tmesh, [Body("bar", material)])
    integ = Integrator(model, dt, model.axis_dofs(), f_int_path=path)
    random_state(integ)
    return model, integ


def _split(ctx, integ) -> dict:
    """Median seconds of the pieces of the J2 step."""
    from ..internal_force.quadrature import velocity_update

    force = integ.nonlinear[0]
    f, fo = force.f.x.array, force.f_owned
    prev_f, prev_u = np.zeros_like(fo), integ.u_owned.copy()
    out = {"ghost_forward": ctx.median(lambda: integ._u_fn.x.scatter_forward()),
           "velocity_update": ctx.median(lambda: velocity_update(force.coef, fo, integ.u_owned,
                                                                 integ.v_owned, prev_f, prev_u))}
    g, qs = force.geometry, force.qs
    if force.path == "fast":
        out["zero_f"] = ctx.median(lambda: f.fill(0.0))
        out["fused_kernel"] = ctx.median(lambda: force._fused(
            force.params, force.dt, g.dofs, g.dNdr, g.dNdz, g.N, g.inv_r, g.w, integ._u_fn.x.array,
            f, *qs.kernel_arrays, force._work))
        out["ghost_reverse"] = ctx.median(lambda: compat.scatter_add(force.f.x))
        # the point updates alone (state in and out, the update) on the same strains: the
        # generic path's point loop
        eps = _point_strains(force)
        sq = np.zeros(4 * 3 * max(force.cells.size, 1))
        qd = np.arange(3 * force.cells.size, dtype=np.int32).reshape(-1, 3)
        out["point_updates"] = ctx.median(lambda: force._points(
            force.params, force.dt, eps, g.w, qs.eps_p, qs.state, qs.sigma, qd, sq, force._work))
    else:
        out["strain_expression"] = ctx.median(lambda: compat.eval_expression_into(
            force._eps_expr, force.model.mesh, force.cells, force._eps_buf))
        out["point_updates"] = ctx.median(lambda: force._points(
            force.params, force.dt, force._eps_buf, g.w, qs.eps_p, qs.state, qs.sigma,
            force._qdofs, force._sigma_q.x.array, force._work))

        def assemble():
            from dolfinx import fem
            from petsc4py import PETSc

            vec = compat.petsc_vec(force.f)
            with vec.localForm() as local:
                local.set(0.0)
            fem.petsc.assemble_vector(vec, force._form)
            vec.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        out["assemble_vector"] = ctx.median(assemble)
    return out



def _point_strains(force) -> np.ndarray:
    """The strains (cells, 3 * 4) at the points of the force's cells, from its geometry."""
    g = force.geometry
    u = force.u.x.array
    ur, uz = u[2 * g.dofs], u[2 * g.dofs + 1]
    eps = np.empty((g.dofs.shape[0], 3, 4))
    eps[:, :, 0] = (g.dNdr * ur).sum(axis=1)[:, None]
    eps[:, :, 1] = np.einsum("qi,ni->nq", g.N, ur) / g.r
    eps[:, :, 2] = (g.dNdz * uz).sum(axis=1)[:, None]
    eps[:, :, 3] = 0.5 * ((g.dNdz * ur).sum(axis=1) + (g.dNdr * uz).sum(axis=1))[:, None]
    return eps.reshape(g.dofs.shape[0], 12)


def linear_reference(ctx):
    """(mesh, h, dofs, linear integrator, timings of the linear step and of MatMult (s)) of the
    benchmark's bar at the mode's step size: what the plastic rows are measured against."""
    tmesh, h = ctx.mesh(ctx.mode.step_dofs)
    model, lin = bar_integrator(tmesh)
    t = {"linear_step": ctx.median(step_fn(lin)),
         "matmult": time_matmult(ctx, lin.K, lin.u_vec.array)}
    return tmesh, h, int(model.n_global), lin, t


def linear_floors(ctx, lin, N: int, t: dict) -> dict:
    """:func:`.roofline.floor` of MatMult and of the linear step, with their times ``t``."""
    rates, ranks = roofline.machine_rates(ctx), ctx.comm.size
    mb = matrix_bytes(lin.A, N)
    mm = roofline.floor(rates, roofline.linear_bytes(mb["matmult_bytes_per_dof"], N, ranks),
                        {"flops": 2.0 * mb["nnz"] / ranks})
    step = roofline.floor(rates, roofline.linear_bytes(mb["step_bytes_per_dof"], N, ranks),
                          roofline.linear_arithmetic(mb["nnz"], N, ranks))
    return {"matmult": roofline.with_ratio(mm, t["matmult"]),
            "linear_step": roofline.with_ratio(step, t["linear_step"])}


def small_strain_floor(ctx, integ, kernel: str, seconds: float) -> dict:
    """:func:`.roofline.floor` of the small-strain path-dependent step of ``integ`` (its
    first force; the rank with the most bytes, its points and their yielded fraction now),
    with its time."""
    force = integ.nonlinear[0]
    local = roofline.small_strain_bytes(force, integ.model.n_owned)
    eps_bar = force.qs.state[..., 0]
    most, points, yielded = max(ctx.comm.allgather(
        (local, eps_bar.size, float((eps_bar > 0).mean()) if eps_bar.size else 0.0)))
    rec = roofline.floor(roofline.machine_rates(ctx), most,
                         roofline.point_arithmetic(kernel, points, yielded))
    return roofline.with_ratio(rec, seconds)


def yielding_rock(h: float):
    """Drucker-Prager with the elastic constants of the steel and its unconfined compressive
    strength at :func:`yielding_steel`'s yield stress: most points yield, at any mesh size."""
    from ..materials.drucker_prager import DruckerPrager

    ucs = 2.0 * 200e9 * 1e-6 / h
    return DruckerPrager(E=200e9, nu=0.3, density=7850.0, ucs=ucs, tensile_strength=0.05 * ucs)


def part_j2(ctx) -> dict:
    comm = ctx.comm
    tmesh, h, N, lin, t = linear_reference(ctx)
    steel = yielding_steel(h)
    res = {"n_dofs": N, "h": h, "dt": lin.dt, "yield_stress": steel.yield_stress}
    floors = linear_floors(ctx, lin, N, t)
    _, integ = j2_integrator(tmesh, "fast", lin.dt, J2_ELASTIC)
    t["j2_fast_elastic"] = ctx.median(step_fn(integ))
    floors["j2_fast_elastic"] = small_strain_floor(ctx, integ, "j2_small_strain",
                                                   t["j2_fast_elastic"])
    del integ
    _, integ = j2_integrator(tmesh, "fast", lin.dt, yielding_rock(h))
    step = step_fn(integ)
    step()  # the first step yields most points of the random state
    t["dp_fast"] = ctx.median(step)
    floors["dp_fast"] = small_strain_floor(ctx, integ, "dp_small_strain", t["dp_fast"])
    eps_bar = integ.nonlinear[0].qs.state[..., 0]
    res["yielded_fraction_dp"] = comm.allreduce(int((eps_bar > 0).sum())) / max(
        comm.allreduce(int(eps_bar.size)), 1)
    del integ
    splits = {}
    for path in ("fast", "generic"):
        _, integ = j2_integrator(tmesh, path, lin.dt, steel)
        step = step_fn(integ)
        step()  # the first step yields most points of the random state
        t[f"j2_{path}"] = ctx.median(step)
        floors[f"j2_{path}"] = small_strain_floor(ctx, integ, "j2_small_strain", t[f"j2_{path}"])
        force = integ.nonlinear[0]
        splits[path] = _split(ctx, integ)
        inside = ("point_updates",) if path == "fast" else ()  # fast: inside the fused kernel
        splits[path]["rest"] = t[f"j2_{path}"] - sum(
            v for k, v in splits[path].items() if k not in inside)
        yielded = comm.allreduce(int((force.qs.state[..., 0] > 0).sum()))
        points = comm.allreduce(int(force.qs.state[..., 0].size))
        res[f"yielded_fraction_{path}"] = yielded / max(points, 1)
        res["n_cells"] = comm.allreduce(int(force.cells.size))
    res["timings"] = t
    res["split"] = splits
    res["floor"] = floors
    # per triangle (every row runs on the same triangles)
    res["ns_per_element_cycle"] = {k: 1e9 * v / res["n_cells"] for k, v in t.items()}
    res["machine_rates"] = roofline.machine_rates(ctx)
    res["ns_per_dof"] = per_dof(t, N)
    res["ratio_to_linear_step"] = {k: v / t["linear_step"] for k, v in t.items()}
    res["ratio_to_matmult"] = {k: v / t["matmult"] for k, v in t.items()}
    labels = {"matmult": "MatMult K u", "linear_step": "linear step (MatMultAdd + AXPY)",
              "j2_fast_elastic": "J2 step, fused kernel, every point elastic",
              "j2_fast": "J2 step, fused cell kernel", "j2_generic": "J2 step, generic dolfinx",
              "dp_fast": "Drucker-Prager step, fused cell kernel"}
    rows = [[label, f"{1e3 * t[k]:.3f}", f"{res['ns_per_dof'][k]:.2f}",
             f"{res['ratio_to_matmult'][k]:.2f}", f"{res['ratio_to_linear_step'][k]:.2f}",
             roofline.floor_cell(floors.get(k))]
            for k, label in labels.items()]
    ctx.table(f"8. J2 plasticity (3 points per cell, {res['n_cells']:,} cells, "
              f"{res['yielded_fraction_fast']:.0%} of the points yielded, Drucker-Prager "
              f"{res['yielded_fraction_dp']:.0%}): {N:,} dofs, "
              f"{comm.size} rank(s)",
              ["what", "ms/step", "ns/dof/step", "/ MatMult", "/ linear step", "x the floor"],
              rows)
    ctx.log(roofline.rates_line(res["machine_rates"]))
    for path in ("fast", "generic"):
        parts = ", ".join(f"{k} {1e3 * v:.3f}" for k, v in splits[path].items())
        inside = ("; point_updates (state in and out and the update at every point, timed "
                  "alone on the same strains) is inside fused_kernel") if path == "fast" else ""
        ctx.log(f"   {path} step (ms): {parts}{inside}; rest = step - pieces: Python and noise")
    return res
