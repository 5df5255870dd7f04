"""Assembled operators against exact values: mass = rho * volume, K kills rigid z motion,
both to a count of roundings (tests/roundoff.py)."""
import math

import numpy as np
import pytest

from impact_fenics import meshing
from impact_fenics.bodies import Body, DeformableModel
from impact_fenics.materials import LinearElastic
from impact_fenics.operators import assemble_stiffness, lumped_mass
from roundoff import rounding

STEEL = LinearElastic(E=200e9, nu=0.3, density=7850.0)
ALU = LinearElastic(E=70e9, nu=0.33, density=2700.0)


def _sum(comm, a):
    return comm.allreduce(float(np.sum(a)))


def _mass_round(comm, n_nodes_local: int) -> float:
    """Relative round-off of a body's mass: each node's lumped mass sums its cells' ring
    integrals (about 30 roundings), the total sums the nodes (one rounding each)."""
    return rounding(30 + comm.allreduce(n_nodes_local))


@pytest.mark.parametrize("structured", [True, False])
def test_total_mass_is_rho_times_ring_volume(structured):
    # bar: volume pi a^2 L; the ring measure 2 pi r makes the lumped masses kg
    a, L = 0.05, 0.3
    model = DeformableModel(meshing.bar(radius=a, length=L, h=0.01, structured=structured),
                            [Body("bar", STEEL)])
    m = lumped_mass(model)
    exact = STEEL.density * math.pi * a ** 2 * L
    for comp in (0, 1):
        assert abs(_sum(model.comm, m[comp::2]) - exact) <= _mass_round(
            model.comm, m.size // 2) * exact


def test_total_mass_per_body_with_two_materials():
    a, ls, lt = 0.1, 0.2, 0.3
    model = DeformableModel(meshing.coaxial_bars(radius=a, striker_length=ls, target_length=lt,
                                                 h=0.025), [Body("striker", STEEL), Body("target", ALU)])
    m = lumped_mass(model)
    for body, mat, length in (("striker", STEEL, ls), ("target", ALU, lt)):
        exact = mat.density * math.pi * a ** 2 * length
        dofs = model.body_dofs(body, 1)
        assert abs(_sum(model.comm, m[dofs]) - exact) <= _mass_round(model.comm, dofs.size) * exact


def test_lumped_mass_is_positive_on_the_axis():
    model = DeformableModel(meshing.bar(radius=0.05, length=0.2, h=0.01), [Body("bar", STEEL)])
    m = lumped_mass(model)
    axis = model.axis_dofs()
    assert model.comm.allreduce(int(np.sum(m[axis] <= 0.0))) == 0


@pytest.mark.parametrize("matrix_type", ["aij", "baij"])
def test_stiffness_annihilates_rigid_z_translation(matrix_type):
    model = DeformableModel(meshing.bar(radius=0.05, length=0.3, h=0.01, structured=False),
                            [Body("bar", STEEL)])
    K = assemble_stiffness(model, matrix_type)
    t, f = K.createVecs()
    t.array[:] = 0.0
    t.array[1::2] = 1.0  # u_z = 1 m everywhere
    K.mult(t, f)
    scale = K.norm(2)  # Frobenius norm (N/m), the size of a typical K entry times sqrt(nnz)
    # a row sum of at most 18 entries, each assembled from up to 6 cells' entries (about
    # 20 roundings of a quadrature each): 44 roundings of sum_j |K_ij| <= sqrt(18) |K|_F
    assert f.norm(3) <= rounding(44 * math.sqrt(18), scale)  # NORM_INFINITY
    # and a radial translation is not rigid in axisymmetry (eps_tt = u_r / r)
    t.array[:] = 0.0
    t.array[0::2] = 1.0
    K.mult(t, f)
    assert f.norm(3) > 1e-6 * scale
