"""The explicit loop of paper eq. (1) on PETSc vectors: one MatMultAdd and one AXPY per step.

The modified Euler scheme

    a^n = M^-1 (f^n - f_int(u^n)),  v^{n+1} = v^n + dt a^n,  u^{n+1} = u^n + dt v^{n+1}

runs as: each internal force adds -dt M^-1 f_int(u^n) into v (the linear
bodies by  v <- A u + v, one MatMultAdd with A = -dt M^-1 K scaled once; a
path-dependent body by its quadrature force, a finite-strain body (Q1, F-bar) by its
finite-strain force: the forces of :mod:`.internal_force`, each behind the protocol of
:mod:`.internal_force.base`), the few loaded dofs get dt M^-1 f^n, then  u <- u + dt v
(VecAXPY). Fixed dofs have zero rows in A (zero coefficients in the other forces) and
stay at rest. When every body is linear the step is the MatMultAdd and the AXPY,
nothing else. The velocity is kept as a state of its own
(not recovered from differences of displacements), so a body that drifts far
keeps its velocity to full precision.

The step comes from a step policy (:mod:`.stepping`, a constant h by default) through
the half steps of :mod:`.loop`: the increments into v take h_n, the AXPY h_{n+1/2}. Under
a constant step both are h, nothing is rescaled, and the step is the one above.

Between :meth:`predict` and :meth:`advance`, contact sets read the predicted
state from the views ``u_owned``/``v_owned`` and write the corrected positions
and velocities of their own dofs back into them.
"""
from __future__ import annotations

import math
import time

import numpy as np
from numba import njit
from petsc4py import PETSc

from .bodies import DeformableModel
from .errors import InputError, require
from .internal_force import LinearForce, QuadratureForce
from .internal_force.finite import FiniteStrainForce
from .jit_watch import direct, load
from .loads import SurfaceLoad
from .loop import HalfStep
from .materials import is_finite
from .operators import lumped_mass
from .stability import parts_stable_dt
from .stepping import ConstantStep, FollowingStep


@njit(cache=True)
def _add_load(v, dofs, coef, value) -> None:
    """v[dofs] += coef * value: a load's velocity increment dt M^-1 f^n (m/s) on its free
    dofs, ``value`` its history at t^n (Pa), in one compiled pass."""
    for i in range(dofs.size):
        v[dofs[i]] += coef[i] * value


@njit(cache=True)
def keep_velocities(v, dofs, out) -> None:
    """out[i] = v[dofs[i]] (m/s): the velocities of the multiply-touched dofs between two
    increments."""
    for i in range(dofs.size):
        out[i] = v[dofs[i]]


@njit(cache=True)
def share_correction(v, dofs, first, before, after, f, h_avg) -> float:
    """The correction (J) that makes a pass's booking h_n 1/2 (v_before + v_after) . f on
    ``dofs`` the kinetic identity's share h_n 1/2 (v^{n-1/2} + v^{n+1/2}) . f:
    sum 1/2 h_n [(v^{n+1/2} - v_after) - (v_before - v^{n-1/2})] . f, with ``v`` the final
    v^{n+1/2}, ``first`` v^{n-1/2}, ``before``/``after`` the velocities around the pass
    (m/s, on ``dofs``) and ``f`` the force of the pass (N, owned dofs)."""
    s = 0.0
    for i in range(dofs.size):
        d = dofs[i]
        s += ((v[d] - after[i]) - (before[i] - first[i])) * f[d]
    return 0.5 * h_avg * s


