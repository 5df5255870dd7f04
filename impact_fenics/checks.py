"""The checks of a run: divergence (a runaway speed, an energy not finite or grown),
the penalty's chatter and contact energy gain, and the contact counters they read.

Units: s, m/s, J.
"""
from __future__ import annotations

import math

import numpy as np
from mpi4py import MPI

from .contact import RigidBody
from .energy import GREW, NOT_FINITE, energy_verdict
from .errors import UnstableRunError
from .step_block import count_beyond

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


def penalty_trouble(track: dict) -> str:
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


def runaway_speed(model, v_owned: np.ndarray, contacts: list, comm: MPI.Comm) -> float:
    """Speed (m/s) above which a run counts as diverged: the fastest wave speed of
    the materials of ``model``'s bodies, or RUNAWAY_FACTOR x the fastest initial speed
    (``v_owned``, the owned dofs' velocities, and the contact sets' rigid bodies) if that
    is higher. Collective."""
    waves = [b.material.wave_speed() for b in model.bodies.values()]
    v0 = float(np.abs(v_owned).max(initial=0.0))
    v0 = max([comm.allreduce(v0, op=MPI.MAX)] +
             [abs(c.rigid.v) for c in contacts if c.rigid is not None])
    return max(max(waves), RUNAWAY_FACTOR * v0)


class Divergence:
    """The checks that stop a run as diverged (UnstableRunError, its message naming the
    step, the time (s), dt and the stable bound): a node or rigid body beyond the
    runaway speed (m/s, fixed at the run's start), an energy not finite or grown beyond
    ``growth_limit`` x the energy put in."""

    def __init__(self, dt: float, dt_critical: float, contacts: list, runaway_speed: float,
                 growth_limit: float):
        self.dt, self.dt_critical, self.contacts = dt, dt_critical, contacts
        self.runaway_speed = runaway_speed
        self.growth_limit = float(growth_limit)

    def _runaway(self, n: int, what: str) -> None:
        """Stop at step n: ``what`` passed the runaway speed the run checked against
        (:attr:`runaway_speed`, fixed at its start)."""
        raise UnstableRunError(self.diagnosis(
            n, f"{what}, beyond the runaway speed {self.runaway_speed:.4g} m/s "
               "(not finite, or a strain beyond 1)"))

    def rigid_runaway(self, n: int, body: RigidBody) -> None:
        """Stop at step n: ``body`` moves at a speed that is not finite."""
        self._runaway(n, f"the rigid body '{body.name}' moves at {body.v} m/s")

    def node_runaway(self, n: int, v_check: "OwnedVec") -> None:
        """Stop at step n: a node moves beyond the runaway speed (collective)."""
        self._runaway(n, f"a node moves at {v_check.norm_inf():.4g} m/s")

    def energy_growth(self, row: dict, E0: float | None, n: int) -> None:
        """Stop a run whose energy (J) is not finite or grew beyond the growth limit x
        the energy put in (``E0``, the ledger's E_0, or the external work); ``row``: the
        energy columns of output step n."""
        ext = row["external_work"]
        E0 = E0 or 0.0
        limit = self.growth_limit
        verdict = energy_verdict(row["kinetic"], row["strain"], ext, row["contact_work"],
                                 row["total"], E0, limit)
        if verdict == NOT_FINITE:
            raise UnstableRunError(self.diagnosis(n, "the energy is not finite"))
        if verdict == GREW:
            budget = max(abs(E0), abs(ext), 1e-300)
            what = "kinetic energy" if row["kinetic"] > row["total"] else "energy"
            grown = max(row["kinetic"], row["total"])
            raise UnstableRunError(self.diagnosis(
                n, f"the {what} {grown:.4g} J grew beyond {limit:g} x the energy put in "
                   f"({budget:.4g} J)"))

    def diagnosis(self, n: int, what: str) -> str:
        """The message of a run that diverged at step n: ``what``, the time, dt, the stable
        bound and the penalty's beta_max."""
        penalty = [c.method.info.get("beta_max") for c in self.contacts if c.method.name == "penalty"]
        extra = ""
        if penalty:
            extra = f"; penalty beta_max = {max(penalty):.3g} (stable below 4/3)"
        return (f"run diverged at step {n} (t = {n * self.dt:.6g} s): {what}; "
                f"dt = {self.dt:.4g} s, stable dt <= {self.dt_critical:.4g} s{extra}")


