"""The energy ledger: the kinetic identity of the half-step scheme (J).

With v^{n+1/2} = v^{n-1/2} + h M^-1 (F^n - f_int(u^n)) and u^{n+1} = u^n + h v^{n+1/2}
(the modified Euler scheme at a constant step h; v^0 is read as v^{-1/2}), every step
satisfies

    1/2 |v^{n+1/2}|^2_M - 1/2 |v^{n-1/2}|^2_M = sum over forces 1/2 (v^{n-1/2} + v^{n+1/2}) . h f^n

for any force f. So the work of an applied or contact force through step n,
W_n = sum over m = 0..n of 1/2 (v^{m-1/2} + v^{m+1/2}) . h F^m, is booked step by step
(:class:`LoadWork`, the contact sets). The internal forces' work telescopes at a constant
h, since 1/2 h (v^{m-1/2} + v^{m+1/2}) = 1/2 (u^{m+1} - u^{m-1}): for the linear bodies to
-(Phi_n - Phi_-1) with Phi_n = 1/2 (u^{n+1})' K u^n = 1/2 (u^n + h v^{n+1/2})' K u^n, the
form booked, and for the path-dependent bodies to their trapezoid deformation work
sum 1/2 (f_int^{m-1} + f_int^m) . (u^m - u^{m-1}) plus the same boundary term
1/2 h v^{n+1/2} . f_int^n. The row of output step n (the state after step n) therefore
holds

    E_n = 1/2 |v^{n+1/2}|^2_M + 1/2 (u^n)' K u^n + psi_e^n + W_p^n + 1/2 h v^{n+1/2} . f_int^n

(K over the linear bodies, psi_e the stored elastic energy sum 1/2 sigma : C^-1 : sigma w at the path-dependent
bodies' points, W_p their plastic work, f_int^n the internal force of every body, read
from the step's prediction), and E_n - E_ref - W_n = 0 to round-off, where E_ref is the
initial state, 1/2 |v^0|^2_M (a run starts with u^0 = 0 and unstressed points; an
integrator given a displaced state adds its linear bodies' Phi_-1 = 1/2 (u^0)' K u^{-1},
u^{-1} = u^0 - h v^0, as Simulation._initial_energy does). A
position set apart from the velocity (a jump j^m = u^m - u^{m-1} - h v^{m-1/2}, as in
DME) adds 1/2 (j^m)' K (u^{m-1} + u^m); contact methods that jump report it as work.

Against the form it replaced (E_n^old = 1/2 (v^{n-1/2})' M v^{n+1/2} + 1/2 (u^n)' K u^n
with trapezoid works 1/2 h v^{m-1/2} . (F^{m-1} + F^m) from m = 1), the columns differ
by exact boundary terms: E_n = E_n^old + 1/2 h v^{n+1/2} . F^n, W_n = W_n^old +
1/2 h v^{n+1/2} . F^n + 1/2 h v^0 . F^0 (F the applied and contact forces), so the
first row now includes the first step's contact.
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
    """Work (J) of the surface loads by the kinetic identity, accumulated every step on
    their few dofs: step n adds 1/2 h (v^{n-1/2} + v^{n+1/2}) . F^n, in two passes, one
    before the step (:meth:`accumulate`) and one after it (:meth:`complete`)."""

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

        self._half = [0.0] * len(loads)  # a varying step: 1/2 s v^{n-1/2} . F per load
        self._t = 0.0  # and t^n (s)

    def _add(self, v: np.ndarray, n: int) -> None:
        """Add 1/2 h v . F^n (F^n the loads at t^n = n h)."""
        t, power = n * self.dt, self._power
        for ld, dofs in zip(self.loads, self._dofs):
            s = ld.history(t)
            if s == 0.0:
                continue
            self._local += 0.5 * self.dt * s * power(ld.force, v, dofs)

    def accumulate(self, integrator) -> None:
        """Step n's first half, 1/2 h v^{n-1/2} . F^n (call before predict). Under a varying
        step h_n is known after predict: 1/2 s(t^n) v^{n-1/2} . F is kept per load."""
        if integrator.step.constant:
            self._add(integrator.v_owned, integrator.n)
            return
        self._t = t = integrator.t
        power, v = self._power, integrator.v_owned
        for i, (ld, dofs) in enumerate(zip(self.loads, self._dofs)):
            s = ld.history(t)
            self._half[i] = 0.0 if s == 0.0 else 0.5 * s * power(ld.force, v, dofs)

    def complete(self, integrator) -> None:
        """Step n's second half, 1/2 h v^{n+1/2} . F^n (call after advance: the step
        just taken is integrator.n - 1); under a varying step the whole step's
        h_n 1/2 s (v^{n-1/2} + v^{n+1/2}) . F."""
        if integrator.step.constant:
            self._add(integrator.v_owned, integrator.n - 1)
            return
        t, h_avg = self._t, integrator.step.h_avg
        power, v = self._power, integrator.v_owned
        for i, (ld, dofs) in enumerate(zip(self.loads, self._dofs)):
            s = ld.history(t)
            if s != 0.0:
                self._local += h_avg * (self._half[i] + 0.5 * s * power(ld.force, v, dofs))

    @property
    def local(self) -> float:
        """This rank's part of W_n (J)."""
        return self._local

    def total(self) -> float:
        """W_n (J), summed over ranks."""
        return self.comm.allreduce(self._local)


