"""Internal force of the linear bodies: K assembled once, f_int = K u by one MatMultAdd.

The velocity update  v <- v - dt M^-1 K u  runs as  v <- A u + v  with
A = -dt M^-1 K scaled once (zero rows on the fixed dofs). K covers the cells of
the linear bodies only (all of them when every body is linear, which is the
original path, unchanged).
"""
from __future__ import annotations

import numpy as np
from petsc4py import PETSc

from ..bodies import DeformableModel
from ..forms import Part
from ..operators import assemble_stiffness


class LinearForce:
    """K (N/m) over ``parts`` and A = -dt M^-1 K; ``mass`` the owned lumped masses (kg),
    ``fixed_global`` the global indices of the owned fixed dofs."""

    def __init__(self, model: DeformableModel, parts: list[Part], dt: float, mass: np.ndarray,
                 fixed_global: np.ndarray, matrix_type: str = "aij"):
        self.K = assemble_stiffness(model, matrix_type, parts)
        # a second assembly, not K.copy(): a copied BAIJ matrix multiplies slower
        self.A = assemble_stiffness(model, matrix_type, parts)
        scale = self.K.createVecRight()
        scale.array[:] = -dt / mass
        self.A.diagonalScale(L=scale)
        self.A.zeroRows(fixed_global.astype(PETSc.IntType), diag=0.0)
        scale.destroy()
