"""Contact in plane strain (small strain): node pairs paired by x and node to segment, the
symmetry plane's rules only where a half model declares one (docs/plane_strain.md).

Oracles:

* the half model: a striker (nu = 0.3, free sides) hitting a target, the section
  x in [0, w] with symmetry = "x=0" against the full section x in [-w, w] (both
  structured with alternating diagonals, mirror symmetric): the same displacement at
  every node of the half, the full model's contact force twice the half's, node pairs
  and node to segment, FILM and DME;
* the symmetry-plane rule of node to segment: a slave on x = 0 over a master tip on
  x = 0 takes the axial normal with a declared plane, the segment's without one.
"""
import math

import numpy as np
import pytest
from mpi4py import MPI

from impact_fenics import meshing
from impact_fenics.bodies import Body, DeformableModel
from impact_fenics.contact import DME, FILM, pair_surfaces
from impact_fenics.contact.segments import build, node_to_segment
from impact_fenics.geometry import PLANE_STRAIN, Geometry
from impact_fenics.materials import LinearElastic
from impact_fenics.simulation import Settings, Simulation

EPS = float(np.finfo(float).eps)
STEEL = LinearElastic(E=200e9, nu=0.3, density=7850.0)
W, L_S, L_T = 0.01, 0.02, 0.03  # m: the half width, the striker's and the target's length
V0 = 5.0  # m/s, the striker's speed (+y)
N_STEPS = 150
# the plane-strain longitudinal speed sqrt((lambda + 2G) / rho) (m/s)
C_L = math.sqrt(STEEL.E * (1 - STEEL.nu) / ((1 + STEEL.nu) * (1 - 2 * STEEL.nu)) / STEEL.density)


def _mesh(kind: str, width: float):
    """The two bars x in [0, width] (m): matching faces of 4 intervals per w (node pairs),
    or 4 on the striker and 6 on the target per w (node to segment). Even counts per w:
    the diagonals alternate by column, so the half is the full grid's right half only then."""
    comm = MPI.COMM_WORLD
    if kind == "pairs":
        return meshing.coaxial_bars(radius=width, striker_length=L_S, target_length=L_T,
                                    h=W / 4, structured=True, comm=comm)
    return meshing.coaxial_bars_sized(radius=width, striker_length=L_S, target_length=L_T,
                                      h_striker=W / 4, h_target=W / 6, structured=True,
                                      comm=comm)


