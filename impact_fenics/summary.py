"""A run's summary (summary.json): its figures per body and per contact set (the impact
figures), its timing, energy and provenance.

Units: s, m, kg, m/s, N, J, Pa.
"""
from __future__ import annotations

import sys
import time

import numpy as np
from mpi4py import MPI

from .cell_fields import PEAK_NAMES
from .contact.segments import SegmentConstraints
from .outputs import ENERGY_COLUMNS


def run_summary(sim, times, stopped_at: int, wall: float, last_energy: dict | None,
                max_bal: float, track: dict) -> dict:
    """The summary of ``sim``'s run (summary.json): status, steps, sizes, dt and the stable
    bounds (s), provenance, set-up and loop times by phase (``times``: the run's
    PhaseTimers or None, ``wall``: the loop's wall time, s), per body figures, the impact
    figures, peak stresses, the last energy row ``last_energy`` (J) with the largest
    balance error ``max_bal``, contact figures (``track``: checks.ContactTrack.as_dict).
    Collective."""
    model, s, comm = sim.model, sim.settings, sim.comm
    n_cells = comm.allreduce(model.mesh.topology.index_map(2).size_local)
    summary = {
        "status": sim.status,
        "stopped_at_step": int(stopped_at),
        "n_steps": int(sim.n_steps),
        "n_ranks": comm.size,
        "n_dofs": int(model.n_global),
        "n_cells": int(n_cells),
        "dt": s.dt,
        "dt_critical": sim.dt_critical,
        "stable_dt": dict(sim.stable_dt),
        "stable_dt_limiting": sim.stable_dt_limiting,
        "t_end": sim.n_steps * s.dt,
        "wall_time": wall,
    }
    steps = getattr(sim, "listed_steps", None)
    if not sim.integrator.step.constant and steps is not None:  # a varying step: s.dt the first
        summary["t_end"] = float(sum(steps))
        summary["dt_range"] = [min(steps), max(steps)]
    elif not sim.integrator.step.constant and hasattr(sim.step_policy, "h_range"):
        summary["t_end"] = float(sim.integrator.t)  # a step that follows a limit: the time
        # reached and the steps' range before the clipped last one
        summary["dt_range"] = [float(h) for h in sim.step_policy.h_range]
    if s.title is not None:
        summary["title"] = s.title
    summary.update(provenance())
    summary["setup_time"] = dict(sim.setup_time)
    if sim.dt_converged is not None:
        summary["dt_critical_converged"] = sim.dt_converged
    if times is not None and times.n_steps > 0:
        medians = times.medians(comm)
        totals = times.total(comm)
        summary["time_per_step_median"] = medians
        summary["time_per_step_total"] = totals
        summary["step_time_median"] = step = times.median_of_sum(comm=comm)
        # shares from the totals and walls averaged over the ranks: they add up to <= 1
        mean = np.append(times.totals, wall)
        comm.Allreduce(MPI.IN_PLACE, mean)
        mean /= comm.size
        share = {k: (float(mean[i] / mean[-1]) if mean[-1] > 0 else 0.0)
                 for i, k in enumerate(times.phases)}
        summary["timing"] = {  # the loop's wall time by phase (s), and its share
            "phases": {k: {"total": totals[k], "median": medians[k], "share": share[k]}
                       for k in totals},
            "rest_share": max(0.0, 1.0 - sum(share.values())),
            "loop_over_steps_median": wall / (times.n_steps * step) if step > 0 else None,
            "compiled_in_loop": list(sim.compiled_in_loop),
            "compiled_steps": sim.compiled_steps,
            "compiled_frames": sim.compiled_frames,
            "definition": "total and median: the slowest rank's (s); share: the phase's "
                          "total over the loop's wall time, both averaged over the ranks; "
                          "rest: the loop's own Python, progress and signal checks; "
                          "compiled_in_loop: numba kernels that compiled inside the loop; "
                          "compiled_steps: the steps ran as compiled blocks with their "
                          "output steps' sums (linear bodies: step_block.py); "
                          "compiled_frames: the blocks wrote the frames too (one rank)"}
    geometry = getattr(model, "geometry", None)
    if geometry is not None and geometry.plane:  # every figure is the slab's (kg, N, J)
        summary["geometry"] = {"kind": geometry.kind, "thickness": geometry.thickness,
                               "symmetry": geometry.symmetry}
    summary["bodies"] = body_figures(model, sim.integrator, sim.body_mass, sim._v_start,
                                      _velocities(sim), comm, getattr(sim, "_finite_u", None))
    element_cycle_figures(summary, {name: model.owned_cells(name).size for name in model.bodies},
                          comm, sim.integrator)
    if sim.contacts:
        summary["impact"] = impact_figures(sim.history.data(), sim.contacts, sim._v_start,
                                           _velocities(sim), s.dt, model, comm)
    if sim._peaks[-1]:
        names = PEAK_NAMES if geometry is None or not geometry.plane else tuple(  # sigma_yy
            n.replace("sigma_zz", geometry.public("sigma_zz")) for n in PEAK_NAMES)
        summary["peak_stress"] = dict(zip(names, sim._peaks.tolist()))
    if last_energy is not None:
        last = last_energy
        summary["energy"] = {k: last[k] for k in ENERGY_COLUMNS}  # the last row's
        summary["energy_initial"] = sim.ledger.E0  # E_0 (J), the initial state's
        summary["energy_balance_error_rel"] = max_bal
        if sim.integrator.nonlinear:
            summary["plastic_dissipation"] = last["plastic_work"]
        summary["energy_balance_definition"] = (
            "largest over the output steps of |E_n - E_0 - W_n| / (largest |term| so far), "
            "E_0 = 1/2 v^0 M v^0 the initial state, E_n (after step n) = 1/2 v^(n+1/2) M "
            "v^(n+1/2) + 1/2 u^n K u^n (the linear bodies) + the stored elastic energy and "
            "the plastic work of the path-dependent ones + 1/2 dt v^(n+1/2) f_int(u^n), W_n "
            "the work of loads and contact through step n, each step's "
            "1/2 dt (v^(n-1/2) + v^(n+1/2)) F^n (the half-step scheme's kinetic identity)")
        if not sim.integrator.step.constant:
            summary["energy_balance_definition"] += (
                "; under a varying step dt is h_n in the work and h_(n+1/2) in the boundary "
                "term, and E_n adds work_gap, the sum over the changes of step of 1/4 "
                "(h_(n+1/2) - h_(n-1/2)) (v^(n-1/2) - v^(n+1/2)) f_int(u^n), the internal "
                "work the split into stored energy and dissipation leaves out")
        if sim.integrator.finite:
            summary["energy_balance_definition"] += (
                "; a finite-strain body books its work by the kinetic identity, and work_gap "
                "adds that work less psi(u^n) + its plastic work + 1/2 h_(n+1/2) v^(n+1/2) "
                "f_int(u^n) (O(dt^2))")
    if sim.integrator.nonlinear:
        summary["eps_p_max"] = eps_p_max(sim.integrator.nonlinear, sim.status == "diverged", comm)
    if sim.integrator.finite:  # (a small-strain body's eps_p_max above, if any, included)
        finite = finite_figures(sim.integrator.finite, sim.status == "diverged", comm)
        summary["eps_p_max"] = max(summary.get("eps_p_max", 0.0), finite.pop("eps_p_max"))
        summary.update(finite)
    if sim.contacts:
        c = sim.contacts[0]
        summary["contact"] = {  # the first contact set, or all of them for the figures below
            "method": c.method.name,
            "n_constraints": c.n,
            "max_penetration": track["max_penetration"],
            "method_info": getattr(c.method, "info", {}),
            "first_contact_step": track["first_contact"],
            "last_contact_step": track["last_contact"],
        }
        if getattr(c, "repair_every", 0):  # node to segment re-paired in the loop
            summary["contact"]["repair_every"] = c.repair_every
            summary["contact"]["repairs"] = c.repairs
        if len(sim.contacts) > 1:
            summary["contacts"] = [{"method": c.method.name, "n_constraints": c.n,
                                    "surfaces": list(c.constraints.names),
                                    "method_info": getattr(c.method, "info", {})}
                                   for c in sim.contacts]
        frictional = [c for c in sim.contacts if getattr(c, "friction", None) is not None]
        if frictional:  # the dissipation (both parts, J) and the peak tangential force (N)
            summary["friction"] = [{"surfaces": list(c.constraints.names), **c.friction.summary()}
                                   for c in frictional]
        moving = [c.moving_rigid for c in sim.contacts if c.moving_rigid is not None]
        if moving:  # each moving rigid body's state at the end (m, m/s; x: in the plane)
            summary["rigid_bodies"] = {r.name: rigid_state(r) for r in moving}
        for c in sim.contacts:  # a rigid body driven by a rod: its wave energies (J)
            if c.rigid is not None and c.rigid.impedance > 0:
                summary.setdefault("rod_waves", {})[c.rigid.name] = {
                    "incident": c.rigid.wave_incident, "reflected": c.rigid.wave_reflected,
                    "delivered": c.rigid.wave_delivered}
        if times is not None and times.n_steps > 0:
            summary["contact_cpu_time_per_step_median"] = times.median_of_sum(
                ("contact_detection", "contact_solve", "contact_update"), comm)
    return summary


