"""The contact interface: the predicted state of the contact dofs, one method, the commit.

A set is one *kind* of geometry and one method: node pairs, a rigid face, or node
to segment (constraints from :mod:`.segments`, S banded); the methods (penalty, FILM,
DME) have a kernel for each structure of S. What follows is written for node pairs and
rigid faces; the segment kind (:meth:`ContactSet._init_segments`) gathers both
components of its slave and master nodes the same way, forms g~ = g0 + G u~ and books
the same ledger, with its method's kernels called between. Told to
(:meth:`ContactSet.set_repairing`), it re-pairs its slaves every few steps at the
start of the step, in X + u^n, and rebuilds G, g0 and S from the new pairs.

Each step the explicit loop predicts without contact; :meth:`ContactSet.step`
then

1. *detection*: gathers the predicted z displacement and velocity of the
   contact dofs (one Allgatherv), in global constraint order, on every rank,
   and forms the predicted gaps g~_i = b_i + u~[up_i] - u~[lo_i];
2. *solve*: hands the set to the method, which corrects positions and
   velocities of the contact dofs (and of the rigid body) only;
3. *update*: writes the corrected values back to the owned dofs and books
   the contact work (one compiled call, which also counts the active
   constraints, the total force and the smallest gap for the history).

For penalty, FILM fast and DME the three are one compiled call
(:mod:`.fused`; under MPI after a compiled pack and the Allgatherv), the rigid
body's prediction and commit included: only its force functions (Python
callables) are evaluated around it. Another method (FILM dense, a user's) runs
its correct() between a compiled detection and a compiled commit, with the
rigid body in Python (RigidBody.predict and advance, the same arithmetic).
Every kernel takes the constants dt/m, m/dt and 1/d, made at set-up and rewritten
only when the step changes (:meth:`ContactSet.set_step`): no division per
constraint in a step.

State lives in *slots*: one per contact dof (the lower nodes first, then the
upper nodes of node pairs) and one more for a rigid upper body. Constraint i
ties slot ``lo[i]`` to slot ``up[i]``; every constraint on a rigid body points
to its single slot, so scatter-adding the forces sums them on the body. The
slots' layout and the kernels of detection, write-back and booking are in
:mod:`.state`, compiled with numba; every rank runs them on the same
gathered data, so the answer does not depend on the partition.

Signs: the contact force ``force`` (N) is compressive-positive; it pushes the
upper side up (+z) and the lower side down.
"""
from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Callable, Protocol

import numpy as np
from mpi4py import MPI

from ..errors import InputError
from . import fused
from .banded import apply_multipliers, band_of_s_steps, bandwidth, bandwidth_of, gap_of
from .dme import DME
from .film import FILM
from .pairing import Constraints
from .prescribed import PrescribedVelocity
from .penalty import Penalty, lambda_max_diag_plus_rank_one
from .segments import (END_TOLERANCE, Repairing, SegmentConstraints, current_positions,
                       repair_reach, rows_of_pairs)
from .state import (ALL_POS, CODE, DT, H_AVG, IMPEDANCE, INCIDENT, JUMP_BOOK, JUMPS, KAPPA, LEDGER,
                    LOCAL, MASS_WEIGHTED, MISC_SIZE, N_CONS, N_DEFORMABLE, N_LOCAL, PAIRS, POS,
                    RECV_U, RESTITUTION, RIGID, RIGID_F_PREV, RIGID_FACE, RIGID_MASS, RIGID_WORK,
                    SEGMENTS, STATS, TO, WAVES, PhaseTimes, _commit, _commit_segments,
                    _committed_gap, _detect_gathered, _detect_local, _detect_segments, _pack, _take,
                    _unpack, apply_forces, gathered_order, kinetic_share, owned_slots)


@dataclass
class RigidBody:
    """A rigid body with one z dof, its state replicated on every rank.

    mass in kg; ``force(t)`` the external z force (N); u, v in m and m/s.

    Optionally driven by a rod above it (percussive drilling): a rod of
    impedance Z = rho c A (``impedance``, kg/s) carrying an incident
    compressive force wave F_i(t) (``incident``, N, compressive > 0) down onto
    the body. The rod's force on the body is F = 2 F_i - Z w, w = -v the
    downward velocity (Lundberg 1982), with w the step average
    (v^n + v^{n+1})/2: in z, F_z^n = -2 F_i(t^n) - Z (v^n + v^{n+1})/2. The
    implicit half of it is an added mass Z dt/2:

        (m + Z dt/2) v^{n+1} = (m - Z dt/2) v^n + dt (f(t^n) - 2 F_i(t^n) + F_contact),

    so the contact methods see the effective mass m + Z dt/2. The reflected
    wave is F_r = F_i - Z w (w the same step average). Then
    F_i^2 - F_r^2 = Z w F exactly, so the wave energies (J)

        incident  sum dt F_i^2 / Z,  reflected  sum dt F_r^2 / Z,
        delivered sum dt F w   (the rod's work on the body)

    balance to round-off: incident = reflected + delivered.

    A *fixed* part (``fixed=True``: a wall, an anvil's seat) has infinite mass (zero
    inverse mass, so kappa = 0 in its sets), no force and no rod; it never moves, and it
    may be in any number of contact sets. A moving part belongs to one set.

    In plane strain a moving part also translates along x (docs/friction.md 11): ``u_x``,
    ``v_x`` (m, m/s) and the external x force ``force_x(t)`` (N, None: none), its mass M
    (the rod acts along y only). Its set makes the x dof live (``slides``) where the part
    has a sideways velocity or force, or where any method's friction couples it (the
    face's x nodes free); then
    V^{n+1/2} = V^{n-1/2} + h_n (f_x + sum of the tangential forces) / M and
    U^{n+1} = U^n + h_{n+1/2} V^{n+1/2}. No rotation: the face keeps its orientation.

    A *prescribed* part (``prescribed``: its v(t), :class:`.prescribed.PrescribedVelocity`)
    is a fixed part that moves: infinite mass (``fixed`` is True: zero inverse mass, so
    the methods serve it as a fixed part), no force, rod or sideways motion, and each step
    its v^{n+1/2} is the mean of v(t) over the step (ContactSet.drive_prescribed). Its
    ``reaction`` is the z force the contact exerts on it in the last step (N), and the
    work of the motion that holds it, -sum h_n 1/2 (v^{n-1/2} + v^{n+1/2}) reaction, is its
    external work (docs/friction.md 12). It belongs to one contact set.
    """

    name: str
    mass: float
    force: Callable[[float], float] = lambda t: 0.0
    u: float = 0.0
    v: float = 0.0
    impedance: float = 0.0
    incident: Callable[[float], float] | None = None
    wave_incident: float = 0.0
    wave_reflected: float = 0.0
    wave_delivered: float = 0.0
    fixed: bool = False
    u_x: float = 0.0
    v_x: float = 0.0
    force_x: Callable[[float], float] | None = None
    slides: bool = False  # the x dof is live (set by its contact set)
    prescribed: PrescribedVelocity | None = None
    reaction: float = 0.0  # N, z: the contact's force on a prescribed part in the last step

    def __post_init__(self) -> None:
        if self.prescribed is not None:
            if (self.v != 0.0 or self.impedance != 0.0 or self.incident is not None
                    or self.v_x != 0.0 or self.force_x is not None or self.fixed):
                raise InputError(f"rigid body '{self.name}': a prescribed velocity takes no "
                                 "initial velocity, rod, sideways motion or fixed flag")
            self.fixed = True
            self.v = self.prescribed(0.0)
        if self.fixed and self.prescribed is None:
            if (self.v != 0.0 or self.impedance != 0.0 or self.incident is not None
                    or self.v_x != 0.0 or self.force_x is not None):
                raise InputError(f"rigid body '{self.name}': a fixed part has no velocity, "
                                 "rod or incident wave")
            self.mass = np.inf
        if self.prescribed is not None:
            self.mass = np.inf
        if not self.mass > 0:
            raise InputError(f"rigid body '{self.name}': mass = {self.mass} kg must be > 0")
        if not self.impedance >= 0:
            raise InputError(f"rigid body '{self.name}': impedance = {self.impedance} kg/s "
                             "must be >= 0")
        if (self.incident is not None) and not self.impedance > 0:
            raise InputError(f"rigid body '{self.name}': an incident wave needs a rod "
                             "impedance > 0 (kg/s)")

    @property
    def sideways(self) -> bool:
        """Whether the part is given a sideways (x) velocity or force."""
        return self.v_x != 0.0 or self.force_x is not None

    def predict_x(self, t: float, dt: float, h_avg: float) -> tuple[float, float]:
        """(U~, V~) at t + dt without contact (m, m/s): V~ = V^{n-1/2} + h_n f_x(t^n) / M,
        U~ = U^n + h_{n+1/2} V~."""
        v_tilde = self.v_x
        if self.force_x is not None:
            v_tilde = v_tilde + h_avg * float(self.force_x(t)) / self.mass
        return self.u_x + dt * v_tilde, v_tilde

    def effective_mass(self, dt: float) -> float:
        """m + Z dt/2 (kg): the mass a contact force accelerates within a step (``dt`` the
        velocity's step h_n; inf for a fixed part)."""
        return self.mass + 0.5 * self.impedance * dt

    def _drive(self, t: float) -> float:
        """External z force of step n without the rod's damping: f(t) - 2 F_i(t) (N)."""
        return self.force(t) - (2.0 * self.incident(t) if self.incident is not None else 0.0)

    def predict(self, t: float, dt: float, h_avg: float | None = None) -> tuple[float, float]:
        """(u~, v~) at t + dt without contact (m, m/s): the velocity over the step ``h_avg``
        (h_n, s; ``dt`` if not given), the position over ``dt`` (h_{n+1/2})."""
        h = dt if h_avg is None else h_avg
        if self.impedance == 0.0:
            v_tilde = self.v + h * self._drive(t) / self.mass
        else:
            half = 0.5 * self.impedance * h
            v_tilde = ((self.mass - half) * self.v + h * self._drive(t)) / (self.mass + half)
        return self.u + dt * v_tilde, v_tilde

    def advance(self, t: float, dt: float, u_next: float, v_next: float) -> float:
        """Commit (u^{n+1}, v^{n+1}); book the rod's waves of the step; return the
        external z force F^n of the step (N), the rod's included."""
        force = self._drive(t)
        if self.impedance > 0:
            w = -0.5 * (self.v + v_next)  # downward, step-averaged
            f_i = self.incident(t) if self.incident is not None else 0.0
            rod = 2.0 * f_i - self.impedance * w  # the rod's push on the body (N, down)
            f_r = f_i - self.impedance * w
            self.wave_incident += dt * f_i * f_i / self.impedance
            self.wave_reflected += dt * f_r * f_r / self.impedance
            self.wave_delivered += dt * rod * w
            force = self.force(t) - rod
        self.u, self.v = float(u_next), float(v_next)
        return force