def _impact(kind: str, method: str, half: bool):
    """The run of one model: (node x, y, body (0 striker, 1 target), node u, contact force
    per step, the striker's mass), gathered (the two faces' nodes share their x, y)."""
    comm = MPI.COMM_WORLD
    tmesh = _mesh(kind, W if half else 2 * W)
    if not half:
        tmesh.mesh.geometry.x[:, 0] -= W
    geometry = Geometry(PLANE_STRAIN, 0.01, "x=0" if half else None)
    model = DeformableModel(tmesh, [Body("striker", STEEL), Body("target", STEEL)],
                            geometry=geometry)
    dt = 0.3 * (W / 6) / C_L  # s, well below the stable step of both (the same in both)
    sim = Simulation(model, Settings(dt=dt, n_steps=N_STEPS, out=None, quiet=True),
                     initial_velocity={"striker": (0.0, V0)})
    if kind == "pairs":
        cons = pair_surfaces(model, "striker_contact", "target_contact")
    else:  # the finer target face as slave
        cons = node_to_segment(model, "target_contact", "striker_contact")
    sim.add_contact(cons, FILM() if method == "film" else DME(restitution=0.0))
    sim.run()
    xy = model.node_xy[: model.n_owned // 2]
    body = np.zeros((xy.shape[0], 1))
    body[model.body_dofs("target", 1) // 2] = 1.0
    xy = np.hstack([xy, body])
    u = sim.integrator.u_vec.array.reshape(-1, 2)
    nodes = comm.allgather((xy, u))
    return (np.concatenate([a for a, _ in nodes]), np.concatenate([b for _, b in nodes]),
            np.asarray(sim.history.data()["contact_force"]), sim.body_mass["striker"])


@pytest.mark.parametrize("kind", ["pairs", "segments"])
@pytest.mark.parametrize("method", ["film", "dme"])
def test_half_model_equals_the_full_one(kind, method):
    """The half against the full model. Both are one computation in exact arithmetic (the
    full one mirror symmetric, its u_x = 0 on x = 0 by symmetry where the half holds it),
    so they differ by round-off alone: the full model's forces on x = 0 are sums of mirror
    terms that cancel to some 18 products' rounding a step, the contact solve adds its own
    (a pair's row, a slave's row on at most two segments: within 18 more), and a step's
    error reaches u as dt^2 / m f <= 4 |u| (omega dt <= 2) times those 36 eps, through the
    velocity into the displacement, growing as n^2 / 2 over n steps: 72 n^2 eps of the
    largest u. The contact force is S^-1 times the predicted gap, a linear function of the
    state (u, v) whose error grows as the state's: the same 72 n^2 eps of the largest force."""
    xy_h, u_h, f_h, m_h = _impact(kind, method, half=True)
    xy_f, u_f, f_f, m_f = _impact(kind, method, half=False)
    assert f_h.max() > 0.0, "the bars never touched"
    key = lambda xy: np.lexsort((np.round(xy[:, 0] / 1e-7), np.round(xy[:, 1] / 1e-7),
                                 xy[:, 2]))
    right = xy_f[:, 0] >= -1e-12
    xy_f, u_f = xy_f[right], u_f[right]
    a, b = key(xy_h), key(xy_f)
    assert np.allclose(xy_h[a], xy_f[b], rtol=0, atol=1e-12)
    scale = float(np.abs(u_f).max())
    err = float(np.abs(u_h[a] - u_f[b]).max())
    f_scale = float(np.abs(f_f).max())
    f_err = float(np.abs(f_f - 2.0 * f_h).max())
    print(f"{kind}, {method}: half against full, u differs by {err:.3g} m of {scale:.3g} m, "
          f"the force by {f_err:.3g} N of {f_scale:.4g} N; masses {m_h!r}, {m_f!r} kg")
    assert err <= 72 * N_STEPS ** 2 * EPS * scale
    assert f_err <= 72 * N_STEPS ** 2 * EPS * f_scale
    assert abs(m_f - 2 * m_h) <= 64 * EPS * m_f


def _tip_on_x0(axis: bool):
    """A slave touching, at the origin, a master wedge's tip whose two faces rise to
    (-1, 1) and (1, 1) mm (the wedge above them): both segments project it onto their
    common node, a tie."""
    mm = 1e-3
    master_xy = np.array([[-1.0, 1.0], [0.0, 0.0], [1.0, 1.0]]) * mm
    segments = np.array([[0, 1], [1, 2]])
    inside = np.array([[-0.3, 0.8], [0.3, 0.8]]) * mm  # a point of the wedge behind each
    return build(np.array([[0.0, 0.0]]), np.array([[0, 1]]), master_xy,
                 np.array([[2, 3], [4, 5], [6, 7]]), segments, inside, axis=axis)


def test_symmetry_plane_rule_only_where_declared():
    """A slave on x = 0 at a master tip on x = 0: with the plane declared (the axis rule)
    its normal is (0, -1) exactly, whatever face the tie chose; without it the tie's face
    keeps its own normal, tilted by 45 degrees (x = 0 is then like any other x)."""
    on = _tip_on_x0(True)
    off = _tip_on_x0(False)
    assert on.normal[0, 0] == 0.0 and on.normal[0, 1] == -1.0
    assert abs(abs(off.normal[0, 0]) - math.sqrt(0.5)) <= 4 * EPS
    assert off.normal[0, 1] < 0.0
    assert on.g0[0] == 0.0 and off.g0[0] == 0.0