def element_cycle_figures(summary: dict, body_cells: dict[str, int], comm: MPI.Comm,
                          integrator=None) -> None:
    """The time per element per cycle (ns; LS-DYNA's "time per zone cycle") into ``summary``:
    the whole run's, the loop's wall time / (cells x steps taken), and each body's,
    ``f_int_seconds`` (its force's time, the slowest rank's) over its cells x steps. With
    two or more forces (``integrator.force_seconds``, timed apart) a body's time is its
    own force's, shared by cells among the linear bodies (one operator steps them all);
    with one, the f_int phase's, shared by cells. ``body_cells``: each body's cells owned
    by this rank. Collective."""
    steps = summary["stopped_at_step"]
    cells = summary["n_cells"]
    if steps <= 0 or cells <= 0:
        return
    summary["ns_per_element_cycle"] = 1e9 * summary["wall_time"] / (cells * steps)
    counts = dict(zip(body_cells, comm.allreduce(np.array(list(body_cells.values()),
                                                          dtype=np.int64))))
    timed = integrator is not None and len(getattr(integrator, "forces", ())) > 1
    if timed:
        seconds = np.empty_like(integrator.force_seconds)
        comm.Allreduce(integrator.force_seconds, seconds, op=MPI.MAX)
        shares = [(t, bodies) for t, bodies in zip(seconds, integrator.force_bodies)]
    else:
        f_int = summary.get("timing", {}).get("phases", {}).get("f_int", {}).get("total")
        shares = [] if f_int is None else [(f_int, list(body_cells))]
    for name, n in counts.items():
        body = summary["bodies"].setdefault(name, {})
        body["n_cells"] = int(n)
    for t, bodies in shares:
        n_force = sum(int(counts[b]) for b in bodies)
        for b in bodies:
            n = int(counts[b])
            if n > 0:
                body = summary["bodies"][b]
                body["f_int_seconds"] = float(t) * n / n_force
                body["ns_per_element_cycle"] = 1e9 * body["f_int_seconds"] / (n * steps)
    summary["ns_per_element_cycle_definition"] = (
        "the loop's wall time / (n_cells x stopped_at_step) (ns); per body: f_int_seconds / "
        "(the body's n_cells x stopped_at_step), f_int_seconds the time of the body's own "
        "force (the slowest rank's) when the bodies have forces of their own, shared by "
        "cells among the linear bodies (one operator), else the f_int phase's time shared "
        "by cells")


