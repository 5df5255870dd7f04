"""The rigid wall's three methods against the 1D impact of an elastic bar.

A bar of length L with nu = 0 at a small speed v0 (strain v0 / c0 = 2e-4: the
neo-Hookean bar is linear to that order) onto a rigid wall: the continuum
solution is the 1D one (nu = 0 admits exact plane waves: the lateral faces stay
free of stress and every section moves as one, the d'Alembert solution): the bar
stays in contact for 2 L / c0 (c0 = sqrt(E / rho)) and leaves with +v0.
The lumped chain reaches this only as h -> 0: the layer of nodes on the face
(mass rho pi a^2 h / 2, exactly, the row sum of Q1's consistent mass) loses its
kinetic energy K0 h / (2 L) at the impact (FILM, DME; a stiff spring about as
much), about as much again at the release, and the chain's dispersion leaves
vibration energy behind. So the contact duration and the rebound velocity
carry errors of order h / L: the tests bound them by h / L and 1.5 h / L and
demand that they shrink from h = a/2 to h = a/4.

Exact statements, to round-off: the activation loss of the first step is
1/2 m_face v0^2 = K0 h / (2 L); the penalty wall with beta = 1 (``scaled``) is FILM
(one step from one state: the same correction to a few roundings; over a run: within
the spread of a one-ulp change of v0, tests/roundoff.py); with any penalty the
kinetic identity K + W_int + L_wall + E_spring = K0 holds at every step (the spring
energy 1/2 p g^2 is stored, then returned when the spring releases: zero after the bar
has left), to the round-off of a ledger (roundoff.ledger).
"""
import math

import numpy as np
import pytest
from mpi4py import MPI

from finite_body import bar_simulation
from impact_fenics.contact import Penalty
from impact_fenics.quad_meshes import quad_bar
from wall_oracle import RigidWall, standalone_plane
from impact_fenics.materials.neo_hookean import NeoHookean
from roundoff import assert_within_spread, ledger, one_ulp, rounding

E, RHO, V0, A, L = 200e9, 7850.0, 1.0, 0.01, 0.1  # Pa, kg/m^3, m/s, m, m
C0 = math.sqrt(E / RHO)
BAR = NeoHookean(E=E, nu=0.0, density=RHO)


def impact(comm, n_r: int, method: str, penalty="scaled", beta: float = 1.0, v0: float = V0):
    """The bar (n_r x 10 n_r square cells) at ``v0`` (m/s) from contact at t = 0 to 2.6 L / c0
    on the fixed plane through Simulation: its summary, its rows (history and energy, one
    a step, and the bar's mean velocity_z = momentum_z / mass, m/s) and the duration of
    contact (s)."""
    from impact_fenics.scenes import track_bar

    mesh = quad_bar(comm, A, L, n_r, 10 * n_r)
    wall = Penalty(penalty, beta_target=beta) if method == "penalty" else method
    sim = bar_simulation(mesh, BAR, 2.6 * L / C0, (0.0, -v0), wall, history_every=1,
                         energy_every=1)
    track_bar(sim, A, L)
    s = sim.run()
    h = {**sim.history.data(), **sim.energy.data()}
    mass = comm.allreduce(float(sim.integrator.mass[1::2].sum()))
    h["velocity_z"] = h["momentum_z"] / mass
    h["length"] = L + h["u_z_top"] - h["u_z_bottom"]
    on = np.flatnonzero(h["n_active"] > 0)
    # row k holds the state after step k + 1: row 0 is after the first step's correction
    assert on[0] == 0 and on[-1] + 1 < h["time"].size  # in contact from the start, then free
    duration = h["time"][on[-1] + 1] - h["time"][on[0]]
    return s, h, duration


@pytest.mark.parametrize("method, beta", [("film", 1.0), ("penalty", 0.5)],
                         ids=["film", "penalty_beta_0.5"])
