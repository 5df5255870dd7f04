"""The explicit loop of paper eq. (1) on PETSc vectors: one MatMultAdd and one AXPY per step.

The modified Euler scheme

    a^n = M^-1 (f^n - K u^n),  v^{n+1} = v^n + dt a^n,  u^{n+1} = u^n + dt v^{n+1}

runs as  v <- A u + v  (MatMultAdd with A = -dt M^-1 K, scaled once), the few
loaded dofs get dt M^-1 f^n, then  u <- u + dt v  (VecAXPY). Fixed dofs have
zero rows in A and stay at rest. The velocity is kept as a state of its own
(not recovered from differences of displacements), so a body that drifts far
keeps its velocity to full precision.

Between :meth:`predict` and :meth:`advance`, contact sets read the predicted
state from the views ``u_owned``/``v_owned`` and write the corrected positions
and velocities of their own dofs back into them.
"""
from __future__ import annotations

import numpy as np
from petsc4py import PETSc

from .bodies import DeformableModel
from .errors import InputError
from .loads import SurfaceLoad
from .operators import assemble_stiffness, lumped_mass


class Integrator:
    """State (u^n, v^n) of the deformable dofs and the step without contact.

    Units: dt in s, displacements in m, velocities in m/s, masses in kg.
    """

    def __init__(self, model: DeformableModel, dt: float, fixed_dofs: np.ndarray,
                 loads: list[SurfaceLoad] | None = None, matrix_type: str = "aij"):
        if not dt > 0.0:
            raise InputError(f"dt = {dt} s: the time step must be > 0")
        self.model = model
        self.dt = float(dt)
        self.n = 0
        self.loads = loads or []
        self.fixed = np.unique(np.asarray(fixed_dofs, dtype=np.int32))
        self.K = assemble_stiffness(model, matrix_type)
        self.mass = lumped_mass(model)
        self.A = self._update_matrix(assemble_stiffness(model, matrix_type))
        self._u = self.K.createVecRight()
        self._v = self.K.createVecRight()
        self._u.set(0.0), self._v.set(0.0)
        # numpy views on the owned entries of u and v (m, m/s): contact sets read the
        # prediction from them and write their corrected dofs back into them
        self.u_owned = self._u.array
        self.v_owned = self._v.array
        self._free = np.ones(model.n_owned, dtype=bool)
        self._free[self.fixed] = False
        # per load: its free dofs (a fixed dof stays at rest under any load), dt f / m
        # there, and two buffers
        free = [self._free[ld.dofs] for ld in self.loads]
        self._load_dofs = [ld.dofs[k].astype(np.intp) for ld, k in zip(self.loads, free)]
        self._load_coef = [self.dt * ld.force[k] / self.mass[ld.dofs[k]]
                           for ld, k in zip(self.loads, free)]
        self._load_buf = [(np.empty(d.size), np.empty(d.size)) for d in self._load_dofs]

    def _update_matrix(self, A: PETSc.Mat) -> PETSc.Mat:
        """Scale a fresh copy of K into A = -dt M^-1 K with zero rows on the fixed dofs.

        (A second assembly, not K.copy(): a copied BAIJ matrix multiplies slower.)"""
        scale = self.K.createVecRight()
        scale.array[:] = -self.dt / self.mass
        A.diagonalScale(L=scale)
        A.zeroRows(self.model.to_global(self.fixed).astype(PETSc.IntType), diag=0.0)
        scale.destroy()
        return A

    # ------------------------------------------------------------ state
    @property
    def t(self) -> float:
        """Time of the current state (s)."""
        return self.n * self.dt

    def set_initial(self, u0: np.ndarray | None, v0: np.ndarray | None) -> None:
        """Set u^0 (m) and v^0 (m/s) on the owned dofs; fixed dofs are kept at zero."""
        self.n = 0
        for target, values in ((self.u_owned, u0), (self.v_owned, v0)):
            target[:] = 0.0 if values is None else values
            target[~self._free] = 0.0

    def displacement(self, out: np.ndarray) -> np.ndarray:
        """u^n (m) on the owned dofs, copied into ``out``."""
        out[:] = self.u_owned
        return out

    def velocity(self, out: np.ndarray) -> np.ndarray:
        """v^n (m/s) on the owned dofs, copied into ``out``."""
        out[:] = self.v_owned
        return out

    @property
    def u_vec(self) -> PETSc.Vec:
        """The displacement vector u^n (read it, do not resize it)."""
        return self._u

    # ------------------------------------------------------------ the step
    def predict(self) -> None:
        """Step without contact: (u, v) become the predicted (u~^{n+1}, v~^{n+1})."""
        self.A.multAdd(self._u, self._v, self._v)
        if self.loads:
            t = self.t
            for ld, dofs, coef, (buf, inc) in zip(self.loads, self._load_dofs,
                                                  self._load_coef, self._load_buf):
                value = ld.history(t)
                if value != 0.0:
                    np.take(self.v_owned, dofs, out=buf)
                    np.multiply(coef, value, out=inc)
                    buf += inc
                    self.v_owned[dofs] = buf
        self._u.axpy(self.dt, self._v)

    def take_velocity(self, dofs: np.ndarray, out: np.ndarray) -> None:
        """v on owned ``dofs`` (m/s): v^n before :meth:`predict`."""
        np.take(self.v_owned, dofs, out=out)

    def advance(self) -> None:
        """Accept the step: the corrected state becomes (u^{n+1}, v^{n+1})."""
        self.n += 1