def provenance() -> dict:
    """Version of impact_fenics, the date (UTC) and the command line of this run."""
    from importlib import metadata

    try:
        version = metadata.version("impact_fenics")
    except metadata.PackageNotFoundError:
        version = "unknown"
    return {"version": version, "date": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
            "command_line": " ".join(sys.argv)}


def rigid_state(rigid) -> dict[str, float]:
    """A moving rigid body's mass (kg) and its displacement and velocity along the axis or
    y (m, m/s), with x where it translates in the plane (plane strain)."""
    if rigid.prescribed is not None:  # its motion given: no mass (infinite), its reaction (N)
        return {"prescribed": True, "u": float(rigid.u), "v": float(rigid.v),
                "reaction": float(rigid.reaction)}
    out = {"mass": float(rigid.mass), "u": float(rigid.u), "v": float(rigid.v)}
    if rigid.slides or rigid.v_x != 0.0:
        out.update(u_x=float(rigid.u_x), v_x=float(rigid.v_x))
    return out


def mean_velocities(integ, body_z: dict[str, np.ndarray], body_mass: dict[str, float],
                    contacts: list, comm: MPI.Comm) -> dict[str, float]:
    """Mean z velocity (m/s) of every body now: momentum / mass; a rigid body's own.
    ``body_z``: each body's owned z dofs, ``body_mass`` its mass (kg). Collective."""
    local = np.array([float(np.dot(integ.mass[d], integ.v_owned[d])) for d in body_z.values()])
    comm.Allreduce(MPI.IN_PLACE, local)
    out = {name: float(p / body_mass[name]) for name, p in zip(body_z, local)}
    out.update({c.rigid.name: float(c.rigid.v) for c in contacts if c.rigid is not None})
    return out


