"""Contact in plane strain (small strain): node pairs paired by x and node to segment, the
symmetry plane's rules only where a half model declares one (docs/plane_strain.md).

Oracles:

* the half model: a striker (nu = 0.3, free sides) hitting a target, the section
  x in [0, w] with symmetry = "x=0" against the full section x in [-w, w] (both
  structured with alternating diagonals, mirror symmetric): the same displacement at
  every node of the half, the full model's contact force twice the half's, node pairs
  and node to segment, FILM and DME;
* the rigid twin of the half model: a flat rigid punch of half-width b (the nodes with
  |x| <= b) pushed into a block, half (x >= 0, half the punch's mass and force) against
  full, FILM and DME: the same displacements, the punch's too, and the energy ledger
  closing to round-off in both;
* the symmetry-plane rule of node to segment: a slave on x = 0 over a master tip on
  x = 0 takes the axial normal with a declared plane, the segment's without one.
"""
import math

import numpy as np
import pytest
from mpi4py import MPI

from impact_fenics import loads, meshing
from impact_fenics.bodies import Body, DeformableModel
from impact_fenics.contact import DME, FILM, RigidBody, pair_surfaces, rigid_face
from impact_fenics.contact.segments import build, node_to_segment
from impact_fenics.geometry import PLANE_STRAIN, Geometry
from impact_fenics.materials import LinearElastic
from impact_fenics.simulation import Settings, Simulation
from roundoff import ledger

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


B, PUNCH_MASS, PEAK = 0.005, 0.02, 200e6  # m, kg (the full punch's), Pa


def _punch(method: str, half: bool):
    """A rigid flat punch of half-width B on a block 2 W x W (x in [-W, W], or the half
    x in [0, W] with symmetry = "x=0", half the punch's mass and force), bottom held in
    y, pushed by -PEAK 2 B t (N) rising over 2 us: (node x, y, node u, punch u, summary,
    the number of constraints)."""
    comm = MPI.COMM_WORLD
    share = 0.5 if half else 1.0
    tmesh = meshing.block(W * (1 if half else 2), W, h=W / 8, comm=comm)
    if not half:
        tmesh.mesh.geometry.x[:, 0] -= W
    t = 0.01
    model = DeformableModel(tmesh, [Body("block", STEEL)],
                            geometry=Geometry(PLANE_STRAIN, t, "x=0" if half else None))
    pulse = loads.Trapezoid(peak=1.0, t_rise=2e-6, t_fall=1.0, t_end=2.0)
    punch = RigidBody("punch", share * PUNCH_MASS,
                      force=lambda time: -share * PEAK * 2 * B * t * pulse(time))
    dt = 0.3 * (W / 8) / C_L
    sim = Simulation(model, Settings(dt=dt, n_steps=N_STEPS, out=None, quiet=True),
                     fixed=[model.facet_dofs("bottom", 1)])
    cons = rigid_face(model, "top", B, "punch")
    sim.add_contact(cons, FILM() if method == "film" else DME(restitution=0.0), rigid=punch)
    summary = sim.run()
    xy = model.node_xy[: model.n_owned // 2]
    u = sim.integrator.u_vec.array.reshape(-1, 2)
    nodes = comm.allgather((xy, u))
    return (np.concatenate([a for a, _ in nodes]), np.concatenate([b for _, b in nodes]),
            punch.u, summary, cons.n)


@pytest.mark.parametrize("method", ["film", "dme"])
def test_rigid_punch_half_model_equals_the_full_one(method):
    """The half against the full model under a rigid punch, round-off as for the two
    bodies (72 n^2 eps of the largest u, the punch's displacement included); the faces:
    the 5 nodes of x in [0, B] and the 9 of [-B, B]; each run's ledger within
    tests/roundoff.py's bound (the steps' roundings summed)."""
    xy_h, u_h, p_h, s_h, n_h = _punch(method, half=True)
    xy_f, u_f, p_f, s_f, n_f = _punch(method, half=False)
    assert (n_h, n_f) == (5, 9)
    assert p_h < 0.0, "the punch did not move down"
    key = lambda xy: np.lexsort((np.round(xy[:, 0] / 1e-7), np.round(xy[:, 1] / 1e-7)))
    right = xy_f[:, 0] >= -1e-12
    xy_f, u_f = xy_f[right], u_f[right]
    a, b = key(xy_h), key(xy_f)
    assert np.allclose(xy_h[a], xy_f[b], rtol=0, atol=1e-12)
    scale = max(float(np.abs(u_f).max()), abs(p_f))
    err = max(float(np.abs(u_h[a] - u_f[b]).max()), abs(p_h - p_f))
    print(f"rigid punch, {method}: half against full, u differs by {err:.3g} m of "
          f"{scale:.3g} m (punch {p_h!r}, {p_f!r} m); ledgers "
          f"{s_h['energy_balance_error_rel']:.3g}, {s_f['energy_balance_error_rel']:.3g}")
    assert err <= 72 * N_STEPS ** 2 * EPS * scale
    for s in (s_h, s_f):
        assert s["energy_balance_error_rel"] <= ledger(s["n_steps"], s["n_dofs"])


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


def test_node_to_segment_messages_name_x_and_y():
    """In plane strain node to segment names the coordinates x and y (as the probes and the
    node pairs do): a slave face with no master segment within reach is refused in one
    line giving its first node as (x=..., y=...)."""
    from impact_fenics.errors import InputError

    model = DeformableModel(_mesh("pairs", W), [Body("striker", STEEL), Body("target", STEEL)],
                            geometry=Geometry(PLANE_STRAIN, 0.01))
    with pytest.raises(InputError, match=r"have no segment of 'striker_end' within reach "
                                         r"\S+ m, first at \(x=[-0-9.e]+, y=[-0-9.e]+\)"):
        node_to_segment(model, "target_contact", "striker_end")
