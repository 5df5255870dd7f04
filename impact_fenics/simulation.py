"""A run: the explicit loop with contact, the energy ledger, outputs, timers and progress.

Units throughout: s, m, kg, N, Pa, J.
"""
from __future__ import annotations

import math
import os
import sys
import time
from dataclasses import dataclass

import numpy as np
from mpi4py import MPI

from . import forms, interrupts, output, plotting, rundir
from .bodies import DeformableModel
from .contact import ContactSet, RigidBody
from .contact.pairing import Constraints
from .energy import Ledger, LoadWork, deformable_energy
from .errors import InputError, UnstableRunError, require
from .integrator import Integrator
from .loads import SurfaceLoad
from .probes import Probes
from .stability import converged_omega_max, critical_dt, element_omega_bound
from .timers import PhaseTimers

# Per-step divergence check: every DIVERGENCE_EVERY steps one VecNorm of v (a pass
# over 8 B/dof against the step's ~219 B/dof: 1-3 % of a step measured, so under
# 0.2 % spread over 16 steps); a deformable node's velocity that is not finite or
# exceeds the runaway speed (the fastest wave speed, or 10x the fastest initial
# speed if higher: beyond it the strain would exceed 1) stops the run as diverged.
# A rigid body's velocity is checked every step for being finite (it may be fast:
# a punch that a soft penalty does not hold is wrong, not diverged).
DIVERGENCE_EVERY = 16
RUNAWAY_FACTOR = 10.0
# Penalty misbehaviour, marked in the status of a run that completes: chatter, i.e.
# the number of active penalty constraints reversing its trend (a rise followed by
# a fall or the other way) at least CHATTER_MIN times and in CHATTER_SHARE of the
# contact steps (a settling contact reverses a few times, a chattering one nearly
# every step); and contact energy gain, i.e. contact work done ON the bodies (J), at
# an output step after contact with every spring released, above GAIN_SHARE of the
# energy put in (a released spring can only have given back what it took; while
# springs are loaded their work includes the energy they store, of either sign).
PENALTY_BOUND = 4.0 / 3.0
CHATTER_MIN, CHATTER_SHARE, GAIN_SHARE = 10, 0.05, 0.01
PHASES = ("f_int", "contact_detection", "contact_solve", "contact_update", "history", "output")


@dataclass
class Settings:
    """How a run steps and what it writes.

    ``dt`` in s, or ``cfl``: dt = cfl * the stable limit (element bound);
    ``t_end`` in s (or ``n_steps``); outputs every ``output_every`` steps (XDMF
    fields and the energy ledger) and ``history_every`` steps (CSV rows)."""

    dt: float | None = None
    cfl: float | None = None
    t_end: float | None = None
    n_steps: int | None = None
    out: str | None = None
    output_every: int = 50
    history_every: int = 1
    fields: bool = True
    force_dt: bool = False
    force: bool = False  # run what the checks refuse: a penalty above its stable bound
    converged_dt: bool = False
    matrix_type: str = "aij"
    energy_growth_limit: float = 10.0
    quiet: bool = False
    timers: bool = True
    plots: bool = True  # history.png and energy.png in the output directory (rank 0)

    def steps(self) -> int:
        """Number of steps to run."""
        require(self.dt is not None and self.dt > 0, f"dt = {self.dt} s: must be > 0")
        if self.n_steps is None:
            require(self.t_end is not None and self.t_end > 0, "give t_end > 0 (s) or n_steps")
            require(self.t_end >= self.dt * (1 - 1e-9), f"t_end = {self.t_end:.4g} s is shorter "
                                                        f"than one step dt = {self.dt:.4g} s")
            return int(math.ceil(self.t_end / self.dt - 1e-9))
        require(self.n_steps > 0, f"n_steps = {self.n_steps}: must be > 0")
        return int(self.n_steps)


