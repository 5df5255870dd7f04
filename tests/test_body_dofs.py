"""A body's owned dofs are every owned node its cells touch, on any rank.

On a mesh ghosted by shared facet, an owned node whose cells of a body all sit on
another rank and meet this rank's cells at that node only is not in any of this rank's
cells of that body (the modern stack's 2-rank partition of the bonded discs has one).
Its body's initial velocity, mass and momentum must still reach it.

Oracle: the bodies of the bonded discs are two slabs, the linear disc at z <= 5 mm and
the J2 disc at z >= 5 mm (their interface nodes shared), so a body's nodes are known from
the nodes' coordinates alone, whatever the partition. The initial momentum of a run that
throws one disc is then exactly v0 times the lumped mass of that slab's nodes, summed
here from the mass vector (same terms, so the sums agree to the reordering of a sum of
positive terms: n eps relative).
"""
import numpy as np
from mpi4py import MPI

from impact_fenics.simulation import Settings, Simulation
from test_energy import _bonded_with_a_loaded_face

COMM = MPI.COMM_WORLD
INTERFACE = 5e-3  # m, the discs' common face
SLABS = {"anvil": lambda z, tol: z <= INTERFACE + tol, "plate": lambda z, tol: z >= INTERFACE - tol}


def _slab_dofs(model, body: str, component: int) -> np.ndarray:
    """Owned dofs of ``component`` of the nodes inside ``body``'s slab (by coordinates)."""
    n_nodes = model.n_owned // model.bs
    z = model.node_xy[:n_nodes, 1]
    tol = 1e-9 * model.length_scale
    return (np.flatnonzero(SLABS[body](z, tol)) * model.bs + component).astype(np.int32)


def test_a_body_holds_every_owned_node_its_cells_touch_on_any_rank():
    model = _bonded_with_a_loaded_face()
    for body in SLABS:
        for component in (0, 1):
            got, want = model.body_dofs(body, component), _slab_dofs(model, body, component)
            missing = COMM.allreduce(int(np.setdiff1d(want, got).size))
            extra = COMM.allreduce(int(np.setdiff1d(got, want).size))
            assert (missing, extra) == (0, 0), (body, component, missing, extra)


def test_a_thrown_body_starts_with_its_whole_momentum():
    """The J2 disc thrown at 3 m/s, the linear disc at rest: v0 is 3 m/s on exactly the
    J2 disc's nodes (its interface included), the mass and the momentum its slab's."""
    model = _bonded_with_a_loaded_face()
    vz = 3.0
    sim = Simulation(model, Settings(cfl=0.5, n_steps=1, quiet=True),
                     initial_velocity={"plate": (0.0, vz)})
    v0 = sim.integrator.v_owned
    want = np.zeros(model.n_owned)
    want[_slab_dofs(model, "plate", 1)] = vz
    assert COMM.allreduce(int(np.count_nonzero(v0 != want))) == 0
    mass = sim.integrator.mass
    slab_mass = COMM.allreduce(float(mass[_slab_dofs(model, "plate", 1)].sum()))
    momentum = COMM.allreduce(float(mass @ v0))
    n = COMM.allreduce(_slab_dofs(model, "plate", 1).size)
    eps = np.finfo(float).eps
    # sums of the same n positive terms in another order: n eps relative each
    assert abs(sim.body_mass["plate"] - slab_mass) <= n * eps * slab_mass
    assert abs(momentum - vz * slab_mass) <= 2 * n * eps * vz * slab_mass