def test_elastic_bar_rebounds_as_in_1d(comm, method, beta):
    errors = []
    for n_r in (2, 4):
        s, h, duration = impact(comm, n_r, method, beta=beta)
        h_over_l = (A / n_r) / L
        err_t = abs(duration / (2 * L / C0) - 1.0)
        err_v = abs(h["velocity_z"][-1] / V0 - 1.0)
        assert err_t <= h_over_l and err_v <= 1.5 * h_over_l, (n_r, err_t, err_v)
        assert abs(s["energy_balance_error_rel"]) <= ledger(s["n_steps"], s["n_dofs"])
        assert h["n_active"][-1] == 0  # every spring released
        errors.append((err_t, err_v))
    assert errors[1][0] < errors[0][0] and errors[1][1] < errors[0][1]


def test_first_activation_loss_is_the_face_layers_kinetic_energy(comm):
    """At t = 0 the face nodes (mass rho pi a^2 h / 2) stop: FILM books 1/2 m v0^2.

    Both to round-off: a node's lumped mass is a sum over its cells of a 2 x 2 Gauss rule
    with the 2 pi R weight (about 30 roundings), the kinetic energy 1/2 m v^2 (3 more)
    summed over the nodes (one rounding per term; the closed form: 6)."""
    n_r = 2
    s, h, _ = impact(comm, n_r, "film")
    n_nodes = (n_r + 1) * (10 * n_r + 1)
    K0 = 0.5 * RHO * math.pi * A * A * L * V0 ** 2
    assert s["energy_initial"] == pytest.approx(K0, rel=rounding(40 + n_nodes))
    # the loss books 1/2 (v^- + v) m (v - v~) of each face node (6 roundings) summed over
    # the n_r + 1 face nodes
    assert h["activation_loss"][0] == pytest.approx(K0 * (A / n_r) / (2 * L),
                                                    rel=rounding(40 + 6 + n_r + 1))


# one predicted state of five nodes (dt != dt_avg): arriving, pressing on the wall, pulled
# off it, in the air, and one higher up (Z = 0.01 m) arriving
Z5 = np.array([0.0, 0.0, 0.0, 0.0, 0.01])  # m
MASS5 = np.array([2.0, 0.7, 1.3, 3.1, 0.9])  # kg
DT, DT_AVG = 1.1e-7, 1.05e-7  # s
Z_N = np.array([2e-7, 0.0, 0.0, 5e-7, -0.01 + 3e-7])  # u_z before the step (m)
VZ = np.array([-3.0, -1.0, 0.5, -1.0, -4.0])  # predicted v_z (m/s)
F_INT = np.linspace(-1.0, 1.0, 10)  # N


def _state():
    u, v = np.zeros(10), np.zeros(10)
    v[0::2], v[1::2] = 0.3, VZ
    u[0::2], u[1::2] = 1e-3, Z_N + DT * VZ
    return u, v


def _plane_step(method, **kw):
    """One correction of the fixed plane from the state above: (u, v, reactions (N),
    number active, loss (J), internal-work correction (J))."""
    u, v = _state()
    plane = standalone_plane(Z5, MASS5, u, v, method, **kw)
    w_fix = plane.step(u, v, DT, DT_AVG, F_INT)
    return u, v, plane.set.force.copy(), plane.n_active_local, plane.contact_loss_local, w_fix


def _wall_step(method, **kw):
    """The same correction by the oracle (the former rigid wall's kernel)."""
    u, v = _state()
    wall = RigidWall(np.arange(5), Z5, MASS5, method, **kw)
    w_fix = wall.step(u, v, DT, DT_AVG, F_INT)
    return u, v, wall.impulse.copy(), wall.n_active_local, wall.contact_loss_local, w_fix


def _scales():
    """Per node: the position's magnitudes (|Z|, |u~|, |g~|: g~ = Z + u~ cancels) and the
    velocity's (|v~| and the position's over dt: a correction is g~ / dt)."""
    u, _ = _state()
    gap = Z5 + u[1::2]
    scale_u = np.maximum.reduce([np.abs(Z5), np.abs(u[1::2]), np.abs(gap)])
    return scale_u, np.maximum(np.abs(VZ), scale_u / DT)