def _velocities(sim) -> dict[str, float]:
    """:func:`mean_velocities` of ``sim``'s bodies now."""
    return mean_velocities(sim.integrator, sim._body_z, sim.body_mass, sim.contacts, sim.comm)


def body_figures(model, integ, body_mass: dict[str, float], v_start: dict[str, float],
                 v_end: dict[str, float], comm: MPI.Comm, finite_u: list | None = None) -> dict:
    """Per body: mass (kg), mean z velocity (m/s) at the start and at the end,
    and at the end kinetic 1/2 sum m v^2 and strain energy (J): 1/2 u . K u over its dofs,
    or the stored elastic energy psi_e of a path-dependent or finite-strain body, which
    also gets its plastic work (J). ``integ``: the run's integrator (its state now); ``v_start``, ``v_end``:
    :func:`mean_velocities` at the start and now; ``finite_u``: the finite-strain forces'
    kept u^n (every local entry, m), or None. Collective."""
    Ku = integ.u_vec.duplicate()
    if integ.K is not None:  # the linear bodies' stiffness
        integ.K.mult(integ.u_vec, Ku)
    else:
        Ku.set(0.0)
    ku = Ku.array
    psi = {f.body: f.elastic_energy_local() for f in integ.nonlinear}  # path-dependent
    # a finite-strain body's psi(F_bar) at the u^n its state was last updated at (the
    # energy rows' u^n, kept by the run), else at the current u
    kept = finite_u if finite_u is not None else [None] * len(integ.finite)
    psi.update({f.body: f.stored_energy_local(u) for f, u in zip(integ.finite, kept)})
    # the plastic work of path-dependent bodies (a finite-strain elastic one has no state)
    plastic = {f.body: f.plastic_work_local for f in integ.nonlinear + integ.finite
               if f in integ.nonlinear or f.material.n_state > 0}
    finite = {f.body for f in integ.finite}
    out = {}
    for name in model.bodies:
        dofs = np.concatenate([model.body_dofs(name, 0), model.body_dofs(name, 1)])
        strain = psi[name] if name in psi else 0.5 * float(np.dot(integ.u_owned[dofs], ku[dofs]))
        local = np.array([0.5 * float(np.dot(integ.mass[dofs] * integ.v_owned[dofs],
                                              integ.v_owned[dofs])), strain,
                          plastic.get(name, 0.0)])
        comm.Allreduce(MPI.IN_PLACE, local)
        out[name] = {"mass": body_mass[name], "strain": "finite" if name in finite else "small",
                     "velocity_z_initial": v_start[name], "velocity_z_final": v_end[name],
                     "kinetic_energy": float(local[0]), "strain_energy": float(local[1])}
        if name in plastic:
            out[name]["plastic_work"] = float(local[2])
    Ku.destroy()
    return out


