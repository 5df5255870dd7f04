"""Parts 2 and 2b: contact time per step against the number of constraints (rigid punch
and node pairs, every method), and FILM's solvers alone; part friction: the contact step
with and without Coulomb friction at Sim3 (the punch, 610 constraints), every method.

The phases are those ContactSet.step times (impact_fenics/contact/interface.py).
Penalty, FILM fast and DME run the whole step as one compiled call
(contact/fused.py: take the predicted contact dofs, form the gaps, correct, write
back, book the contact work), booked as solve; detection and update are then
only the Python around it (the rigid body's prediction and commit; under MPI
the compiled pack and the Allgatherv in detection). FILM dense keeps three
phases: detection (one compiled call), its numpy/LAPACK solve, the commit (one
compiled call). These runs take the Python step (``compiled_steps=False``): on one
rank with linear bodies a run's steps between events are compiled blocks
(impact_fenics/step_block.py) in which the Python around the call is gone and the
whole contact step is booked as solve (the whole-run part measures that path).
Part 2b times a solver against an empty compiled call with the same arguments.
"""
from __future__ import annotations

import os

import numpy as np
from numba import njit

from ..materials import STEEL
from ..scenes import punch_indentation
from .bar import BIG
from .common import Mode

CONTACT_METHODS = ("penalty", "film_fast", "film_dense", "dme")
PHASES = ("contact_detection", "contact_solve", "contact_update", "f_int")
SPLIT = ("   penalty, FILM fast, DME: solve = the one compiled call of the step (gather, gaps, "
         "method, write-back, booking); detect/update = the Python around it (rigid body, MPI "
         "gather); FILM dense: detect, its solve, update as three calls")


@njit(cache=True)
def _empty_call(gap, d, kappa, out):
    """Nothing, with a solver's arguments: the floor of one compiled call."""
    return out


def _contact_mesh(comm, kind: str, n: int):
    from .. import meshing

    h = 1.0 / (n - 1)
    if kind == "rigid":  # n surface nodes with r <= 1 m, coarse below
        return meshing.punch_block(width=1.5, depth=0.5, h_surface=h, grading=1.0, h_max=0.25,
                                   breaks=((1.0, n - 1),), comm=comm)
    # node pairs: two thin structured strips of radius 1 m, n nodes per face;
    # the striker is pressed against the clamped target, so every pair stays closed
    return meshing.coaxial_bars(radius=1.0, striker_length=2 * h, target_length=2 * h, h=h,
                                structured=True, comm=comm)


def _contact_sim(kind: str, tmesh, n: int, method: str, steps: int):
    from .. import loads
    from ..bodies import Body, DeformableModel
    from ..contact import DME, FILM, Penalty, pair_surfaces
    from ..simulation import Settings, Simulation

    m = {"penalty": lambda: Penalty("scaled"), "film_fast": lambda: FILM("fast"),
         "film_dense": lambda: FILM("dense"), "dme": lambda: DME(0.0)}[method]()
    # the Python step (not step_block's compiled steps, where the contact step is all
    # solve): its phases show the Python around the compiled call
    settings = Settings(cfl=0.9, n_steps=steps, output_every=BIG, history_every=1,
                        fields=False, out=None, quiet=True, compiled_steps=False)
    if kind == "rigid":  # the paper's punch (R_z = 1 m) on a block with n surface nodes
        sim = punch_indentation(settings, m, radius=1.0, tmesh=tmesh)
        c = sim.contacts[0]
    else:
        model = DeformableModel(tmesh, [Body("striker", STEEL), Body("target", STEEL)])
        push = loads.SurfaceLoad(model, "striker_end", loads.Constant(50e6))
        sim = Simulation(model, settings, fixed=[model.facet_dofs("target_end", 1)],
                         loads=[push])
        c = sim.add_contact(pair_surfaces(model, "striker_contact", "target_contact"), m)
    if c.n != n:
        raise RuntimeError(f"{kind} contact: {c.n} constraints instead of {n}")
    return sim