class OwnedVec:
    """The largest speed max_i |v_i| over the owned entries of a numpy array on every rank,
    NaN on every rank if any rank holds a NaN (collective; no allocation: one scratch
    array and one two-value reduction), and the cheaper check whether any speed exceeds
    a limit (or is NaN): one compiled pass and a one-value reduction. Read from the
    array itself, so it sees every write. Not PETSc's NORM_INFINITY: with MPICH (the
    wheels) its MPI_MAX drops a NaN on some ranks, so the ranks would disagree about a
    runaway and hang."""

    def __init__(self, array: np.ndarray, comm: MPI.Comm):
        self._array, self._comm = array, comm
        self._abs = np.empty_like(array)
        self._buf = np.zeros(2)  # (largest |v|, 1 if a NaN)
        self._count = np.zeros(1)
        count_beyond(array, np.inf)  # loaded now, not in a step

    def exceeds(self, limit: float) -> bool:
        """Does any |v_i| on any rank exceed ``limit`` or is it NaN? (the same answer on
        every rank; about half the time of :meth:`norm_inf`)"""
        self._count[0] = count_beyond(self._array, limit)
        if self._comm.size > 1:
            self._comm.Allreduce(MPI.IN_PLACE, self._count, op=MPI.MAX)
        return self._count[0] > 0

    def norm_inf(self) -> float:
        np.abs(self._array, out=self._abs)
        local = float(self._abs.max()) if self._abs.size else 0.0
        nan = local != local
        self._buf[0], self._buf[1] = (0.0 if nan else local), (1.0 if nan else 0.0)
        if self._comm.size > 1:
            self._comm.Allreduce(MPI.IN_PLACE, self._buf, op=MPI.MAX)
        return math.nan if self._buf[1] else float(self._buf[0])


class ContactTrack:
    """Per step, from the contact sets' stats (number active, total force, smallest gap;
    updated in place by their steps, read here through memoryviews): the largest committed
    penetration (m), the first and last steps with contact, the steps in contact and the
    reversals of the number of active penalty constraints (chatter); at output steps the
    loop books the penalty's energy gain and budget (J, see CHATTER_MIN).

    The counters are :attr:`state` (the compiled steps of step_block update it too);
    :attr:`step` is a closure over a memoryview of it (an item costs less than an
    attribute)."""

    __slots__ = ("step", "state", "penalty", "gain", "budget")

    def __init__(self, contacts: list):
        stats = [memoryview(c.stats) for c in contacts]
        self.gain = self.budget = 0.0
        # the counters (layout step_block.T_*, which updates them in its compiled steps):
        # the smallest committed gap (m) so far, or 0 (-max penetration); the first and
        # last steps with contact (-1: none yet); the steps in contact; the reversals; then
        # per penalty set its last number active and its last nonzero change
        penalty = [(memoryview(c.stats), 5 + 2 * k) for k, c in
                   enumerate(c for c in contacts if c.method.name == "penalty")]
        self.penalty = bool(penalty)
        self.state = np.zeros(5 + 2 * max(1, len(penalty)))
        self.state[1:3] = -1.0
        s = memoryview(self.state)

        def step(n: int) -> None:
            touching = False
            for st in stats:
                if st[2] < s[0]:
                    s[0] = st[2]
                if st[0] > 0.0:
                    touching = True
            if touching:
                if s[1] < 0.0:
                    s[1] = n
                s[2] = n
                s[3] += 1.0
            for st, k in penalty:  # reversals of the number of active penalty constraints
                n_active = st[0]
                d = n_active - s[k]
                if d * s[k + 1] < 0.0:
                    s[4] += 1.0
                s[k] = n_active
                if d:
                    s[k + 1] = d
        self.step = step

    @property
    def first(self) -> int | None:
        """The first step with contact (None before it)."""
        return int(self.state[1]) if self.state[1] >= 0.0 else None

    def as_dict(self) -> dict:
        lowest, first, last, steps, reversals = self.state[:5].tolist()
        return {"max_penetration": max(0.0, -lowest),
                "first_contact": int(first) if first >= 0.0 else None,
                "last_contact": int(last) if last >= 0.0 else None, "contact_steps": int(steps),
                "reversals": int(reversals), "gain": self.gain, "budget": self.budget}