class Ledger:
    """E_n, the work terms and the balance error, evaluated at output steps, against the
    initial state's energy ``E0`` (J, summed over ranks)."""

    def __init__(self, comm: MPI.Comm, E0: float):
        self.comm = comm
        self.E0 = E0
        self.scale = abs(E0)  # largest |term| seen, the reference for the relative error

    def record(self, kinetic: float, strain: float, external_work: float,
               contact_work: float, plastic_work: float = 0.0,
               work_gap: float = 0.0) -> tuple[float, float, float]:
        """(E_n, E_n - E_0 - W_n, its relative error) at one output step: all energies in J,
        already summed over ranks; the relative error is |E_n - E_0 - W_n| over the largest
        |term| seen so far (0 while every term is 0).

        ``strain`` is the stored energy of every body with its step's boundary term
        (1/2 (u^n)' K u^n of the linear ones, psi_e of the path-dependent ones, plus
        1/2 h v^{n+1/2} . f_int^n of all), ``plastic_work`` the work dissipated at their points, so E_n = kinetic +
        strain + plastic_work; W_n = external_work + contact_work. (The path-dependent
        bodies' deformation work, sum 1/2 (f_int^{n-1} + f_int^n) . du, is reported beside
        the balance: it equals d psi_e + W_p.) ``work_gap``: under a varying step, the
        internal forces' work that the split into stored energy, its boundary term and
        dissipation leaves out, sum 1/4 (h_{n+1/2} - h_{n-1/2}) (v^{n-1/2} - v^{n+1/2}) .
        f_int^n (0 at a constant step), part of E_n."""
        E = kinetic + strain + plastic_work + work_gap
        E0 = self.E0
        balance = E - E0 - external_work - contact_work
        self.scale = scale = max(self.scale, abs(E), abs(external_work), abs(contact_work))
        rel = abs(balance) / scale if scale > 0 else 0.0
        return E, balance, rel


# energy_verdict's answers
STABLE, NOT_FINITE, GREW = 0, 1, 2


@njit(cache=True)
def energy_verdict(kinetic: float, strain: float, external_work: float, contact_work: float,
                   total: float, E0: float, limit: float) -> int:
    """Is the energy of an output step sound? NOT_FINITE if kinetic, strain, external or
    contact work (J) is not finite; GREW if E_n (``total``, J) or the kinetic energy
    exceeds ``limit`` x the energy put in, max(|E_0|, |W_ext|) (when either is nonzero);
    else STABLE. (The loop's stability check, in Python and in the compiled steps.)

    E_n is conserved by the scheme even above its stable step, where the form is
    indefinite (its kinetic and stored parts grow with opposite signs): it grows only by
    the work of a force that gains energy (a chattering penalty). The kinetic energy
    1/2 |v^{n+1/2}|^2_M is positive, at most E_n while the step is stable, and grows
    with the unstable mode."""
    if not (math.isfinite(kinetic) and math.isfinite(strain) and math.isfinite(external_work)
            and math.isfinite(contact_work)):
        return NOT_FINITE
    budget = max(abs(E0), abs(external_work), 1e-300)
    if max(total, kinetic) > limit * budget and (E0 != 0.0 or external_work != 0.0):
        return GREW
    return STABLE