class Simulation:
    """Deformable bodies, their conditions, loads, contact and the run settings."""

    def __init__(self, model: DeformableModel, settings: Settings,
                 fixed: list[np.ndarray] | None = None, loads: list[SurfaceLoad] | None = None,
                 initial_velocity: dict[str, tuple[float, float]] | None = None):
        self.model = model
        self.comm: MPI.Comm = model.comm
        self.settings = settings
        require((settings.dt is None) != (settings.cfl is None), "give either dt or cfl")
        require(settings.output_every > 0 and settings.history_every > 0,
                "output_every and history_every must be > 0 (steps)")
        fixed = [model.axis_dofs()] + list(fixed or [])
        fixed_owned = np.unique(np.concatenate(fixed)).astype(np.int32)
        self.loads = list(loads or [])
        # stability: refuse dt above the conservative element bound unless forced
        fixed_local = np.unique(np.concatenate([model.axis_dofs(owned=False)] +
                                               [self._local_fixed(f) for f in fixed[1:]]))
        self.dt_critical = critical_dt(element_omega_bound(model, fixed_local))
        if settings.cfl is not None:
            require(settings.cfl > 0, f"cfl = {settings.cfl}: must be > 0")
            settings.dt = settings.cfl * self.dt_critical
        self.n_steps = settings.steps()
        if settings.dt > self.dt_critical and not settings.force_dt:
            raise InputError(f"dt = {settings.dt:.4g} s is above the stable limit "
                             f"{self.dt_critical:.4g} s (element bound on 2/omega_max); "
                             "lower dt or force it")
        self.integrator = Integrator(model, settings.dt, fixed_owned, self.loads,
                                     settings.matrix_type)
        self.dt_converged = None
        if settings.converged_dt:
            self.dt_converged = critical_dt(converged_omega_max(
                self.integrator.K, self.integrator.mass, model.to_global(fixed_owned)))
        v0 = np.zeros(model.n_owned)
        for body, (vr, vz) in (initial_velocity or {}).items():
            v0[model.body_dofs(body, 0)] = vr
            v0[model.body_dofs(body, 1)] = vz
        self.integrator.set_initial(None, v0)
        self._body_z = {name: model.body_dofs(name, 1).astype(np.intp) for name in model.bodies}
        self.body_mass = {name: self.comm.allreduce(float(self.integrator.mass[d].sum()))
                          for name, d in self._body_z.items()}
        self.contacts: list[ContactSet] = []
        self._probe_specs: list[tuple[str, tuple[float, float], str]] = []
        self.status = "not started"

    def _local_fixed(self, owned: np.ndarray) -> np.ndarray:
        """Local (ghosted) indices of fixed dofs given as owned ones: share them via a scatter."""
        from dolfinx import fem

        f = fem.Function(self.model.V)
        f.x.array[:] = 0.0
        f.x.array[owned] = 1.0
        f.x.scatter_forward()
        return np.flatnonzero(f.x.array > 0.5).astype(np.int32)

    # ------------------------------------------------------------ scene set-up
    def add_contact(self, constraints: Constraints, method, rigid: RigidBody | None = None) -> ContactSet:
        """Enforce ``constraints`` with ``method`` (penalty, FILM or DME)."""
        contact_dofs = constraints.lower if constraints.upper is None else \
            np.concatenate([constraints.lower, constraints.upper])
        loaded = [self.model.to_global(ld.dofs) for ld in self.loads]
        if loaded and self.comm.allreduce(int(np.isin(np.concatenate(loaded), contact_dofs).sum())):
            raise InputError(f"a surface load acts on nodes of the contact surfaces "
                             f"'{constraints.names[0]}'/'{constraints.names[1]}': load another "
                             "facet group (the contact bookkeeping assumes no load there)")
        c = ContactSet(constraints, self.integrator, method, rigid)
        c.initialize()
        beta = getattr(method, "info", {}).get("beta_max") if method.name == "penalty" else None
        if beta is not None and beta > PENALTY_BOUND and not self.settings.force:
            raise InputError(f"penalty: beta_max = {beta:.4g} is above the stable bound 4/3 of "
                             f"persistent contact (p from {method.info['p_min']:.4g} to "
                             f"{method.info['p_max']:.4g} N/m, dt = {self.settings.dt:.4g} s): "
                             "the contact would chatter and gain energy; lower the penalty, use "
                             "penalty = \"scaled\", or force it")
        self.contacts.append(c)
        return c

    def add_probe(self, name: str, point: tuple[float, float], quantity: str = "sigma_zz") -> None:
        """Record ``quantity`` (a stress component name, or u_r, u_z) at ``point`` (r, z) in m."""
        self._probe_specs.append((name, point, quantity))

    # ------------------------------------------------------------ the run
    def run(self, extra=None) -> dict:
        """Step to the end (or to a failure or a signal) and return the summary.

        ``extra(sim)`` may return more summary entries (checks of a demo); they are
        written with the rest, before the output directory is published."""
        s = self.settings
        model, integ, comm = self.model, self.integrator, self.comm
        n_steps = self.n_steps
        # from here a signal only sets a flag (interrupts.deferred) until the directory is
        # in place; one before the first step removes the staging directory and stops
        stop = _StopFlag()
        staging = writer = None
        try:
            staging = rundir.prepare_directory(s.out, comm) if s.out else None
            writer = self._field_writer(staging) if (staging and s.fields) else None
            u_fn = writer.u if writer else None
            probes = self._make_probes(u_fn) if self._probe_specs else None
            tables = self._tables(staging, probes)
            if stop.collective(comm):
                raise interrupts.Interrupted(stop.signum)
        except BaseException:
            if writer is not None:
                writer.close()  # collective: left to the garbage collector it can hang MPI
            if staging:
                rundir.abandon_directory(staging, comm)
            stop.restore()
            raise
        self.history = tables["history"]
        self.energy = tables["energy"]
        self.probes = probes
        ledger = Ledger(comm)
        load_work = LoadWork(self.loads, s.dt, comm)
        times = PhaseTimers(PHASES) if s.timers else None
        buf = {k: np.empty(model.n_owned) for k in ("u", "v", "v_next", "ku")}
        Ku = integ.K.createVecRight()
        last_energy, max_bal = None, 0.0
        runaway = self._runaway_speed()
        v_check = _OwnedVec(integ.v_owned, comm)
        rigid = [c.rigid for c in self.contacts if c.rigid is not None]
        serial = comm.size == 1
        track = {"max_penetration": 0.0, "first_contact": None, "last_contact": None,
                 "contact_steps": 0, "reversals": 0, "gain": 0.0, "budget": 0.0,
                 "penalty": [k for k, c in enumerate(self.contacts) if c.method.name == "penalty"],
                 "n_prev": [0] * len(self.contacts), "d_prev": [0] * len(self.contacts)}
        progress = _Progress(n_steps, s.dt, quiet=s.quiet or comm.rank != 0)
        self.status = "running"
        stopped_at = n_steps
        clock = time.perf_counter
        t_run = clock()
        try:
            for n in range(n_steps):
                is_output = (n % s.output_every == 0) or (n == n_steps - 1)
                is_history = (n % s.history_every == 0) or is_output
                t0 = clock()
                if is_output:
                    pre = self._pre_output(buf, Ku)
                load_work.accumulate(integ)
                integ.predict()
                t1 = clock()
                for c in self.contacts:
                    c.step()
                self._track_contact(track, n)
                integ.advance()
                t3 = clock()
                if is_history:
                    self._history_row(tables, probes, u_fn, buf)
                t4 = clock()
                for body in rigid:
                    if not math.isfinite(body.v):
                        self._runaway(n, f"the rigid body '{body.name}' moves at {body.v} m/s")
                if n % DIVERGENCE_EVERY == DIVERGENCE_EVERY - 1 or n == n_steps - 1:
                    v_max = v_check.norm_inf()
                    if not v_max <= runaway:
                        self._runaway(n, f"a node moves at {v_max:.4g} m/s")
                if is_output:
                    row = self._post_output(pre, buf, ledger, load_work)
                    max_bal = max(max_bal, row["balance_error_rel"])
                    last_energy = row
                    if track["penalty"]:
                        track["budget"] = max(track["budget"], abs(ledger.E0 or 0.0),
                                              abs(row["external_work"]))
                        if track["first_contact"] is not None and not any(
                                c.any_active for c in self.contacts):  # springs all released
                            track["gain"] = max(track["gain"], row["contact_work"])
                    tables["energy"].row()[:] = [row[k] for k in tables["energy"].columns]
                    self._check_stability(row, ledger, n)
                    if writer is not None:
                        writer.set_state(buf["u"], buf["v"])
                        writer.write((integ.n - 1) * s.dt)
                    for tbl in tables.values():
                        tbl.flush()
                t5 = clock()
                if times is not None:
                    now = times.current
                    now[0] = t1 - t0
                    for c in self.contacts:
                        now[1] += c.times.detection
                        now[2] += c.times.solve
                        now[3] += c.times.update
                    now[4] = t4 - t3
                    now[5] = t5 - t4
                    times.record()
                progress.update(n + 1)
                # the flag every step; under MPI the ranks agree every AGREE_EVERY steps
                # and after the last one (a signal in the last steps is never lost)
                if serial:
                    caught = interrupts.STATE.signum != 0
                else:
                    caught = (((n + 1) % interrupts.AGREE_EVERY == 0 or n + 1 == n_steps)
                              and stop.collective(comm))
                if caught:
                    stop.collective(comm)  # names the signal (serial: no communication)
                    self.status = f"interrupted by {stop.name}"
                    stopped_at = n + 1
                    break
            else:
                self.status = "completed" + self._penalty_trouble(track)
        except UnstableRunError as exc:
            self.status = "diverged"
            stopped_at = integ.n
            self._failure = str(exc)
        except BaseException:
            stop.restore()
            raise
        finally:
            progress.done()
            wall = clock() - t_run
            v_check.destroy()
            for tbl in tables.values():
                tbl.flush()
            if writer is not None:
                writer.close()
        try:
            summary = self._summary(times, stopped_at, wall, last_energy, max_bal, track)
            self.summary = summary
            if extra is not None and self.status.startswith("completed"):
                summary.update(extra(self))
            if staging:
                # after an interrupt the data files are complete: skip the plots, finish fast
                if s.plots and comm.rank == 0 and not stop.signum:
                    plotting.write_history_plots(staging, self.history.data(), self.energy.data(),
                                                 [(name, q) for name, _, q in self._probe_specs])
                if not self.status.startswith("interrupted") and stop.collective(comm):
                    summary["interrupted"] = (f"{stop.name} after the last step, while the "
                                              "output was finished (it is complete)")
                output.write_json(os.path.join(staging, "summary.json"), summary, comm)
                self.out_dir = rundir.finalize_directory(staging, s.out, comm)
            stop.collective(comm)  # a signal while the directory was moved into place
        finally:
            stop.restore()
        self.signal = stop.signum
        if self.status == "diverged":
            raise UnstableRunError(self._failure)
        return summary

    # ------------------------------------------------------------ pieces of the loop
    def _pre_output(self, buf, Ku) -> dict:
        integ = self.integrator
        integ.displacement(buf["u"])
        integ.velocity(buf["v"])
        integ.K.mult(integ.u_vec, Ku)
        buf["ku"][:] = Ku.array
        return {"rigid_v": [c.rigid.v if c.rigid else 0.0 for c in self.contacts]}

    def _post_output(self, pre, buf, ledger, load_work) -> dict:
        integ = self.integrator
        integ.velocity(buf["v_next"])
        kinetic, strain = deformable_energy(integ.mass, buf["v"], buf["v_next"], buf["u"],
                                            buf["ku"], self.comm)
        ext = load_work.total()
        work_c = 0.0
        for c, v_now in zip(self.contacts, pre["rigid_v"]):
            if c.rigid is not None:
                kinetic += c.kinetic_energy_rigid(v_now, c.rigid.v)
                ext += c.rigid_external_work
            work_c += c.contact_work
        row = ledger.record(kinetic, strain, ext, work_c)
        row["activation_loss"] = sum(c.activation_loss for c in self.contacts)
        row["step"] = integ.n - 1
        row["time"] = (integ.n - 1) * self.settings.dt
        # z momentum (kg m/s) of v^{n+1}: in total (every node once) and per body
        # (a node that two bonded bodies share counts in both)
        v = buf["v_next"]
        local = np.array([float(np.dot(integ.mass[1::2], v[1::2]))] +
                         [float(np.dot(integ.mass[d], v[d])) for d in self._body_z.values()])
        momenta = np.zeros_like(local)
        self.comm.Allreduce(local, momenta)
        total = float(momenta[0])
        for name, p in zip(self._body_z, momenta[1:]):
            row[f"momentum_z_{name}"] = float(p)
        for c in self.contacts:
            if c.rigid is not None:
                row[f"momentum_z_{c.rigid.name}"] = c.rigid.mass * c.rigid.v
                total += c.rigid.mass * c.rigid.v
        row["momentum_z"] = total
        return row

    @staticmethod
    def _penalty_trouble(track: dict) -> str:
        """' (penalty chatter ...; contact energy gain ...)' or '' (see CHATTER_MIN)."""
        marks = []
        rev = track["reversals"]
        if rev >= CHATTER_MIN and rev >= CHATTER_SHARE * track["contact_steps"]:
            marks.append(f"penalty chatter: the active set reversed {rev} times in "
                         f"{track['contact_steps']} contact steps")
        if track["gain"] > GAIN_SHARE * track["budget"] and track["gain"] > 0:
            marks.append(f"contact energy gain: the penalty did {track['gain']:.4g} J of work "
                         f"on the bodies ({track['gain'] / max(track['budget'], 1e-300):.1%} "
                         "of the energy put in)")
        return f" ({'; '.join(marks)})" if marks else ""

    def _runaway_speed(self) -> float:
        """Speed (m/s) above which a run counts as diverged: the fastest wave speed of
        the materials, or RUNAWAY_FACTOR x the fastest initial speed if that is higher."""
        waves = [b.material.wave_speed() for b in self.model.bodies.values()]
        v0 = float(np.abs(self.integrator.v_owned).max(initial=0.0))
        v0 = max([self.comm.allreduce(v0, op=MPI.MAX)] +
                 [abs(c.rigid.v) for c in self.contacts if c.rigid is not None])
        return max(max(waves), RUNAWAY_FACTOR * v0)

    def _runaway(self, n: int, what: str) -> None:
        raise UnstableRunError(self._diagnosis(
            n, f"{what}, beyond the runaway speed {self._runaway_speed():.4g} m/s "
               "(not finite, or a strain beyond 1)"))

    def _check_stability(self, row: dict, ledger: Ledger, n: int) -> None:
        values = [row["kinetic"], row["strain"], row["external_work"], row["contact_work"]]
        budget = max(abs(ledger.E0 or 0.0), abs(row["external_work"]), 1e-300)
        if not all(np.isfinite(values)):
            raise UnstableRunError(self._diagnosis(n, "the energy is not finite"))
        limit = self.settings.energy_growth_limit
        if row["total"] > limit * budget and (ledger.E0 or row["external_work"]):
            raise UnstableRunError(self._diagnosis(
                n, f"the energy {row['total']:.4g} J grew beyond {limit:g} x the energy put in "
                   f"({budget:.4g} J)"))

    def _diagnosis(self, n: int, what: str) -> str:
        penalty = [c.method.info.get("beta_max") for c in self.contacts if c.method.name == "penalty"]
        extra = ""
        if penalty:
            extra = f"; penalty beta_max = {max(penalty):.3g} (stable below 4/3)"
        return (f"run diverged at step {n} (t = {n * self.settings.dt:.6g} s): {what}; "
                f"dt = {self.settings.dt:.4g} s, stable dt <= {self.dt_critical:.4g} s{extra}")

    def _track_contact(self, track: dict, n: int) -> None:
        if not self.contacts:
            return
        pen = max(c.max_penetration() for c in self.contacts)
        track["max_penetration"] = max(track["max_penetration"], pen)
        if any(c.any_active for c in self.contacts):
            if track["first_contact"] is None:
                track["first_contact"] = n
            track["last_contact"] = n
            track["contact_steps"] += 1
        for k in track["penalty"]:  # reversals of the number of active penalty constraints
            n_active = int(np.count_nonzero(self.contacts[k].active))
            d = n_active - track["n_prev"][k]
            if d * track["d_prev"][k] < 0:
                track["reversals"] += 1
            track["n_prev"][k] = n_active
            if d:
                track["d_prev"][k] = d

    # ------------------------------------------------------------ outputs
    def _stress_pieces(self, u, name: str):
        pieces = []
        for body in self.model.bodies.values():
            expr = forms.stress_components(u, body.material)[name]
            pieces.append((expr, self.model.tmesh.cells(body.name)))
        return pieces

    def _field_writer(self, staging: str) -> output.FieldWriter:
        snapshots = self.n_steps // self.settings.output_every + 1
        if snapshots > output.MANY_SNAPSHOTS and self.comm.rank == 0:
            print(f"warning: {snapshots} field snapshots; dolfinx 0.5 rewrites fields.xdmf at "
                  "each, so their cost grows with the square of their number: raise "
                  "output_every or set fields off", flush=True)
        names = ("sigma_rr", "sigma_zz", "sigma_tt", "sigma_rz", "von_mises")
        return output.FieldWriter(os.path.join(staging, "fields.xdmf"), self.model.V,
                                  lambda u: {k: self._stress_pieces(u, k) for k in names})

    def _make_probes(self, u_fn):
        from dolfinx import fem

        if u_fn is None:
            u_fn = fem.Function(self.model.V)
        self._probe_u = u_fn
        specs = []
        for name, point, quantity in self._probe_specs:
            if quantity in ("u_r", "u_z"):
                expr = u_fn[0 if quantity == "u_r" else 1]
            else:
                body = self._body_at(point)
                comps = forms.stress_components(u_fn, body.material)
                require(quantity in comps, f"probe '{name}': unknown quantity '{quantity}' "
                                           f"(use u_r, u_z or {', '.join(comps)})")
                expr = comps[quantity]
            specs.append((name, point, expr))
        return Probes(u_fn, specs)

    def _body_at(self, point):
        from .probes import locate_cell

        cell, mine = locate_cell(self.model.mesh, point)
        name = None
        if mine:
            for body in self.model.bodies:
                if cell in self.model.tmesh.cells(body):
                    name = body
        name = self.comm.allreduce([name] if name else [], op=MPI.SUM)[0]
        return self.model.bodies[name]

    def _tables(self, staging: str | None, probes) -> dict:
        """History (kept in memory, and on disk with an output directory), energy and
        per-pair tables."""
        comm = self.comm
        path = (lambda name: os.path.join(staging, name)) if staging else (lambda name: None)
        cap = min(self.n_steps // self.settings.history_every + 2, 4096)
        cols = ["step", "time"] + (probes.names if probes else [])
        for k, c in enumerate(self.contacts):
            tag = f"c{k}_" if len(self.contacts) > 1 else ""
            cols += [f"{tag}n_active", f"{tag}contact_force", f"{tag}min_gap"]
            if c.rigid is not None:
                cols += [f"{tag}{c.rigid.name}_u", f"{tag}{c.rigid.name}_v", f"{tag}{c.rigid.name}_force"]
            cols += [f"{tag}cpu_detection", f"{tag}cpu_solve", f"{tag}cpu_update"]
        tables = {"history": output.Table(path("history.csv"), cols, comm, cap, keep=True),
                  "energy": output.Table(path("energy.csv"), ["step", "time"] + list(_ENERGY_COLUMNS)
                                         + self._momentum_columns(), comm, 256, keep=True)}
        for k, c in enumerate(self.contacts):
            name = "contact_pairs.csv" if len(self.contacts) == 1 else f"contact_pairs_{k}.csv"
            if staging:
                tables[f"pairs{k}"] = output.Table(
                    path(name), ["step", "time", "pair", "r", "gap", "force", "active"],
                    comm, min(cap, 256) * c.n)
        return tables

    def _momentum_columns(self) -> list[str]:
        names = list(self._body_z) + [c.rigid.name for c in self.contacts if c.rigid is not None]
        return ["momentum_z"] + [f"momentum_z_{n}" for n in names]

    def _history_row(self, tables, probes, u_fn, buf) -> None:
        integ = self.integrator
        n = integ.n  # state after the step
        t = n * self.settings.dt
        row = tables["history"].row()
        row[0], row[1] = n, t
        k = 2
        if probes is not None:
            integ.displacement(self._probe_u.x.array[: self.model.n_owned])
            self._probe_u.x.scatter_forward()
            vals = probes.evaluate()
            row[k:k + vals.size] = vals
            k += vals.size
        for i, c in enumerate(self.contacts):
            total = float(c.force.sum())
            row[k:k + 3] = [int(c.active.sum()), total, c.min_gap]
            k += 3
            if c.rigid is not None:
                row[k:k + 3] = [c.rigid.u, c.rigid.v, total]
                k += 3
            row[k:k + 3] = [c.times.detection, c.times.solve, c.times.update]
            k += 3
            tbl = tables.get(f"pairs{i}")
            if tbl is not None:
                block = tbl.rows(c.n)
                block[:, 0], block[:, 1], block[:, 2], block[:, 3] = n, t, c.pair_index, c.r
                block[:, 4], block[:, 5], block[:, 6] = c.committed_gap(), c.force, c.active

    def _summary(self, times, stopped_at, wall, last_energy, max_bal, track) -> dict:
        model, s = self.model, self.settings
        n_cells = self.comm.allreduce(model.mesh.topology.index_map(2).size_local)
        summary = {
            "status": self.status,
            "stopped_at_step": int(stopped_at),
            "n_steps": int(self.n_steps),
            "n_ranks": self.comm.size,
            "n_dofs": int(model.n_global),
            "n_cells": int(n_cells),
            "dt": s.dt,
            "dt_critical": self.dt_critical,
            "t_end": self.n_steps * s.dt,
            "wall_time": wall,
        }
        if self.dt_converged is not None:
            summary["dt_critical_converged"] = self.dt_converged
        if times is not None and times.n_steps > 0:
            summary["time_per_step_median"] = times.medians(self.comm)
            summary["time_per_step_total"] = times.total(self.comm)
            summary["step_time_median"] = times.median_of_sum(comm=self.comm)
        if last_energy is not None:
            last = last_energy
            summary["energy"] = {k: last[k] for k in _ENERGY_COLUMNS}
            summary["energy_balance_error_rel"] = max_bal
        if self.contacts:
            c = self.contacts[0]
            summary["contact"] = {  # the first contact set, or all of them for the figures below
                "method": c.method.name,
                "n_constraints": c.n,
                "max_penetration": track["max_penetration"],
                "method_info": getattr(c.method, "info", {}),
                "first_contact_step": track["first_contact"],
                "last_contact_step": track["last_contact"],
            }
            if len(self.contacts) > 1:
                summary["contacts"] = [{"method": c.method.name, "n_constraints": c.n,
                                        "surfaces": list(c.constraints.names),
                                        "method_info": getattr(c.method, "info", {})}
                                       for c in self.contacts]
            if times is not None and times.n_steps > 0:
                summary["contact_cpu_time_per_step_median"] = times.median_of_sum(
                    ("contact_detection", "contact_solve", "contact_update"), self.comm)
        return summary


_ENERGY_COLUMNS = ("kinetic", "strain", "total", "external_work", "contact_work",
                   "activation_loss", "balance_error", "balance_error_rel")


class _StopFlag:
    """SIGINT/SIGTERM set a flag (interrupts.deferred) while this object lives; the loop
    reads it and the ranks agree on it collectively."""

    def __init__(self):
        interrupts.clear()
        self._guard = interrupts.deferred()
        self._guard.__enter__()
        self._open = True
        self.signum = 0
        self.name = None

    def collective(self, comm: MPI.Comm) -> bool:
        """True on every rank once any rank has caught a signal; all then name the same one."""
        self.signum = interrupts.agree(comm)
        if self.signum:
            self.name = interrupts.name(self.signum)
        return bool(self.signum)

    def restore(self) -> None:
        if self._open:
            self._open = False
            self._guard.__exit__(None, None, None)


class _OwnedVec:
    """A PETSc Vec on the owned entries of a numpy array (no copy): its norms are collective."""

    def __init__(self, array: np.ndarray, comm: MPI.Comm):
        from petsc4py import PETSc

        self._vec = PETSc.Vec().createWithArray(array, comm=comm)
        self._inf = PETSc.NormType.NORM_INFINITY

    def norm_inf(self) -> float:
        self._vec.stateIncrease()  # written through numpy: PETSc must not reuse a cached norm
        return self._vec.norm(self._inf)

    def destroy(self) -> None:
        self._vec.destroy()


class _Progress:
    """Step, simulated time, steps/s and ETA on rank 0, when stdout is a terminal."""

    def __init__(self, n_steps: int, dt: float, quiet: bool):
        self.n_steps, self.dt = n_steps, dt
        self.enabled = (not quiet) and sys.stdout.isatty()
        self.t0 = time.perf_counter()
        self.last = self.t0

    def update(self, n: int) -> None:
        if not self.enabled:
            return
        now = time.perf_counter()
        if now - self.last < 0.5 and n < self.n_steps:
            return
        self.last = now
        rate = n / max(now - self.t0, 1e-9)
        eta = (self.n_steps - n) / max(rate, 1e-9)
        sys.stdout.write(f"\rstep {n}/{self.n_steps}  t = {n * self.dt:.4e} s  "
                         f"{rate:,.0f} steps/s  ETA {eta:,.0f} s   ")
        sys.stdout.flush()

    def done(self) -> None:
        if self.enabled:
            sys.stdout.write("\n")
            sys.stdout.flush()
