"""The contact interface: the predicted state of the contact dofs, one method, the commit.

Each step the explicit loop predicts without contact; :meth:`ContactSet.step`
then

1. *detection*: gathers the predicted z displacement and velocity of the
   contact dofs (one Allgatherv), in global constraint order, on every rank,
   and forms the predicted gaps g~ = b + u~_upper - u~_lower;
2. *solve*: hands the set to the method, which corrects positions and
   velocities of the contact dofs (and of the rigid body) only;
3. *update*: writes the corrected values back to the owned dofs and books
   the contact work.

Every rank computes the same correction from the same gathered data, so the
answer does not depend on the partition. Signs: the contact force ``force``
(N) is compressive-positive; it pushes the upper side up (+z) and the lower
side down.
"""
from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Callable, Protocol

import numpy as np
from mpi4py import MPI

from ..errors import InputError
from .pairing import Constraints


@dataclass
class RigidBody:
    """A rigid body with one z dof, its state replicated on every rank.

    mass in kg; ``force(t)`` the external z force (N); u, v in m and m/s.
    """

    name: str
    mass: float
    force: Callable[[float], float] = lambda t: 0.0
    u: float = 0.0
    v: float = 0.0

    def __post_init__(self) -> None:
        if not self.mass > 0:
            raise InputError(f"rigid body '{self.name}': mass = {self.mass} kg must be > 0")


class ContactMethod(Protocol):
    """A way to enforce g >= 0 on the predicted state of a :class:`ContactSet`."""

    name: str
    jumps: bool  # True if it may set positions apart from u^n + dt v^{n+1}

    def setup(self, c: "ContactSet") -> None:
        """Precompute what depends only on masses and dt."""

    def correct(self, c: "ContactSet") -> None:
        """Correct the predicted state in place; set ``c.force`` and ``c.active``."""


@dataclass
class PhaseTimes:
    """CPU time (s) of the last step's contact phases."""

    detection: float = 0.0
    solve: float = 0.0
    update: float = 0.0


