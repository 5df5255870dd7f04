"""A finite-strain explicit run: Q1 mean-dilatation bodies, a variable time step, a rigid wall.

The scheme with the velocity at half steps:

    v^{n+1/2} = v^{n-1/2} + 1/2 (dt_{n-1/2} + dt_{n+1/2}) M^-1 (f_ext^n - f_int(u^n)),
    u^{n+1}   = u^n + dt_{n+1/2} v^{n+1/2},

with dt_{-1/2} := dt_{1/2}. With a constant step it is the modified Euler scheme
of the Integrator (v^{n+1} = v^n + dt a^n, u^{n+1} = u^n + dt v^{n+1}). The
kinetic identity holds exactly for any f and any steps:

    1/2 |v^{n+1/2}|_M^2 - 1/2 |v^{n-1/2}|_M^2 = 1/2 (v^{n-1/2} + v^{n+1/2}) . dt_avg f^n,

so the ledger books the internal work W_int = sum dt_avg 1/2 (v^- + v~) . f_int and
the wall's activation loss the same way, and K + W_int + L = K_0 to round-off.
The stored energy plus the plastic work equal W_int up to the time
discretisation (O(dt^2), reported as ``work_gap``): the trapezoid of a
nonquadratic energy is not exact.

**The step follows the deformation.** Every ``dt_interval`` steps (default 10)
the stable limit is re-estimated from the current cells,
dt_lim = min_cells L / c with L = A / (largest diagonal) (h / sqrt 2 for a square
of side h) and c the material's elastic dilatational speed, and the step is
``safety`` x dt_lim (default 0.5; tests compare it with the converged
2 / omega_max of the linearised operator). With a fixed ``dt`` instead, the run
stops (UnstableRunError, exit 3 in a demo) once the current limit falls below it.
Each row of the history holds the Δt that led to its state (0 at the start) and the
current limit; the summary holds Δt's range and the body's own limit at the start
(``stable_dt``) and the smallest it reached (``stable_dt_smallest``).

**What a run writes** (``settings.out``, as every run of the package: staged in
``DIR.partial`` and published by rundir.py, SIGINT/SIGTERM stop it at a step
boundary with a complete directory, progress on a terminal only):
``history.csv`` (HISTORY_COLUMNS, SI units, one row every ``history_every``
steps and the last state), ``fields.xdmf`` (xdmf.py: quadrilaterals, the
displacement and velocity v^{n-1/2} at the nodes, per cell the Cauchy stress,
von Mises, eps_p_eq and a temperature, every ``output_every`` steps and the
end), ``history.png`` and ``summary.json`` (shape, energies, dt range, time by
phase, provenance). The wall's energy: ``activation_loss`` what it took and
kept, ``penalty_energy`` what a penalty wall's springs hold (given back when
they release), so K + W_int + activation_loss + penalty_energy = K_0.

Under MPI each rank updates the points of its owned cells; f_int's ghost
entries are summed into their owners, and u's ghosts are refreshed before each
force evaluation, so every rank count gives the same numbers (to the order of
floating-point sums).
"""
from __future__ import annotations

import os
import shutil
import sys
import time
from dataclasses import dataclass, field

import numpy as np
from dolfinx import mesh as dmesh
from mpi4py import MPI

from . import console, interrupts, output, rundir
from .bodies import Body, DeformableModel
from .contact.plane import FixedPlane, boundary_nodes
from .errors import FINITE_STRAIN_NEEDS_QUADRILATERALS, InputError, UnstableRunError, require
from .integrator import Integrator
from .materials import is_finite
from .quad_meshes import one_body, quad_bar  # noqa: F401 (quad_bar: its users')
from .stepping import FollowingStep
from .jit_watch import gained, signature_counts
from .timers import PhaseTimers

HISTORY_COLUMNS = ("step", "time", "dt", "dt_limit", "kinetic", "internal_work", "activation_loss",
                   "stored", "plastic_work", "balance_error", "work_gap", "n_active", "j_min",
                   "eps_p_max", "length", "face_radius", "wall_force", "penalty_energy",
                   "velocity_z")
PHASES = ("f_int", "wall", "history", "output")  # f_int: the integrator's step
CELL_FIELDS = ("sigma_rr", "sigma_zz", "sigma_tt", "sigma_rz", "von_mises", "eps_p_eq")