def profiled(constraints) -> bool:
    """Whether a rigid face's initial gaps b differ (a button's profile) by more than the
    round-off of its nodes' coordinates (1e-12 of the face's extent in r, m)."""
    b, r = np.asarray(constraints.b), np.asarray(constraints.r)
    if b.size == 0:
        return False
    return float(np.ptp(b)) > 1e-12 * max(float(np.abs(r).max()), float(np.abs(b).max()))


def refuse_shared_rigid(rigid: RigidBody, names: tuple[str, str], sets,
                        tie: bool = False) -> None:
    """A moving rigid part belongs to one contact set: the sets correct one after another
    (a Gauss-Seidel sweep), not as the coupled solve its kappa 1 1' would need across
    them. Refuse ``rigid`` for a new set of surfaces ``names`` if one of ``sets`` holds
    it, in one line naming both; a fixed part (kappa = 0) couples nothing and may be in
    any number of sets, unless one of them is a tie (``tie``: the new set is one): a
    tied part, fixed or not, is in its tie alone."""
    for c in sets:
        if getattr(c, "rigid", None) is rigid:
            old = "/".join(f"'{x}'" for x in c.constraints.names)
            new = "/".join(f"'{x}'" for x in names)
            if tie or c.method.name == "tie":
                raise InputError(f"rigid body '{rigid.name}' is in a tie and in another "
                                 f"contact set, {old} and {new}: a tied part belongs to its "
                                 "tie alone")
            if rigid.fixed and rigid.prescribed is None:
                continue
            raise InputError(f"rigid body '{rigid.name}' is in two contact sets, {old} and "
                             f"{new}: a moving rigid part belongs to one set (sets correct "
                             "one after another, not as one coupled solve)")


class ContactMethod(Protocol):
    """A way to enforce g >= 0 on the predicted state of a :class:`ContactSet`."""

    name: str
    jumps: bool  # True if it may set positions apart from u^n + dt v^{n+1}

    def setup(self, c: "ContactSet") -> None:
        """Precompute what depends only on masses and dt."""

    def correct(self, c: "ContactSet") -> None:
        """Correct ``c.u``, ``c.v`` in place from the predicted state; set ``c.force``, ``c.active``."""


# ----------------------------------------------------------------------------- the set

