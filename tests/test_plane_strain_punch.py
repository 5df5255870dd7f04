"""The Prandtl punch in plane strain: a flat rigid punch pressed slowly into a perfectly
plastic J2 block (docs/plane_strain.md, "The Prandtl punch").

Oracle: the limit pressure of a flat punch of half-width a on a rigid-perfectly plastic
von Mises half-space in plane strain is (2 + pi) k, k = sigma_y / sqrt(3) (Prandtl;
Hill's field gives the same, frictionless or rough), so the half model (symmetry plane
x = 0) carries F' = a (2 + pi) k per thickness at the limit. The block is 20 a wide and
10 a deep (the half 10 a x 10 a), its base held in x and y (a free-sliding base lets the
block split at a lower load), its cells graded toward the punch's corner (x = a, y = 0:
the pressure's singularity), Q1 with the mean dilatation (B-bar: the incompressible
plastic flow does not lock). The punch is a rigid face on the nodes of |x| <= a,
frictionless (DME), a crosshead of prescribed velocity ramped from 0 to V over 40
elastic transits of the depth and held to a travel of 100 yield strains of a (the curve
has flattened: its rise over the last tenth is stated). The limit is read as the mean
force over the last tenth of the travel.

Inertia: V is set by rho V c_L = 0.01 (2 + pi) k, the stress of a sudden start at V, an
upper bound on what the smooth ramp leaves ringing; in steady flow at constant V the small-
strain velocity field does not accelerate, so no inertial term is left in the reading.
The prescribed ramp is the heavy punch's force ramp it replaced (whose speed the limit
force lowered by 0.4 % of V), so the same bound.

The displacement finite element limit load converges from above, at O(h) here (the nodal
punch's edge is smeared over the corner cell h_c: its load is carried by a width between
a and a + h_c, an excess of at most h_c / a).
"""
import math

import numpy as np
import pytest
from mpi4py import MPI

from impact_fenics import meshing
from impact_fenics.bodies import Body, DeformableModel
from impact_fenics.contact import DME, RigidBody, rigid_face
from impact_fenics.contact.prescribed import crosshead
from impact_fenics.geometry import PLANE_STRAIN, Geometry
from impact_fenics.materials import J2
from impact_fenics.simulation import Settings, Simulation
from roundoff import ledger

COMM = MPI.COMM_WORLD
RHO, E, NU, SY = 7850.0, 200e9, 0.3, 200e6  # kg/m^3, Pa, -, Pa
A = 0.01  # m, the punch's half-width
WIDTH, DEPTH = 10 * A, 10 * A  # m: the half block (a block 20 a wide, 10 a deep)
T = 0.01  # m, the slab's thickness
N_PUNCH, GRADING = 4, 1.25  # cells under the half punch; growth per cell away from the corner
P_LIMIT = (2 + math.pi) * SY / math.sqrt(3)  # Pa, Prandtl's limit pressure
C_L = math.sqrt(E * (1 - NU) / ((1 + NU) * (1 - 2 * NU)) / RHO)  # m/s
INERTIA = 0.01  # rho V c_L / p_limit: a sudden start's stress over the limit pressure
V_PUNCH = INERTIA * P_LIMIT / (RHO * C_L)  # m/s (0.129)
T_RAMP = 40 * DEPTH / C_L  # s, the velocity ramp: 40 elastic transits of the depth
YIELD_TRAVEL = A * SY / E  # m, a yield strain of a
TRAVEL = 100 * YIELD_TRAVEL  # m, the punch's travel at the end
READ_FROM = 0.9  # the limit: the mean force over the travel's last tenth


def punch_run(refine: int) -> tuple[dict, dict, float]:
    """The summary, the history (time, punch_force, punch_u, ...) of the punch on the mesh
    refined ``refine`` times, and the mesh's corner cell h_c (m)."""
    tmesh = meshing.flat_punch_block(A, WIDTH, DEPTH, N_PUNCH, GRADING, refine, comm=COMM)
    material = J2(E=E, nu=NU, density=RHO, yield_stress=SY, hardening=0.0)
    model = DeformableModel(tmesh, [Body("block", material)],
                            geometry=Geometry(PLANE_STRAIN, T, "x=0"))
    punch = RigidBody("punch", math.inf, prescribed=crosshead("punch", V_PUNCH, T_RAMP))
    t_end = T_RAMP / 2 + TRAVEL / V_PUNCH
    sim = Simulation(model, Settings(quiet=True, plots=False, fields=False, timers=False,
                                     out=None, t_end=t_end, cfl=0.5, history_every=10),
                     fixed=[model.facet_dofs("bottom", 0), model.facet_dofs("bottom", 1)])
    sim.add_contact(rigid_face(model, "punch_face", A, "punch"), DME(), rigid=punch)
    summary = sim.run()
    return summary, sim.history.data(), tmesh.info["h_corner"]


def limit_error(hist: dict) -> tuple[float, float, float]:
    """The limit's error F' / (a (2 + pi) k) - 1 over the travel's last tenth, its ringing
    spread there, and its rise from the tenth before (the curve's creep)."""
    ratio = hist["punch_force"] / (P_LIMIT * A * T)
    travel = -hist["punch_u"] / TRAVEL
    last = travel > READ_FROM
    before = (travel > 2 * READ_FROM - 1) & ~last
    assert last.sum() > 20 and before.sum() > 20
    mean = float(ratio[last].mean())
    return (mean - 1, float(ratio[last].max() - ratio[last].min()),
            mean - float(ratio[before].mean()))