def test_scaled_penalty_step_at_beta_one_is_the_film_step():
    """One correction from one predicted state: the spring p = m / (dt dt_avg) on the
    predicted gap g~ puts the node where FILM does, both by the fixed plane. FILM:
    d = dt dt_avg (1/m) (3 roundings), 1/d (1), f = -g~ / d (1); penalty: p = beta / d
    (4), f = -p g~ (1); then both v = v~ + f (dt_avg / m) (3), u = u~ + dt dv (2) and
    g~ = (Z - z_wall) + u~ (2): at most 12 roundings on the largest magnitude of the
    node's terms (_scales), and for the reaction f = m (v - v~) / dt_avg the velocity's
    bound times m / dt_avg."""
    u_f, v_f, f_f, n_f, _, _ = _plane_step("film")
    u_p, v_p, f_p, n_p, _, _ = _plane_step("penalty", penalty="scaled", beta_target=1.0)
    assert n_f == n_p == 3  # the arriving, the pressing and the high arriving node
    scale_u, scale_v = _scales()
    assert np.all(np.abs(v_p[1::2] - v_f[1::2]) <= rounding(12) * scale_v)
    assert np.all(np.abs(u_p[1::2] - u_f[1::2]) <= rounding(12) * scale_u)
    assert np.all(np.abs(f_p - f_f) <= rounding(12) * scale_v * MASS5 / DT_AVG)
    assert np.array_equal(u_p[0::2], u_f[0::2]) and np.array_equal(v_p[0::2], v_f[0::2])


@pytest.mark.parametrize("method, kw", [("film", {}), ("dme", {}),
                                        ("penalty", {"penalty": "scaled", "beta_target": 0.7}),
                                        ("penalty", {"penalty": 3e13})],
                         ids=["film", "dme", "penalty_scaled", "penalty_stiffness"])
def test_plane_step_is_the_wall_step(method, kw):
    """The fixed plane (a contact set with a fixed rigid part) against the former wall's
    kernel (the oracle, tests/wall_oracle.py), one correction from one state, class (b)
    of tests/roundoff.py: the two evaluate the same closed forms in other orders. The
    plane's longer path is counted above (12 roundings: the velocity and the position
    through S's diagonal and h/m); the wall's is shorter (FILM: g~ (2), g~ / dt (1),
    v~ - (1), u = z_wall - Z (1); penalty: 12). DME moves a node onto the plane, u =
    -(Z - z_wall) = z_wall - Z and v = 0 exactly in both: equal. The loss
    -1/2 (v^- + v) m (v - v~) and the internal-work correction 1/2 dt_avg (v - v~) f_int
    are the same expressions on velocities within the bound dv: each node's term moves
    by at most m (|v^-| + 2 |v| + |v~|) dv / 2 (loss) or dt_avg |f_int| dv / 2, and its
    own roundings (6, summed over the 5 nodes: 6 + 5) on the terms' magnitudes."""
    u_p, v_p, f_p, n_p, loss_p, fix_p = _plane_step(method, **kw)
    u_w, v_w, f_w, n_w, loss_w, fix_w = _wall_step(method, **kw)
    assert n_p == n_w == 3
    assert np.array_equal(u_p[0::2], u_w[0::2]) and np.array_equal(v_p[0::2], v_w[0::2])
    scale_u, scale_v = _scales()
    if method == "dme":
        assert np.array_equal(u_p, u_w) and np.array_equal(v_p, v_w)
    du = rounding(12) * scale_u
    dv = rounding(12) * scale_v
    assert np.all(np.abs(u_p[1::2] - u_w[1::2]) <= du)
    assert np.all(np.abs(v_p[1::2] - v_w[1::2]) <= dv)
    # the reaction m (v - v~) / dt_avg (3 more roundings of it)
    assert np.all(np.abs(f_p - f_w) <= dv * MASS5 / DT_AVG + rounding(3, np.abs(f_w)))
    v_new = v_w[1::2]
    v_old = VZ + DT_AVG * F_INT[1::2] / MASS5
    terms = 0.5 * np.abs(v_old + v_new) * MASS5 * np.abs(v_new - VZ)
    move = MASS5 * (np.abs(v_old) + 2 * np.abs(v_new) + np.abs(VZ)) * dv / 2
    assert abs(loss_p - loss_w) <= float(np.sum(move)) + rounding(11, float(np.sum(terms)))
    fix_terms = 0.5 * DT_AVG * np.abs(v_new - VZ) * np.abs(F_INT[1::2])
    fix_move = DT_AVG * np.abs(F_INT[1::2]) * dv / 2
    assert abs(fix_p - fix_w) <= float(np.sum(fix_move)) + rounding(11, float(np.sum(fix_terms)))


