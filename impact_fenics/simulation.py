"""A run: the explicit loop with contact, the energy ledger, outputs, timers and progress.

Units throughout: s, m, kg, N, Pa, J.
"""
from __future__ import annotations

import gc
import math
import os
import shutil
import time
from dataclasses import dataclass

import numpy as np
from mpi4py import MPI

from . import interrupts, output, plotting, rundir
from .cell_fields import PEAK_NAMES, STRESS_NAMES, CellStress, track_peaks
from .bodies import DeformableModel
from .checks import (DIVERGENCE_EVERY, PENALTY_BOUND, ContactTrack, Divergence, OwnedVec,
                     penalty_trouble, runaway_speed)
from .contact import ContactSet, RigidBody
from .contact.interface import refuse_shared_rigid
from .contact.state import shared_jump_work
from .contact.pairing import Constraints
from .contact.segments import SegmentConstraints
from .energy import (Ledger, LoadWork, OutputSums, copy_state,
                     energy_verdict, gap_dot, half_dot, strain_from_prediction)
from .errors import (InputError, OutputError, UnstableRunError, file_system_failure,
                     output_failed, require)
from .integrator import Integrator
from .jit_watch import contiguous_float64, direct, gained, load, signature_counts
from .internal_force.cell_fields import PlasticCellFields
from .loads import SurfaceLoad
from .materials import is_finite
from .operators import assemble_stiffness
from .outputs import ENERGY_COLUMNS, momentum_columns, open_tables, record_pairs
from .probes import GAUGE_LENGTH, Probes
from .xdmf import FieldWriter
from .schedule import Progress, Schedule, StopFlag
from .step_block import StepBlock
from .stepping import ConstantStep, FollowingStep
from .summary import mean_velocities, run_summary
from .stability import (converged_omega_max, critical_dt, element_omega_bounds,
                        ghosted_dofs)
from .timers import PhaseTimers

# the steps a run to t_end may take before it ends (a bound of the loop, never reached
# by a run whose step follows a limit that stays above zero)
MAX_STEPS = 2**62

PHASES = ("f_int", "contact_detection", "contact_solve", "contact_update", "history", "output")
OUTPUT_PHASE = PHASES.index("output")


@dataclass
class Settings:
    """How a run steps and what it writes.

    ``dt`` in s, or ``cfl``: dt = cfl * the stable limit (element bound);
    ``t_end`` in s (or ``n_steps``); outputs every ``output_every`` steps (XDMF
    fields), ``energy_every`` steps (the energy ledger's rows and its stability check;
    None: with the fields, every ``output_every`` steps), ``history_every`` steps (CSV
    rows; an energy row's step has one too) and
    ``pairs_every`` steps (the per-pair rows of contact_pairs.h5: gap, force and
    active flag of every constraint, 24 B a pair, e.g. 14.6 kB a row at the punch's
    610 pairs: every 10 steps, the default, their cost is under 1 % of its step)."""

    dt: float | None = None
    cfl: float | None = None
    t_end: float | None = None
    n_steps: int | None = None
    out: str | None = None
    output_every: int = 50
    energy_every: int | None = None
    history_every: int = 1
    pairs_every: int = 10
    fields: bool = True
    force_dt: bool = False
    force: bool = False  # run what the checks refuse: a penalty above its stable bound
    converged_dt: bool = False
    matrix_type: str = "aij"
    energy_growth_limit: float = 10.0
    quiet: bool = False
    timers: bool = True
    plots: bool = True  # history.png and energy.png in the output directory (rank 0)
    f_int_path: str = "fast"  # path-dependent bodies: "fast" (fused cell kernel) or "generic"
    compiled_steps: bool = True  # the steps between events as compiled blocks where they apply
    title: str | None = None  # the run's name in its summary and pictures (a scene's title)
    max_steps: int | None = None  # a step that follows the limit: stop (exit 3) beyond these


def _set_dofs(constraints) -> np.ndarray:
    """The global z dofs of a contact set's nodes (replicated on every rank)."""
    if isinstance(constraints, SegmentConstraints):
        return constraints.dofs
    return np.concatenate([d for d in (constraints.lower, constraints.upper) if d is not None])


def _position_bodies(integ: Integrator) -> list[str]:
    """The bodies whose stored energy the ledger takes from their positions (one_loop.md
    4.7): the small-strain path-dependent ones, and the linear ones whose energy
    telescopes (their force the MatMultAdd of a constant step)."""
    bodies = [force.body for force in integ.nonlinear]
    if integ.linear is not None and integ.linear.scaled:
        bodies += integ.force_bodies[0]
    return bodies


def _flag_dofs(model: DeformableModel, bodies) -> np.ndarray:
    """1.0 on the owned dofs of ``bodies``, 0.0 elsewhere. Collective."""
    flags = np.zeros(model.n_owned)
    for name in bodies:
        for component in range(2):
            flags[model.body_dofs(name, component)] = 1.0
    return flags


def position_booked(model: DeformableModel, integ: Integrator) -> np.ndarray:
    """1.0 on the owned dofs of the bodies whose stored energy the ledger takes from their
    positions, where a position jump (DME's) is work: a small-strain path-dependent body
    (its trapezoid of f . du), a linear body whose energy telescopes (its force the
    MatMultAdd of a constant step); 0.0 on the others, whose work is booked by the kinetic
    identity (a finite-strain body, the linear per-step pass): one_loop.md 4.7. Collective."""
    return _flag_dofs(model, _position_bodies(integ))


def shared_booked(model: DeformableModel, integ: Integrator) -> np.ndarray | None:
    """1.0 on the owned dofs that a body booked from its positions shares with a body
    booked by the kinetic identity (a bonded node: one node in both bodies' cells), where
    a jump is due on the first body's share of the force alone; None when no rank has
    one. Such a pair needs a finite-strain body or a varying step, so the first body is
    a small-strain path-dependent one (its force's own array). Collective."""
    mine = _position_bodies(integ)
    others = [name for name in model.bodies if name not in mine]
    if not others:
        return None
    shared = _flag_dofs(model, mine) * _flag_dofs(model, others)
    return shared if model.comm.allreduce(bool(shared.any()), op=MPI.LOR) else None


class SharedJumps:
    """The jumps' work on the contact slots of bonded dofs (:func:`shared_booked`):
    1/2 j . (f^{n-1} + f^n) with f each small-strain force's own array, booked after the
    prediction of step n and before the sets' commits (which record j and book the other
    slots' jumps; one_loop.md 4.7). Its work (J, this rank) goes into the contact work."""

    def __init__(self, integ: Integrator, slots: list[tuple]):
        """``slots``: per contact set, (the set, its shared slots' positions, their owned
        dofs), as :meth:`.ContactSet.book_jumps_on` returns them."""
        self.entries = [(c, pos, local, force.f_owned, np.zeros(pos.size))
                        for c, pos, local in slots if pos.size
                        for force in integ.nonlinear]
        self.work_local = 0.0
        for c, pos, local, f, f_prev in self.entries:
            load(shared_jump_work, c.jump, pos, local, f, f_prev)

    def book(self) -> None:
        """Book the previous step's jumps on the shared slots (after the prediction)."""
        work = 0.0
        for c, pos, local, f, f_prev in self.entries:
            work += shared_jump_work(c.jump, pos, local, f, f_prev)
        self.work_local += work