class Integrator:
    """State (u^n, v^n) of the deformable dofs and the step without contact.

    Units: dt in s, displacements in m, velocities in m/s, masses in kg. ``policy`` gives
    the steps (``next(n, t)``, :mod:`.stepping`), by default the constant ``dt``; ``dt``
    is the first step h_{1/2}, the one the operators are built for. A following policy
    (:class:`~.stepping.FollowingStep`) not yet bound is bound here to the finite-strain
    forces' limit (min over their current cells), and its first step is ``dt`` (give
    None, or the same value). ``per_step_linear``: the linear force's per-step pass (no A,
    its work booked; the default with a finite-strain body, whose step varies).

    A driver whose steps vary calls :meth:`track_increments` once (the dofs that take more
    than one increment, D) and :meth:`after_contact` after every step's contact: the
    forces that book their work in their pass (the linear one's per-step pass, the finite
    ones) then book the kinetic identity's share exactly on D too (one_loop.md 4.7).
    """

    def __init__(self, model: DeformableModel, dt: float | None, fixed_dofs: np.ndarray,
                 loads: list[SurfaceLoad] | None = None, matrix_type: str = "aij",
                 f_int_path: str = "fast", policy=None, per_step_linear: bool | None = None):
        if policy is None:  # (the limit is the caller's to check; the count the run's)
            if dt is None or not dt > 0.0:
                raise InputError(f"dt = {dt} s: the time step must be > 0")
            policy = ConstantStep(dt, None, math.inf, n_steps=1)
        self.model = model
        self.n = 0
        self.loads = loads or []
        self.fixed = np.unique(np.asarray(fixed_dofs, dtype=np.int32))
        self.mass = lumped_mass(model)
        self.free = np.ones(model.n_owned, dtype=bool)  # owned dofs not fixed
        self.free[self.fixed] = False
        # the internal forces (internal_force.base.Force): K over the linear bodies (K, A
        # None without any), a quadrature force per path-dependent body, a finite-strain
        # force per finite-strain body; the finite ones first: their limit can give the
        # first step
        finite = [b.name for b in model.bodies.values() if is_finite(b.material)]
        nonlinear = [b.name for b in model.bodies.values()
                     if not b.material.linear and b.name not in finite]
        self.finite: list[FiniteStrainForce] = []
        self._u_fn = None
        if nonlinear or finite:
            # u with ghost entries (the cell kernels read them), the Function of the
            # generic path its own
            self._u, self._u_fn = model.dofs.function_vec()
        else:
            self._u = model.dofs.create_vec()
        self._v = model.dofs.create_vec()
        # a finite-strain force's increment is h_n coef f with coef = -1/m (its kernel's
        # arithmetic)
        inverse = np.where(self.free, -1.0 / self.mass, 0.0) if finite else None
        for name in finite:
            force = FiniteStrainForce(model.V, model.node_xy, model.owned_cells(name),
                                      model.bodies[name].material, self._u_fn,
                                      model.geometry)
            force.coef = inverse
            force.body = name  # the body it serves (the summary's per-body figures)
            self.finite.append(force)
        if isinstance(policy, FollowingStep) and not policy.bound:
            require(self.finite, "a following step needs a finite-strain body (its cells "
                                 "give the limit)")
            others = [b for b in model.bodies if b not in finite]
            if others:  # the element bound of the bodies whose cells do not move
                policy.others = min(policy.others, parts_stable_dt(model, self.fixed, others))
            policy.bind(self.finite_limit)
        first = policy.first()
        if dt is not None and dt != first:
            raise ValueError(f"dt = {dt} s is not the policy's first step {first} s")
        if not first > 0.0:
            raise InputError(f"dt = {first} s: the time step must be > 0")
        self.dt = float(first)
        linear_parts = [p for p in model.parts if p[0].linear]
        self.linear = None
        self.K = None
        if linear_parts:
            # a finite-strain body makes the step vary: the per-step pass, not A
            per_step = bool(self.finite) if per_step_linear is None else per_step_linear
            self.linear = LinearForce(model, linear_parts, self.dt, self.mass, self.fixed,
                                      matrix_type, scaled=not per_step)
            self.K = self.linear.K
        self.nonlinear: list[QuadratureForce] = []
        if nonlinear:
            coef = np.where(self.free, -self.dt / self.mass, 0.0)
            self.nonlinear = [QuadratureForce(model, name, self._u_fn, self.dt, coef, f_int_path,
                                              mass=self.mass) for name in nonlinear]
        for force in self.finite:  # its point updates take the step just taken: h at the first
            force.set_step(self.dt, self.dt)
        self._u.set(0.0), self._v.set(0.0)
        if self.linear is not None:
            self.linear.bind(self._u, self._v)
        # every force, in the order their increments go into v: linear, small, finite
        self.forces = (([self.linear] if self.linear is not None else []) + self.nonlinear
                       + self.finite)
        # the bodies each force steps, and with two or more forces each one's time (s,
        # this rank, summed over the steps): the cost of each body, apart
        self.force_bodies = (([[b.name for b in model.bodies.values()
                                if b.name not in nonlinear and b.name not in finite]]
                              if self.linear is not None else [])
                             + [[name] for name in nonlinear] + [[name] for name in finite])
        self.force_seconds = np.zeros(len(self.forces))
        self._clock = time.perf_counter if len(self.forces) > 1 else None
        # numpy views on the owned entries of u and v (m, m/s): contact sets read the
        # prediction from them and write their corrected dofs back into them
        self.u_owned = self._u.array if self._u_fn is None else self._u_fn.x.array[:model.n_owned]
        self.v_owned = self._v.array
        # per load: its free dofs (a fixed dof stays at rest under any load), their force
        # (N per unit of the pulse) and masses (kg), and dt f / m there
        free = [self.free[ld.dofs] for ld in self.loads]
        self._load_dofs = [ld.dofs[k].astype(np.intp) for ld, k in zip(self.loads, free)]
        self._load_force = [ld.force[k] for ld, k in zip(self.loads, free)]
        self._load_mass = [self.mass[d] for d in self._load_dofs]
        self._load_coef = [self.dt * f / m for f, m in zip(self._load_force, self._load_mass)]
        # the loads' compiled increment, its entry taken now (no dispatch in the loop)
        self._add_load = (direct(_add_load, self.v_owned, self._load_dofs[0], self._load_coef[0],
                                 1.0) if self.loads else None)
        # serial: u has no ghosts, the scatter before the quadrature forces is not needed
        self._scatter = (self._u_fn is not None and model.comm.size > 1)
        # the half steps: the forces and the loads rescaled when (h, h_n) changes
        self.step = HalfStep(policy, self.dt, self.forces + [_LoadSteps(self)])
        self._tracked: np.ndarray | None = None  # D (owned local dofs), once tracked

    def track_increments(self, extra: np.ndarray | None = None) -> np.ndarray:
        """Make D, the free owned dofs that take more than one increment a step: a node of
        two forces' cells, a loaded dof, and ``extra`` (owned local dofs: the contact
        slots). Each step's passes then keep the velocities on D around every increment
        (one compiled gather a force), and :meth:`after_contact` corrects the bookings.
        A dof of D that turns out to take one increment gets a correction of 0. Returns D."""
        model = self.model
        # per body, the owned dofs its cells touch on any rank (body_dofs: a node whose
        # cells of a body are all another rank's still takes that body's increment)
        seen = np.zeros(model.n_owned, dtype=np.int32)
        for name in model.bodies:
            seen[model.body_dofs(name, 0)] += 1
            seen[model.body_dofs(name, 1)] += 1
        touched = seen > 1  # shared by two bodies (of one force or two: a superset)
        for dofs in self._load_dofs:
            touched[dofs] = True
        if extra is not None and extra.size:
            touched[np.asarray(extra, dtype=np.intp)] = True
        touched &= self.free
        D = np.flatnonzero(touched).astype(np.intp)
        # (index, force, its force array) of the forces that book in their pass
        self._booking = [(k, f, a) for k, f in enumerate(self.forces)
                         if (a := _pass_force(f)) is not None]
        if not self._booking:  # (small-strain forces only: nothing to correct)
            return D
        self._tracked = D
        self._kept = np.zeros((len(self.forces) + 1, D.size))
        load(keep_velocities, self.v_owned, D, self._kept[0])
        load(share_correction, self.v_owned, D, self._kept[0], self._kept[0], self._kept[1],
             self.v_owned, 1.0)
        return D

    def after_contact(self) -> None:
        """After the step's contact (v is v^{n+1/2}): each booking force's correction on D
        added to its work (J, this rank)."""
        if self._tracked is None:
            return
        D, kept, v, h_avg = self._tracked, self._kept, self.v_owned, self.step.h_avg
        for k, force, f in self._booking:
            force.work_local += share_correction(v, D, kept[0], kept[k], kept[k + 1], f, h_avg)

    def finite_limit(self) -> float:
        """The finite-strain forces' stable step now (s): min over their current cells of
        L / c (collective)."""
        return min(force.stable_dt() for force in self.finite)

    # ------------------------------------------------------------ state
    @property
    def t(self) -> float:
        """Time t^n of the current state (s): n dt under a constant step."""
        return self.step.time(self.n)

    def set_initial(self, u0: np.ndarray | None, v0: np.ndarray | None) -> None:
        """Set u^0 (m) and v^0 (m/s) on the owned dofs; fixed dofs are kept at zero."""
        self.n = 0
        self.step.restart()
        for target, values in ((self.u_owned, u0), (self.v_owned, v0)):
            target[:] = 0.0 if values is None else values
            target[~self.free] = 0.0

    def displacement(self, out: np.ndarray) -> np.ndarray:
        """u^n (m) on the owned dofs, copied into ``out``."""
        out[:] = self.u_owned
        return out

    def velocity(self, out: np.ndarray) -> np.ndarray:
        """v^n (m/s) on the owned dofs, copied into ``out``."""
        out[:] = self.v_owned
        return out

    @property
    def A(self) -> PETSc.Mat | None:
        """The linear force's A = -dt M^-1 K (None without linear bodies)."""
        return self.linear.A if self.linear is not None else None

    @property
    def u_function(self):
        """The ``fem.Function`` u lives in (its ghosts read by the cell kernels), None when
        every body is linear."""
        return self._u_fn

    @property
    def v_vec(self) -> PETSc.Vec:
        """The velocity vector (read it, do not resize it)."""
        return self._v

    @property
    def u_vec(self) -> PETSc.Vec:
        """The displacement vector u^n (read it, do not resize it)."""
        return self._u

    # ------------------------------------------------------------ the step
    def predict(self) -> None:
        """Step without contact: (u, v) become the predicted (u~^{n+1}, v~^{n+1})."""
        u, v = self.u_owned, self.v_owned
        if self._scatter and self.step.ahead is None:  # u's ghosts for the cell kernels (the
            # MatMultAdd reads none) and for a following policy's limit (current cells)
            self._u.ghostUpdate(addv=PETSc.InsertMode.INSERT, mode=PETSc.ScatterMode.FORWARD)
        h, h_avg = self.step.begin(self.n)
        clock = self._clock
        if self._tracked is not None:  # v on D before every increment and after the last
            D, kept = self._tracked, self._kept
            keep_velocities(v, D, kept[0])
            k = 1
            for force in self.forces:
                if clock is None:
                    force.velocity_increment(u, v, h_avg)
                else:
                    start = clock()
                    force.velocity_increment(u, v, h_avg)
                    self.force_seconds[k - 1] += clock() - start
                keep_velocities(v, D, kept[k])
                k += 1
        elif clock is None:
            for force in self.forces:
                force.velocity_increment(u, v, h_avg)
        else:  # each force timed apart (two clock reads a force, no array made)
            seconds = self.force_seconds
            k = 0
            for force in self.forces:
                start = clock()
                force.velocity_increment(u, v, h_avg)
                seconds[k] += clock() - start
                k += 1
        if self.loads:
            t = self.t
            v, add_load = self.v_owned, self._add_load
            for ld, dofs, coef in zip(self.loads, self._load_dofs, self._load_coef):
                value = float(ld.history(t))
                if value != 0.0:
                    add_load(v, dofs, coef, value)
        self._u.axpy(h, self._v)

    def next_step(self) -> float:
        """h_{n+1/2} (s) of the coming step, asked of the policy now (u's ghosts refreshed
        first, as :meth:`predict` does; it then takes this step without asking again)."""
        if self._scatter:
            self._u.ghostUpdate(addv=PETSc.InsertMode.INSERT, mode=PETSc.ScatterMode.FORWARD)
        return self.step.peek(self.n)

    def predictor(self):
        """:meth:`predict` as a function for the loop: when every body is linear and no
        load is applied, the step's two PETSc calls (the linear force's MatMultAdd, VecAXPY)
        bound as locals of a closure (about 0.15 us a step less than the method's attribute
        look-ups and tests), under a constant step only; otherwise the method itself. Same
        operations, same results."""
        if (self.A is None or self.nonlinear or self.finite or self.loads
                or not self.step.constant):
            return self.predict
        mult_add, axpy = self.A.multAdd, self._u.axpy
        u, v, dt = self._u, self._v, self.dt

        def predict() -> None:
            mult_add(u, v, v)
            axpy(dt, v)
        return predict

    def advance(self) -> None:
        """Accept the step: the corrected state becomes (u^{n+1}, v^{n+1})."""
        self.step.end()
        self.n += 1


def _pass_force(force) -> np.ndarray | None:
    """The owned force array (N) a force books its pass's work with, None for a force whose
    work is booked otherwise (the scaled linear force: telescoped; the small-strain
    force: the trapezoid)."""
    if isinstance(force, LinearForce):
        return None if force.scaled else force.pass_force
    if isinstance(force, FiniteStrainForce):
        return force.f_owned
    return None


class _LoadSteps:
    """The loads' coefficients h_n f / m (m/s per unit of the pulse) of an integrator,
    rewritten in place when h_n changes (the set-up's arithmetic)."""

    def __init__(self, integ: Integrator):
        self.integ = integ

    def set_step(self, h: float, h_avg: float) -> None:
        integ = self.integ
        for f, m, coef in zip(integ._load_force, integ._load_mass, integ._load_coef):
            np.multiply(h_avg, f, out=coef)  # (h_n f) / m, in place
            np.divide(coef, m, out=coef)