def test_scaled_penalty_at_beta_one_is_film(comm):
    """Over the whole run (148 steps, the face's nodes in contact from the first): the
    two differ by a few roundings at each contact step, and the differences grow as the
    run goes on. Bound: the steps x the spread of FILM under a one-ulp change of v0
    (tests/roundoff.py, class (c)); the active set must be the same at every step."""
    a, ha, _ = impact(comm, 2, "film")
    ap, hap, _ = impact(comm, 2, "film", v0=one_ulp(V0))
    b, hb, _ = impact(comm, 2, "penalty", beta=1.0)
    n = a["n_steps"]
    assert n == b["n_steps"] == ap["n_steps"]
    assert np.array_equal(ha["n_active"], hb["n_active"])
    for key in ("velocity_z", "length", "kinetic", "wall_force"):
        assert_within_spread(hb[key], ha[key], hap[key], n, key)
    # the energy: the work of FILM's corrections is the spring's (its loss and what it holds)
    assert_within_spread(hb["contact_work"], ha["contact_work"], hap["contact_work"], n,
                         "contact_work")


def test_penalty_stiffness_stores_and_returns_its_energy(comm):
    """A stiffness in N/m (p dt^2 / m = 0.8 at the lightest face node, dt half the bar's
    limit at the start): while the
    springs are loaded they hold energy, the contact's work falls below its final value
    and comes back as they release (the kinetic identity counts it, to round-off, at
    every step)."""
    from impact_fenics.contact.plane import boundary_nodes
    from finite_body import finite_body

    body = finite_body(quad_bar(comm, A, L, 2, 20), BAR)
    nodes = boundary_nodes(body.V, body.n_owned_nodes)
    face = nodes[np.abs(body.node_xy[nodes, 1]) <= 1e-9 * L]  # the candidates that touch
    m_min = comm.allreduce(float(body.mass[2 * face + 1].min(initial=np.inf)), op=MPI.MIN)
    dt = 0.5 * body.force.stable_dt()
    p = 0.8 * m_min / dt ** 2  # N/m
    # beta = p dt^2 / m at the set-up's step: p (3 roundings), / m, x dt, x dt (3)
    spring = Penalty(p)
    bar_simulation(quad_bar(comm, A, L, 2, 20), BAR, 2.6 * L / C0, (0.0, -V0), spring)
    assert comm.allreduce(spring.info["beta_max"], op=MPI.MAX) == pytest.approx(
        0.8, rel=rounding(6))
    s, h, _ = impact(comm, 2, "penalty", penalty=p)
    K0 = s["energy_initial"]
    bound = ledger(s["n_steps"], s["n_dofs"]) * K0
    assert np.abs(h["balance_error"]).max() <= bound
    assert h["contact_work"].min() < h["contact_work"][-1] - 1e-3 * K0  # stored, returned
    assert h["n_active"][-1] == 0


def test_penalty_above_the_bound_is_refused(comm):
    from impact_fenics.errors import InputError

    with pytest.raises(InputError, match=r"beta_max = .* is above the stable bound 4/3"):
        bar_simulation(quad_bar(comm, A, L, 2, 20), BAR, 1e-6, (0.0, -V0), Penalty(1e15))