def eps_p_max(forces: list, diverged: bool, comm: MPI.Comm) -> float:
    """The largest equivalent plastic strain (-) at a point of the path-dependent bodies
    at the final displacement (the points' update there, as in the last frame; their
    last update if the run ``diverged``); ``forces``: the integrator's path-dependent
    forces. Collective."""
    if not diverged:
        u = forces[0].u  # (every force's displacement Function)
        u.x.scatter_forward()
        states = [f.point_stresses(u.x.array).state for f in forces]
    else:
        states = [f.qs.state for f in forces]
    local = max(float(st[..., 0].max(initial=0.0)) for st in states)
    return comm.allreduce(local, op=MPI.MAX)


def finite_figures(forces: list, diverged: bool, comm: MPI.Comm) -> dict:
    """The finite-strain bodies' figures at the final displacement u^N: the largest
    equivalent plastic strain at a point (-) and the smallest J = det F (-), the points
    updated to u^N by one more force evaluation with the last step (their last update,
    at u^(N-1), if the run ``diverged``), as the finite-strain driver reports them.
    Collective."""
    if not diverged:
        forces[0].u.x.scatter_forward()  # (every force's displacement Function)
        for f in forces:
            f.set_step(f.h, f.h)  # the points' step: the last one taken
            f.evaluate()
    local = max(float(f.state[..., 0].max(initial=0.0)) for f in forces)
    return {"eps_p_max": comm.allreduce(local, op=MPI.MAX),
            "j_min": min(f.j_min for f in forces)}


def contact_bodies(c, model, comm: MPI.Comm) -> dict[str, str]:
    """The bodies of a contact set: {"lower": the body below, "upper": the body or rigid
    body above}, as the scene names the faces of node pairs; for node to segment
    the master's outward normals say which side the slave is on (their mean z
    component > 0: above), and {"slave", "master"} name the two roles too. Collective."""
    def body_of(global_dofs):
        counts = np.array([np.isin(global_dofs, model.to_global(
            model.body_dofs(b, 1))).sum() for b in model.bodies])
        counts = comm.allreduce(counts)
        return list(model.bodies)[int(np.argmax(counts))]

    cons = c.constraints
    if isinstance(cons, SegmentConstraints):  # (replicated on every rank)
        slave, master = body_of(cons.slave_dofs[:, 1]), body_of(cons.master_dofs[:, 1])
        above = float(np.mean(cons.normal[:, 1])) > 0.0  # the slave above the master?
        lower, upper = (master, slave) if above else (slave, master)
        return {"lower": lower, "upper": upper, "slave": slave, "master": master}
    lower = body_of(cons.lower)
    upper = c.rigid.name if c.rigid is not None else body_of(cons.upper)
    return {"lower": lower, "upper": upper}


def impact_figures(history: dict[str, np.ndarray], contacts: list, v_start: dict[str, float],
                   v_end: dict[str, float], dt: float, model, comm: MPI.Comm) -> list[dict]:
    """Per contact set: peak force, impulse, time in contact, separations and, where the
    two sides part, the rebound velocities and the coefficient of restitution, from the
    ``history`` table's columns and :func:`mean_velocities` at the start and at the end
    (m/s). Collective."""
    from .report import contact_figures, restitution

    h = history
    out = []
    for k, c in enumerate(contacts):
        tag = f"c{k}_" if len(contacts) > 1 else ""
        force = f"{tag}{c.rigid.name}_force" if c.rigid is not None else f"{tag}contact_force"
        bodies = contact_bodies(c, model, comm)
        lower, upper = bodies["lower"], bodies["upper"]
        fig = {"surfaces": "/".join(c.constraints.names), **bodies}
        if c.method.name == "tie":
            fig["tie"] = True
        fig.update(contact_figures(h["time"], h[force], h[f"{tag}n_active"], dt))
        fig.update(restitution((v_start[lower], v_end[lower]),
                               (v_start[upper], v_end[upper])))
        out.append(fig)
    return out