def _contact_run(sim, n: int, method: str, steps: int) -> dict:
    """Run one contact scene; medians of the phases (s per step) and the active set."""
    from ..errors import UnstableRunError

    rec = {"n_constraints": n, "method": method, "n_dofs": int(sim.model.n_global), "steps": steps}
    try:
        s = sim.run()
        rec["status"] = s["status"]
    except UnstableRunError as exc:
        rec["status"] = f"diverged: {exc}"
        s = sim.summary
    med = s.get("time_per_step_median", {})
    for ph in PHASES:
        rec[ph] = med.get(ph, float("nan"))
    rec["contact"] = s.get("contact_cpu_time_per_step_median", float("nan"))
    rec["step"] = s.get("step_time_median", float("nan"))
    na = np.asarray(sim.history.data()["n_active"], dtype=float)
    rec["n_active_median"] = float(np.median(na)) if na.size else 0.0
    rec["contact_ns_per_constraint"] = 1e9 * rec["contact"] / n
    return rec


def _methods(mode: Mode, n: int):
    """(method, steps) run at ``n`` constraints: FILM dense only up to the cap."""
    for method in CONTACT_METHODS:
        if method == "film_dense":
            if n <= mode.dense_cap:
                yield method, mode.dense_steps
        else:
            yield method, mode.contact_steps


def part_contact(ctx) -> dict:
    mode = ctx.mode
    out = {"dense_cap": mode.dense_cap, "rigid": [], "pairs": []}
    for kind in ("rigid", "pairs"):
        rows = []
        for n in mode.contact_ns:
            tmesh = _contact_mesh(ctx.comm, kind, n)
            for method, steps in _methods(mode, n):
                rec = _contact_run(_contact_sim(kind, tmesh, n, method, steps), n, method, steps)
                out[kind].append(rec)
                rows.append([n, method, rec["n_dofs"], f"{rec['n_active_median']:.0f}"]
                            + [f"{1e6 * rec[k]:.1f}" for k in PHASES[:3] + ("contact",)]
                            + [f"{rec['contact_ns_per_constraint']:.0f}", f"{1e6 * rec['f_int']:.1f}"])
            del tmesh
        title = ("rigid punch (rigid_face on punch_block)" if kind == "rigid"
                 else "node pairs (pair_surfaces on coaxial_bars)")
        ctx.table(f"2. Contact per step, {title}; FILM dense only up to {mode.dense_cap} "
                  "constraints (O(n^3)); medians in us",
                  ["n", "method", "dofs", "active", "detect", "solve", "update", "contact",
                   "ns/constr", "f_int"], rows)
    ctx.log(SPLIT)
    return out