@njit(cache=True)
def _output_sums(mass, v_next, body_dofs, body_start, out) -> None:
    """out[0] = 1/2 v_next' M v_next (J), out[2] = sum of m v_next over the z dofs (odd
    entries; kg m/s), out[3 + b] = sum of m v_next over body_dofs[body_start[b]:
    body_start[b + 1]]: one pass over the owned dofs (2 per node, r then z), two nodes at
    a time into separate partial sums (independent additions pipeline). out[1] is left
    to the caller (the stored energy, :func:`strain_from_prediction`, :func:`half_dot`)."""
    k0 = k1 = p0 = p1 = 0.0
    n = mass.size
    i = 0
    while i + 3 < n:
        k0 += mass[i] * v_next[i] * v_next[i] + mass[i + 1] * v_next[i + 1] * v_next[i + 1]
        k1 += mass[i + 2] * v_next[i + 2] * v_next[i + 2] + mass[i + 3] * v_next[i + 3] * v_next[i + 3]
        p0 += mass[i + 1] * v_next[i + 1]
        p1 += mass[i + 3] * v_next[i + 3]
        i += 4
    while i < n:
        k0 += mass[i] * v_next[i] * v_next[i]
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
def gap_dot(v_prev, v, f) -> float:
    """sum (v_prev - v) . f (W s: m/s times N): a step's 1/4 (h_{n+1/2} - h_{n-1/2})
    (v^{n-1/2} - v^{n+1/2}) . f_int^n without its factor."""
    s = 0.0
    for i in range(v.size):
        s += (v_prev[i] - v[i]) * f[i]
    return s


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
def strain_from_prediction(u, v_pred, v_now, minus_m_over_dt, f_int) -> float:
    """f_int = -m / h (v~ - v^{n-1/2}) (N), the internal force f_int(u^n) where no
    applied force acts, with v~ = v^{n-1/2} + h M^-1 (F^n - f_int(u^n)) the predicted
    velocity (m/s); returns 1/2 u . f_int (J; 1/2 u'K u for linear bodies): :func:`half_dot`
    of u and f_int, the same sums in the same order, in the one pass that fills f_int."""
    s0 = s1 = 0.0
    n = u.size
    i = 0
    while i + 3 < n:
        f0 = (v_pred[i] - v_now[i]) * minus_m_over_dt[i]
        f1 = (v_pred[i + 1] - v_now[i + 1]) * minus_m_over_dt[i + 1]
        f2 = (v_pred[i + 2] - v_now[i + 2]) * minus_m_over_dt[i + 2]
        f3 = (v_pred[i + 3] - v_now[i + 3]) * minus_m_over_dt[i + 3]
        f_int[i], f_int[i + 1], f_int[i + 2], f_int[i + 3] = f0, f1, f2, f3
        s0 += u[i] * f0 + u[i + 1] * f1
        s1 += u[i + 2] * f2 + u[i + 3] * f3
        i += 4
    while i < n:
        f0 = (v_pred[i] - v_now[i]) * minus_m_over_dt[i]
        f_int[i] = f0
        s0 += u[i] * f0
        i += 1
    return 0.5 * (s0 + s1)


class OutputSums:
    """The sums of an output step over the owned dofs, in one compiled pass and one
    reduction over the ranks: kinetic 1/2 |v^{n+1/2}|^2_M (J), the z momentum of v^{n+1/2}
    in total and per body (kg m/s), with the stored energy and its boundary term
    (J, this rank's part: :func:`strain_from_prediction`, :func:`half_dot`) and
    any further local numbers handed in (summed with them).

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
        self._sums = direct(_output_sums, mass, mass, self._dofs, self._start, self._local)

    @property
    def size(self) -> int:
        """The number of sums (3 + bodies + the extra numbers)."""
        return self._local.size

    def reduce(self, v_next: np.ndarray, strain: float, extra=()) -> memoryview:
        """(kinetic, strain, p_z, p_z per body..., extra...) summed over the ranks, as floats
        (a view, valid until the next call); ``strain`` this rank's stored energy (J).
        ``v_next``: v^{n+1/2}, a contiguous float64 array like ``mass``."""
        local = self._local_view
        self._sums(self.mass, v_next, self._dofs, self._start, self._local)
        local[1] = strain
        k = 3 + self.n_bodies
        for x in extra:
            local[k] = x
            k += 1
        if self.comm.size > 1:
            self.comm.Allreduce(self._local, self._total)
        return self._result