def _slow_enough() -> None:
    assert T_RAMP >= 10 * DEPTH / C_L  # the ramp spans many elastic transits
    assert RHO * V_PUNCH * C_L <= INERTIA * P_LIMIT * (1 + 1e-12)


def test_prandtl_punch_coarse_mesh_above_the_limit_within_one_corner_cell():
    """The coarse mesh (4 cells under the half punch, h_c = 0.173 a): the limit from above,
    by at most the corner cell's share h_c / a plus the ringing bound (the nodal punch's
    edge smears the load over at most one cell beyond x = a); the ledger closes."""
    _slow_enough()
    summary, hist, h_c = punch_run(0)
    error, spread, creep = limit_error(hist)
    print(f"h_c/a = {h_c / A:.4f}: F'/(a(2+pi)k) - 1 = {error:+.4e} (ringing spread "
          f"{spread:.1e}, rise over the last tenth {creep:.1e}); bound h_c/a + {INERTIA}")
    assert INERTIA < error <= h_c / A + INERTIA  # above the limit beyond the ringing bound
    assert spread <= INERTIA
    assert summary["energy_balance_error_rel"] <= ledger(summary["n_steps"], summary["n_dofs"])


@pytest.mark.study
def test_prandtl_punch_refinement_study():
    """Three meshes, every cell halved each time: the error falls from above; the
    finest's is within the O(h) convergence from the finer of the coarser pair,
    e_2 <= e_1 h_c2 / h_c1 (the error's coefficient e / h_c does not grow: the smeared
    edge's excess is linear in the corner cell, and the higher-order terms fall with h),
    plus the reading's uncertainty (the ringing spread and the curve's rise over the
    last tenth, both read off the run). Richardson's prediction with the pair's own rate
    in h_c is printed beside it."""
    _slow_enough()
    rows = []
    for refine in range(3):
        summary, hist, h_c = punch_run(refine)
        error, spread, creep = limit_error(hist)
        rows.append((h_c, error, spread, creep))
        rate = (math.log(rows[-2][1] / error) / math.log(rows[-2][0] / h_c) if refine
                else float("nan"))
        print(f"refine {refine}: h_c/a = {h_c / A:.4f}, F'/(a(2+pi)k) - 1 = {error:+.4e}, "
              f"rate in h_c {rate:.3f} (ringing spread {spread:.1e}, rise over the last tenth "
              f"{creep:.1e}, {summary['n_steps']} steps)")
        assert summary["energy_balance_error_rel"] <= ledger(summary["n_steps"],
                                                              summary["n_dofs"])
    (h0, e0, _, _), (h1, e1, _, _), (h2, e2, s2, c2) = rows
    assert 0 < e2 < e1 < e0  # from above, falling
    rate = math.log(e0 / e1) / math.log(h0 / h1)  # the coarser pair's rate in h_c
    bound = e1 * h2 / h1 + s2 + abs(c2)
    print(f"rates in h_c: {rate:.3f}, {math.log(e1 / e2) / math.log(h1 / h2):.3f}; finest "
          f"error {e2:.4e} against O(h) e1 h_c2/h_c1 = {e1 * h2 / h1:.4e} + reading "
          f"{s2 + abs(c2):.1e} = {bound:.4e} (Richardson with the pair's rate: "
          f"{e1 * (h2 / h1) ** rate:.4e})")
    assert e2 <= bound


def _nodes(tmesh) -> np.ndarray:
    """Every rank's node coordinates (x, y), m, gathered (rounded to 1e-12 m to merge the
    ranks' copies of a shared node)."""
    xy = np.round(tmesh.mesh.geometry.x[:, :2], 12)
    return np.unique(np.vstack(COMM.allgather(xy)), axis=0)


def test_flat_punch_block_is_nested_with_a_node_at_the_corner():
    """The generator: a node at the punch's corner (a, 0), the grid's lines shrinking
    toward the corner, every node of the coarse mesh a node of the refined one (nested,
    each cell halved; h_c more than halved by the square-rooted ratio); bad sizes
    refused in one line."""
    coarse = meshing.flat_punch_block(A, WIDTH, DEPTH, N_PUNCH, GRADING, 0, comm=COMM)
    fine = meshing.flat_punch_block(A, WIDTH, DEPTH, N_PUNCH, GRADING, 1, comm=COMM)
    nodes_c, nodes_f = _nodes(coarse), _nodes(fine)
    assert np.any(np.all(np.abs(nodes_c - [A, 0.0]) < 1e-12, axis=1))
    # a coarse node is a fine node if one lies within a thousandth of the fine mesh's
    # smallest cell (any other fine node is at least a cell away; gmsh places a
    # progression's nodes by its own sums, to about 1e-9 of the block here)
    gap = np.min(np.linalg.norm(nodes_c[:, None, :] - nodes_f[None, :, :], axis=2), axis=1)
    assert np.all(gap <= 1e-3 * fine.info["h_corner"])
    xs = np.unique(nodes_c[:, 0])
    steps = np.diff(xs)
    k = int(np.searchsorted(xs, A))  # xs[k] = a
    assert np.all(steps[:k - 1] > steps[1:k]) and np.all(steps[k:-1] < steps[k + 1:])
    assert 0.5 * coarse.info["h_corner"] > fine.info["h_corner"]
    with pytest.raises(meshing.InputError, match="flat_punch_block"):
        meshing.flat_punch_block(A, 0.5 * A, DEPTH, comm=COMM)
