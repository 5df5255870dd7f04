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

import numpy as np
from mpi4py import MPI

from .loads import SurfaceLoad


class LoadWork:
    """Work (J) of the surface loads, accumulated every step on their few dofs."""

    def __init__(self, loads: list[SurfaceLoad], dt: float, comm: MPI.Comm):
        self.loads = loads
        self.dt = dt
        self.comm = comm
        self._dofs = [ld.dofs.astype(np.intp) for ld in loads]
        self._v = [np.empty(ld.dofs.size) for ld in loads]
        self._local = 0.0

    def accumulate(self, integrator) -> None:
        """Add 1/2 dt (v^n)' (F^{n-1} + F^n) for step n (call before predict, n >= 1)."""
        n = integrator.n
        if n == 0:
            return
        t_now, t_prev = n * self.dt, (n - 1) * self.dt
        for ld, dofs, v in zip(self.loads, self._dofs, self._v):
            s = ld.history(t_prev) + ld.history(t_now)
            if s == 0.0:
                continue
            integrator.take_velocity(dofs, v)
            self._local += 0.5 * self.dt * s * float(np.dot(ld.force, v))

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
               contact_work: float, plastic_work: float = 0.0,
               deformation_work: float = 0.0) -> dict[str, float]:
        """Balance at one output step; all energies in J, already summed over ranks.

        ``strain`` is the stored elastic energy of every body (1/2 u'Ku of the linear
        ones, psi_e of the path-dependent ones), ``plastic_work`` the work dissipated
        at their points; ``deformation_work`` sum 1/2 (f_int^{n-1} + f_int^n) . du of
        the path-dependent bodies, reported beside (it equals d psi_e + W_p)."""
        E = kinetic + strain + plastic_work
        if self.E0 is None:
            self.E0 = E
        balance = E - self.E0 - external_work - contact_work
        self.scale = max(self.scale, abs(E), abs(self.E0), abs(external_work), abs(contact_work))
        rel = abs(balance) / self.scale if self.scale > 0 else 0.0
        return {"kinetic": kinetic, "strain": strain, "total": E,
                "external_work": external_work, "contact_work": contact_work,
                "plastic_work": plastic_work, "deformation_work": deformation_work,
                "balance_error": balance, "balance_error_rel": rel}


def deformable_energy(mass: np.ndarray, v_now: np.ndarray, v_next: np.ndarray,
                      u_now: np.ndarray, Ku_now: np.ndarray, comm: MPI.Comm,
                      scratch: np.ndarray | None = None) -> tuple[float, float]:
    """Kinetic 1/2 v^n' M v^{n+1} and strain 1/2 u^n' K u^n (J), summed over ranks
    (``scratch``: a buffer like ``mass`` for M v^n, else one is allocated)."""
    mv = np.multiply(mass, v_now, out=scratch)
    local = np.array([0.5 * float(np.dot(mv, v_next)), 0.5 * float(np.dot(u_now, Ku_now))])
    total = np.empty(2)
    comm.Allreduce(local, total)
    return float(total[0]), float(total[1])
