"""The energy ledger in the discrete form the scheme conserves (J).

With v^{n+1} = v^n + dt M^-1 (F^n - K u^n) and u^{n+1} = u^n + dt v^{n+1},

    E_n = 1/2 (v^n)' M v^{n+1} + 1/2 (u^n)' K u^n

changes by exactly  E_{m} - E_{m-1} = 1/2 dt (v^m)' (F^{m-1} + F^m)  where F is
every applied force (surface loads, contact, forces on rigid bodies). So the
work of a force, W_n = sum over m = 1..n of 1/2 dt (v^m)' (F^{m-1} + F^m),
closes the balance  E_n - E_0 - W_n = 0  to round-off. A position set apart
from the velocity (a jump j^m = u^m - u^{m-1} - dt v^m, as in DME) adds
1/2 (j^m)' K (u^{m-1} + u^m); contact methods that jump report it as work.

A path-dependent body (internal force f_int(u, state), :mod:`.internal_force`)
enters the same identity as a force: its deformation work, booked each step as
1/2 (f_int^{m-1} + f_int^m) . (u^m - u^{m-1}), takes the place of the change
of 1/2 u'Ku, and at its quadrature points it splits exactly into the change of
the stored elastic energy psi_e = sum 1/2 sigma : C^-1 : sigma w and the
plastic work W_p = sum 1/2 (sigma^{m-1} + sigma^m) : (eps_p^m - eps_p^{m-1}) w.
The ledger's energy is then  1/2 (v^n)' M v^{n+1} + 1/2 (u^n)' K u^n + psi_e + W_p
(K over the linear bodies), balanced by the same work terms to round-off.
"""
from __future__ import annotations

import math

import numpy as np
from mpi4py import MPI
from numba import njit

from .jit_watch import direct
from .loads import SurfaceLoad


@njit(cache=True)
def _load_power(force, v, dofs) -> float:
    """sum force[i] v[dofs[i]] (N m/s per unit of the load's history): one compiled pass."""
    s = 0.0
    for i in range(dofs.size):
        s += force[i] * v[dofs[i]]
    return s


class LoadWork:
    """Work (J) of the surface loads, accumulated every step on their few dofs."""

    def __init__(self, loads: list[SurfaceLoad], dt: float, comm: MPI.Comm,
                 v: np.ndarray | None = None):
        """``v``: the integrator's owned velocities (m/s), the array :meth:`accumulate` reads
        (its compiled kernel is loaded for it now, not in the loop)."""
        self.loads = loads
        self.dt = dt
        self.comm = comm
        self._dofs = [ld.dofs.astype(np.intp) for ld in loads]
        self._local = 0.0
        self._power = (direct(_load_power, loads[0].force, v if v is not None else np.zeros(1),
                              self._dofs[0]) if loads else None)

    def accumulate(self, integrator) -> None:
        """Add 1/2 dt (v^n)' (F^{n-1} + F^n) for step n (call before predict, n >= 1)."""
        n = integrator.n
        if n == 0:
            return
        t_now, t_prev = n * self.dt, (n - 1) * self.dt
        v, power = integrator.v_owned, self._power
        for ld, dofs in zip(self.loads, self._dofs):
            s = ld.history(t_prev) + ld.history(t_now)
            if s == 0.0:
                continue
            self._local += 0.5 * self.dt * s * power(ld.force, v, dofs)

    @property
    def local(self) -> float:
        """This rank's part of W_n (J)."""
        return self._local

    def total(self) -> float:
        """W_n (J), summed over ranks."""
        return self.comm.allreduce(self._local)


