"""Node-to-segment master geometry from the owners' copies of its nodes.

``V.tabulate_dof_coordinates`` maps each node through one of its cells; a rank
holding a node as a ghost maps it through another cell than the owner does, so
the two copies may differ in the last bit. The master nodes' coordinates must be
the owners' copies, bit for bit, on every rank: the oracle here is an owned-only
gather of the tabulated coordinates, keyed by global node index, computed in the
test from dolfinx alone. The scenes are those of tests/test_contact_nts.py, each
face of the short wide bars (whose target face two ranks split) and each face of
the nosed striker taken as master in turn, so that a master node held as a ghost
somewhere occurs on two and three ranks.
"""
import numpy as np
import pytest
from mpi4py import MPI

from impact_fenics import meshing
from impact_fenics.bodies import Body, DeformableModel
from impact_fenics.contact.segments import node_to_segment
from impact_fenics.materials import STEEL
from impact_fenics.scenes import ALUMINIUM


def _bars(comm, radius=0.05, length=0.2, n_striker=6, n_target=9):
    tmesh = meshing.coaxial_bars_sized(radius=radius, striker_length=length,
                                       target_length=length, h_striker=radius / n_striker,
                                       h_target=radius / n_target, comm=comm)
    return DeformableModel(tmesh, [Body("striker", STEEL), Body("target", STEEL)])


def _nose(comm):
    tmesh = meshing.nosed_striker_on_block(nose_radius=0.02, h_striker=0.02 / 8,
                                           h_block=0.02 / 12, comm=comm)
    return DeformableModel(tmesh, [Body("striker", STEEL), Body("block", ALUMINIUM)])


SCENES = {  # name: (model, slave group, master group, reach in m or None)
    "bars": (_bars, "target_contact", "striker_contact", None),
    "wide_bars": (lambda c: _bars(c, 0.1, 0.02, 12, 18), "target_contact", "striker_contact",
                  None),
    "wide_bars_split_master": (lambda c: _bars(c, 0.1, 0.02, 12, 18), "striker_contact",
                               "target_contact", None),
    "nose": (_nose, "block_contact", "nose", 1.01 * 0.02),
    "block_master": (_nose, "nose", "block_contact", 0.1),
}


def _owners_copies(model) -> np.ndarray:
    """(n_global_nodes, 2): every node's tabulated (r, z) on the rank that owns it."""
    imap = model.V.dofmap.index_map
    lo, hi = imap.local_range
    x = model.V.tabulate_dof_coordinates()[: hi - lo, :2]
    parts = model.comm.allgather((np.arange(lo, hi), x))
    out = np.full((imap.size_global, 2), np.nan)
    for g, xy in parts:
        out[g] = xy
    return out


def _ghost_copies_of(model, nodes: np.ndarray) -> int:
    """How many of the global ``nodes`` some rank holds as a ghost (summed over ranks)."""
    imap = model.V.dofmap.index_map
    ghosts = np.asarray(imap.ghosts)
    return model.comm.allreduce(int(np.isin(nodes, ghosts).sum()))


@pytest.mark.parametrize("scene", list(SCENES))
def test_master_nodes_carry_their_owners_coordinates(scene):
    make, slave, master, reach = SCENES[scene]
    comm = MPI.COMM_WORLD
    model = make(comm)
    c = node_to_segment(model, slave, master, reach=reach)
    nodes = c.master_dofs[:, 1] // 2
    assert np.array_equal(c.master_dofs, np.stack([2 * nodes, 2 * nodes + 1], axis=1))
    owners = _owners_copies(model)
    assert np.array_equal(c.master_xy, owners[nodes])
    # the slaves too (they always read owned nodes), and every rank holds the same geometry
    assert np.array_equal(c.slave_xy, owners[c.slave_dofs[:, 1] // 2])
    mine = (c.master_xy, c.segments, c.normal, c.g0, c.xi, c.seg)
    for other in comm.allgather(mine):
        assert all(np.array_equal(a, b) for a, b in zip(mine, other))
    if scene == "wide_bars_split_master" and comm.size > 1:
        # the case this guards against occurs: some master node is a ghost on a rank
        assert _ghost_copies_of(model, nodes) > 0