@dataclass
class FiniteSettings:
    """t_end (s); dt (s) fixed, or None for the adaptive step safety x dt_lim, re-estimated
    every dt_interval steps; history every history_every steps (bounded: decimated in memory),
    fields every output_every steps (and at t = 0 and the end). ``out``: the run directory
    (staged in out.partial, see rundir.py) that gets history.csv, fields.xdmf,
    history.png and summary.json; ``force`` runs a penalty wall above its stable bound."""

    t_end: float = 80e-6
    dt: float | None = None
    safety: float = 0.5
    dt_interval: int = 10
    history_every: int = 10
    max_steps: int = 10_000_000
    ledger: bool = True
    output_every: int = 50
    out: str | None = None
    fields: bool = True
    plots: bool = True
    quiet: bool = True
    force: bool = False
    timers: bool = True
    summary_extra: dict = field(default_factory=dict)  # entries copied into the summary


class _OneBody:
    """What :class:`~impact_fenics.xdmf.FieldWriter` reads of a model, for one quadrilateral
    body: comm, mesh, V, node_xy (local nodes, m), the body's name and its local cells."""

    def __init__(self, run: "FiniteRun", name: str):
        self.comm, self.mesh, self.V, self.node_xy = run.comm, run.mesh, run.V, run.node_xy
        self.bodies = [name]
        self.tmesh = self
        self._cells = np.arange(run.mesh.topology.index_map(2).size_local, dtype=np.int32)

    def cells(self, name: str) -> np.ndarray:
        return self._cells


class _TimeProgress:
    """Simulated time, steps/s and the ETA on one line, on a terminal only (rank 0)."""

    def __init__(self, t_end: float, enabled: bool):
        self.t_end = t_end
        self.on = enabled and console.on_terminal()
        self.start = self.shown = time.perf_counter()

    def show(self, n: int, t: float, dt: float) -> None:
        if not self.on:
            return
        now = time.perf_counter()
        if now - self.shown < 0.5 and t < self.t_end * (1.0 - 1e-12):  # the last one always
            return
        self.shown = now
        frac = t / self.t_end
        eta = (now - self.start) * (1.0 - frac) / max(frac, 1e-12)
        sys.stdout.write(f"\rt = {t:.4e} of {self.t_end:.4e} s  step {n}  dt {dt:.3e} s  "
                         f"{n / max(now - self.start, 1e-9):,.0f} steps/s  ETA {eta:,.0f} s   ")
        sys.stdout.flush()

    def close(self) -> None:
        if self.on:
            sys.stdout.write("\n")
            sys.stdout.flush()