class Ledger:
    """E_n, the work terms and the balance error, evaluated at output steps."""

    def __init__(self, comm: MPI.Comm):
        self.comm = comm
        self.E0: float | None = None
        self.scale = 0.0  # largest |term| seen, the reference for the relative error

    def record(self, kinetic: float, strain: float, external_work: float,
               contact_work: float, plastic_work: float = 0.0) -> tuple[float, float, float]:
        """(E_n, E_n - E_0 - W_n, its relative error) at one output step: all energies in J,
        already summed over ranks; the relative error is |E_n - E_0 - W_n| over the largest
        |term| seen so far (0 while every term is 0).

        ``strain`` is the stored elastic energy of every body (1/2 u'Ku of the linear
        ones, psi_e of the path-dependent ones), ``plastic_work`` the work dissipated
        at their points, so E_n = kinetic + strain + plastic_work; W_n = external_work +
        contact_work. (The path-dependent bodies' deformation work, sum 1/2 (f_int^{n-1}
        + f_int^n) . du, is reported beside the balance: it equals d psi_e + W_p.)"""
        E = kinetic + strain + plastic_work
        E0 = self.E0
        if E0 is None:
            self.E0 = E0 = E
        balance = E - E0 - external_work - contact_work
        self.scale = scale = max(self.scale, abs(E), abs(E0), abs(external_work),
                                 abs(contact_work))
        rel = abs(balance) / scale if scale > 0 else 0.0
        return E, balance, rel


# energy_verdict's answers
STABLE, NOT_FINITE, GREW = 0, 1, 2


@njit(cache=True)
def energy_verdict(kinetic: float, strain: float, external_work: float, contact_work: float,
                   total: float, E0: float, limit: float) -> int:
    """Is the energy of an output step sound? NOT_FINITE if kinetic, strain, external or
    contact work (J) is not finite; GREW if E_n (``total``, J) exceeds ``limit`` x the
    energy put in, max(|E_0|, |W_ext|) (when either is nonzero); else STABLE. (The
    loop's stability check, in Python and in the compiled steps.)"""
    if not (math.isfinite(kinetic) and math.isfinite(strain) and math.isfinite(external_work)
            and math.isfinite(contact_work)):
        return NOT_FINITE
    budget = max(abs(E0), abs(external_work), 1e-300)
    if total > limit * budget and (E0 != 0.0 or external_work != 0.0):
        return GREW
    return STABLE


@njit(cache=True)
def _output_sums(mass, v_now, v_next, body_dofs, body_start, out) -> None:
    """out[0] = 1/2 v_now' M v_next (J), out[2] = sum of m v_next over the z dofs (odd
    entries; kg m/s), out[3 + b] = sum of m v_next over body_dofs[body_start[b]:
    body_start[b + 1]]: one pass over the owned dofs (2 per node, r then z), two nodes at
    a time into separate partial sums (independent additions pipeline). out[1] is left
    to the caller (the strain energy, :func:`half_dot`)."""
    k0 = k1 = p0 = p1 = 0.0
    n = mass.size
    i = 0
    while i + 3 < n:
        k0 += mass[i] * v_now[i] * v_next[i] + mass[i + 1] * v_now[i + 1] * v_next[i + 1]
        k1 += mass[i + 2] * v_now[i + 2] * v_next[i + 2] + mass[i + 3] * v_now[i + 3] * v_next[i + 3]
        p0 += mass[i + 1] * v_next[i + 1]
        p1 += mass[i + 3] * v_next[i + 3]
        i += 4
    while i < n:
        k0 += mass[i] * v_now[i] * v_next[i]
        if i % 2 == 1:
            p0 += mass[i] * v_next[i]
        i += 1
    out[0] = 0.5 * (k0 + k1)
    out[2] = p0 + p1
    for b in range(body_start.size - 1):
        q0 = q1 = 0.0
        j = body_start[b]
        end = body_start[b + 1]
        while j + 1 < end:
            q0 += mass[body_dofs[j]] * v_next[body_dofs[j]]
            q1 += mass[body_dofs[j + 1]] * v_next[body_dofs[j + 1]]
            j += 2
        if j < end:
            q0 += mass[body_dofs[j]] * v_next[body_dofs[j]]
        out[3 + b] = q0 + q1


@njit(cache=True)
def half_dot(u, ku) -> float:
    """1/2 u' ku (J for u in m and ku = K u in N), two nodes at a time into separate
    partial sums."""
    s0 = s1 = 0.0
    n = u.size
    i = 0
    while i + 3 < n:
        s0 += u[i] * ku[i] + u[i + 1] * ku[i + 1]
        s1 += u[i + 2] * ku[i + 2] + u[i + 3] * ku[i + 3]
        i += 4
    while i < n:
        s0 += u[i] * ku[i]
        i += 1
    return 0.5 * (s0 + s1)


