"""Internal force of the linear bodies: K assembled once, f_int = K u.

The velocity update  v <- v - h_n M^-1 K u  runs, in a scene without a finite-strain
body (a constant step), as  v <- A u + v  (one MatMultAdd) with A = -h_n M^-1 K scaled
once (zero rows on the fixed dofs), h_n the increment's step. In a scene with one (the
step follows its cells, so h_n changes) A is not built: w = K u (one MatMult), then one
compiled pass v += h_n (-1/m) w over the owned dofs (0 on the fixed ones) that books the
kinetic identity's work h_n 1/2 (v^- + v~) . K u (the finite-strain force's pass). K
covers the cells of the linear bodies only (all of them when every body is linear,
which is the original path, unchanged).
"""
from __future__ import annotations

import numpy as np
from petsc4py import PETSc

from ..bodies import DeformableModel
from ..forms import Part
from ..operators import assemble_stiffness
from ..jit_watch import load
from ..stability import parts_stable_dt
from .base import Booking
from .finite import velocity_update


class LinearForce:
    """K (N/m) over ``parts`` and A = -h_n M^-1 K; ``mass`` the owned lumped masses (kg),
    ``fixed`` the owned (local) fixed dofs, ``dt`` the step (s) A is scaled for first.
    ``scaled``: False for the per-step pass of a varying step (no A, see the module's
    docstring); :attr:`work_local` its booked work (J, this rank).

    :meth:`velocity_increment` multiplies the Vecs :meth:`bind` gave it (the integrator's
    u and v, whose owned arrays the loop passes)."""

    def __init__(self, model: DeformableModel, parts: list[Part], dt: float, mass: np.ndarray,
                 fixed: np.ndarray, matrix_type: str = "aij", scaled: bool = True):
        self.model, self.parts, self.mass, self.matrix_type = model, parts, mass, matrix_type
        self.fixed = np.asarray(fixed, dtype=np.int32)
        self._fixed_global = model.to_global(self.fixed).astype(PETSc.IntType)
        self.K = assemble_stiffness(model, matrix_type, parts)
        self.A = None
        self.scaled = scaled
        self.h = self.h_avg = None
        self._u = self._v = self._Ku = None
        self._stable_dt = None
        self.work_local = 0.0
        if scaled:
            self.set_step(dt, dt)
        else:  # w = K u and the pass's -1/m (0 on the fixed dofs)
            self.h = self.h_avg = float(dt)
            self._w = self.K.createVecLeft()
            self.coef = -1.0 / mass
            self.coef[self.fixed] = 0.0
            load(velocity_update, self.coef, self._w.array, self.coef, 1.0)

    @property
    def pass_force(self) -> np.ndarray:
        """K u^n (N, owned dofs) of the last per-step pass: the force its work is booked with."""
        return self._w.array

    def bind(self, u: PETSc.Vec, v: PETSc.Vec) -> None:
        """The displacement (m) and velocity (m/s) Vecs the loop steps."""
        self._u, self._v = u, v

    def set_step(self, h: float, h_avg: float) -> None:
        """A = -h_avg M^-1 K, built anew when h_avg changes (the set-up's arithmetic: the
        same A as a run that started with this step). Under a constant step it is built
        once. The per-step pass only keeps the steps."""
        self.h = float(h)
        if h_avg == self.h_avg:
            return
        if not self.scaled:
            self.h_avg = float(h_avg)
            return
        if self.A is not None:
            self.A.destroy()
        # a second assembly, not K.copy(): a copied BAIJ matrix multiplies slower
        self.A = assemble_stiffness(self.model, self.matrix_type, self.parts)
        scale = self.K.createVecRight()
        scale.array[:] = -h_avg / self.mass
        self.A.diagonalScale(L=scale)
        self.A.zeroRows(self._fixed_global, diag=0.0)
        scale.destroy()
        self.h_avg = float(h_avg)

    def velocity_increment(self, u: np.ndarray, v: np.ndarray, h_avg: float) -> None:
        """v <- A u + v (one MatMultAdd on the bound Vecs, over the arrays ``u``, ``v``), or
        the per-step pass: w = K u, v += h_avg (-1/m) w, its work booked."""
        if self.scaled:
            self.A.multAdd(self._u, self._v, self._v)
        else:
            self.K.mult(self._u, self._w)
            self.work_local += velocity_update(self.coef, self._w.array, v, h_avg)

    def stable_dt(self) -> float:
        """2 / omega of the element bound over these bodies' cells (s), fixed dofs removed;
        computed once (the cells do not move at small strain). Collective."""
        if self._stable_dt is None:
            names = [n for n, p in zip(self.model.part_names, self.model.parts)
                     if any(p is q for q in self.parts)]
            self._stable_dt = parts_stable_dt(self.model, self.fixed, names)
        return self._stable_dt

    def book(self) -> Booking:
        """stored = 1/2 u . K u of the bound u (J, this rank's owned rows)."""
        if self._Ku is None:
            self._Ku = self.K.createVecLeft()
        self.K.mult(self._u, self._Ku)
        stored = 0.5 * float(np.dot(self._u.array_r, self._Ku.array_r))
        return Booking(work=None, stored=stored, dissipated=0.0)