class FiniteRun:
    """One finite-strain body on a quadrilateral mesh, u_r = 0 on the axis, optionally a wall.

    ``velocity`` (v_r, v_z) in m/s; ``wall`` 'film', 'dme' or 'penalty' (contact/plane.py) at
    z = ``z_wall`` (m), the penalty a stiffness in N/m or 'scaled' (beta = ``penalty_beta``
    at every step), ``friction`` its Coulomb law (film and dme; contact/friction.py);
    ``fixed_z``, ``fixed_r`` owned nodes held in z, in r; ``name`` the body's name in the
    fields."""

    def __init__(self, mesh: dmesh.Mesh, material, settings: FiniteSettings,
                 velocity: tuple[float, float] = (0.0, 0.0), wall: str | None = None,
                 z_wall: float = 0.0, fixed_z: np.ndarray | None = None,
                 penalty: float | str = "scaled", penalty_beta: float = 1.0, name: str = "body",
                 friction=None, fixed_r: np.ndarray | None = None):
        require(mesh.topology.cell_type == dmesh.CellType.quadrilateral,
                f"the mesh's cells are {mesh.topology.cell_type.name}s: "
                f"{FINITE_STRAIN_NEEDS_QUADRILATERALS}")
        require(is_finite(material), "the material must be a finite-strain one")
        s = settings
        require(s.t_end > 0, f"t_end = {s.t_end} s: must be > 0")
        require(s.dt is None or s.dt > 0, f"dt = {s.dt} s: must be > 0")
        require(0 < s.safety <= 1 and s.dt_interval >= 1, "safety in (0, 1], dt_interval >= 1")
        require(s.history_every >= 1 and s.output_every >= 1,
                "history_every and output_every must be >= 1")
        self.mesh, self.material, self.settings = mesh, material, settings
        self.comm = mesh.comm
        # the body through the one integrator: its finite-strain force, lumped mass (the Q1
        # rule), u_r = 0 on the axis (and u_z on ``fixed_z``), the step following its cells
        self.model = model = DeformableModel(one_body(mesh, name), [Body(name, material)])
        self.V = model.V
        self.n_owned_nodes = self.V.dofmap.index_map.size_local
        self.n_owned = model.n_owned
        self.node_xy = model.node_xy
        fixed = model.axis_dofs()
        if fixed_z is not None:
            fixed = np.concatenate([fixed, 2 * np.asarray(fixed_z, dtype=np.int32) + 1])
        if fixed_r is not None:  # (u_r = 0 on these nodes too: a face held in r and z)
            fixed = np.concatenate([fixed, 2 * np.asarray(fixed_r, dtype=np.int32)])
        self.step_policy = FollowingStep(None, s.t_end, s.dt, s.safety, s.dt_interval)
        self.integrator = integ = Integrator(model, None, fixed, policy=self.step_policy)
        self.force = integ.finite[0]
        self.u_fn = integ.u_function
        self.u = self.u_fn.x.array  # owned + ghost
        self.u_owned = integ.u_owned
        self.mass = integ.mass
        self.free = integ.free
        self.coef = self.force.coef
        v0 = np.zeros(self.n_owned)
        v0[0::2], v0[1::2] = velocity
        integ.set_initial(None, v0)
        self.v = integ.v_owned
        self.u_vec, self.v_vec = integ.u_vec, integ.v_vec
        n_local_nodes = self.node_xy.shape[0]
        hi = self.node_xy.max(axis=0) if n_local_nodes else np.full(2, -np.inf)
        lo = self.node_xy.min(axis=0) if n_local_nodes else np.full(2, np.inf)
        self.comm.Allreduce(MPI.IN_PLACE, hi, op=MPI.MAX)
        self.comm.Allreduce(MPI.IN_PLACE, lo, op=MPI.MIN)
        length, r_max = float(hi[1] - lo[1]), float(hi[0])
        self.length0 = length
        # the wall: every owned boundary node is a candidate
        self.wall = None
        if wall is not None:
            self.wall = FixedPlane(self.comm, boundary_nodes(self.V, self.n_owned_nodes),
                                   self.node_xy, model.offset, self.mass, self.u_owned, self.v,
                                   wall, z_wall, penalty=penalty, beta_target=penalty_beta,
                                   length=length, friction=friction, fixed=fixed)
        self.name = name
        self.status = "set up"
        self.signal = 0
        # tracked nodes: the ends of the axis (0, Z_max) and (0, Z_min), whose distance is
        # the bar's length, and the lower corner (R, Z_min), whose r is the face's radius
        self._top = self._owned_node(0.0, float(hi[1]))
        self._bottom = self._owned_node(0.0, float(lo[1]))
        self._corner = self._owned_node(r_max, float(lo[1]))

    def _owned_node(self, r: float, z: float) -> int:
        """The owned node at (r, z) (m), or -1 if another rank owns it."""
        xy = self.node_xy[: self.n_owned_nodes]
        if xy.size == 0:
            return -1
        d = np.hypot(xy[:, 0] - r, xy[:, 1] - z)
        k = int(np.argmin(d))
        return k if d[k] <= 1e-9 * max(self.length0, 1e-300) else -1

    # ------------------------------------------------------------ measures (every rank)
    def dt_limit(self) -> float:
        """Current stable estimate min L / c (s) over all ranks (before the safety factor):
        the force's own."""
        return self.force.stable_dt()

    def tracked(self, u: np.ndarray | None = None) -> tuple[float, float]:
        """(current length (m): the axis length, z of the node that started at (0, Z_max)
        minus z of the one that started at (0, Z_min), on the wall or off it after a
        rebound; current r (m) of the node that started at (R, Z_min)), of the current u
        or of ``u`` (m)."""
        u = self.u if u is None else u
        vals = np.full(3, -np.inf)  # top z, -bottom z, corner r (one MAX reduction)
        if self._top >= 0:
            vals[0] = self.node_xy[self._top, 1] + u[2 * self._top + 1]
        if self._bottom >= 0:
            vals[1] = -(self.node_xy[self._bottom, 1] + u[2 * self._bottom + 1])
        if self._corner >= 0:
            vals[2] = self.node_xy[self._corner, 0] + u[2 * self._corner]
        self.comm.Allreduce(MPI.IN_PLACE, vals, op=MPI.MAX)
        return float(vals[0] + vals[1]), float(vals[2])

    def kinetic(self, v: np.ndarray | None = None) -> float:
        """1/2 v M v (J) of the current v (v^{n-1/2}) or of ``v`` (m/s, owned)."""
        v = self.v if v is None else v
        return self.comm.allreduce(0.5 * float(np.dot(self.mass, v * v)))

    def eps_p_max(self) -> float:
        local = float(self.force.state[..., 0].max()) if self.force.state.size else 0.0
        return self.comm.allreduce(local, op=MPI.MAX)

    # ------------------------------------------------------------ the run
    def penalty_beta(self, dt: float, dt_avg: float) -> float:
        """Largest beta_i = p_i dt dt_avg / m_i (-) of a penalty wall over all ranks (0 without)."""
        local = self.wall.beta_max_local(dt, dt_avg) if self.wall is not None else 0.0
        return self.comm.allreduce(local, op=MPI.MAX)

    def _check_penalty(self, dt: float, dt_avg: float, n: int, t: float) -> None:
        """A penalty wall above the stable bound 4/3 (contact/penalty.py) is refused unless
        forced: before the run as bad input, during it (the step grew) as a stopped run."""
        from .contact.penalty import STABILITY_BOUND

        beta = self.penalty_beta(dt, dt_avg)
        self.beta_max = max(getattr(self, "beta_max", 0.0), beta)
        if beta > STABILITY_BOUND and not self.settings.force:
            what = (f"[wall] penalty = {self.wall.penalty:.4g} N/m: beta_max = p dt^2 / m = "
                    f"{beta:.4g} is above the stable bound 4/3")
            if n == 0:
                raise InputError(f"{what} at dt = {dt:.4g} s; lower the penalty, use "
                                 'penalty = "scaled", or force it')
            raise UnstableRunError(f"run stopped at step {n} (t = {t:.6g} s): {what} at the "
                                   f"current dt = {dt:.4g} s")

    def _cell_values(self, u: np.ndarray) -> dict[str, np.ndarray]:
        """The cell fields of the state at ``u`` (m, every local entry): Cauchy stress (Pa),
        von Mises (Pa), eps_p_eq (-) and the temperature (K) of a material with one."""
        sig, eps, temp = self.force.cell_values(u)  # stress columns rr, tt, zz, rz
        m = sig[:, :3].mean(axis=1)
        d = sig[:, :3] - m[:, None]
        vm = np.sqrt(1.5 * ((d * d).sum(axis=1) + 2.0 * sig[:, 3] ** 2))
        out = {"sigma_rr": sig[:, 0], "sigma_tt": sig[:, 1], "sigma_zz": sig[:, 2],
               "sigma_rz": sig[:, 3], "von_mises": vm, "eps_p_eq": eps}
        if self.has_temperature:
            out["temperature"] = temp
        return out

    @property
    def has_temperature(self) -> bool:
        return getattr(self.material, "temperature_index", -1) >= 0

    # ------------------------------------------------------------ the run
    def run(self, extra=None) -> dict:
        """Step to t_end and return the summary. With ``settings.out`` the run directory gets
        history.csv, fields.xdmf, history.png and summary.json (staged, see rundir.py; a
        signal stops the run at a step boundary with a complete directory). ``extra(run)``
        may return more summary entries (checks of a demo) of a completed run; they are
        written with the rest, before the output directory is published."""
        from .schedule import StopFlag  # the signal flag every run shares
        from .xdmf import FieldWriter

        s, comm = self.settings, self.comm
        policy = self.step_policy
        dt_lim = policy.limit
        dt0 = policy.first()
        self._check_penalty(dt0, dt0, 0, 0.0)
        # the body's own stable step (s): at the start, and the smallest the run reaches
        self.stable_dt = {self.name: dt_lim}
        if comm.rank == 0 and not s.quiet:
            from .report import stable_step_line

            shared = (f"every body steps the fixed dt = {dt0:.3g} s" if s.dt is not None else
                      f"every body steps {s.safety:g} x the smallest, re-estimated every "
                      f"{s.dt_interval} steps (first dt = {dt0:.3g} s)")
            print(stable_step_line(self.stable_dt, self.name, shared,
                                   "current cells, min L / c"), flush=True)
        t_setup = time.perf_counter()
        stop = StopFlag()
        staging = writer = table = None
        try:
            staging = rundir.prepare_directory(s.out, comm) if s.out else None
            hist_path = os.path.join(staging, "history.csv") if staging else None
            xdmf = os.path.join(staging, "fields.xdmf") if (staging and s.fields) else None
            table = output.Table(hist_path, HISTORY_COLUMNS, comm) if hist_path else None
            names = CELL_FIELDS + (("temperature",) if self.has_temperature else ())
            writer = FieldWriter(xdmf, _OneBody(self, self.name), names) if xdmf else None
            if stop.collective(comm):
                raise interrupts.Interrupted(stop.signum)
        except BaseException:
            if writer is not None:
                writer.close()
            if staging:
                rundir.abandon_directory(staging, comm)
            stop.restore()
            raise
        # (the force's kernels and the wall's load with them, at their set-up)
        self.setup_time = {"outputs": time.perf_counter() - t_setup}
        timers = PhaseTimers(PHASES) if s.timers else None
        progress = _TimeProgress(s.t_end, not s.quiet and comm.rank == 0)
        cap = 4096
        hist = np.zeros((cap, len(HISTORY_COLUMNS)))
        n_rows, stride = 0, s.history_every
        K0 = self.kinetic(self.v)
        total_mass = comm.allreduce(float(self.mass[1::2].sum()))
        w_int = taken = 0.0
        t, dt_prev = 0.0, None
        n = 0
        serial = comm.size == 1
        failure = None
        clock = time.perf_counter
        integ, force, wall = self.integrator, self.force, self.wall
        step, predict, advance = integ.step, integ.predict, integ.advance
        # the state u^n (every local entry), v^{n-1/2} an output step keeps, written after
        # the step's force evaluation (the points' stresses at u^n)
        u_kept, v_kept = np.empty_like(self.u), np.empty_like(self.v)
        self.status = "running"
        jit_before = signature_counts()
        t_run = clock()
        try:
            while t < s.t_end * (1.0 - 1e-12):
                t0 = clock()
                if n >= s.max_steps:
                    raise UnstableRunError(f"more than {s.max_steps} steps before t_end = {s.t_end} s")
                frame = writer is not None and n % s.output_every == 0
                row_due = n % stride == 0 or (table is not None and n % s.history_every == 0)
                if frame or row_due:
                    self.u_fn.x.scatter_forward()  # (u's ghosts, as the step's own scatter)
                    u_kept[:] = self.u
                    v_kept[:] = self.v
                    w_kept, taken_kept = w_int, taken
                # h_{n+1/2} from the policy, f_int(u^n), v^{n+1/2} = v^{n-1/2} + h_n M^-1 f,
                # u^{n+1} = u^n + h_{n+1/2} v^{n+1/2}: the one integrator's step
                predict()
                dt, dt_avg = step.h, step.h_avg
                dt_lim, new_limit = policy.limit, policy.renewed
                w_int += force.last_work
                if new_limit and n > 0 and wall is not None and wall.method == "penalty":
                    self._check_penalty(dt, dt_avg, n, t)
                t1 = clock()
                if frame:
                    writer.write(t, n, u_kept, writer.ghosted(v_kept, 1),
                                 self._cell_values(u_kept))
                t2 = clock()
                if row_due:
                    led = 0.0 if dt_prev is None else dt_prev  # the step to this state
                    row = self._history_row(n, t, led, dt_lim, K0, w_kept, taken_kept,
                                            total_mass, u_kept, v_kept)
                    if table is not None and n % s.history_every == 0:
                        table.row()[:] = row
                    if n % stride == 0:
                        if n_rows == cap:  # keep memory bounded: every other row, double the stride
                            hist[: cap // 2] = hist[0:cap:2]
                            n_rows, stride = cap // 2, 2 * stride
                        if n % stride == 0:
                            hist[n_rows] = row
                            n_rows += 1
                t3 = clock()
                if wall is not None:
                    w_int += wall.step(self.u_owned, self.v, dt, dt_avg, force.f_owned)
                    taken = wall.contact_loss_local
                advance()
                t += dt
                dt_prev = dt
                n += 1
                if n % 16 == 0 and not comm.allreduce(  # collective: every rank stops alike
                        bool(np.isfinite(np.dot(self.v, self.v))), op=MPI.LAND):
                    raise UnstableRunError(f"run diverged at step {n} (t = {t:.6g} s): velocity "
                                           "not finite")
                t5 = clock()
                if timers is not None:
                    now = timers.current
                    now[:] = (t1 - t0, t5 - t3, t3 - t2, t2 - t1)
                    timers.record()
                progress.show(n, t, dt)
                done = not t < s.t_end * (1.0 - 1e-12)
                caught = (interrupts.STATE.signum != 0 if serial else
                          (n % interrupts.AGREE_EVERY == 0 or done) and stop.collective(comm))
                if caught:
                    stop.collective(comm)
                    self.status = f"interrupted by {stop.name}"
                    break
            else:
                self.status = "completed"
        except UnstableRunError as exc:
            self.status = "diverged"
            failure = str(exc)
            if staging is None:
                stop.restore()
                if table is not None:
                    table.close()
                if writer is not None:
                    writer.close()
                raise
        except BaseException:
            stop.restore()
            raise
        finally:
            progress.close()
        wall_time = comm.allreduce(clock() - t_run, op=MPI.MAX)
        # kernels compiled inside the loop (a signature not loaded at set-up): none
        self.compiled_in_loop = gained(jit_before, signature_counts())
        try:
            # the final state: force at u^N so that the state and the stored energy are current
            if self.status != "diverged":
                self.force.set_step(dt_prev, dt_prev)  # its points' step: the last one taken
                self.u_fn.x.scatter_forward()
                self.force.evaluate()
                row = self._history_row(n, t, dt_prev, dt_lim, K0, w_int, taken, total_mass,
                                        self.u, self.v)
                if table is not None:  # the last state, u^N, always
                    table.row()[:] = row
                if n_rows == cap:
                    hist[: cap // 2] = hist[0:cap:2]
                    n_rows = cap // 2
                hist[n_rows] = row
                n_rows += 1
                if writer is not None:
                    writer.write(t, n, self.u, writer.ghosted(self.v, 1),
                                 self._cell_values(self.u))
            if table is not None:
                table.close()
            if writer is not None:
                writer.close()
            self.n_steps, self.t = n, t
            self.history = {c: hist[:n_rows, i].copy() for i, c in enumerate(HISTORY_COLUMNS)}
            summary = self._summary(K0, n, t, policy.h_range, w_int, taken, wall_time, timers)
            summary.update(s.summary_extra)
            if failure is not None:
                summary["failure"] = failure
            self.summary = summary
            if extra is not None and self.status.startswith("completed"):
                summary.update(extra(self))
            if staging:
                scene = summary.get("scene_file")
                if scene and comm.rank == 0 and os.path.isfile(scene):
                    shutil.copy(scene, os.path.join(staging, "scene" + os.path.splitext(scene)[1]))
                if s.plots and comm.rank == 0 and not stop.signum:
                    from .plotting import write_finite_plots

                    write_finite_plots(staging, self.history, summary.get("title"))
                if not self.status.startswith("interrupted") and stop.collective(comm):
                    summary["interrupted"] = (f"{stop.name} after the last step, while the "
                                              "output was finished (it is complete)")
                output.write_json(os.path.join(staging, "summary.json"), summary, comm)
                self.out_dir = rundir.finalize_directory(staging, s.out, comm, self.status)
            stop.collective(comm)
        finally:
            stop.restore()
        self.signal = stop.signum
        self.summary = summary
        if failure is not None:
            raise UnstableRunError(failure)
        return summary

    @property
    def stable_dt_smallest(self) -> dict[str, float]:
        """The body's smallest stable step of the run so far (s)."""
        return {self.name: self.step_policy.smallest}

    def _history_row(self, n, t, dt, dt_lim, K0, w_int, taken, total_mass, u, v) -> list:
        """One history row (every rank the same) of the state ``u`` = u^n (m, every local
        entry), ``v`` = v^{n-1/2} (m/s, owned): see HISTORY_COLUMNS (SI units); ``dt`` the
        step that led to this state (0 at the start), ``dt_lim`` the current limit."""
        comm, wall = self.comm, self.wall
        stored = comm.allreduce(self.force.stored_energy_local(u)) if self.settings.ledger else 0.0
        wp = comm.allreduce(self.force.plastic_work_local)
        kin = self.kinetic(v)
        wi = comm.allreduce(w_int)
        tk = comm.allreduce(taken)
        spring = comm.allreduce(wall.spring_energy_local) if wall is not None else 0.0
        length, radius = self.tracked(u)
        n_act = comm.allreduce(wall.n_active_local) if wall is not None else 0
        force = comm.allreduce(wall.force_local) if wall is not None else 0.0
        vz = comm.allreduce(float(np.dot(self.mass[1::2], v[1::2]))) / total_mass
        return [n, t, dt, dt_lim, kin, wi, tk - spring, stored, wp, kin + wi + tk - K0,
                comm.allreduce(self.force.trapezoid_local) - stored - wp, n_act, self.force.j_min,
                self.eps_p_max(), length, radius, force, spring, vz]

    def _summary(self, K0, n, t, dts, w_int, taken, wall_time, timers) -> dict:
        """The run's figures (SI units); every rank returns the same dictionary."""
        from .summary import provenance

        s, comm = self.settings, self.comm
        K = self.kinetic()
        stored = comm.allreduce(self.force.stored_energy_local())
        wp = comm.allreduce(self.force.plastic_work_local)
        wi, tk = comm.allreduce(w_int), comm.allreduce(taken)
        spring = comm.allreduce(self.wall.spring_energy_local) if self.wall is not None else 0.0
        length, radius = self.tracked()
        n_cells = comm.allreduce(self.force.geometry.dofs.shape[0])
        summary = {
            "status": self.status, "strain": "finite", "n_steps": n, "stopped_at_step": n,
            "t_end": t, "t_end_requested": s.t_end, "n_ranks": comm.size,
            "n_cells": n_cells, "n_dofs": int(self.V.dofmap.index_map.size_global * 2),
            "dt_min": comm.allreduce(dts[0], op=MPI.MIN), "dt_max": comm.allreduce(dts[1], op=MPI.MAX),
            "stable_dt": dict(self.stable_dt), "stable_dt_limiting": self.name,
            "stable_dt_smallest": dict(self.stable_dt_smallest),
            "dt_rule": "fixed" if s.dt is not None else
            f"{s.safety} x min(A / max diagonal) / c, every {s.dt_interval} steps",
            "initial_kinetic": K0, "kinetic": K, "stored_elastic": stored, "plastic_work": wp,
            "internal_work": wi, "activation_loss": tk - spring, "penalty_energy": spring,
            "kinetic_identity_error": (K + wi + tk - K0) / K0 if K0 else K + wi + tk,
            "work_gap": (comm.allreduce(self.force.trapezoid_local) - stored - wp),
            "final_length": length, "final_face_radius": radius, "eps_p_max": self.eps_p_max(),
            "j_min": self.force.j_min, "wall_time": wall_time,
            "length_definition": "final_length: the axis length, z of the node that started "
                                 "at (0, Z_max) minus z of the one that started at (0, Z_min) "
                                 "(m), on the wall or off it; final_face_radius: r of the node "
                                 "that started at (R, Z_min) (m)",
            "energy_definition": "kinetic 1/2 v M v at the last half step; internal_work the "
                                 "booked work of f_int (kinetic identity: kinetic + internal_work "
                                 "+ activation_loss + penalty_energy = initial_kinetic to "
                                 "round-off); activation_loss the energy the wall took and kept; "
                                 "penalty_energy 1/2 p g^2 stored in the wall's springs (returned "
                                 "when they release); work_gap = internal_work booked by the "
                                 "trapezoid - stored - plastic (O(dt^2))",
        }
        summary["element_steps_per_second"] = n_cells * n / max(wall_time, 1e-300)
        summary["ns_per_element_cycle"] = 1e9 * wall_time / max(n_cells * n, 1)
        if self.wall is not None:
            summary["wall"] = {"method": self.wall.method, "z": self.wall.z_wall,
                               "n_candidates": comm.allreduce(self.wall.nodes.size)}
            if self.wall.method == "penalty":
                summary["wall"]["penalty"] = self.wall.penalty
                summary["wall"]["beta_max"] = getattr(self, "beta_max", None)
                summary["wall"]["beta_bound"] = 4.0 / 3.0
            if getattr(self.wall, "friction", None) is not None:  # D, L_t (J), peak force (N)
                summary["wall"].update(self.wall.friction.summary())
        summary.update(provenance())
        summary["setup_time"] = dict(getattr(self, "setup_time", {}))
        if timers is not None and timers.n_steps > 0:
            summary.update(timers.summary(comm, wall_time))
            summary["timing"]["compiled_in_loop"] = list(getattr(self, "compiled_in_loop", []))
        return summary