class ContactSet:
    """Constraints, their gathered state and the rigid body, on every rank.

    Slot arrays (length ``n_slots``): ``u``, ``v`` the state the method corrects
    (m, m/s; on entry the prediction), ``u_pred``, ``v_pred`` the prediction,
    ``mass`` (kg). Constraint arrays (length n): ``lo``, ``up`` their slots,
    ``b`` the initial gaps (m), ``gap`` the predicted gaps, ``force`` (N) and
    ``active``. ``d`` and ``kappa`` describe S = h_{n+1/2} h_n G M^-1 G' = diag(d) +
    kappa 1 1' (m/N): kappa = h_{n+1/2} h_n / m_rigid, 0 for node pairs and a fixed
    part. The rigid part is above its face's nodes (``constraints.upper`` None: the
    punch, the bit) or below them (``constraints.lower`` None: a wall); ``side`` is +1
    or -1 and ``nodes`` the constraints' node slots. Every constant that holds the step
    (h_n / m, m / h_n, d, 1/d, kappa, a scaled penalty) is rewritten by :meth:`set_step`;
    the set starts with h_{n+1/2} = h_n = ``integrator.dt``. The committed
    state of a step is ``u_now``, ``v_now`` (the fused step of a rigid face does
    not write its nodes' scratch rows u, v, gap and was_active). All are rows of
    a few packed arrays (``_floats``, ``_ints``, ``_flags``, ``_misc``; layout
    in :mod:`.state`).
    """

    def __init__(self, constraints: Constraints | SegmentConstraints, integrator,
                 method: ContactMethod, rigid: RigidBody | None = None):
        model = integrator.model
        self.comm: MPI.Comm = model.comm
        self.constraints = constraints
        self.integrator = integrator
        self.method = method
        self.dt = self.h_avg = integrator.dt  # h_{n+1/2} and h_n (s)
        self.n = n = constraints.n
        if isinstance(constraints, SegmentConstraints):
            if rigid is not None:
                raise InputError("node-to-segment contact takes no rigid body")
            self._init_segments(constraints)
            return
        below = constraints.lower is None
        if (constraints.upper is None or below) != (rigid is not None):
            raise InputError("a rigid contact face needs exactly one rigid body, "
                             "and node pairs need none")
        self.rigid = rigid
        if rigid is not None and rigid.sideways:
            self._refuse_sideways(rigid, constraints, model)
            rigid.slides = True
        self.kind = RIGID_FACE if rigid is not None else PAIRS
        self.r = constraints.r
        dofs = (constraints.upper if below else constraints.lower if rigid else
                np.concatenate([constraints.lower, constraints.upper]))
        self.n_deformable = nd = dofs.size
        self.n_slots = ns = nd + (1 if rigid else 0)
        # the state, packed in a few arrays for the one compiled call of a step (fused.py);
        # the attributes below are views of their rows (layout: state.py)
        self._floats = np.zeros((19, ns))  # 12 slot rows, 6 constraint rows (n <= ns), 1 slot row
        self._ints = np.zeros((11, nd), dtype=np.int32)  # 3 constraint rows, 8 slot maps
        self._slots, self._cons = self._floats[:12], self._floats[12:JUMP_BOOK, :n]
        self.jump_book = self._floats[JUMP_BOOK]  # every slot's jumps booked: book_jumps_on
        self.jump_book[:] = 1.0
        self._flags = np.zeros((2, n), dtype=np.bool_)  # active, was_active
        self._misc = np.zeros(MISC_SIZE)
        (self.u, self.v, self.u_pred, self.v_pred, self.u_now, self.v_now, self.mass,
         self.f_prev, self.dt_over_m, self.m_over_dt, self.ku_prev, self.jump) = self._slots
        self.b, self.gap, self.force, self.d, self.d_inv, self.p = self._cons
        self.lo, self.up, self.work = self._ints[:3, :n]  # work: scratch for the methods' kernels
        self.active, self.was_active = self._flags
        self.b[:] = constraints.b
        self.lo[:] = nd if below else np.arange(n)
        self.up[:] = np.arange(n) if below else nd if rigid else np.arange(n, 2 * n)
        self.side = -1.0 if below else 1.0
        self.nodes = self.up if below else self.lo  # each constraint's node slot (rigid)
        self.body = nd if rigid else -1
        # which slots this rank owns, and where the gathered values go
        local, pos, all_pos, self._counts, self._displs = owned_slots(model, dofs, self.comm)
        ints = self._ints
        ints[LOCAL, :local.size], ints[POS, :local.size] = local, pos
        self._local, self._pos = ints[LOCAL, :local.size], ints[POS, :local.size]
        recv_u, recv_v = gathered_order(self._counts, self._displs)
        # per slot: where its predicted u and v are read (the Allgatherv buffer under MPI,
        # the owned arrays in serial) and the owned dof it is written back to (-1: another
        # rank's), for the fused rigid-face pass
        to = np.full(nd, -1, dtype=np.int32)
        to[pos] = local
        from_u, from_v = to.copy(), to.copy()
        if self.comm.size > 1:
            from_u[all_pos], from_v[all_pos] = recv_u, recv_v
        ints[RECV_U:TO + 1] = recv_u, recv_v, all_pos, from_u, from_v, to
        self._recv_u, self._recv_v, self._all_pos = ints[RECV_U:ALL_POS + 1]
        self._send = np.empty(2 * self._local.size)
        self._recv = np.empty(2 * nd)
        self._gather(integrator.mass, integrator.mass, self.mass, np.empty(ns))
        self._step_constants()
        self.times = PhaseTimes()
        # after each step: number of active constraints, total contact force (N) and the
        # smallest committed gap (m); a history row copies them from here
        self.stats = self._misc[STATS:STATS + 3]
        self.stats[:] = 0.0, 0.0, np.inf
        self._gap_out = np.empty(n)
        # the deformable slots' F^n (N): minus their sum is a prescribed part's reaction
        self._node_forces = self.f_prev[:nd]
        self._v_prescribed_prev = 0.0
        self.jumps = bool(getattr(method, "jumps", False))
        self._ledger = _ContactWork(self)
        method.setup(self)
        self._fused = self._fused_method()
        if self._fused is not None:
            code, p, e, mass_weighted = self._fused
            self.p[:] = p
            misc = self._misc
            misc[CODE], misc[DT], misc[KAPPA], misc[RESTITUTION] = code, self.dt, self.kappa, e
            misc[MASS_WEIGHTED], misc[JUMPS], misc[N_DEFORMABLE] = mass_weighted, self.jumps, nd
            misc[N_CONS], misc[N_LOCAL] = n, self._local.size
            if rigid is not None:
                misc[RIGID], misc[RIGID_MASS], misc[IMPEDANCE] = 1.0, rigid.mass, rigid.impedance
                misc[INCIDENT] = rigid.incident is not None
            misc[H_AVG] = self.h_avg
        # its arguments but the step's own (first, the rigid body's forces), fixed for the run
        self._fused_call = (None if self._fused is None else
                            (integrator.u_owned, integrator.v_owned,
                             self._recv if self.comm.size > 1 else np.empty(0), self._floats,
                             self._ints, self._flags, self._misc))
        self._gathered = self.comm.size > 1
        self.friction = None  # the tangential pass (set_friction); None: frictionless

    def _init_segments(self, c: SegmentConstraints) -> None:
        """The segment kind: slave node k has slots (2k, 2k+1) = (r, z), master node k
        (2(n_s + k), 2(n_s + k) + 1); constraint i is row i of G, six (slot ``cs[i]``,
        coefficient ``cc[i]``) entries: the slave's dofs with the normal n, the master
        nodes' with -N_a n and -N_b n. ``free`` is False on fixed dofs (never moved);
        ``band``/``bw``: S = h_{n+1/2} h_n G M^-1 G' (m/N) as a lower band, rebuilt in place
        by :meth:`set_step`. The force (N) pushes the slave along n and the master nodes
        along -n in proportion to N_a, N_b."""
        integ, n = self.integrator, self.n
        model = integ.model
        self.kind, self.rigid, self.r, self._fused = SEGMENTS, None, c.r, None
        dofs = c.dofs.astype(np.int64)
        self.n_slots = self.n_deformable = ns = dofs.size
        n_slave = c.slave_xy.shape[0]
        (self._local, self._pos, self._all_pos, self._counts,
         self._displs) = owned_slots(model, dofs, self.comm)
        self._recv_u, self._recv_v = gathered_order(self._counts, self._displs)
        self._send = np.empty(2 * self._local.size)
        self._recv = np.empty(2 * ns)
        (self.u, self.v, self.u_pred, self.v_pred, self.u_now, self.v_now, self.f_prev,
         self.ku_prev, self.jump) = np.zeros((9, ns))
        self.jump_book = np.ones(ns)  # every slot's jumps booked: book_jumps_on
        self.mass = np.empty(ns)
        self._gather(integ.mass, integ.mass, self.mass, np.empty(ns))
        self.m_over_dt = self.mass / self.h_avg  # m / h_n (kg/s): the booking's (state._book)
        free_owned = np.ones(model.n_owned)
        free_owned[integ.fixed] = 0.0
        free = np.empty(ns)
        self._gather(free_owned, free_owned, free, np.empty(ns))
        self.free = free > 0.5
        self.minv = np.where(self.free, 1.0 / self.mass, 0.0)
        s = np.arange(n)
        self.cs = np.stack([2 * s, 2 * s + 1, 2 * (n_slave + c.a), 2 * (n_slave + c.a) + 1,
                            2 * (n_slave + c.b), 2 * (n_slave + c.b) + 1], axis=1).astype(np.int64)
        na, nb = 1.0 - c.xi, c.xi
        nr, nz = c.normal[:, 0], c.normal[:, 1]
        self.cc = np.stack([nr, nz, -na * nr, -na * nz, -nb * nr, -nb * nz], axis=1)
        self.g0 = c.g0.copy()
        self.bw = bandwidth(self.cs, self.cc, self.minv)
        self.band = np.empty((n, self.bw + 1))
        band_of_s_steps(self.cs, self.cc, self.minv, self.dt, self.h_avg, self.bw, self.band)
        self.has_row = np.ones(n, dtype=np.bool_)  # which slaves have a row (_repair)
        if np.any(self.band[:, 0] <= 0.0):
            k = int(np.flatnonzero(self.band[:, 0] <= 0.0)[0])
            raise InputError(f"contact: the constraint of '{c.names[0]}' node at "
                             f"(r={c.slave_xy[k, 0]:.6g}, z={c.slave_xy[k, 1]:.6g}) moves no "
                             "free dof")
        self.gap, self.force, self._gap_out = np.empty(n), np.zeros(n), np.empty(n)
        self.active, self.was_active = np.zeros((2, n), dtype=np.bool_)
        self.times = PhaseTimes()
        self._misc = np.zeros(MISC_SIZE)
        self.stats = self._misc[STATS:STATS + 3]
        self.stats[:] = 0.0, 0.0, np.inf
        self.jumps = bool(getattr(self.method, "jumps", False))
        self._ledger = _ContactWork(self)
        self.repair_every = 0  # re-pairing off (set_repairing): the set-up's pairs
        self.friction = None  # the tangential pass (set_friction); None: frictionless
        self.method.setup(self)

    def set_friction(self, friction, tangential_penalty: float | str = "scaled",
                     force: bool = False) -> None:
        """Coulomb friction on this set (docs/friction.md): ``friction`` a coefficient
        μ >= 0, ``"stick"``, a table {static, dynamic, decay} or a
        :class:`.friction.FrictionLaw`. μ = 0 makes nothing: the set's step stays the
        frictionless one. Built for FILM, DME and the penalty (its tangential spring
        ``tangential_penalty``: N/m, or ``"scaled"``, beta_t = 1 per row; one whose
        beta_t passes 4/3 is refused unless ``force``) on node pairs, a flat rigid or
        fixed face (the wall) and node to segment (re-paired too, :meth:`set_repairing`, in
        either order; the penalty's normal bound at most 1 where rows couple or re-pair);
        refused in one line elsewhere. Call before the run."""
        from .friction import (DME_T, FILM_T, PENALTY_T, STABILITY_BOUND, Tangential,
                               friction_law)

        law = friction_law(friction)
        if law.is_zero:
            self.friction = None
            return
        what = f"friction = {law.text()}"
        if self.method.name == "tie":
            raise InputError(f"{what} on the tie '{self.constraints.names[0]}'/"
                             f"'{self.constraints.names[1]}': a bonded face does not slide "
                             "(a tie takes no friction)")
        if isinstance(tangential_penalty, str):
            if tangential_penalty != "scaled":
                raise InputError(f"tangential_penalty = '{tangential_penalty}': give a "
                                 "stiffness in N/m or 'scaled'")
        elif not (isinstance(tangential_penalty, (int, float)) and tangential_penalty > 0):
            raise InputError(f"tangential_penalty = {tangential_penalty!r} N/m: must be > 0")
        if self.kind == SEGMENTS:
            from .friction_segments import SegmentTangential

            if not isinstance(self.method, (FILM, DME, Penalty)):
                raise InputError(f"{what}: friction needs method film, dme or penalty")
            spring = tangential_penalty if isinstance(self.method, Penalty) else None
            tangential = SegmentTangential(self, law, what, spring, force)
            if self.repair_every:  # the pass follows each re-pairing (the penalty: its spring)
                tangential.start_repairing(what)
            tangential.initialize()  # its kernels loaded now: the set was initialized
            self.friction = tangential
            problem = tangential.bound_problem()  # the penalty's (docs/friction.md 4.2)
            if problem:
                raise InputError(problem)
            return
        if isinstance(self.method, Penalty):
            kernel = PENALTY_T
        elif isinstance(self.method, FILM):
            kernel = FILM_T
        elif isinstance(self.method, DME):
            kernel = DME_T
        else:
            raise InputError(f"{what}: friction needs method film, dme or penalty")
        if self.rigid is not None and not self.rigid.fixed and profiled(self.constraints):
            raise InputError(f"{what}: a button (a rigid face with a profile) with friction is "
                             "not built: its tangent is tilted, which the rigid kind does not "
                             "have")
        tangential = Tangential(self, law, kernel, tangential_penalty, force)
        rigid = self.rigid
        if rigid is not None and not rigid.fixed:
            if tangential.slides:  # its x dof is coupled by the pass (docs/friction.md 11)
                rigid.slides = True
                tangential.initialize()
            elif rigid.sideways:
                raise InputError(f"rigid body '{rigid.name}' with {what}: a sideways velocity "
                                 "or force is refused: a node of its face is held in x (a "
                                 "symmetry plane holds the part)")
        if kernel == PENALTY_T and tangential.beta_max > STABILITY_BOUND and not force:
            raise InputError(f"tangential_penalty = {tangential_penalty!r} N/m: beta_t = "
                             f"{tangential.beta_max:.3g} passes the stable bound 4/3 (k_t h "
                             "h_n (1/m_lo + 1/m_up), + n/M on a sliding part); lower it, "
                             "use 'scaled' or force")
        self.friction = tangential
        if self._fused is not None:  # the step's one call runs the pass too (fused.py)
            from ..jit_watch import direct

            self._friction_call = self._fused_call + tangential.fused_args
            self._contact_friction_step = direct(fused.contact_step_friction,
                                                 *self._friction_call, 0.0, 0.0)

    def set_repairing(self, every: int, reach: float | None = None,
                      end_tol: float = END_TOLERANCE) -> None:
        """Re-pair the slaves with the segments they face every ``every`` steps (0: never,
        the set-up's pairs for the whole run), in the configuration X + u^n at the start
        of the step, within ``reach`` (m; :func:`.segments.repair_reach` unless given),
        the master face continued past its ends by ``end_tol`` of the end segment
        (:class:`.segments.Repairing`). Call before the run. The segment kind only.

        Each re-pairing (:meth:`_repair`) rewrites the rows of G, their gaps' constants
        and the band of S in place; a slave beyond an end of the master face (or out of
        reach) has no row until it comes back (:func:`.segments.rows_of_pairs`). The
        band's storage grows only when a re-pairing widens it past every earlier one.
        A penalty keeps the p chosen at set-up, there bounded over every row a
        re-pairing can make (:meth:`.penalty.Penalty.setup`); its ``beta_max`` is the
        largest Gershgorin bound of the rows the run used."""
        if self.method.name == "tie":
            raise InputError("a tie does not re-pair: its nodes are bonded to the part")
        if self.kind != SEGMENTS:
            raise InputError("re-pairing is for node-to-segment contact")
        if self.friction is not None and int(every):  # refused: e > 0
            self.friction.refuse_repairing(f"friction = {self.friction.law.text()}")
        every = int(every)
        if every < 0:
            raise InputError(f"contact: repair_every = {every} must be >= 0 (0: never)")
        if every and getattr(getattr(self.method, "pivoting", None), "solver", "") == "dense":
            raise InputError("contact: re-pairing needs the band solver (film solver = "
                             "'fast'): the dense one keeps S as it was at set-up")
        self.repair_every = every
        if not every:
            return
        self.has_row[:] = True
        c = self.constraints
        n_slave = c.slave_xy.shape[0]
        self._repairing = Repairing(c, repair_reach(c) if reach is None else reach, end_tol)
        self._slave_x = np.empty((n_slave, 2))
        self._master_x = np.empty((c.master_xy.shape[0], 2))
        self._first_row = np.empty(self.n_slots, np.int64)  # bandwidth_of's scratch
        self.repairs = 0  # re-pairings made
        self.method.setup(self)  # a penalty's p, bounded over every row (the flag is set)
        self._load_repair_kernels()
        if self.friction is not None:  # the tangential pass follows each re-pairing
            self.friction.start_repairing(f"friction = {self.friction.law.text()}")

    def _repair(self) -> None:
        """Re-pair at X + u^n and rebuild G, g0 and S's band (see :meth:`set_repairing`).

        u^n is the set's committed state ``u_now``: every rank's commit writes the owners'
        copies of the contact dofs from the same gathered data, so ``u_now`` equals the
        owners' u^n bit for bit on every rank; X is the set-up's, each node from its
        owner's copy (:func:`.segments.owned_coordinates`). No message and no allocation
        but a wider band's."""
        c, n_slave = self.constraints, self.constraints.slave_xy.shape[0]
        current_positions(c.slave_xy, self.u_now, 0, self._slave_x)
        current_positions(c.master_xy, self.u_now, n_slave, self._master_x)
        p = self._repairing(self._slave_x, self._master_x)
        rows_of_pairs(p.active, p.a, p.b, p.xi, p.normal, p.gap, p.dist, self._repairing.reach,
                      n_slave, self.u_now, self.cs, self.cc, self.g0)
        self.has_row = p.active
        bw = bandwidth_of(self.cs, self.cc, self.minv, self._first_row)
        if bw + 1 > self.band.shape[1]:
            self.band = np.empty((self.n, bw + 1))
        self.bw = bw
        band_of_s_steps(self.cs, self.cc, self.minv, self.dt, self.h_avg, bw, self.band)
        rebanded = getattr(self.method, "rebanded", None)  # a user's method: none
        if rebanded is not None:
            rebanded(self)
        if self.friction is not None:  # T's rows, A's band, the coupling: rebuilt in place
            self.friction.repaired()
        self.repairs += 1

    def _load_repair_kernels(self) -> None:
        """Load the re-pairing's compiled calls by their argument types (none runs)."""
        from ..jit_watch import load

        c, n_slave = self.constraints, self.constraints.slave_xy.shape[0]
        p, r = self._repairing.pairs, self._repairing
        r(c.slave_xy, c.master_xy)  # the search's kernels, by one call (its pairs are scratch)
        load(current_positions, c.slave_xy, self.u_now, 0, self._slave_x)
        load(rows_of_pairs, p.active, p.a, p.b, p.xi, p.normal, p.gap, p.dist, r.reach, n_slave,
             self.u_now, self.cs, self.cc, self.g0)
        load(bandwidth_of, self.cs, self.cc, self.minv, self._first_row)
        load(band_of_s_steps, self.cs, self.cc, self.minv, self.dt, self.h_avg, self.bw,
             self.band)
        method_calls = getattr(self.method, "kernel_calls", None)  # its own, re-pairing's too
        for fn, args in (method_calls(self) if method_calls else []):
            load(fn, *args)

    # ------------------------------------------------------------ the step's constants
    def _step_constants(self) -> None:
        """h_n / m, m / h_n (0 at a fixed part's slot), kappa = h_{n+1/2} h_n / m_rigid and
        the diagonal d_i = h_{n+1/2} h_n (1/m_lo + 1/m_up) of S (the rigid slot's share
        is kappa), with h_{n+1/2} = ``self.dt``, h_n = ``self.h_avg``; under a constant
        step the expressions of a constant step (dt^2)."""
        h, h_avg = self.dt, self.h_avg
        hh = h ** 2 if h == h_avg else h * h_avg
        rigid, nd = self.rigid, self.n_deformable
        if rigid is not None:
            self.mass[nd] = self._rigid_slot_mass()
        self.dt_over_m[:] = h_avg / self.mass
        self.m_over_dt[:] = self.mass / h_avg
        if rigid is not None and rigid.fixed:
            self.m_over_dt[nd] = 0.0  # it does not move: its reaction does no work
        self.kappa = 0.0 if rigid is None else hh / self.mass[nd]
        up = 0.0 if rigid else 1.0 / self.mass[self.up]
        self.d[:] = hh * (1.0 / self.mass[self.nodes] + up)
        self.d_inv[:] = 1.0 / self.d

    def book_no_jumps(self) -> None:
        """Book no work of the position jumps (DME's): the run books every body's work by
        the kinetic identity (a finite-strain body, a linear body's per-step pass under a
        varying step), which no jump enters; the contact's share is then its slots'
        1/2 h_n (v^{n-1/2} + v^{n+1/2}) . F^n alone (one_loop.md 4.7)."""
        self.jumps = False
        self._misc[JUMPS] = 0.0

    def book_jumps_on(self, owned: np.ndarray, shared: np.ndarray | None = None
                      ) -> tuple[np.ndarray, np.ndarray]:
        """Book the work of the position jumps on the slots whose dof ``owned`` (a flag per
        owned dof of this rank) marks as a body's whose stored energy is booked from its
        positions (a small-strain path-dependent body's trapezoid; a linear body's
        telescoped energy under a constant step), and on no other: a finite-strain body's
        work, and a linear body's per-step pass, are their kinetic shares, which no jump
        enters (one_loop.md 4.7). Every slot booked: as before; none: :meth:`book_no_jumps`.
        ``shared`` (a flag per owned dof, or None) marks the flagged dofs that such a body
        shares with a body of the other kind (a bonded node): their jumps are due on the
        first body's share of the force only, so this set's commit books none of them and
        the caller books them (:func:`.state.shared_jump_work`) from the slots' jumps, which
        the set still records. Returns this rank's shared slots: (their positions in the
        slot arrays, their owned dofs), empty when none. Collective (each rank knows the
        flags of the slots it owns)."""
        none = (np.zeros(0, dtype=np.int32), np.zeros(0, dtype=np.int32))
        if not self.jumps:
            return none
        mine = np.zeros(self.n_slots)
        mine[self._pos] = owned[self._local]
        split = none
        if shared is not None:
            here = shared[self._local] != 0.0
            mine[self._pos[here]] = 0.0
            split = (self._pos[here].astype(np.int32), self._local[here].astype(np.int32))
        self.comm.Allreduce(mine, self.jump_book, op=MPI.MAX)
        if self.rigid is not None:
            self.jump_book[-1] = 0.0  # the part's slot: not deformable, never read
        any_shared = self.comm.allreduce(int(split[0].size), op=MPI.SUM) > 0
        if not self.jump_book[:self.n_deformable].any() and not any_shared:
            self.book_no_jumps()
        return split

    def set_step(self, h: float, h_avg: float) -> None:
        """Steps h_{n+1/2} (positions) and h_n (velocities) of the next step (s): rewrite
        every constant that holds them (h_n / m, m / h_n, S's diagonal and kappa or its
        band, a penalty chosen from S), in place. Nothing changes when they are the set's."""
        if h == self.dt and h_avg == self.h_avg:
            return
        self.dt, self.h_avg = float(h), float(h_avg)
        if self.kind == SEGMENTS:
            self._segment_step()
            return
        self._step_constants()
        self.method.setup(self)
        if self.friction is not None:
            self.friction.set_step()
        if self._fused is not None:
            if type(self.method) is Penalty:
                self.p[:] = self.method.p
            misc = self._misc
            misc[DT], misc[H_AVG], misc[KAPPA] = self.dt, self.h_avg, self.kappa
            if self.rigid is not None:
                misc[RIGID_MASS] = self.rigid.mass

    def _segment_step(self) -> None:
        """The segment kind at new steps (docs/node_to_segment.md, "A varying step"): m / h_n
        and S = h_{n+1/2} h_n G M^-1 G' rewritten in place (its storage as it is), the method
        told (``rebanded``: the pivoting's kept factor dropped, a penalty's p rescaled), the
        tangential pass's constants too. Nothing is allocated (the dense comparison solver
        aside)."""
        np.divide(self.mass, self.h_avg, out=self.m_over_dt)
        band_of_s_steps(self.cs, self.cc, self.minv, self.dt, self.h_avg, self.bw, self.band)
        rebanded = getattr(self.method, "rebanded", None)  # a user's method: none
        if rebanded is not None:
            rebanded(self)
        if self.friction is not None:
            self.friction.set_step()

    def penalty_beta(self) -> float:
        """beta_max = lambda_max(P^1/2 S P^1/2) (-) of a penalty set at the current steps
        (0 for another method)."""
        if self.method.name != "penalty" or self.n == 0:
            return 0.0
        if self.kind == SEGMENTS:
            return float(self.method.info["beta_max"])  # Gershgorin's bound on the band
        p = np.asarray(self.method.p, dtype=float)
        return lambda_max_diag_plus_rank_one(p * self.d, self.kappa, np.sqrt(p))

    def kinetic_share(self, f_int: np.ndarray) -> tuple:
        """The contact's share of the half-step scheme's kinetic identity on this rank's
        owned slots after a step, with the internal force ``f_int`` (N, owned dofs) of
        the step: (energy taken (J), internal-work correction (J), number active, force
        (N), springs' energy (J)); see state.kinetic_share. A rigid face's set."""
        return kinetic_share(self._local, self._pos, f_int, self.h_avg, self.mass, self.u_pred,
                             self.v_pred, self.v_now, self.b, self.lo, self.up, self.p,
                             self.active)

    # ------------------------------------------------------------ gather
    def _gather(self, src_u: np.ndarray, src_v: np.ndarray, u_out: np.ndarray,
                v_out: np.ndarray) -> None:
        """src_u, src_v (owned arrays) on the contact dofs, into slot order on every rank."""
        if self.comm.size == 1:
            _take(src_u, src_v, self._local, self._pos, u_out, v_out)
            return
        _pack(src_u, src_v, self._local, self._send)
        self.comm.Allgatherv(self._send, [self._recv, self._counts, self._displs, MPI.DOUBLE])
        _unpack(self._recv, self._recv_u, self._recv_v, self._all_pos, u_out, v_out)

    def initialize(self) -> None:
        """Read u^0 and v^0 of the contact dofs (call after the integrator's set_initial)."""
        integ = self.integrator
        start = getattr(self.method, "start", None)  # a tie: its nodes at the part's v^0
        if start is not None:
            start(self)
        self._gather(integ.u_owned, integ.v_owned, self.u_now, self.v_now)
        if self.kind == SEGMENTS:
            self._load_segment_kernels()
            if self.friction is not None:
                self.friction.initialize()
            return
        if self.rigid is not None:
            r = self.rigid
            self.u_now[-1], self.v_now[-1] = r.u, r.v
            self._misc[WAVES:WAVES + 3] = r.wave_incident, r.wave_reflected, r.wave_delivered
        self._load_kernels()
        if self.friction is not None:
            self.friction.initialize()

    def _fused_method(self):
        """(code, penalty stiffnesses (N/m), restitution, mass-weighted positions) of a
        method that the one compiled call runs (fused.contact_step), or None: a method of
        another type (FILM dense, a user's) runs its own correct() between detection and
        commit."""
        self._contact_step = fused.contact_step
        m = self.method
        if type(m) is Penalty:
            return fused.PENALTY, m.p, 0.0, False
        if type(m) is FILM and m.solver == "fast":
            return fused.FILM_FAST, 0.0, 0.0, False
        if type(m) is DME:
            return ((fused.DME_CLUSTER if self.rigid is not None else fused.DME_PAIRS), 0.0,
                    m.e, m.positions == "mass_weighted")
        return None

    def _load_kernels(self) -> None:
        """Load (or compile) every compiled call of a step now, at set-up, so that none
        compiles inside the first timed step: by their argument types the fused step
        (or detection and commit), and a method outside it by one call on open gaps (no
        force: it changes nothing that the next detection does not overwrite)."""
        from ..jit_watch import direct, load

        integ = self.integrator
        load(_pack, integ.u_owned, integ.v_owned, self._local, self._send)
        load(_committed_gap, self.b, self.u_now, self.lo, self.up, self._gap_out)
        if self._fused is not None:
            # the step calls the compiled entry point itself (the arguments' types are
            # fixed for the run)
            self._contact_step = direct(fused.contact_step, *self._fused_call, 0.0, 0.0)
            return
        slots = (self.u_pred, self.v_pred, self.u, self.v, self.b, self.lo, self.up, self.gap,
                 self.active, self.was_active)
        load(_detect_local, integ.u_owned, integ.v_owned, self._local, self._pos, *slots)
        load(_detect_gathered, self._recv, self._recv_u, self._recv_v, self._all_pos, *slots)
        w = self._ledger
        load(_commit, self._local, self._pos, integ.u_owned, integ.v_owned, self.dt,
             self.h_avg, self.n_deformable, self.m_over_dt, self.u, self.v, self.u_pred,
             self.v_pred, self.u_now, self.v_now, self.f_prev, self.ku_prev, self.jump,
             self.jump_book, self.jumps, w.jumped, self.active, self.was_active, self.b,
             self.lo, self.up, self.force, self.stats)
        self.u[:], self.v[:] = self.u_now, self.v_now
        self.gap[:] = 1.0  # open: no constraint is active
        self.method.correct(self)
        self.force[:] = 0.0
        self.active[:] = False

    def _load_segment_kernels(self) -> None:
        """The segment kind's compiled calls of a step (detection, the method's kernels,
        write-back, booking), loaded by their argument types without running them."""
        from ..jit_watch import load

        integ = self.integrator
        calls = [(_detect_segments, (self.u_pred, self.v_pred, self.u, self.v, self.g0, self.cs,
                                     self.cc, self.gap, self.active, self.was_active)),
                 (_commit_segments, (self._local, self._pos, integ.u_owned, integ.v_owned,
                                     self.dt, self.h_avg, self.m_over_dt, self.u, self.v,
                                     self.v_pred, self.u_now, self.v_now, self.f_prev,
                                     self.ku_prev, self.jump, self.jump_book, self.jumps,
                                     False, self.active,
                                     self.was_active,
                                     self.g0, self.cs, self.cc, self._gap_out))]
        if self.comm.size == 1:
            calls.append((_take, (integ.u_owned, integ.v_owned, self._local, self._pos,
                                  self.u_pred, self.v_pred)))
        else:
            calls += [(_pack, (integ.u_owned, integ.v_owned, self._local, self._send)),
                      (_unpack, (self._recv, self._recv_u, self._recv_v, self._all_pos,
                                 self.u_pred, self.v_pred))]
        method_calls = getattr(self.method, "kernel_calls", None)  # a user's method: none
        for fn, args in calls + (method_calls(self) if method_calls else []):
            load(fn, *args)

    def use_separate_calls(self) -> None:
        """Run the step as detection, the method's correct() and the commit (three compiled
        calls) with the rigid body's prediction and commit in Python, as before the fused
        call: the reference it equals bit for bit, for tests and the benchmark. Call
        before the run."""
        self._fused = None
        self._load_kernels()

    # ------------------------------------------------------------ for methods
    def s_diagonal(self) -> np.ndarray:
        """Diagonal part d of S = h_{n+1/2} h_n G M^-1 G' = diag(d) + kappa 1 1' (m/N); of
        a banded S (segments) its diagonal."""
        return self.band[:, 0] if self.kind == SEGMENTS else self.d

    def apply_forces(self, force: np.ndarray) -> None:
        """Apply compressive contact forces (N) to the predicted state."""
        if self.kind == SEGMENTS:
            apply_multipliers(force, self.cs, self.cc, self.mass, self.free, self.h_avg,
                              self.u, self.v, self.dt)
            return
        apply_forces(force, self.lo, self.up, self.dt_over_m, self.dt, self.u, self.v)

    # ------------------------------------------------------------ the step
    def step(self) -> None:
        """Detect, solve and update for the step n -> n+1 (after the integrator's predict).

        Penalty, FILM fast and DME: one compiled call (fused.contact_step: the rigid
        body's prediction, take the predicted contact dofs, form the gaps, correct,
        write back, book, commit the rigid body), under MPI after a compiled pack and
        the Allgatherv. Its time is booked as ``solve``; ``detection`` holds the Python
        before it (the rigid body's external force at t^n, the Allgatherv) and ``update``
        the copy of the rigid body's state after it. Another method, and every method on
        segments: detection, the method's correct() and the commit as three calls, timed
        as such."""
        if self.kind == SEGMENTS:
            self._step_segments()
            return
        prescribed = self.rigid is not None and self.rigid.prescribed is not None
        if prescribed:
            self._drive_prescribed(self.integrator.t)
        if self._fused is None:
            self._step_unfused()
        else:
            self._step_fused()
        if prescribed:
            self._book_prescribed()

    def _step_fused(self) -> None:
        """The step of penalty, FILM fast and DME as one compiled call (:meth:`step`)."""
        integ = self.integrator
        clock = time.perf_counter
        t0 = clock()
        rigid = self.rigid
        f_ext = f_in = 0.0
        if rigid is not None:  # the only Python of the body: its force functions at t^n
            f_ext = float(rigid.force(integ.t))
            if rigid.incident is not None:
                f_in = float(rigid.incident(integ.t))
        tangential = self.friction
        folded = tangential is not None and tangential.folds
        slides = rigid is not None and rigid.slides
        if slides:
            self._slide_before(integ.t)
        if self._gathered:
            _pack(integ.u_owned, integ.v_owned, self._local, self._send)
            self.comm.Allgatherv(self._send, [self._recv, self._counts, self._displs, MPI.DOUBLE])
            if folded:
                tangential.exchange()
        t1 = clock()
        if folded:  # the normal step and the tangential pass in one call
            u_r, v_r, far = self._contact_friction_step(*self._friction_call, f_ext, f_in)
            tangential.check_slip(far)
            tangential = None
        else:
            u_r, v_r = self._contact_step(*self._fused_call, f_ext, f_in)
        t2 = clock()
        if rigid is not None:
            rigid.u, rigid.v = u_r, v_r
            if rigid.impedance > 0.0:
                misc = self._misc
                rigid.wave_incident, rigid.wave_reflected, rigid.wave_delivered = (
                    float(misc[WAVES]), float(misc[WAVES + 1]), float(misc[WAVES + 2]))
        if tangential is not None:  # the tangential pass as a call of its own
            self._misc[LEDGER] += tangential.step()
        if slides:
            self._slide_after(integ.t)
        t3 = clock()
        times = self.times
        times.detection, times.solve, times.update = t1 - t0, t2 - t1, t3 - t2

    def _step_unfused(self) -> None:
        """The step of a method outside the fused call: detection, correct(), commit."""
        integ = self.integrator
        clock = time.perf_counter
        t0 = clock()
        slides = self.rigid is not None and self.rigid.slides
        if self.rigid is not None:
            self._predict_rigid(integ.t)
            if slides:
                self._slide_before(integ.t)
        if self.comm.size == 1:
            _detect_local(integ.u_owned, integ.v_owned, self._local, self._pos, self.u_pred,
                          self.v_pred, self.u, self.v, self.b, self.lo, self.up, self.gap,
                          self.active, self.was_active)
        else:
            _pack(integ.u_owned, integ.v_owned, self._local, self._send)
            self.comm.Allgatherv(self._send, [self._recv, self._counts, self._displs, MPI.DOUBLE])
            _detect_gathered(self._recv, self._recv_u, self._recv_v, self._all_pos, self.u_pred,
                             self.v_pred, self.u, self.v, self.b, self.lo, self.up, self.gap,
                             self.active, self.was_active)
        t1 = clock()
        self.method.correct(self)
        t2 = clock()
        if self.rigid is not None:  # commit the rigid body first: the booking needs its F^n
            v_n = self.rigid.v
            rigid_f = self.rigid.advance(integ.t, self.h_avg, self.u[-1], self.v[-1])
            self._ledger.book_rigid(v_n, self.rigid.v, rigid_f)
        self._ledger.book(integ.n)
        if self.friction is not None:
            self._misc[LEDGER] += self.friction.step()
        if slides:
            self._slide_after(integ.t)
        t3 = clock()
        times = self.times
        times.detection, times.solve, times.update = t1 - t0, t2 - t1, t3 - t2

    def _step_segments(self) -> None:
        """The segment kind's step: gather, the predicted gaps g0 + G u~, correct(), write
        back and book."""
        integ = self.integrator
        clock = time.perf_counter
        t0 = clock()
        if self.repair_every and integ.n % self.repair_every == 0:
            self._repair()
        self._gather(integ.u_owned, integ.v_owned, self.u_pred, self.v_pred)
        _detect_segments(self.u_pred, self.v_pred, self.u, self.v, self.g0, self.cs, self.cc,
                         self.gap, self.active, self.was_active)
        t1 = clock()
        self.method.correct(self)
        # the tangential pass last (docs/friction.md 2), booked apart from the normal share
        w_t = None if self.friction is None else self.friction.step()
        t2 = clock()
        if w_t is None:
            self._ledger.book_segments(integ.n)
        else:
            self._ledger.book_segments(integ.n, w_t)
        t3 = clock()
        times = self.times
        times.detection, times.solve, times.update = t1 - t0, t2 - t1, t3 - t2

    # ------------------------------------------------------------ the rigid body
    @staticmethod
    def _refuse_sideways(rigid: RigidBody, constraints, model) -> None:
        """A sideways (x) velocity or force needs a plane-strain model and a flat face
        (docs/friction.md 11); refused in one line elsewhere."""
        if not model.geometry.plane:
            raise InputError(f"rigid body '{rigid.name}': a sideways velocity or force is "
                             "refused in an axisymmetric model (the axis: a body of "
                             "revolution moves along z only)")
        if profiled(constraints):
            raise InputError(f"rigid body '{rigid.name}': a button (a face with a profile) "
                             "cannot move sideways (its profile would move along x)")

    def _advance_rigid_x(self, t: float) -> None:
        """A sliding part's x dof over a step without a tangential pass on it:
        V^{n+1/2} = V~, U^{n+1} = U~, and the work of f_x by the kinetic identity,
        1/2 h_n (V^{n-1/2} + V^{n+1/2}) f_x(t^n), into the part's external work (J)."""
        rigid = self.rigid
        v_old = rigid.v_x
        rigid.u_x, rigid.v_x = rigid.predict_x(t, self.dt, self.h_avg)
        self._book_rigid_x(t, v_old)

    def _book_rigid_x(self, t: float, v_old: float) -> None:
        """The work of the part's x force f_x(t^n) in the step that took its V from
        ``v_old`` to the present one (kinetic identity, J)."""
        rigid = self.rigid
        if rigid.force_x is not None:
            self._misc[RIGID_WORK] += (0.5 * self.h_avg * (v_old + rigid.v_x)
                                       * float(rigid.force_x(t)))

    def _slide_before(self, t: float) -> None:
        """Before the step: a sliding part's x prediction into the tangential pass's slot."""
        if self.friction is not None and self.friction.slides:
            self.friction.predict_rigid(t)

    def _slide_after(self, t: float) -> None:
        """After the step: a sliding part's x dof from the tangential pass's slot, or
        advanced on its own without one."""
        rigid = self.rigid
        if self.friction is not None and self.friction.slides:
            v_old = rigid.v_x
            self.friction.commit_rigid()
            self._book_rigid_x(t, v_old)
        else:
            self._advance_rigid_x(t)

    def _drive_prescribed(self, t: float) -> None:
        """A prescribed part before step n: keep v^{n-1/2}, set v^{n+1/2} the mean of v(t)
        over [t^n, t^n + h_{n+1/2}] (PrescribedVelocity.mean) in the body and its committed
        slot, from which both step paths predict it as a fixed part's, u~ = u^n + h v."""
        rigid = self.rigid
        self._v_prescribed_prev = rigid.v
        rigid.v = self.v_now[-1] = rigid.prescribed.mean(t, self.dt)

    def _book_prescribed(self) -> None:
        """A prescribed part after step n: its reaction R^n = -sum of the nodes' contact
        forces F_k^n = (m_k / h_n)(v_k^{n+1/2} - v~_k^{n+1/2}) (N, z; the force on it by
        Newton's third law), the body's share B^n = 1/2 h_n (v^{n-1/2} + v^{n+1/2}) R^n of
        the contact work into the set's work, and -B^n, the work of the motion that holds
        it, into its external work (J; docs/friction.md 12)."""
        rigid = self.rigid
        reaction = -float(self._node_forces.sum())
        rigid.reaction = reaction
        share = 0.5 * self.h_avg * (self._v_prescribed_prev + rigid.v) * reaction
        misc = self._misc
        misc[LEDGER] += share
        misc[RIGID_WORK] -= share

    # The two places that know how a rigid body moves on its own: its slot mass and
    # its prediction without contact. Everything else treats it as one more slot.
    def _rigid_slot_mass(self) -> float:
        """Mass (kg) of the rigid body's slot: its mass plus the added mass Z h_n/2 of a
        driving rod (RigidBody.effective_mass); inf for a fixed part."""
        return self.rigid.effective_mass(self.h_avg)

    def _predict_rigid(self, t: float) -> None:
        """The rigid body's slot: its predicted state (u~, v~) at t + dt without contact,
        from its external force (and its rod's incident wave) at t (RigidBody.predict)."""
        self.u_pred[-1], self.v_pred[-1] = self.rigid.predict(t, self.dt, self.h_avg)

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

    @property
    def moving_rigid(self) -> RigidBody | None:
        """The set's rigid part if it moves (its kinetic energy, momentum and work are the
        run's; a prescribed part's work alone), None without one or for a fixed part (a
        wall: it never moves)."""
        return (self.rigid if self.rigid is not None
                and (not self.rigid.fixed or self.rigid.prescribed is not None) else None)

    def kinetic_energy_rigid(self, v_next: float) -> float:
        """1/2 m_p (v^{n+1/2})^2 (J) of the rigid body, and 1/2 m_p V_x^2 of its present x
        velocity where it slides (docs/friction.md 11)."""
        if self.rigid is None:
            return 0.0
        rigid = self.rigid
        if rigid.prescribed is not None:  # infinite mass: its motion is the work it is given
            return 0.0
        if rigid.slides:
            return 0.5 * rigid.mass * (v_next * v_next + rigid.v_x * rigid.v_x)
        return 0.5 * rigid.mass * v_next * v_next

    def committed_gap(self) -> np.ndarray:
        """Gap (m) of the committed state, in global constraint order (a reused buffer)."""
        if self.kind == SEGMENTS:
            return gap_of(self.g0, self.cs, self.cc, self.u_now, self._gap_out)
        _committed_gap(self.b, self.u_now, self.lo, self.up, self._gap_out)
        return self._gap_out

    @property
    def any_active(self) -> bool:
        """Is any constraint active after the last step?"""
        return self.stats[0] > 0

    @property
    def min_gap(self) -> float:
        """The smallest committed gap (m) after the last step."""
        return float(self.stats[2])


