"""Assembled operators: the stiffness K (N/m), the lumped mass (kg) and load vectors (N)."""
from __future__ import annotations

import numpy as np
from petsc4py import PETSc
from dolfinx import fem
import dolfinx.fem.petsc  # noqa: F401  (registers fem.petsc)

from .bodies import DeformableModel
from .compat import compile_form
from .errors import InputError
from .forms import lumped_mass_form, stiffness_form


def assemble_stiffness(model: DeformableModel, matrix_type: str = "aij",
                       parts: list | None = None) -> PETSc.Mat:
    """Assemble K (N/m) as a PETSc matrix; ``matrix_type`` 'aij' or 'baij' (block size 2).

    ``parts``: the (material, measure) parts to include (default: every body; a
    path-dependent material contributes its elastic stiffness).

    The matrix is created in its final format (converting, or copying, a BAIJ
    matrix costs seconds and leaves a slower MatMult)."""
    if matrix_type not in ("aij", "baij"):
        raise InputError(f"matrix_type = '{matrix_type}': use 'aij' or 'baij'")
    form = compile_form(stiffness_form(model.V, model.parts if parts is None else parts))
    K = fem.petsc.create_matrix(form, matrix_type)
    K.zeroEntries()
    fem.petsc.assemble_matrix(K, form)
    K.assemble()
    return K


def assemble_owned(model: DeformableModel, form) -> np.ndarray:
    """Assemble a linear form and return its owned entries (ghost contributions added)."""
    vec = fem.petsc.assemble_vector(compile_form(form))
    vec.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
    with vec.localForm() as local:
        values = local.array_r[: model.n_owned].copy()
    vec.destroy()
    return values


def lumped_mass(model: DeformableModel) -> np.ndarray:
    """Owned entries of the lumped mass vector (kg), row sums of the consistent mass."""
    m = assemble_owned(model, lumped_mass_form(model.V, model.parts))
    bad = int(np.sum(m <= 0.0))
    if model.comm.allreduce(bad):
        raise InputError(f"{model.comm.allreduce(bad)} dofs have no positive lumped mass: "
                         "check that every cell belongs to a body with density > 0")
    return m