class ContactSet:
    """Constraints, their gathered state and the rigid body, on every rank.

    Arrays in global constraint order (length n): ``u_lo``/``v_lo`` the lower z
    displacement (m) and velocity (m/s), ``u_up``/``v_up`` the upper ones (the
    rigid body's values repeated when the upper side is rigid), ``gap`` the
    predicted gap (m), ``m_lo``/``m_up`` the lumped masses (kg), ``force`` the
    contact force (N) and ``active`` the active set. Methods correct the state
    with :meth:`apply_forces` (force methods) or by setting positions and
    velocities directly (DME, then with :meth:`set_upper_rigid`).
    """

    def __init__(self, constraints: Constraints, integrator, method: ContactMethod,
                 rigid: RigidBody | None = None):
        model = integrator.model
        self.comm: MPI.Comm = model.comm
        self.constraints = constraints
        self.integrator = integrator
        self.method = method
        self.dt = integrator.dt
        self.n = n = constraints.n
        if (constraints.upper is None) != (rigid is not None):
            raise InputError("a rigid contact face needs exactly one rigid body, "
                             "and node pairs need none")
        self.rigid = rigid
        self.b = constraints.b
        self.r = constraints.r
        self.pair_index = np.arange(n)
        # all contact dofs in one array: lower ones first, then upper ones (pairs only)
        dofs = constraints.lower if rigid else np.concatenate([constraints.lower, constraints.upper])
        self._n_dofs = nd = dofs.size
        lo, hi = model.offset, model.offset + model.n_owned
        mine = np.flatnonzero((dofs >= lo) & (dofs < hi))
        self._my_local = (dofs[mine] - lo).astype(np.intp)
        self._my_pos = mine.astype(np.intp)
        self._counts = np.array(self.comm.allgather(2 * mine.size))
        self._displs = np.concatenate([[0], np.cumsum(self._counts)[:-1]])
        positions = np.concatenate(self.comm.allgather(mine))
        if not np.array_equal(np.sort(positions), np.arange(nd)):
            raise InputError("contact dofs are not all owned exactly once: "
                             "each contact node must belong to one body")
        self._all_pos = positions.astype(np.intp)
        # send buffer: [u of my dofs, v of my dofs]; receive: the same, rank after rank
        self._send = np.empty(2 * mine.size)
        self._recv = np.empty(2 * nd)
        order = []
        for r, count in enumerate(self._counts // 2):
            start = self._displs[r]
            order.append(np.arange(start, start + count))
        self._recv_u = np.concatenate(order).astype(np.intp) if order else np.zeros(0, np.intp)
        self._recv_v = (self._recv_u + np.repeat(self._counts // 2, self._counts // 2)).astype(np.intp)
        # masses (kg) of all contact dofs
        self.mass = np.empty(nd)
        self._gather(integrator.mass, integrator.mass, self.mass, np.empty(nd))
        self.m_lo = self.mass[:n]
        self.m_up = self.mass[n:] if rigid is None else None
        # committed state (u^n, v^n) of the contact dofs, replicated
        self.u_now = np.zeros(nd)
        self.v_now = np.zeros(nd)
        # predicted (then corrected) state; methods read and correct the views
        self.u_pred, self.v_pred = np.empty(nd), np.empty(nd)
        self.u_new, self.v_new = np.empty(nd), np.empty(nd)
        self.u_lo, self.v_lo = self.u_new[:n], self.v_new[:n]
        if rigid is None:
            self.u_up, self.v_up = self.u_new[n:], self.v_new[n:]
        else:
            self.u_up, self.v_up = np.empty(n), np.empty(n)
        self.gap = np.empty(n)
        self.force = np.zeros(n)
        self.active = np.zeros(n, dtype=bool)
        self.was_active = np.zeros(n, dtype=bool)
        self.times = PhaseTimes()
        self.jumps = bool(getattr(method, "jumps", False))
        self._tmp = np.empty(nd)
        self._out_u = np.empty(mine.size)
        self._out_v = np.empty(mine.size)
        self._ledger = _ContactWork(self)
        self._rigid_u = self._rigid_v = 0.0
        self._rigid_v_pred = 0.0
        self._rigid_f = 0.0
        method.setup(self)

    # ------------------------------------------------------------ gather / scatter
    def _gather(self, u_src: np.ndarray, v_src: np.ndarray, u_out: np.ndarray,
                v_out: np.ndarray) -> None:
        """u_src, v_src (owned arrays) on the contact dofs, into global order on every rank."""
        k = self._my_local.size
        np.take(u_src, self._my_local, out=self._send[:k])
        np.take(v_src, self._my_local, out=self._send[k:])
        if self.comm.size == 1:
            u_out[self._my_pos] = self._send[:k]
            v_out[self._my_pos] = self._send[k:]
            return
        self.comm.Allgatherv(self._send, [self._recv, self._counts, self._displs, MPI.DOUBLE])
        u_out[self._all_pos] = self._recv[self._recv_u]
        v_out[self._all_pos] = self._recv[self._recv_v]

    def initialize(self) -> None:
        """Read u^0 and v^0 of the contact dofs (call after the integrator's set_initial)."""
        integ = self.integrator
        self._gather(integ._ua, integ._va, self.u_now, self.v_now)

    # ------------------------------------------------------------ helpers for methods
    def s_diagonal(self) -> np.ndarray:
        """Diagonal part d of S = dt^2 G M^-1 G' = diag(d) + kappa 1 1' (m/N)."""
        d = 1.0 / self.m_lo
        if self.m_up is not None:
            d = d + 1.0 / self.m_up
        return self.dt ** 2 * d

    def s_coupling(self) -> float:
        """kappa = dt^2 / m_rigid (m/N) for a rigid upper side, 0 for node pairs."""
        return 0.0 if self.rigid is None else self.dt ** 2 / self.rigid.mass

    def apply_forces(self, force: np.ndarray) -> None:
        """Apply compressive contact forces (N): velocities change by dt F/m, positions by dt^2 F/m."""
        dt = self.dt
        dv = self._tmp[: self.n]
        np.divide(force, self.m_lo, out=dv)
        dv *= dt
        self.v_lo -= dv
        dv *= dt
        self.u_lo -= dv
        if self.rigid is None:
            np.divide(force, self.m_up, out=dv)
            dv *= dt
            self.v_up += dv
            dv *= dt
            self.u_up += dv
        else:
            dv_rigid = dt * float(force.sum()) / self.rigid.mass
            self.set_upper_rigid(self._rigid_v + dv_rigid, self._rigid_u + dt * dv_rigid)

    def set_upper_rigid(self, v: float, u: float) -> None:
        """Set the rigid body's corrected velocity (m/s) and position (m)."""
        self._rigid_v, self._rigid_u = v, u
        self.u_up.fill(u)
        self.v_up.fill(v)

    @property
    def rigid_state(self) -> tuple[float, float]:
        """The rigid body's current (predicted or corrected) (u, v) in m and m/s."""
        return self._rigid_u, self._rigid_v

    # ------------------------------------------------------------ the step
    def step(self) -> None:
        """Detect, solve and update for the step n -> n+1 (after the integrator's predict)."""
        integ = self.integrator
        clock = time.perf_counter
        t0 = clock()
        # --- detection
        self._gather(integ._ua, integ._va, self.u_pred, self.v_pred)
        self.u_new[:] = self.u_pred
        self.v_new[:] = self.v_pred
        if self.rigid is not None:
            rb = self.rigid
            self._rigid_f = rb.force(integ.t)
            self._rigid_v_pred = rb.v + self.dt * self._rigid_f / rb.mass
            self.set_upper_rigid(self._rigid_v_pred, rb.u + self.dt * self._rigid_v_pred)
        np.subtract(self.u_up, self.u_lo, out=self.gap)
        self.gap += self.b
        self.was_active[:] = self.active
        t1 = clock()
        # --- solve
        self.method.correct(self)
        t2 = clock()
        # --- update
        np.take(self.u_new, self._my_pos, out=self._out_u)
        np.take(self.v_new, self._my_pos, out=self._out_v)
        integ.put(self._my_local, self._out_u, self._out_v)
        self._ledger.book(integ.n)
        self.u_now[:] = self.u_new
        self.v_now[:] = self.v_new
        if self.rigid is not None:
            self.rigid.u, self.rigid.v = self._rigid_u, self._rigid_v
        t3 = clock()
        self.times.detection, self.times.solve, self.times.update = t1 - t0, t2 - t1, t3 - t2

    # ------------------------------------------------------------ outputs
    @property
    def contact_work(self) -> float:
        """Work (J) of the contact forces so far, jumps included (see impact_fenics.energy)."""
        return self._ledger.work

    @property
    def activation_loss(self) -> float:
        """Energy (J) lost in the steps where constraints became active (and the step after)."""
        return self._ledger.activation_loss

    @property
    def rigid_external_work(self) -> float:
        """Work (J) of the external force on the rigid body."""
        return self._ledger.rigid_external_work

    def kinetic_energy_rigid(self, v_now: float, v_next: float) -> float:
        """1/2 m_p v^n v^{n+1} (J) of the rigid body."""
        return 0.0 if self.rigid is None else 0.5 * self.rigid.mass * v_now * v_next

    def committed_gap(self) -> np.ndarray:
        """Gap (m) of the committed state, in global constraint order."""
        n = self.n
        up = self.u_now[n:] if self.rigid is None else self.rigid.u
        return self.b + up - self.u_now[:n]

    def max_penetration(self) -> float:
        """Largest committed penetration max(0, -g) (m)."""
        return float(max(0.0, -self.committed_gap().min()))


class _ContactWork:
    """Work of the contact forces in the ledger's discrete form (impact_fenics.energy).

    The contact force on a contact dof is its momentum change over the step,
    F^n = m (v^{n+1} - v~^{n+1}) / dt; step n adds 1/2 dt v^n . (F^{n-1} + F^n).
    A position set apart from u^n + dt v^{n+1} (a jump j, DME) adds
    1/2 j . K (u^n + u^{n+1}) one step later, when K u^{n+1} on the contact dofs
    is known from the free prediction: K u^n = -m (v~^{n+1} - v^n) / dt there.
    """

    def __init__(self, c: ContactSet):
        self.c = c
        nd = c.u_now.size
        self.f_prev, self.f_now = np.zeros(nd), np.zeros(nd)
        self.ku_prev, self.ku_now = np.zeros(nd), np.zeros(nd)
        self.jump = np.zeros(nd)
        self.tmp = np.empty(nd)
        self.jumped = False
        self.grew_last = False
        self.work = 0.0
        self.activation_loss = 0.0
        self.rigid_external_work = 0.0
        self.rigid_fc_prev = 0.0
        self.rigid_f_prev = 0.0

    def book(self, n_step: int) -> None:
        c, dt = self.c, self.c.dt
        np.subtract(c.v_new, c.v_pred, out=self.f_now)
        self.f_now *= c.mass / dt
        inc = 0.0
        if n_step > 0:
            self.f_prev += self.f_now
            inc = 0.5 * dt * float(np.dot(c.v_now, self.f_prev))
        if c.jumps:
            np.subtract(c.v_pred, c.v_now, out=self.ku_now)
            self.ku_now *= -c.mass / dt
            if self.jumped:
                self.ku_prev += self.ku_now
                inc += 0.5 * float(np.dot(self.jump, self.ku_prev))
            # this step's jump: u^{n+1} - u^n - dt v^{n+1}
            np.multiply(c.v_new, dt, out=self.tmp)
            np.subtract(c.u_new, c.u_now, out=self.jump)
            self.jump -= self.tmp
            self.jumped = bool(np.any(self.jump))
            self.ku_prev[:] = self.ku_now
        if c.rigid is not None:
            rb = c.rigid  # still at (u^n, v^n)
            fc = rb.mass * (c._rigid_v - c._rigid_v_pred) / dt
            if n_step > 0:
                inc += 0.5 * dt * rb.v * (self.rigid_fc_prev + fc)
                self.rigid_external_work += 0.5 * dt * rb.v * (self.rigid_f_prev + c._rigid_f)
            self.rigid_fc_prev, self.rigid_f_prev = fc, c._rigid_f
        self.work += inc
        grew = bool(np.any(c.active & ~c.was_active))
        if grew or self.grew_last:
            self.activation_loss -= inc
        self.grew_last = grew
        self.f_prev[:] = self.f_now