@njit(cache=True)
def copy_state(u, v, u_out, v_out) -> None:
    """u_out = u, v_out = v (the state u^n, m, and v^n, m/s, an output step keeps): one pass."""
    for i in range(u.size):
        u_out[i] = u[i]
        v_out[i] = v[i]


@njit(cache=True)
def strain_from_prediction(u, v_pred, v_now, minus_m_over_dt) -> float:
    """1/2 u' K u (J) with K u = -m / dt (v~ - v^n) (N), where v~ = v^n + dt M^-1 (f^n -
    K u^n) is the predicted velocity (m/s) and no force f acts: :func:`half_dot` of u and
    that K u, the same sums in the same order, in one pass that stores no K u."""
    s0 = s1 = 0.0
    n = u.size
    i = 0
    while i + 3 < n:
        s0 += (u[i] * ((v_pred[i] - v_now[i]) * minus_m_over_dt[i])
               + u[i + 1] * ((v_pred[i + 1] - v_now[i + 1]) * minus_m_over_dt[i + 1]))
        s1 += (u[i + 2] * ((v_pred[i + 2] - v_now[i + 2]) * minus_m_over_dt[i + 2])
               + u[i + 3] * ((v_pred[i + 3] - v_now[i + 3]) * minus_m_over_dt[i + 3]))
        i += 4
    while i < n:
        s0 += u[i] * ((v_pred[i] - v_now[i]) * minus_m_over_dt[i])
        i += 1
    return 0.5 * (s0 + s1)


class OutputSums:
    """The sums of an output step over the owned dofs, in one compiled pass and one
    reduction over the ranks: kinetic 1/2 (v^n)' M v^{n+1} (J), the z momentum of v^{n+1}
    in total and per body (kg m/s), with the strain energy 1/2 (u^n)' K u^n (J, this
    rank's part: :func:`strain_from_prediction` or :func:`half_dot`) and any further local
    numbers handed in (summed with them).

    ``mass`` the lumped masses (kg) of the owned dofs; ``body_z`` per body the indices of
    its owned z dofs."""

    def __init__(self, mass: np.ndarray, body_z: list[np.ndarray], comm: MPI.Comm,
                 n_extra: int = 0):
        self.mass = mass
        self.comm = comm
        self.n_bodies = len(body_z)
        self._dofs = (np.concatenate(body_z) if body_z else np.zeros(0)).astype(np.int64)
        self._start = np.cumsum([0] + [d.size for d in body_z]).astype(np.int64)
        self._local = np.zeros(3 + self.n_bodies + n_extra)
        self._total = np.zeros_like(self._local)
        self._local_view = memoryview(self._local)
        # the sums as floats (memoryview items): this rank's, or the reduced ones
        self._result = memoryview(self._local if comm.size == 1 else self._total)
        # its kernel's compiled entry, for velocities of the type of ``mass`` (float64,
        # contiguous: the loop's arrays), taken now, not at the first output
        self._sums = direct(_output_sums, mass, mass, mass, self._dofs, self._start,
                            self._local)

    @property
    def size(self) -> int:
        """The number of sums (3 + bodies + the extra numbers)."""
        return self._local.size

    def reduce(self, v_now: np.ndarray, v_next: np.ndarray, strain: float,
               extra=()) -> memoryview:
        """(kinetic, strain, p_z, p_z per body..., extra...) summed over the ranks, as floats
        (a view, valid until the next call); ``strain`` this rank's 1/2 (u^n)' K u^n (J).
        ``v_now`` and ``v_next``: contiguous float64 arrays like ``mass``."""
        local = self._local_view
        self._sums(self.mass, v_now, v_next, self._dofs, self._start, self._local)
        local[1] = strain
        k = 3 + self.n_bodies
        for x in extra:
            local[k] = x
            k += 1
        if self.comm.size > 1:
            self.comm.Allreduce(self._local, self._total)
        return self._result