class _ContactWork:
    """Work of the contact forces by the kinetic identity (impact_fenics.energy).

    The contact force on a slot is its momentum change over the step,
    F^n = m (v^{n+1/2} - v~^{n+1/2}) / dt; step n adds 1/2 dt (v^{n-1/2} + v^{n+1/2}) . F^n.
    A position set apart from u^n + dt v^{n+1} (a jump j, DME) adds
    1/2 j . K (u^n + u^{n+1}) one step later, when K u^{n+1} on the contact dofs
    is known from the free prediction: K u^n = -m (v~^{n+1} - v^n) / dt there.
    Its arrays are rows of the set's packed state, which the fused call
    (fused.contact_step) books the same way as :meth:`book` and :meth:`book_rigid`.
    """

    def __init__(self, c: ContactSet):
        self.c = c
        self._state = c._misc[LEDGER:LEDGER + 4]  # work, activation loss, jumped, grew (0/1)
        self._misc = c._misc

    @property
    def work(self) -> float:
        return float(self._state[0])

    @property
    def activation_loss(self) -> float:
        return float(self._state[1])

    @property
    def jumped(self) -> bool:
        return bool(self._state[2])

    @property
    def rigid_external_work(self) -> float:
        return float(self._misc[RIGID_WORK])

    def book_rigid(self, v_n: float, v_next: float, f: float) -> None:
        """Work (J) of the external force F^n on the rigid body in step n by the kinetic
        identity, 1/2 h_n (v^{n-1/2} + v^{n+1/2}) F^n (``v_n``, ``v_next``)."""
        misc = self._misc
        misc[RIGID_WORK] += 0.5 * self.c.h_avg * (v_n + v_next) * f
        misc[RIGID_F_PREV] = f

    def book(self, n_step: int) -> None:
        c = self.c
        integ = c.integrator
        self.add(*_commit(
            c._local, c._pos, integ.u_owned, integ.v_owned,
            c.dt, c.h_avg, c.n_deformable, c.m_over_dt, c.u, c.v, c.u_pred, c.v_pred,
            c.u_now, c.v_now, c.f_prev, c.ku_prev, c.jump, c.jump_book, c.jumps, self.jumped,
            c.active,
            c.was_active, c.b, c.lo, c.up, c.force, c.stats))

    def add(self, inc: float, jumped: bool, grew: bool) -> None:
        """Step n's increment ``inc`` (J) into the work, and into the activation loss when
        the active set grew in this step or the one before; whether it ``jumped``."""
        state = self._state
        state[0] += inc
        if grew or state[3]:
            state[1] -= inc
        state[2] = 1.0 if jumped else 0.0
        state[3] = 1.0 if grew else 0.0

    def book_segments(self, n_step: int, w_t: float = 0.0) -> None:
        """The segment kind's commit: write the owned dofs back, book step n as
        :meth:`book` does (the one booking, state._book) and the history's stats;
        ``w_t`` (J) the tangential work held in the increment, which goes to the work
        but not to the activation loss (docs/friction.md 5)."""
        c = self.c
        integ = c.integrator
        inc, jumped, grew, min_gap = _commit_segments(
            c._local, c._pos, integ.u_owned, integ.v_owned, c.dt, c.h_avg, c.m_over_dt, c.u,
            c.v, c.v_pred, c.u_now, c.v_now, c.f_prev, c.ku_prev, c.jump, c.jump_book, c.jumps,
            self.jumped,
            c.active, c.was_active, c.g0, c.cs, c.cc, c._gap_out)
        self.add(inc - w_t, jumped, grew)
        self._state[0] += w_t
        c.stats[0], c.stats[1], c.stats[2] = np.count_nonzero(c.active), c.force.sum(), min_gap