def part_solvers(ctx) -> dict:
    from ..contact.film import solve_dense, solve_fast

    mode = ctx.mode
    rng = np.random.default_rng(11)
    dt = 1e-8
    out, rows = [], []
    one = np.ones(1)
    # load (or compile) before the timer calibrates; solve_fast with its index buffer and
    # 1/d, set-up constants of a contact set as the FILM method passes them
    solve_fast(-one, one, 0.0, np.empty(1), np.empty(1, np.int32), one)
    _empty_call(-one, one, 0.0, np.empty(1))
    for n in mode.solver_ns:
        m = rng.uniform(0.5e-4, 1.5e-4, n)
        d = dt ** 2 / m
        gap = -1e-9 * rng.uniform(0.0, 1.0, n)
        gap[rng.uniform(size=n) < 0.1] *= -1.0  # some open constraints
        f = np.empty(n)
        work = np.empty(n, np.int32)
        d_inv = 1.0 / d
        for label, kappa in (("pairs", 0.0), ("rigid", dt ** 2 / 0.1)):
            rec = {"n": n, "case": label,
                   "fast": ctx.median(lambda: solve_fast(gap, d, kappa, f, work, d_inv),
                                         mode.target / 4)}
            if n <= mode.dense_cap:
                rec["dense"] = ctx.median(lambda: solve_dense(gap, d, kappa, f), mode.target / 4,
                                          max(3, mode.repeats // 2))
            rec["numba_call_floor"] = ctx.median(lambda: _empty_call(gap, d, kappa, f), mode.target / 8)
            out.append(rec)
            rows.append([n, label, f"{1e6 * rec['fast']:.1f}",
                         f"{1e6 * rec['dense']:.1f}" if "dense" in rec else "-",
                         f"{1e6 * rec['numba_call_floor']:.2f}"])
    ctx.table("2b. FILM solvers alone on synthetic gaps (us per call): solve_fast compiled (numba), "
              "solve_dense numpy/LAPACK, and an empty compiled call with the same arguments",
              ["n", "case", "solve_fast", "solve_dense", "empty numba call"], rows)
    return {"cases": out, "dense_cap": mode.dense_cap}


# the punch Sim3 of the whole-run part (R_z = 6 m on punch_block: 610 constraints), its step
SIM3_DT = 3.64e-7
FRICTION_MU = 0.3


def _sim3_contact(comm, tmesh, method: str, mu: float, steps: int) -> dict:
    """One run of the punch Sim3 with ``method`` and friction μ (0: none), the Python step
    (a set with friction runs it, so the frictionless one does too here), no outputs:
    medians (s per step) of the contact step and of the whole step, and the sets' counts."""
    from .. import scenes
    from ..simulation import Settings

    settings = Settings(dt=SIM3_DT, n_steps=steps, out=None, fields=False, quiet=True,
                        plots=False, history_every=1, output_every=BIG, compiled_steps=False)
    sim = scenes.punch_indentation(settings, scenes.make_method(method),
                                   radius=scenes.PUNCH_RADII[6], tmesh=tmesh, comm=comm)
    c = sim.contacts[0]
    if mu > 0.0:
        c.set_friction(mu)
    s = sim.run()
    h = sim.history.data()
    rec = {"method": method, "mu": mu, "n_constraints": c.n, "steps": steps,
           "contact": s["contact_cpu_time_per_step_median"], "step": s["step_time_median"],
           "n_active_median": float(np.median(np.asarray(h["n_active"], dtype=float)))}
    if mu > 0.0:
        rec["n_slip_median"] = float(np.median(np.asarray(h["n_slip"], dtype=float)))
        rec["n_stick_median"] = float(np.median(np.asarray(h["n_stick"], dtype=float)))
    return rec


def part_friction(ctx) -> dict:
    """Friction's cost at Sim3: the contact step (and the whole step) with μ = 0 and
    μ = 0.3 for each method, in one run, medians, with the load average before and after
    (os.getloadavg: the other processes on the cores)."""
    from .. import meshing

    mode = ctx.mode
    steps = max(20, 4 * mode.contact_steps)
    load_before = os.getloadavg()
    tmesh = meshing.punch_block(comm=ctx.comm)
    out = {"steps": steps, "mu": FRICTION_MU, "runs": []}
    rows = []
    for method in ("penalty", "film", "dme"):
        pair = [_sim3_contact(ctx.comm, tmesh, method, mu, steps) for mu in (0.0, FRICTION_MU)]
        out["runs"].extend(pair)
        off, on = pair
        on["contact_ratio"] = on["contact"] / off["contact"]
        on["step_ratio"] = on["step"] / off["step"]
        rows.append([method, off["n_constraints"], f"{on['n_active_median']:.0f}",
                     f"{on['n_stick_median']:.0f}/{on['n_slip_median']:.0f}",
                     f"{1e6 * off['contact']:.1f}", f"{1e6 * on['contact']:.1f}",
                     f"{100 * (on['contact_ratio'] - 1):+.0f} %",
                     f"{1e6 * off['step']:.1f}", f"{1e6 * on['step']:.1f}",
                     f"{100 * on['contact'] / on['step']:.1f} %"])
    out["loadavg_before"], out["loadavg_after"] = list(load_before), list(os.getloadavg())
    ctx.table(f"Friction at Sim3 (punch R_z = 6 m, {steps} steps, the Python step, no "
              f"outputs): the contact step with mu = 0 and mu = {FRICTION_MU}; medians in us",
              ["method", "constraints", "active", "stick/slip", "contact mu=0",
               f"contact mu={FRICTION_MU}", "friction adds", "step mu=0",
               f"step mu={FRICTION_MU}", "contact share"], rows)
    ctx.log(f"   load average (1, 5, 15 min) before {', '.join(f'{x:.2f}' for x in load_before)}"
            f", after {', '.join(f'{x:.2f}' for x in out['loadavg_after'])}")
    return out