class Simulation:
    """Deformable bodies, their conditions, loads, contact and the run settings."""

    def __init__(self, model: DeformableModel, settings: Settings,
                 fixed: list[np.ndarray] | None = None, loads: list[SurfaceLoad] | None = None,
                 initial_velocity: dict[str, tuple[float, float]] | None = None,
                 policy=None):
        """``policy``: the step policy (:mod:`.stepping`); by default the constant step of
        ``settings`` (dt or cfl). Another policy gives every step itself (its ``n_steps``
        known at the start, :class:`~.stepping.StepSequence`); its steps are checked
        against the stable limit unless ``force_dt``. A :class:`~.stepping.FollowingStep`
        with a fixed dt runs to t_end (the last step clipped) and stops the run (status
        "diverged", UnstableRunError: exit 3) at the step whose re-estimated limit falls
        below dt; its adaptive form (dt None) finds its last step at t_end as it goes, at most
        ``settings.max_steps`` of them. Under a varying step the linear bodies take the
        per-step pass and the ledger books by the kinetic identity with the step's terms
        (one_loop.md 4.7: the multiply-touched dofs, ``work_gap``). A finite-strain body
        (Q1, total Lagrangian) needs a FollowingStep, bound here to its current cells and
        capped by the other bodies' element bound; its force's booked work less its split
        (psi(u^n), plastic work, the boundary term) goes into ``work_gap``, O(dt^2)."""
        self.model = model
        self.comm: MPI.Comm = model.comm
        self.settings = settings
        clock = time.perf_counter
        # set-up time (s) by phase: stability bound, operators (forms, JIT, assembly),
        # converged dt, contact (pairing, methods), outputs (files, probes, first frame)
        self.setup_time: dict[str, float] = {}
        t0 = clock()
        require(policy is not None or (settings.dt is None) != (settings.cfl is None),
                "give either dt or cfl")
        finite = [name for name, body in model.bodies.items() if is_finite(body.material)]
        if finite and not isinstance(policy, FollowingStep):
            raise InputError(f"body '{finite[0]}' is a finite-strain body: its step follows its "
                             "cells (give the run a stepping.FollowingStep)")
        require(settings.max_steps is None or (isinstance(settings.max_steps, (int, np.integer))
                                               and settings.max_steps > 0),
                f"max_steps = {settings.max_steps!r}: must be an integer > 0")
        for key in ("output_every", "energy_every", "history_every", "pairs_every"):
            every = getattr(settings, key)
            if key == "energy_every" and every is None:
                continue
            require(isinstance(every, (int, np.integer)) and not isinstance(every, bool)
                    and every > 0, f"{key} = {every!r}: must be an integer > 0 (steps)")
        fixed = [model.axis_dofs()] + list(fixed or [])
        fixed_owned = np.unique(np.concatenate(fixed)).astype(np.int32)
        self.loads = list(loads or [])
        # stability: refuse dt above the conservative element bound unless forced
        fixed_local = np.unique(np.concatenate([model.axis_dofs(owned=False)] +
                                               [self._local_fixed(f) for f in fixed[1:]]))
        omega = element_omega_bounds(model, fixed_local)
        # each body's own stable step (s) and the run's: the smallest, the same number
        self.stable_dt = {name: critical_dt(w) for name, w in omega.items()}
        self.stable_dt_limiting = min(self.stable_dt, key=self.stable_dt.__getitem__)
        self.dt_critical = critical_dt(max(omega.values()))
        if policy is None:
            policy = ConstantStep(settings.dt, settings.cfl, self.dt_critical,
                                  settings.n_steps, settings.t_end, settings.force_dt,
                                  self.stable_dt_limiting)
        # the steps of a policy that lists them, known at set-up (None: a constant step)
        self.listed_steps: list[float] | None = None
        if isinstance(policy, FollowingStep):  # a fixed dt: its steps to t_end, stopped
            # (exit 3) once the current limit falls below it; else the step follows the
            # limit and the run ends when t reaches t_end (the schedules end there)
            if policy.dt is not None:
                self.listed_steps = policy.fixed_steps()
        elif not isinstance(policy, ConstantStep):
            require(getattr(policy, "n_steps", None) is not None,
                    f"{type(policy).__name__}: a step policy that ends at t_end does not run "
                    "in this driver yet; give its steps (stepping.StepSequence)")
            if hasattr(policy, "check"):
                policy.check(self.dt_critical, settings.force_dt, self.stable_dt_limiting)
            self.listed_steps = list(policy.steps)
        self.step_policy = policy
        # a run whose count of steps is found as it goes (it ends at t_end)
        self._ends_at_t = isinstance(policy, FollowingStep) and self.listed_steps is None
        bound = not isinstance(policy, FollowingStep) or policy.bound
        t1 = clock()
        self.setup_time["stability"] = t1 - t0
        self.integrator = Integrator(model, float(policy.first()) if bound else None,
                                     fixed_owned, self.loads,
                                     settings.matrix_type, settings.f_int_path,
                                     policy=self.step_policy,
                                     per_step_linear=not isinstance(policy, ConstantStep))
        settings.dt = float(policy.first())
        if self.listed_steps is not None:
            self.n_steps = len(self.listed_steps)
        elif self._ends_at_t:  # the count if the first step held (the tables' first size;
            # the run's count once it ends)
            self.n_steps = int(math.ceil(policy.t_end / settings.dt - 1e-9))
        else:
            self.n_steps = int(policy.n_steps)
        t2 = clock()
        self.setup_time["operators"] = t2 - t1
        self.dt_converged = None
        if settings.converged_dt:
            # the elastic K of every body (a path-dependent one is stiffest elastically)
            K = self.integrator.K if not self.integrator.nonlinear else assemble_stiffness(model)
            self.dt_converged = critical_dt(converged_omega_max(
                K, self.integrator.mass, model.to_global(fixed_owned)))
            self.setup_time["converged_dt"] = clock() - t2
        # the forces whose work is split into stored energy and dissipation at their points
        self._split_forces = bool(self.integrator.nonlinear or self.integrator.finite)
        # each finite-strain force's u^n (m, ghosts too) at an output step, and the ranks'
        # share of their booked work less its split (J), for work_gap
        self._finite_u = [np.empty_like(f.u.x.array) for f in self.integrator.finite]
        self._finite_gap_local = 0.0
        self.plastic_fields = (PlasticCellFields(model, self.integrator.nonlinear)
                               if self.integrator.nonlinear else None)
        v0 = np.zeros(model.n_owned)
        for body, (vr, vz) in (initial_velocity or {}).items():
            v0[model.body_dofs(body, 0)] = vr
            v0[model.body_dofs(body, 1)] = vz
        self.integrator.set_initial(None, v0)
        self._body_z = {name: model.body_dofs(name, 1).astype(np.intp) for name in model.bodies}
        self.body_mass = {name: self.comm.allreduce(float(self.integrator.mass[d].sum()))
                          for name, d in self._body_z.items()}
        # the sums of an output step: energies, momenta (its kernel loaded now)
        self._output_sums = OutputSums(self.integrator.mass, list(self._body_z.values()),
                                       self.comm, 4 if self._split_forces else 1)
        mass = self.integrator.mass  # the other kernels of an output step, for arrays like it:
        # their compiled entries (the arrays an event passes are contiguous float64 ones)
        self._copy_state = direct(copy_state, mass, mass, mass, mass)
        self._strain_from_prediction = direct(strain_from_prediction, mass, mass, mass, mass,
                                              mass)
        load(half_dot, mass, mass)
        load(energy_verdict, *[0.0] * 7)  # (the stability check of every output step)
        self._event_buf = None  # the run's output buffers, once _bind_output has seen them
        self.contacts: list[ContactSet] = []
        self._probe_specs: list[tuple[str, tuple[float, float], str, float]] = []
        self._cell_field_providers: list = []
        if self.integrator.finite:  # the finite-strain cells' eps_p_eq (and temperature)
            self.add_cell_fields(self._finite_cell_fields)
        elif self.plastic_fields is not None:  # eps_p_eq and yielded of the frame's stresses
            self.add_cell_fields(self.plastic_fields.frame_arrays)
        self._peaks = np.zeros(len(PEAK_NAMES) + 1)  # cell_fields.track_peaks' state
        self._varying = False  # a varying step (set by run)
        self.status = "not started"

    def _local_fixed(self, owned: np.ndarray) -> np.ndarray:
        """Local (ghosted) indices of fixed dofs given as owned ones: share them via a scatter."""
        return ghosted_dofs(self.model, owned)

    # ------------------------------------------------------------ scene set-up
    def add_contact(self, constraints: Constraints, method, rigid: RigidBody | None = None) -> ContactSet:
        """Enforce ``constraints`` (node pairs, a rigid face or, from contact.segments, node
        to segment) with ``method`` (penalty, FILM or DME)."""
        contact_dofs = _set_dofs(constraints)
        for c in self.contacts:  # a tied node is bonded: it belongs to its tie alone
            if ("tie" in (method.name, c.method.name)
                    and np.isin(contact_dofs, _set_dofs(c.constraints)).any()):
                raise InputError(f"the faces '{constraints.names[0]}'/'{constraints.names[1]}' "
                                 f"and '{c.constraints.names[0]}'/'{c.constraints.names[1]}' "
                                 "share nodes and one of them is a tie: a tied node belongs "
                                 "to its tie alone")
        loaded = [self.model.to_global(ld.dofs) for ld in self.loads]
        if loaded and self.comm.allreduce(int(np.isin(np.concatenate(loaded), contact_dofs).sum())):
            raise InputError(f"a surface load acts on nodes of the contact surfaces "
                             f"'{constraints.names[0]}'/'{constraints.names[1]}': load another "
                             "facet group (the contact bookkeeping assumes no load there)")
        if rigid is not None:
            refuse_shared_rigid(rigid, constraints.names, self.contacts, method.name == "tie")
        t0 = time.perf_counter()
        c = ContactSet(constraints, self.integrator, method, rigid)
        c.initialize()
        beta = getattr(method, "info", {}).get("beta_max") if method.name == "penalty" else None
        if beta is not None and self.listed_steps is not None:  # at every (h_{n+1/2}, h_n)
            # the run will take (a step that follows the limit: checked as it changes)
            beta = max(beta, self._penalty_beta_over_steps(c))
        if beta is not None and beta > PENALTY_BOUND and not self.settings.force:
            raise InputError(f"penalty: beta_max = {beta:.4g} is above the stable bound 4/3 of "
                             f"persistent contact (p from {method.info['p_min']:.4g} to "
                             f"{method.info['p_max']:.4g} N/m, dt = {self.settings.dt:.4g} s): "
                             "the contact would chatter and gain energy; lower the penalty, use "
                             "penalty = \"scaled\", or force it")
        self.contacts.append(c)
        self.setup_time["contact"] = self.setup_time.get("contact", 0.0) + time.perf_counter() - t0
        return c

    def _penalty_beta_over_steps(self, c: ContactSet) -> float:
        """The largest beta_max (-) of the penalty set ``c`` over the pairs (h_{n+1/2}, h_n)
        of this run's steps (listed at set-up), the set left at the first. Collective."""
        steps = self.listed_steps
        pairs = {(steps[0], steps[0])}
        pairs.update((steps[k], 0.5 * (steps[k - 1] + steps[k])) for k in range(1, len(steps)))
        beta = 0.0
        for h, h_avg in sorted(pairs):
            c.set_step(h, h_avg)
            beta = max(beta, c.penalty_beta())
        c.set_step(steps[0], steps[0])
        return self.comm.allreduce(beta, op=MPI.MAX)  # (each rank's slots: one verdict)

    def add_probe(self, name: str, point: tuple[float, float], quantity: str = "sigma_zz",
                  length: float = GAUGE_LENGTH) -> None:
        """Record ``quantity`` (a stress component name, or u_r, u_z, ...) at ``point`` (r, z)
        in m; a strain_gauge's ``length`` (m) is centred at the point; a section is the
        plane z of ``point`` (its r is not read)."""
        self._probe_specs.append((name, point, quantity, length))

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
        stop = StopFlag()
        staging = writer = None
        tables: dict = {}
        try:
            t_setup = time.perf_counter()
            staging = rundir.prepare_directory(s.out, comm) if s.out else None
            writer = self._field_writer(staging) if (staging and s.fields) else None
            probes = (Probes(model, self._probe_specs, integ.nonlinear) if self._probe_specs
                      else None)
            tables, self._history_row, self._pair_tables = open_tables(
                staging, probes, self.contacts, integ, s.dt,
                momentum_columns(self._body_z, self.contacts),
                self.n_steps // s.pairs_every + 2, comm)
            if writer is not None:  # the initial state, outside the timed loop
                self._write_fields(writer)
            self.setup_time["outputs"] = time.perf_counter() - t_setup
            if stop.collective(comm):
                raise interrupts.Interrupted(stop.signum)
        except BaseException:
            if writer is not None:
                writer.close()  # collective: left to the garbage collector it can hang MPI
            for tbl in tables.values():  # (their worker threads ended)
                tbl.close()
            if staging:
                rundir.abandon_directory(staging, comm)
            stop.restore()
            raise
        self.history = tables["history"]
        self.energy = tables["energy"]
        if comm.rank == 0 and not s.quiet:
            from .report import stable_step_line

            policy = self.step_policy
            shared = f"every body steps dt = {s.dt:.3g} s"
            if isinstance(policy, FollowingStep) and policy.dt is None:
                shared = (f"every body steps {policy.safety:g} x the current limit, re-estimated "
                          f"every {policy.interval} steps (first dt = {s.dt:.3g} s)")
            print(stable_step_line(self.stable_dt, self.stable_dt_limiting, shared), flush=True)
        self._v_start = mean_velocities(integ, self._body_z, self.body_mass, self.contacts, comm)
        # the set-up made many Python objects (forms, compiled kernels): collect them now
        # and keep them out of later collections, so no collection of them lands in a step
        gc.collect()
        gc.freeze()
        self.probes = probes
        # E_0, the initial state's energy (goes into the summary)
        self.ledger = ledger = Ledger(comm, self._initial_energy())
        load_work = LoadWork(self.loads, s.dt, comm, integ.v_owned)
        varying = self._varying = not integ.step.constant
        if varying:  # the multiply-touched dofs D (contact slots too) and the step's terms
            slots = [c._local for c in self.contacts]  # (each set's owned slot dofs, and
            slots += [c.friction._local for c in self.contacts  # its tangential pass's)
                      if getattr(c, "friction", None) is not None]
            integ.track_increments(np.concatenate(slots) if slots else None)
            self._gap_local = 0.0  # the small-strain bodies' 1/4 dh terms (J, this rank)
            self._v_before = np.empty(model.n_owned)  # v^{n-1/2} (m/s), for those terms
            self._neg_mass = -integ.mass
            load(gap_dot, integ.mass, integ.mass, integ.mass)  # (its entry loaded now)
        self._shared_jumps = None
        if any(c.jumps for c in self.contacts):  # the jumps' work where it is due (4.7)
            booked = position_booked(model, integ)
            shared = shared_booked(model, integ)
            split = [(c, *c.book_jumps_on(booked, shared)) for c in self.contacts]
            if shared is not None:
                self._shared_jumps = SharedJumps(integ, split)
        times = PhaseTimers(PHASES) if s.timers else None
        # an output step's u^n, v^{n-1/2} and internal force f_int(u^n)
        buf = {k: np.empty(model.n_owned) for k in ("u", "v", "f")}
        self._minus_m_over_dt = -integ.mass / s.dt
        Ku = integ.u_vec.duplicate()
        last_energy, max_bal = None, 0.0
        # the runaway speed of this run, fixed at its start (a diverged state's speeds
        # would give another): the check and its message use this one
        runaway = self.runaway_speed = runaway_speed(model, integ.v_owned, self.contacts, comm)
        diverged = Divergence(s.dt, self.dt_critical, self.contacts, runaway, s.energy_growth_limit)
        v_check = OwnedVec(integ.v_owned, comm)
        rigid = [c.rigid for c in self.contacts if c.rigid is not None]
        for c in self.contacts:  # their step constants follow the step (h, h_n) with the forces'
            if c not in integ.step.stepped:
                integ.step.add(c)
        self.track = track = ContactTrack(self.contacts)
        progress = (Progress(n_steps, s.dt, quiet=s.quiet or comm.rank != 0,
                             t_end=self.step_policy.t_end, time_of=lambda: integ.t)
                    if self._ends_at_t else Progress(n_steps, s.dt, s.quiet or comm.rank != 0))
        self.status = "running"
        stopped_at = n_steps
        # The common step is short: the schedules are step counters (the next step of
        # each, see Schedule), locals stand for attributes, the phase times go through
        # a memoryview into the timers' block (booked by one compiled call per block),
        # progress is looked at only when a line may be due, the signal flag is one
        # attribute. Everything else happens on the steps an event is due.
        ends_at_t = self._ends_at_t  # the last step found as the run goes (at t_end)
        if ends_at_t:
            n_steps = MAX_STEPS
            t_end = self.step_policy.t_end
            penalties = [c for c in self.contacts if c.method.name == "penalty"]
        max_steps = s.max_steps  # (a run of listed steps knows its count at set-up)
        last = n_steps - 1
        # energy rows (and their history rows)
        output_at = Schedule(0, s.energy_every or s.output_every, last)
        fields_at = (Schedule(s.output_every - 1, s.output_every, last)  # state n + 1 written
                     if writer is not None else Schedule.never(last))
        pairs_at = Schedule(0, s.pairs_every, last) if self._pair_tables else Schedule.never(last)
        check_at = Schedule(DIVERGENCE_EVERY - 1, DIVERGENCE_EVERY, last)
        serial = comm.size == 1
        agree_at = (Schedule.never(last) if serial else
                    Schedule(interrupts.AGREE_EVERY - 1, interrupts.AGREE_EVERY, last))
        history_every = s.history_every
        next_history = 0
        next_event = min(output_at.next, fields_at.next, pairs_at.next, check_at.next, agree_at.next)
        is_output = is_fields = is_pairs = is_check = is_agree = event = False
        step_contacts = [c.step for c in self.contacts]
        contact_times = [c.times for c in self.contacts]
        # one contact set (the common case): its times go to the row without the sums
        one_contact = contact_times[0] if len(contact_times) == 1 else None
        track_step = track.step if self.contacts else None
        accumulate = load_work.accumulate if self.loads else None
        complete = load_work.complete
        predict, advance = integ.predictor(), integ.advance
        shared_jumps = self._shared_jumps.book if self._shared_jumps is not None else None
        history_row = self._history_row
        rows = times.rows if times is not None else None
        rows_end = times.rows_end if times is not None else 0
        pos, n_phases = 0, len(PHASES)  # offset of this step's phase times in rows
        progress_due = progress.due
        signal_state = interrupts.STATE
        clock = time.perf_counter

        def output_event(row: dict, rec: memoryview, n: int) -> None:
            """After the energy row ``row`` of output step n (from its record ``rec``): its
            checks and the penalty's figures."""
            nonlocal max_bal, last_energy
            max_bal = max(max_bal, row["balance_error_rel"])
            last_energy = row
            if track.penalty:
                track.budget = max(track.budget, abs(ledger.E0 or 0.0), abs(row["external_work"]))
                if rec[-1]:  # contact made, the springs all released
                    track.gain = max(track.gain, row["contact_work"])
            diverged.energy_growth(row, ledger.E0, n)

        # linear bodies: the steps between events run as compiled blocks
        t_block = clock()
        if s.compiled_steps and buf is not self._event_buf:
            self._bind_output(buf)  # (the energy rows of the blocks' output steps)
        block = (StepBlock.for_run(self, tables["history"], times, probes,
                                   (output_at, check_at, pairs_at), self._pair_tables, runaway,
                                   last, track.state,
                                   (buf["u"], buf["v"], self._minus_m_over_dt, buf["f"]),
                                   writer,
                                   fields_at)
                 if s.compiled_steps else None)
        # the blocks write the frames (else a fields step ends its block, the frame after it)
        block_frames = block is not None and block.writer is not None
        self.setup_time["kernels"] = clock() - t_block
        self.compiled_steps = block is not None
        self.compiled_frames = block_frames
        jit_before = signature_counts()
        t_run = clock()
        n = 0
        try:
            while n < n_steps:
                if block is not None and n != agree_at.next:
                    # the steps up to the next fields or agreement step (or the next look at
                    # the progress line, or a full history block) in one compiled call, the
                    # energy rows of its output steps after it: Python steps are only
                    # agreement steps, the same on every rank, so the ranks' collective calls
                    # come in the same order (the block runs the checks, the output steps'
                    # sums and per-pair rows of its steps)
                    if event:  # the step after an event: none due
                        is_output = is_fields = is_pairs = is_check = is_agree = event = False
                    if pos:
                        times.book(pos)
                        pos = 0
                    end = min(agree_at.next, progress_due, n_steps)
                    if not block_frames:
                        end = min(end, fields_at.next + 1)
                    n, next_history = block.run(n, end, next_history, E0=ledger.E0,
                                                hold=not block_frames and end == fields_at.next + 1)
                    t4 = clock()
                    for i in range(block.n_frames):  # the frames it wrote into the batch
                        writer.written(*block.frame(i))
                    if block.n_events:  # their energy rows (the step numbers: integ's)
                        shift = integ.n - n
                        for i in range(block.n_events):
                            rec, k = block.event(i)
                            output_event(self._row_from_record(rec, k + shift, ledger), rec, k)
                    if block.runaway >= 0:
                        diverged.rigid_runaway(block.runaway, block.rigid)
                    if block.diverged >= 0:
                        diverged.node_runaway(block.diverged, v_check)
                    if block.held:  # the frame of the block's last step, timed with it
                        fields_at.due(n - 1)
                        self._write_fields(writer)
                        block.book_held(clock() - t4)
                    elif times is not None:
                        times.totals[OUTPUT_PHASE] += clock() - t4
                    next_event = min(output_at.next, fields_at.next, pairs_at.next,
                                     check_at.next, agree_at.next)
                    if n >= progress_due:
                        progress_due = progress.update(n)
                    # the flag between blocks (under MPI the ranks agree at agree_at's
                    # steps, which are Python steps)
                    if serial and signal_state.signum != 0:
                        stop.collective(comm)
                        self.status = f"interrupted by {stop.name}"
                        stopped_at = n
                        break
                    continue
                if ends_at_t:  # this step's h first: is it the last one?
                    if max_steps is not None and n >= max_steps:
                        raise UnstableRunError(f"run stopped at step {n} (t = {integ.t:.6g} "
                                               f"s): more than max_steps = {max_steps} steps "
                                               f"before t_end = {t_end} s")
                    h = integ.next_step()
                    if penalties and self.step_policy.renewed:
                        self._check_penalties(penalties, h, n)
                    if integ.t + h >= t_end * (1.0 - 1e-12):
                        n_steps = n + 1
                        for sched in (output_at, fields_at, pairs_at, check_at, agree_at):
                            sched.end_at(n)
                        next_event = min(output_at.next, fields_at.next, pairs_at.next,
                                         check_at.next, agree_at.next)
                if n == next_event:  # advance only the schedules due (a call costs ~0.15 us)
                    is_output = output_at.next == n and output_at.due(n)
                    is_fields = fields_at.next == n and fields_at.due(n)
                    is_pairs = pairs_at.next == n and pairs_at.due(n)
                    is_check = check_at.next == n and check_at.due(n)
                    is_agree = agree_at.next == n and agree_at.due(n)
                    next_event = min(output_at.next, fields_at.next, pairs_at.next, check_at.next,
                                     agree_at.next)
                    event = True
                elif event:  # the step after an event: none due
                    is_output = is_fields = is_pairs = is_check = is_agree = event = False
                is_history = n == next_history or is_output
                if n == next_history:
                    next_history += history_every
                t0 = clock()
                if is_output:
                    pre = self._pre_output(buf, Ku)
                if accumulate is not None:
                    accumulate(integ)
                if varying and integ.nonlinear:
                    np.copyto(self._v_before, integ.v_owned)
                predict()
                if shared_jumps is not None:  # bonded slots' jumps, before the commits
                    shared_jumps()
                if is_output:
                    self._internal_force_from_prediction(buf)
                t1 = clock()
                for step in step_contacts:
                    step()
                if track_step is not None:
                    track_step(n)
                if varying:
                    self._after_contact()
                advance()
                if accumulate is not None:
                    complete(integ)
                t3 = clock()
                if is_history:
                    history_row()
                if is_pairs:
                    record_pairs(self._pair_tables, integ.n, s.dt, integ.t if varying else None)
                t4 = clock()
                for body in rigid:
                    if not math.isfinite(body.v):
                        diverged.rigid_runaway(n, body)
                if event:
                    if is_check and v_check.exceeds(runaway):
                        diverged.node_runaway(n, v_check)
                    if is_output:
                        output_event(self._post_output(pre, buf, ledger, load_work),
                                     self._record_view, n)
                    if is_fields:
                        self._write_fields(writer)
                    t5 = clock()
                else:  # no output phase: no clock call (the rigid check above is rest)
                    t5 = t4
                if rows is not None:  # this step's times of PHASES, in their order
                    rows[pos] = t1 - t0
                    if one_contact is not None:
                        rows[pos + 1] = one_contact.detection
                        rows[pos + 2] = one_contact.solve
                        rows[pos + 3] = one_contact.update
                    elif contact_times:
                        detection = solve = update = 0.0
                        for ct in contact_times:
                            detection += ct.detection
                            solve += ct.solve
                            update += ct.update
                        rows[pos + 1] = detection
                        rows[pos + 2] = solve
                        rows[pos + 3] = update
                    rows[pos + 4] = t4 - t3
                    rows[pos + 5] = t5 - t4
                    pos += n_phases
                    if pos == rows_end:
                        times.book(pos)
                        pos = 0
                if n + 1 >= progress_due:
                    progress_due = progress.update(n + 1)
                # the flag every step; under MPI the ranks agree every AGREE_EVERY steps
                # and after the last one (a signal in the last steps is never lost)
                if serial:
                    caught = signal_state.signum != 0
                else:
                    caught = is_agree and stop.collective(comm)
                if caught:
                    stop.collective(comm)  # names the signal (serial: no communication)
                    self.status = f"interrupted by {stop.name}"
                    stopped_at = n + 1
                    break
                n += 1
            else:
                self.status = "completed" + penalty_trouble(track.as_dict())
                stopped_at = n
        except UnstableRunError as exc:
            self.status = "diverged"
            stopped_at = integ.n
            self._failure = str(exc)
        except BaseException:
            stop.restore()
            raise
        finally:
            wall = clock() - t_run
            if ends_at_t:
                self.n_steps = stopped_at  # (the steps taken)
            if times is not None:
                times.book(pos)  # the steps of the last, partial block
            gc.unfreeze()
            progress.done(integ.n)
            # kernels compiled inside the loop (a signature not loaded at set-up): none
            self.compiled_in_loop = gained(jit_before, signature_counts())
            for tbl in tables.values():
                tbl.close()
            if writer is not None:
                writer.close()
        try:
            comm.barrier()  # every table is on disk: any rank may read it back
            summary = run_summary(self, times, stopped_at, wall, last_energy, max_bal,
                                  track.as_dict())
            self.summary = summary
            if extra is not None and self.status.startswith("completed"):
                summary.update(extra(self))
            if staging:
                scene = summary.get("scene_file")
                if scene and comm.rank == 0 and os.path.isfile(scene):
                    shutil.copy(scene, os.path.join(staging, "scene" + os.path.splitext(scene)[1]))
                # after an interrupt the data files are complete: skip the plots, finish fast
                if s.plots and comm.rank == 0 and not stop.signum:
                    plotting.write_history_plots(staging, self.history.data(), self.energy.data(),
                                                 [(name, q) for name, _, q, _ in self._probe_specs],
                                                 s.title)
                if not self.status.startswith("interrupted") and stop.collective(comm):
                    summary["interrupted"] = (f"{stop.name} after the last step, while the "
                                              "output was finished (it is complete)")
                output.write_json(os.path.join(staging, "summary.json"), summary, comm)
                self.out_dir = rundir.finalize_directory(staging, s.out, comm, self.status)
                for tbl in tables.values():
                    tbl.moved(self.out_dir)
            stop.collective(comm)  # a signal while the directory was moved into place
        finally:
            stop.restore()
        self.signal = stop.signum
        if self.status == "diverged":
            raise UnstableRunError(self._failure)
        return summary

    # ------------------------------------------------------------ pieces of the loop
    def _check_penalties(self, penalties: list[ContactSet], h: float, n: int) -> None:
        """A penalty's beta_max at the re-estimated step h = h_{n+1/2} (s) and its h_n: above
        the stable bound 4/3 of persistent contact the run stops (UnstableRunError, exit 3)
        before step n, unless forced. Collective."""
        integ = self.integrator
        h_prev = integ.step.h_prev
        h_avg = h if h_prev is None else 0.5 * (h_prev + h)
        beta = 0.0
        for c in penalties:
            c.set_step(h, h_avg)
            beta = max(beta, c.penalty_beta())
        beta = self.comm.allreduce(beta, op=MPI.MAX)
        if beta > PENALTY_BOUND and not self.settings.force:
            raise UnstableRunError(
                f"run stopped at step {n} (t = {integ.t:.6g} s): penalty beta_max = {beta:.4g} "
                f"is above the stable bound 4/3 of persistent contact at the re-estimated "
                f"dt = {h:.4g} s; lower the penalty, use penalty = \"scaled\", or force it")

    def _after_contact(self) -> None:
        """A varying step's bookings after contact (v = v^{n+1/2}): the booking forces'
        shares on the multiply-touched dofs, and at a change of step the small-strain
        bodies' term of work_gap, 1/4 (h_{n+1/2} - h_{n-1/2}) (v^{n-1/2} - v^{n+1/2}) .
        f_int^n (J, this rank; the linear bodies' is their booked work less the split,
        at an output step)."""
        integ = self.integrator
        integ.after_contact()
        h, h_prev = integ.step.h, integ.step.h_prev
        if integ.nonlinear and h_prev is not None and h != h_prev:
            v_before, v = self._v_before, integ.v_owned
            dot = 0.0
            for force in integ.nonlinear:
                dot += gap_dot(v_before, v, force.f_owned)
            self._gap_local += 0.25 * (h - h_prev) * dot

    def _bind_output(self, buf) -> None:
        """What every output event of this run reads and writes, bound at its first one
        (``buf``: the run's buffers of u^n and v^n): the rigid bodies and their speeds v^n,
        the loads, and the energy columns, a dict updated in place (J)."""
        integ = self.integrator
        # the arrays the compiled entries of an event are bound for (their type unchecked there)
        for a in (buf["u"], buf["v"], buf["f"], self._minus_m_over_dt, integ.u_owned,
                  integ.v_owned):
            if not (contiguous_float64(a, 1) and a.size == integ.mass.size):
                raise TypeError("an output buffer is not a contiguous float64 array over the "
                                "owned dofs")
        self._event_buf = buf
        self._rigid_sets = [c for c in self.contacts if c.moving_rigid is not None]
        self._rigid_v_now = [0.0] * len(self._rigid_sets)
        self._load_terms = list(zip(integ.loads, integ._load_dofs, integ._load_coef))
        self._energy_row = dict.fromkeys(ENERGY_COLUMNS, 0.0)
        # an output step's numbers (layout: see
        # event_record_size), filled by _post_output or by the compiled steps (_row_from_record
        # makes the row from it)
        self._record = np.zeros(self.event_record_size())
        self._record_view = memoryview(self._record)
        # the energy table's row: step, time, ENERGY_COLUMNS, momentum_z, per body and
        # per rigid body (the order _row_from_record writes)
        layout = ["step", "time", *ENERGY_COLUMNS, *momentum_columns(self._body_z, self.contacts)]
        if self.energy.columns != layout:
            raise RuntimeError(f"energy columns {self.energy.columns}, expected {layout}")

    def _pre_output(self, buf, Ku) -> list[float]:
        """Keep u^n and v^n (m, m/s) and the rigid bodies' v^n (returned, a list reused by
        every event) before the step of an output."""
        if buf is not self._event_buf:
            self._bind_output(buf)
        integ = self.integrator
        self._copy_state(integ.u_owned, integ.v_owned, buf["u"], buf["v"])  # u^n, v^n
        if self._split_forces:  # 1/2 u'Ku of the linear bodies (the others book psi_e, W_p)
            if integ.K is not None:
                integ.K.mult(integ.u_vec, Ku)
                self._ku_linear = Ku.array  # (K u^n: the linear bodies' share of f_int)
                self._strain_local = half_dot(buf["u"], self._ku_linear)
            else:
                self._ku_linear = None
                self._strain_local = 0.0
        if self._finite_u:  # each finite-strain force's u^n, its ghosts refreshed (the
            # step's own refresh comes with its prediction, which moves u)
            integ.u_function.x.scatter_forward()
            for force, u_all in zip(integ.finite, self._finite_u):
                np.copyto(u_all, force.u.x.array)
        v_now = self._rigid_v_now
        if v_now:
            for i, c in enumerate(self._rigid_sets):
                v_now[i] = c.rigid.v
        return v_now

    def _internal_force_from_prediction(self, buf) -> None:
        """The internal force f_int(u^n) (N, into buf["f"]) from the step just predicted,
        without a MatMult: v~ = v^{n-1/2} + dt M^-1 (F^n - f_int(u^n)), so
        f_int(u^n) = F^n - M (v~ - v^{n-1/2}) / dt (one compiled pass; F^n the loads). With
        linear bodies only, f_int = K u^n and the strain energy 1/2 u^n.K u^n (J, this
        rank's part) comes from the same pass. On fixed dofs f_int reads 0, where u^n = 0
        and v = 0: the energy is exact (to round-off; the difference loses eps |v| m / dt,
        less than K u's own eps |K| |u| once the motion has lasted a few steps)."""
        u, f = buf["u"], buf["f"]
        if self._varying:  # -m / h_n of this step (the constant step's arithmetic)
            np.divide(self._neg_mass, self.integrator.step.h_avg, out=self._minus_m_over_dt)
        strain = self._strain_from_prediction(u, self.integrator.v_owned, buf["v"],
                                              self._minus_m_over_dt, f)
        if self._load_terms:
            t = self.integrator.t
            for ld, dofs, coef in self._load_terms:
                value = ld.history(t)
                if value != 0.0:  # f on the free loaded dofs: m coef / dt per unit of the pulse
                    load = self._minus_m_over_dt[dofs] * coef
                    strain -= 0.5 * value * float(np.dot(u[dofs], load))
                    np.subtract.at(f, dofs, value * load)
        if not self._split_forces:  # (else _pre_output's 1/2 u'Ku and psi_e)
            self._strain_local = strain

    def _initial_energy(self) -> float:
        """E_0 (J, summed over the ranks): the kinetic energy 1/2 |v^0|^2_M of the initial
        state and its rigid bodies' 1/2 m v^2. A scene starts from u^0 = 0 with its points
        unstressed, so nothing is stored; an integrator given a displaced state u^0
        (``set_initial``; the benchmark's random state) adds its linear bodies' term of
        the telescoped work, 1/2 (u^0)' K u^{-1} with u^{-1} = u^0 - h v^0 (one_loop.md
        4.7), i.e. 1/2 (u^0)' K u^0 - 1/2 h (v^0)' K u^0."""
        integ = self.integrator
        v = integ.v_owned
        local = 0.5 * float(np.dot(integ.mass * v, v))
        u = integ.u_owned
        self._phi_initial = 0.0  # Phi_-1 (J, summed), the linear bodies' initial term
        if integ.K is not None and self.comm.allreduce(bool(np.any(u != 0.0)), op=MPI.LOR):
            Ku = integ.u_vec.duplicate()
            integ.K.mult(integ.u_vec, Ku)
            ku = Ku.array
            phi = 0.5 * float(np.dot(u, ku)) - 0.5 * integ.dt * float(np.dot(v, ku))
            local += phi
            self._phi_initial = self.comm.allreduce(phi)
            Ku.destroy()
        total = self.comm.allreduce(local)
        for c in self.contacts:
            if c.moving_rigid is not None:
                total += c.kinetic_energy_rigid(c.rigid.v)
        return total

    def event_record_size(self) -> int:
        """Floats in an output step's record: the OutputSums (kinetic, strain, p_z, p_z per
        body, the extra local numbers: J, kg m/s), per contact set its work and activation
        loss (J), per rigid body v^n, v^{n+1} (m/s) and its external work (J), then 1 if
        contact was made and no constraint is active after the step (else 0)."""
        n_rigid = sum(c.moving_rigid is not None for c in self.contacts)
        return self._output_sums.size + 2 * len(self.contacts) + 3 * n_rigid + 1

    def _post_output(self, pre, buf, ledger, load_work) -> dict:
        """The energy row of the output step (step integ.n - 1) into the energy table, and
        its energy columns (ENERGY_COLUMNS, J) returned: a dict that every event updates
        in place (after the run it holds the last row's). ``pre``: :meth:`_pre_output`'s.
        The step's numbers go into the record first (the compiled steps fill it alike)."""
        integ = self.integrator
        nonlinear = integ.nonlinear
        sums = self._output_sums
        # the stored energy's boundary term 1/2 dt v^{n+1/2} . f_int(u^n) (dt = h_{n+1/2})
        dt, v_next = integ.step.h, integ.v_owned
        boundary = dt * half_dot(v_next, buf["f"])
        strain = self._strain_local + boundary
        if self._split_forces:  # stored elastic energy, plastic and deformation work (J)
            # the deformation work by the kinetic identity: the trapezoid sum and the
            # path-dependent bodies' boundary term, 1/2 dt v^{n+1/2} . (f_int - K u^n)
            # (their 1/2 dt v^0 . f^0 is 0: a run starts unstressed); a finite-strain
            # body's stored energy psi at u^n, its plastic work, its trapezoid sum, and
            # (into work_gap) its booked work less that split with its boundary term
            if self._ku_linear is not None:
                boundary -= dt * half_dot(v_next, self._ku_linear)
            stored = sum(f.elastic_energy_local() for f in nonlinear)
            plastic = sum(f.plastic_work_local for f in nonlinear)
            deformation = sum(f.deformation_work_local for f in nonlinear) + boundary
            self._finite_gap_local = 0.0
            for f, u_all in zip(integ.finite, self._finite_u):
                psi = f.stored_energy_local(u_all)
                split = psi + f.plastic_work_local + dt * half_dot(v_next, f.f_owned)
                stored += psi
                plastic += f.plastic_work_local
                deformation += f.trapezoid_local
                self._finite_gap_local += f.work_local - split
            total = sums.reduce(v_next, strain, (load_work.local, stored, plastic, deformation))
        else:
            total = sums.reduce(v_next, strain, (load_work.local,))
        rec = self._record_view
        j = sums.size
        rec[:j] = total
        for c in self.contacts:
            rec[j] = c.contact_work
            rec[j + 1] = c.activation_loss
            j += 2
        for c, v_now in zip(self._rigid_sets, pre):
            rec[j] = v_now
            rec[j + 1] = c.rigid.v
            rec[j + 2] = c.rigid_external_work
            j += 3
        rec[j] = float(self.track.first is not None
                       and not any(c.any_active for c in self.contacts))
        if self._varying:
            self._row_time = integ.t - integ.step.h  # t^n (s)
            self._work_gap = self._work_gap_now(buf, dt)
        if self._shared_jumps is not None:  # the bonded slots' jumps (J, every rank's)
            self._shared_work = self.comm.allreduce(self._shared_jumps.work_local)
        return self._row_from_record(rec, integ.n - 1, ledger)

    def _work_gap_now(self, buf, h: float) -> float:
        """work_gap after step n under a varying step (J, summed over the ranks): the
        small-strain bodies' 1/4 dh terms, and the linear bodies' booked work (their
        per-step pass, exact on D) plus Phi_-1 less its split 1/2 (u^n)' K u^n + 1/2
        h_{n+1/2} v^{n+1/2} . K u^n (``h`` = h_{n+1/2}, s), which the same terms make up."""
        integ = self.integrator
        local = self._gap_local + self._finite_gap_local
        if integ.linear is not None:
            ku = integ.linear.pass_force  # K u^n of this step's pass
            local += integ.linear.work_local - (half_dot(buf["u"], ku)
                                                + h * half_dot(integ.v_owned, ku))
        return self.comm.allreduce(local) + self._phi_initial

    def _row_from_record(self, rec: memoryview, n: int, ledger) -> dict:
        """The energy row of output step ``n`` from its record ``rec`` (see
        :meth:`event_record_size`) into the energy table; its energy columns returned
        (:meth:`_post_output`)."""
        sums = self._output_sums
        kinetic, strain = rec[0], rec[1]  # floats (a memoryview's items)
        k = 3 + sums.n_bodies
        ext = rec[k]
        rigid = self._rigid_sets
        first_rigid = j = sums.size + 2 * len(self.contacts)  # (v^n, v^{n+1}, work) each
        for c in rigid:
            kinetic += c.kinetic_energy_rigid(rec[j + 1])
            ext += rec[j + 2]
            j += 3
        work_c = 0.0
        activation = 0  # (an int without contact sets, as the sum of none)
        j = sums.size
        for c in self.contacts:
            work_c += rec[j]
            activation += rec[j + 1]
            j += 2
        if self._shared_jumps is not None:
            work_c += self._shared_work
        plastic = deformation = gap = 0.0
        if self._split_forces:
            strain += rec[k + 1]
            plastic, deformation = rec[k + 2], rec[k + 3]
        if self._varying:
            gap = self._work_gap
        energy, balance, rel = ledger.record(kinetic, strain, ext, work_c, plastic, gap)
        # the table's row through its memoryview (layout checked by _bind_output)
        table = self.energy
        j = table.next_row()
        cells = table.cells
        cells[j] = n
        cells[j + 1] = self._row_time if self._varying else n * self.settings.dt
        row = self._energy_row
        row["kinetic"] = cells[j + 2] = kinetic
        row["strain"] = cells[j + 3] = strain
        row["total"] = cells[j + 4] = energy
        row["external_work"] = cells[j + 5] = ext
        row["contact_work"] = cells[j + 6] = work_c
        row["activation_loss"] = cells[j + 7] = activation
        row["plastic_work"] = cells[j + 8] = plastic
        row["deformation_work"] = cells[j + 9] = deformation
        row["balance_error"] = cells[j + 10] = balance
        row["balance_error_rel"] = cells[j + 11] = rel
        row["work_gap"] = cells[j + 12] = gap
        # z momentum (kg m/s) of v^{n+1}: in total (every node once) and per body
        # (a node that two bonded bodies share counts in both)
        p_total = rec[2]
        m = j + 14
        for b in range(3, k):
            cells[m] = rec[b]
            m += 1
        v_next = first_rigid + 1
        for c in rigid:
            if c.rigid.prescribed is not None:  # infinite mass: it keeps no momentum (a column)
                v_next += 3
                continue
            p = c.rigid.mass * rec[v_next]
            cells[m] = p
            m += 1
            p_total += p
            v_next += 3
        cells[j + 13] = p_total
        for c in rigid:  # a sliding part's x momentum M V (docs/friction.md 11)
            if c.rigid.slides:
                cells[m] = c.rigid.mass * c.rigid.v_x
                m += 1
        return row

    # ------------------------------------------------------------ outputs
    def cell_fields(self) -> dict[str, np.ndarray]:
        """The plastic cell fields now, {name: values over this rank's owned cells}:
        ``eps_p_eq`` (mean equivalent plastic strain of the cell's points) and ``yielded``
        (1 if a point has yielded); empty without path-dependent bodies."""
        return {} if self.plastic_fields is None else self.plastic_fields.arrays()

    def add_cell_fields(self, provider) -> None:
        """Write more cell fields with the stresses: ``provider()`` returns {name: array over
        this rank's owned cells} (the same names at every call), e.g. a plastic strain."""
        self._cell_field_providers.append(provider)

    def _finite_cell_fields(self) -> dict[str, np.ndarray]:
        """The finite-strain cells' mean eps_p_eq (-) of the frame's stresses (added to the
        path-dependent bodies' when there are both) and, for a material with one, their
        temperature (K)."""
        stress = self._cell_stress
        eps = stress.finite_eps_p
        out = {"eps_p_eq": eps}
        if self.plastic_fields is not None:  # (and their yielded)
            out = dict(self.plastic_fields.frame_arrays())
            out["eps_p_eq"] = out["eps_p_eq"] + eps
        if any(getattr(f.material, "temperature_index", -1) >= 0 for f in self.integrator.finite):
            out["temperature"] = stress.finite_temperature
        return out

    def _field_writer(self, staging: str) -> FieldWriter:
        self._cell_stress = CellStress(self.model, self.integrator.nonlinear,
                                       self.integrator.finite)
        self._peak_buf = np.empty(3)  # the peaks reduced over the ranks
        self._track = direct(track_peaks, self._peak_buf, 0.0, self._peaks)
        extra = [name for p in self._cell_field_providers for name in p()]
        # the initial state, then every output_every steps and the last step
        n_frames = 1 + -(-self.n_steps // self.settings.output_every)
        try:
            writer = FieldWriter(os.path.join(staging, "fields.xdmf"), self.model,
                                 cell_fields=list(STRESS_NAMES) + extra, n_frames=n_frames)
        except Exception as exc:  # a full disk at set-up: one line, every rank stopped
            cause = file_system_failure(exc)
            if cause is None:
                raise
            output_failed(OutputError(f"writing the fields to {staging} failed: {cause}"))
        # the stresses are computed straight into the writer's frame buffer
        self._stress_block = writer.cell_block(STRESS_NAMES)
        return writer

    def _write_fields(self, writer: FieldWriter) -> None:
        """u, v (state of step integ.n), the stresses and the extra cell fields."""
        integ = self.integrator
        u = writer.ghosted(integ.u_owned, 0)
        v = writer.ghosted(integ.v_owned, 1)
        self._cell_stress.evaluate(u, out=self._stress_block)
        t = integ.t if not integ.step.constant else integ.n * self.settings.dt
        self._track_peaks(t)
        cells = writer.cell_values
        if self._cell_field_providers:
            for provider in self._cell_field_providers:
                for key, values in provider().items():
                    cells[key][:] = values[: writer.n_cells]
        writer.write(t, integ.n, u, v, cells)

    def _track_peaks(self, t: float) -> None:
        """Largest von Mises and extreme sigma_zz (Pa) over the field outputs, and when
        (the cell stresses' extremes of this output, reduced over the ranks)."""
        peaks = self._cell_stress.peaks  # (max von Mises, max sigma_zz, -min sigma_zz)
        if self.comm.size > 1:
            self._peak_buf[:] = peaks
            self.comm.Allreduce(MPI.IN_PLACE, self._peak_buf, op=MPI.MAX)
            peaks = self._peak_buf
        self._track(peaks, t, self._peaks)
