"""The stiffness and the lumped mass of several meshes over the stacked numbering
(impact_fenics.stacked).

Two meshes as in the numbering's tests: a triangle rectangle (P1) and a quadrilateral
rectangle (Q1, B-bar) beside it, each partitioned by dolfinx over all ranks, each with
its stiffness from the project's own assembly. Oracles:

* the stacked product A x equals sum_k K_k x_k bit for bit (each K_k multiplying its
  own slice of x through its own numbering);
* with one mesh, A equals K entry for entry;
* the total lumped mass equals sum_k rho_k V_k (V_k = pi (r1^2 - r0^2) H, the exact
  volume of revolution of rectangle k) to a counted round-off bound;
* an empty share: one mesh given by its partitioner to all ranks but the last, so that
  the last owns none of its dofs; the product and the mass hold unchanged.

Runs unchanged on 1, 2 and 3 ranks (the empty share needs two).
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from mpi4py import MPI
from dolfinx import mesh as dmesh

from impact_fenics import compat
from impact_fenics.bodies import Body, DeformableModel
from impact_fenics.dofs import SceneDofs
from impact_fenics.errors import InputError
from impact_fenics.materials import LinearElastic
from impact_fenics.meshing import TaggedMesh
from impact_fenics.operators import assemble_stiffness, lumped_mass
from impact_fenics.quad_meshes import tag_rectangle
from impact_fenics.stacked import stacked_mass, stacked_operator

COMM = MPI.COMM_WORLD
EPS = np.finfo(float).eps
STEEL = LinearElastic(E=200e9, nu=0.3, density=7850.0)
ALUMINIUM = LinearElastic(E=70e9, nu=0.33, density=2700.0)

# (r0, z0), (r1, z1) in m and cells per side: every node coordinate is a multiple of
# 1/4 m, exact in binary (the mass bound below relies on it)
TRIANGLES = ([0.0, -1.0], [2.0, 0.0], [8, 4])
QUADS = ([0.0, 0.0], [0.5, 2.0], [2, 8])


def _rectangle(spec, cell_type, partitioner=None) -> dmesh.Mesh:
    lo, hi, n = spec
    kwargs = {} if partitioner is None else {"partitioner": partitioner}
    return dmesh.create_rectangle(COMM, [np.array(lo), np.array(hi)], n, cell_type, **kwargs)


def _triangle_model(material=STEEL) -> DeformableModel:
    mesh = _rectangle(TRIANGLES, dmesh.CellType.triangle)
    tdim = mesh.topology.dim
    cmap = mesh.topology.index_map(tdim)
    cells = np.arange(cmap.size_local + cmap.num_ghosts, dtype=np.int32)
    cell_tags = dmesh.meshtags(mesh, tdim, cells, np.ones(cells.size, dtype=np.int32))
    facet_tags = dmesh.meshtags(mesh, tdim - 1, np.zeros(0, dtype=np.int32),
                                np.zeros(0, dtype=np.int32))
    tm = TaggedMesh(mesh, cell_tags, facet_tags, {"body": 1}, {})
    return DeformableModel(tm, [Body("body", material)])


def _quad_model(material=ALUMINIUM, partitioner=None) -> DeformableModel:
    tm = tag_rectangle(_rectangle(QUADS, dmesh.CellType.quadrilateral, partitioner))
    return DeformableModel(tm, [Body("body", material)])


def _scene(models):
    dofs = SceneDofs([m.V for m in models])
    mats = [assemble_stiffness(m) for m in models]
    return dofs, mats


@pytest.fixture(scope="module")
def two():
    models = [_triangle_model(), _quad_model()]
    dofs, mats = _scene(models)
    return models, dofs, mats, stacked_operator(dofs, mats)


@pytest.fixture(scope="module")
def empty_share():
    if COMM.size < 2:
        pytest.skip("an empty share needs a second rank")
    models = [_triangle_model(), _quad_model(partitioner=compat.partitioner_on_fewer_ranks(1))]
    dofs, mats = _scene(models)
    return models, dofs, mats, stacked_operator(dofs, mats)


# --------------------------------------------------------------------- the operator
def _check_product_is_the_sum(dofs: SceneDofs, mats, A, seed: int) -> None:
    """A x against sum_k K_k x_k, x seeded and given by its scene index (each rank draws
    the whole vector and keeps its owned entries, so owners and ghosts agree).

    Bit for bit, because both products do the same additions in the same order: the
    rows of A in mesh k's slice are K_k's owned rows with their columns renumbered by a
    map that is monotone within a mesh and keeps a column on the rank that owns it. A
    parallel AIJ MatMult sums each row's owned columns in CSR order, then adds its
    off-rank columns in CSR order (the serial one: the whole row in CSR order), and
    both the split and the order of every row are K_k's; the values x_k reads (owned
    and gathered from other ranks) are the same numbers."""
    x_all = np.random.default_rng(seed).uniform(-1.0, 1.0, dofs.n_global)
    x, y = A.createVecs()
    x.array[:] = x_all[dofs.offset:dofs.offset + dofs.n_owned]
    A.mult(x, y)
    for k, K in enumerate(mats):
        s = dofs.owned_slice(k)
        x_k, y_k = K.createVecs()
        x_k.array[:] = x.array[s]
        K.mult(x_k, y_k)
        assert np.array_equal(y.array[s], y_k.array), f"mesh {k}"
        # not vacuous: each mesh's product is not zero somewhere
        assert COMM.allreduce(float(np.max(np.abs(y_k.array), initial=0.0)), op=MPI.MAX) > 0.0
        x_k.destroy()
        y_k.destroy()
    x.destroy()
    y.destroy()


def _off_rank_entries(A, dofs: SceneDofs) -> int:
    """Entries of A in columns other ranks own, over all ranks."""
    _, cols, _ = A.getValuesCSR()
    own = (cols >= dofs.offset) & (cols < dofs.offset + dofs.n_owned)
    return COMM.allreduce(int(np.sum(~own)))


def test_stacked_product_equals_the_sum_of_the_meshes(two):
    _, dofs, mats, A = two
    assert A.getSizes() == ((dofs.n_owned, dofs.n_global),) * 2
    assert A.getOwnershipRange() == (dofs.offset, dofs.offset + dofs.n_owned)
    assert A.getInfo()["nz_used"] == sum(K.getInfo()["nz_used"] for K in mats)
    if COMM.size > 1:
        assert _off_rank_entries(A, dofs) > 0  # the off-rank columns are exercised
    for seed in (1, 2, 3):
        _check_product_is_the_sum(dofs, mats, A, seed)


@pytest.mark.parametrize("make", [_triangle_model, _quad_model], ids=["triangles", "quads"])
def test_one_mesh_gives_K_itself(make):
    model = make()
    K = assemble_stiffness(model)
    A = stacked_operator(model.dofs, [K])
    assert A.getSizes() == K.getSizes()
    assert A.getOwnershipRange() == K.getOwnershipRange()
    for a, k in zip(A.getValuesCSR(), K.getValuesCSR()):
        assert np.array_equal(a, k)


def test_a_matrix_per_mesh_in_its_own_layout(two):
    models, dofs, mats, _ = two
    with pytest.raises(InputError, match="one matrix per mesh"):
        stacked_operator(dofs, mats[:1])
    with pytest.raises(InputError, match="not laid out by its space"):
        stacked_operator(dofs, mats[::-1])
    masses = [lumped_mass(model) for model in models]
    with pytest.raises(InputError, match="one vector per mesh"):
        stacked_mass(dofs, masses[:1])
    with pytest.raises(InputError, match="slice's owned entries"):
        stacked_mass(dofs, masses[::-1])


# -------------------------------------------------------------------- the lumped mass
def _coordinate_scale(spec) -> float:
    """x_max (m): the largest |coordinate| of rectangle ``spec``."""
    lo, hi, _ = spec
    return float(np.max(np.abs([lo, hi])))


def _rounding_bound(models) -> tuple[float, int]:
    """The relative round-off bound of the total lumped mass, and its term count N.

    Exactly, the total of one component is the sum over cells, points q and cell nodes a
    of rho w_q N_a(x_q), N positive terms (3 x 3 per P1 triangle at the degree-2 rule,
    4 x 4 per Q1 cell); sum_a N_a = 1 and both rules integrate r exactly over a straight
    cell, so the exact terms sum to rho V. Computed, each term carries its own relative
    error c eps, and reaches the total through at most N - 1 additions of positive
    numbers (in whatever order the cell loops, the ghost scatter, the sum and the
    allreduce take them), each adding at most eps: |total - rho V| <= (N - 1 + c) eps rho V.

    c, the rounding of one term. Triangles: the form reads the mesh geometry, whose
    coordinates are multiples of 1/4 m (checked), so the Jacobian (differences of
    them) is exact; r_q is a sum of three positive products, the rest a chain of a few
    products: c <= 16. Q1 reads the dof coordinates, each a sum of at most four
    products of exact coordinates and nonnegative weights: within delta = 4 eps x_max
    of exact (checked). J_rr = sum_a r_a dN_a/dxi is worth h_r but is a sum of four
    products of either sign, each at most x_max: absolute error <= 16 eps x_max +
    2 delta (sum_a |dN_a/dxi| = 2), likewise J_zz; r_q, a positive sum, is off by
    8 eps relative plus delta / r_q, and r_q >= (1/2 - 1/(2 sqrt 3)) h_r > h_r / 5:
    c <= (16 x_max + 2 delta/eps + 5 delta/eps) / h_r + (16 x_max + 2 delta/eps) / h_z
    + 16 <= 48 x_max (1/h_r + 1/h_z) + 16; the off-diagonal entries are round-off of a
    rectangle's zero, their product O(eps^2). Then V_k, rho_k V_k and their sum: 8
    roundings more."""
    c, n_terms = 0.0, 0
    for model, spec in zip(models, (TRIANGLES, QUADS)):
        n_cells = model.mesh.topology.index_map(2).size_global
        if model.quadrilateral:
            lo, hi, n = spec
            h_r, h_z = (hi[0] - lo[0]) / n[0], (hi[1] - lo[1]) / n[1]
            n_terms += 16 * n_cells
            c = max(c, 48.0 * _coordinate_scale(spec) * (1.0 / h_r + 1.0 / h_z) + 16.0)
        else:
            n_terms += 9 * n_cells
            c = max(c, 16.0)
    return (n_terms - 1 + c + 8) * EPS, n_terms


def _check_total_mass(models, dofs: SceneDofs) -> None:
    # the premises of the bound: the geometry's coordinates are multiples of 1/4 m, the
    # dof coordinates within 4 eps x_max of them
    for model, spec in zip(models, (TRIANGLES, QUADS)):
        x = model.mesh.geometry.x[:, :2]
        assert np.array_equal(x * 4.0, np.round(x * 4.0))
        xy = model.node_xy
        assert np.all(np.abs(xy - np.round(xy * 4.0) / 4.0) <= 4.0 * EPS * _coordinate_scale(spec))
    masses = [lumped_mass(model) for model in models]
    mass = stacked_mass(dofs, masses)
    # a copy: every mesh's owned slice holds its masses unchanged
    for k, m in enumerate(masses):
        assert np.array_equal(mass.array[dofs.owned_slice(k)], m)
    # the ghosts hold their owners' values: every rank's owned masses by scene index
    owned = np.zeros(dofs.n_global)
    owned[dofs.offset:dofs.offset + dofs.n_owned] = mass.array
    COMM.Allreduce(MPI.IN_PLACE, owned, op=MPI.SUM)  # one nonzero term per entry: exact
    with mass.localForm() as local:
        assert np.array_equal(local.array, owned[dofs.local_to_scene()])
    # both components of a node carry its mass (every offset is even: r at even indices)
    assert np.array_equal(mass.array[0::2], mass.array[1::2])
    total = COMM.allreduce(float(np.sum(mass.array[0::2])))
    exact = sum(material.density * math.pi * (hi[0] ** 2 - lo[0] ** 2) * (hi[1] - lo[1])
                for material, (lo, hi, _) in zip((STEEL, ALUMINIUM), (TRIANGLES, QUADS)))
    bound, n_terms = _rounding_bound(models)
    assert abs(total - exact) <= bound * exact, (total, exact, n_terms, bound)
    mass.destroy()


def test_total_lumped_mass_is_rho_V(two):
    models, dofs, _, _ = two
    _check_total_mass(models, dofs)


# -------------------------------------------------------------------- an empty share
def test_empty_share_takes_part_as_any_other(empty_share):
    models, dofs, mats, A = empty_share
    # forced: the last rank owns none of the quadrilateral mesh's dofs, the others do
    last = COMM.size - 1
    assert dofs.counts[last, 1] == 0 and np.all(dofs.counts[:last, 1] > 0)
    if COMM.rank == last:
        assert models[1].mesh.topology.index_map(2).size_local == 0
        assert dofs.owned_slice(1).start == dofs.owned_slice(1).stop
    for seed in (4, 5):
        _check_product_is_the_sum(dofs, mats, A, seed)
    _check_total_mass(models, dofs)
