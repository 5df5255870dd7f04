"""Assembled operators: the stiffness K (N/m), the lumped mass (kg) and load vectors (N).

On triangles K and the lumped mass are UFL forms assembled by dolfinx. On
quadrilaterals they come from the Q1 geometry of :mod:`.q1`: K from the mean-dilatation
(B-bar) element matrices, inserted into the matrix dolfinx preallocates for the Q1
space (a UFL form over the same cells gives only its sparsity and local-to-global
map), and the lumped mass from the Gauss-point weights, as the finite-strain driver's.
"""
from __future__ import annotations

import numpy as np
import ufl
from petsc4py import PETSc
from dolfinx import fem
import dolfinx.fem.petsc  # noqa: F401  (registers fem.petsc)

from . import q1
from .bodies import DeformableModel
from .compat import compile_form, scatter_add
from .errors import InputError
from .forms import Part, lumped_mass_form, stiffness_form


def assemble_stiffness(model: DeformableModel, matrix_type: str = "aij",
                       parts: list | None = None) -> PETSc.Mat:
    """Assemble K (N/m) as a PETSc matrix; ``matrix_type`` 'aij' or 'baij' (block size 2).

    ``parts``: the (material, measure) parts to include (default: every body; a
    path-dependent material contributes its elastic stiffness).

    The matrix is created in its final format (converting, or copying, a BAIJ
    matrix costs seconds and leaves a slower MatMult)."""
    if matrix_type not in ("aij", "baij"):
        raise InputError(f"matrix_type = '{matrix_type}': use 'aij' or 'baij'")
    if model.quadrilateral:
        return assemble_bbar_stiffness(model, matrix_type, parts)
    form = compile_form(stiffness_form(model.V, model.parts if parts is None else parts,
                                       model.geometry))
    K = fem.petsc.create_matrix(form, matrix_type)
    K.zeroEntries()
    fem.petsc.assemble_matrix(K, form)
    K.assemble()
    return K


def elastic_stiffness(material) -> np.ndarray:
    """D (Pa, 4 x 4) of ``material`` in the notation (rr, tt, zz, rz), tensor shear: read
    from a linear material's stress, the elastic one of a path-dependent material."""
    from .cell_fields import isotropic_stiffness, stiffness_matrix

    D = stiffness_matrix(material) if material.linear else None
    return isotropic_stiffness(material.lmbda, material.mu) if D is None else D


def bbar_element_matrices(model: DeformableModel, part: Part
                          ) -> tuple[q1.QuadGeometry, np.ndarray]:
    """The Q1 geometry of the owned cells of ``part`` and their B-bar element matrices
    (n, 8, 8) (N/m, dof order 2 a + component; :func:`.q1.bbar_element_matrices`)."""
    g = q1.QuadGeometry(model.cell_dofs, model.node_xy, model.owned_cells(model.part_body(part)),
                       model.geometry)
    Ke = np.empty((g.dofs.shape[0], 8, 8))
    q1.bbar_element_matrices(g.dNdR, g.dNdZ, g.N, g.inv_R, g.w, elastic_stiffness(part[0]), Ke)
    return g, Ke


def assemble_bbar_stiffness(model: DeformableModel, matrix_type: str = "aij",
                            parts: list | None = None) -> PETSc.Mat:
    """K (N/m) of the B-bar Q1 element over ``parts`` (default: every body) on a
    quadrilateral mesh: the element matrices of the owned cells, summed into local rows
    (owned and ghost nodes, local unrolled indices) and added to the matrix dolfinx
    preallocates for a Q1 form over the same cells, through its local-to-global map;
    PETSc sends the ghost rows to their owners. An insertion outside the preallocated
    pattern is an error, not a silent reallocation."""
    import scipy.sparse as sp

    parts = model.parts if parts is None else parts
    u, w = ufl.TrialFunction(model.V), ufl.TestFunction(model.V)
    pattern = compile_form(sum(ufl.inner(u, w) * dx for _, dx in parts))
    K = fem.petsc.create_matrix(pattern, matrix_type)
    K.setOption(PETSc.Mat.Option.NEW_NONZERO_ALLOCATION_ERR, True)
    K.zeroEntries()
    n_local = model.n_local
    rows, cols, vals = [], [], []
    for part in parts:
        g, Ke = bbar_element_matrices(model, part)
        dofs = (2 * g.dofs[:, :, None] + np.arange(2)).reshape(-1, 8)  # (n, 8) unrolled
        rows.append(np.repeat(dofs, 8, axis=1).ravel())
        cols.append(np.tile(dofs, (1, 8)).ravel())
        vals.append(Ke.ravel())
    local = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                          shape=(n_local, n_local))
    local.sum_duplicates()
    local.sort_indices()
    K.setValuesLocalCSR(local.indptr.astype(PETSc.IntType), local.indices.astype(PETSc.IntType),
                        local.data, addv=PETSc.InsertMode.ADD_VALUES)
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
    """Owned entries of the lumped mass vector (kg), row sums of the consistent mass
    (on quadrilaterals by the 2x2 Gauss rule of :meth:`.q1.QuadGeometry.lumped_mass`)."""
    if model.quadrilateral:
        m = quadrilateral_lumped_mass(model)
    else:
        m = assemble_owned(model, lumped_mass_form(model.V, model.parts, model.geometry))
    bad = int(np.sum(m <= 0.0))
    if model.comm.allreduce(bad):
        raise InputError(f"{model.comm.allreduce(bad)} dofs have no positive lumped mass: "
                         "check that every cell belongs to a body with density > 0")
    return m


def quadrilateral_lumped_mass(model: DeformableModel) -> np.ndarray:
    """Owned entries of the lumped mass (kg) of a quadrilateral mesh: per body its cells'
    rho sum_q w_q N_a(x_q), ghost contributions summed into their owners."""
    m_fn = fem.Function(model.V)
    n_nodes = model.node_xy.shape[0]
    nodal = np.zeros(n_nodes)
    for name, (material, _) in zip(model.part_names, model.parts):
        g = q1.QuadGeometry(model.cell_dofs, model.node_xy, model.owned_cells(name),
                            model.geometry)
        nodal += g.lumped_mass(material.density, n_nodes)
    m_fn.x.array[0::2] = nodal
    m_fn.x.array[1::2] = nodal
    scatter_add(m_fn.x)
    return m_fn.x.array[: model.n_owned].copy()
