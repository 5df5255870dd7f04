"""A rigid part that moves in the plane (plane strain; docs/friction.md 11): its x dof.

A small steel block (W x H, one cell through its height) pressed by a pressure p on its
top onto a rigid plate below it (the plate is the lower side of every constraint) that
moves sideways at V, Coulomb μ between them. Oracles:

* (a) the existing path: a fixed part keeps today's kernels (its pass does not slide) and
  a moving part without friction runs the same normal step whether it moves sideways or
  not (a flat frictionless face does not see x): every node's u and v equal bit for bit;
  the penalty's friction keeps a part held in x unless it is given a sideways velocity
  or force (a fixed part, a part moving along y only: the previous code's arrays);
  a sideways velocity in axisymmetry or over a symmetry plane is refused in one line, and
  a given tangential stiffness past the penalty's bound with the part's 1/M in it;
* (b) x momentum: Σ m v_x of the nodes + M V of the plate is unchanged by every step
  (no external x force) to the round-off of its sums, FILM, DME and the penalty (also on a
  light plate, M = m), and the ledger closes with the plate's 1/2 M V^2 in the kinetic
  energy;
* (c) the closed form of the two-body drag (a light plate, M = m and 3 m, and a heavy one,
  M = 1000 m, free in x and y): the block's mean x velocity is μ J_n / m, J_n the bottom's
  normal impulse F t M / (M + m) + P_o, F = p W t_s the load and P_o the block's y
  momentum about the pair's centre of mass, which the pressure wave keeps within F H / c;
  so the block accelerates at μ F M / ((M + m) m), the gap to the plate closes at μ F / m
  by t* = m V / (μ F), then both move at M V / (M + m) (the penalty: plus its elastic
  lag, docs/friction.md 11); x momentum to round-off;
* (d) a plate without friction moving sideways keeps V exactly and U = Σ h V.

Serial, 2 and 3 ranks (the plate's state is taken on every rank from the gathered data).
"""
import math

import numpy as np
import pytest
from mpi4py import MPI

from impact_fenics import loads, meshing
from impact_fenics.bodies import Body, DeformableModel
from impact_fenics.contact import DME, FILM, Penalty, RigidBody
from impact_fenics.contact.friction import N_SLIP, N_STICK, X_SLIDES
from impact_fenics.contact.plane import plane_below, wall_part
from impact_fenics.errors import InputError
from impact_fenics.geometry import PLANE_STRAIN, Geometry
from impact_fenics.materials import LinearElastic
from impact_fenics.simulation import Settings, Simulation
from roundoff import EPS, ledger

COMM = MPI.COMM_WORLD
STEEL = LinearElastic(E=200e9, nu=0.0, density=7850.0)  # nu = 0: c_L = sqrt(E / rho)
C_L = math.sqrt(STEEL.E / STEEL.density)
C_S = C_L / math.sqrt(2.0)  # nu = 0: mu_shear = E / 2
TS, W, H = 0.01, 0.02, 0.005  # m: the slab's thickness, the block's width and height
P, MU, V = 1e5, 0.3, 0.05  # Pa, -, m/s
DT = 0.3 * H / C_L
MASS = STEEL.density * W * H * TS  # the block's mass (kg)
F = P * W * TS  # the load on its top (N)


def _run(method, n_steps, friction=MU, v_x=V, plate=None, symmetry=None, spring="scaled",
         force=False):
    """The block on the plate for ``n_steps``; per step (after its contact step) the
    block's P_x, P_y (kg m/s), the plate's V (m/s), the stick and slip counts, the stuck
    rows' largest |V - v_k| (m/s) and the largest μ λ_n (N), then
    the summary, the simulation, the set and the plate (``spring``, ``force``: the
    penalty's tangential stiffness and its forcing)."""
    tmesh = meshing.block(W, H, h=H, comm=COMM)
    model = DeformableModel(tmesh, [Body("block", STEEL)],
                            geometry=Geometry(PLANE_STRAIN, TS, symmetry))
    press = loads.SurfaceLoad(model, "top", lambda t: P, traction=(0.0, -1.0))
    sim = Simulation(model, Settings(dt=DT, n_steps=n_steps, out=None, quiet=True),
                     loads=[press])
    bottom = np.unique(model.facet_dofs("bottom", 1) // 2)
    cons = plane_below(COMM, bottom, model.node_xy, model.offset, 0.0, model.length_scale)
    if plate is None:
        plate = RigidBody("plate", 1000.0 * MASS, v_x=v_x)
    methods = {"film": FILM, "dme": lambda: DME(restitution=0.0), "penalty": Penalty,
               "film_dense": lambda: FILM("dense")}  # (dense: the unfused step)
    c = sim.add_contact(cons, methods[method](), rigid=plate)
    c.set_friction(friction, spring, force)
    mass = sim.integrator.mass
    rows = []
    step = c.step

    def recorded():
        step()
        v = sim.integrator.v_owned
        px = COMM.allreduce(float(np.dot(mass[0::2], v[0::2])))
        py = COMM.allreduce(float(np.dot(mass[1::2], v[1::2])))
        fr = c.friction
        t = fr.stats if fr is not None else np.zeros(8)
        # the stuck rows' largest slip rate |V - v_k| (m/s) and the largest cone radius
        # μ λ_n (N) of the step (the penalty's elastic lag, docs/friction.md 11)
        lag = cone = 0.0
        if fr is not None:
            lag = float(np.abs(plate.v_x - fr.v[fr.up])[fr.state == 1].max(initial=0.0))
            cone = friction * float(np.max(c.force, initial=0.0))
        rows.append((px, py, plate.v_x, t[N_STICK], t[N_SLIP], lag, cone))

    c.step = recorded
    summary = sim.run()
    return np.array(rows), summary, sim, c, plate


def _state(sim):
    integ = sim.integrator
    return integ.u_owned.copy(), integ.v_owned.copy()


# ----------------------------------------------------------------------------- (a)

@pytest.mark.parametrize("method", ["film", "dme", "penalty"])
def test_a_fixed_part_keeps_todays_pass(method):
    """A fixed part (M = inf, V = 0): its tangential slot keeps zero inverse mass and the
    pass runs today's kernel (X_SLIDES = 0), so its arithmetic is main's (checked bit for
    bit against main when this was built; the friction suites pin its figures)."""
    _, summary, _, c, _ = _run(method, 20, plate=wall_part())
    assert not c.friction.slides and not c.rigid.slides
    assert c.friction.scalars[X_SLIDES] == 0.0
    assert np.isinf(c.friction.mass[-1]) and c.friction.h_over_m[-1] == 0.0
    assert summary["energy_balance_error_rel"] <= ledger(summary["n_steps"], summary["n_dofs"])


@pytest.mark.parametrize("method", ["film", "dme", "penalty"])
def test_frictionless_sideways_motion_leaves_the_nodes_bit_for_bit(method):
    """(a) and (d): without friction a flat face does not see x, so a plate moving sideways
    gives every node the same u and v, bit for bit, as one that does not (the normal step
    is the same code on the same numbers); the plate keeps V exactly (no x force acts)
    and U^n = Σ h V, the same additions in the same order as the loop's."""
    n = 40
    rows, s, sim, _, plate = _run(method, n, friction=0.0, v_x=V)
    u_s, v_s = _state(sim)
    _, s0, sim0, _, plate0 = _run(method, n, friction=0.0, v_x=0.0)
    u_0, v_0 = _state(sim0)
    assert np.array_equal(u_s, u_0) and np.array_equal(v_s, v_0)
    assert plate.u == plate0.u and plate.v == plate0.v
    assert np.all(rows[:, 2] == V) and plate.v_x == V  # (d): exactly
    u_x = 0.0
    for _ in range(n):
        u_x += DT * V
    assert plate.u_x == u_x
    assert not plate0.slides and plate.slides
    # the ledger holds the plate's 1/2 M V^2 in its kinetic energy and initial energy
    assert s["energy_balance_error_rel"] <= ledger(s["n_steps"], s["n_dofs"])


@pytest.mark.parametrize("method", ["film", "dme", "penalty"])
def test_a_part_moving_along_y_slides_under_every_method(method):
    """A free part in plane strain has its x dof whether or not it is given a sideways
    velocity: one moving along y alone slides under every method (docs/friction.md 11),
    its slot 1/M, the penalty's "scaled" bound with the part's n/M (beta_t = 1 in
    Gershgorin's row sum). Nothing external acts along x, so Σ m v_x + M V stays 0: the
    bound of the x-momentum test, 8 (N + n + 2) roundings a step, on the run's momentum
    scale (M + m) |v_y| (the friction impulses are at most μ < 1 times the normal ones,
    which exchange at most that momentum); and the ledger closes."""
    v_y = -0.01  # m/s: the plate moves down, the block pressed onto it by p
    plate = RigidBody("plate", 1000.0 * MASS, v=v_y)
    rows, s, sim, c, plate = _run(method, N_STEPS, plate=plate)
    t = c.friction
    assert t.slides and c.rigid.slides and t.scalars[X_SLIDES] == 1.0
    assert t.h_over_m[-1] > 0.0
    if method == "penalty":
        assert s["friction"][0]["beta_t_max"] <= 1.0 + 4 * EPS
    p = rows[:, 0] + plate.mass * rows[:, 2]
    n_nodes = COMM.allreduce(sim.integrator.mass.size // 2)
    scale = (plate.mass + MASS) * abs(v_y)
    bound = EPS * 8 * (n_nodes + c.n + 2) * scale * np.arange(1, N_STEPS + 1)
    print(f"{method}: a y-only plate, x momentum within {np.abs(p).max():.3g} kg m/s of 0 "
          f"(bound at the end {bound[-1]:.3g}), V_x at the end {plate.v_x:.3g} m/s")
    assert np.all(np.abs(p) <= bound)
    assert rows[:, 3].max() + rows[:, 4].max() > 0  # the rows were in contact
    assert s["energy_balance_error_rel"] <= ledger(s["n_steps"], s["n_dofs"])


def test_sideways_refusals():
    """One line each: a part over a symmetry plane (with friction), a fixed part given a
    sideways velocity, a button."""
    for method in ("film", "penalty"):
        with pytest.raises(InputError, match="held in x"):
            _run(method, 1, symmetry="x=0")
    with pytest.raises(InputError, match="a fixed part has no velocity"):
        RigidBody("seat", 1.0, v_x=1.0, fixed=True)
    from impact_fenics.contact import rigid_face
    from impact_fenics.contact.pairing import spherical_button

    tmesh = meshing.block(W, H, h=H, comm=COMM)
    model = DeformableModel(tmesh, [Body("block", STEEL)],
                            geometry=Geometry(PLANE_STRAIN, TS))
    sim = Simulation(model, Settings(dt=DT, n_steps=1, out=None, quiet=True))
    with pytest.raises(InputError, match="a button .* cannot move sideways"):
        sim.add_contact(rigid_face(model, "top", W, "punch", spherical_button(10 * W)), FILM(),
                        rigid=RigidBody("punch", 1.0, v_x=V))


def test_axisymmetric_sideways_is_refused():
    """In axisymmetry a rigid part is a body of revolution: a sideways velocity is refused
    in one line (the axis)."""
    tmesh = meshing.block(W, H, h=H, comm=COMM)
    model = DeformableModel(tmesh, [Body("block", STEEL)], geometry=Geometry())
    sim = Simulation(model, Settings(dt=DT, n_steps=1, out=None, quiet=True))
    bottom = np.unique(model.facet_dofs("bottom", 1) // 2)
    cons = plane_below(COMM, bottom, model.node_xy, model.offset, 0.0, model.length_scale)
    with pytest.raises(InputError, match="axisymmetric model"):
        sim.add_contact(cons, FILM(), rigid=RigidBody("plate", 1.0, v_x=V))


# ----------------------------------------------------------------------------- (b), (c)

N_STEPS = 320  # t* = m V / (μ F) is 220 steps


@pytest.mark.parametrize("method", ["film", "dme", "film_dense", "penalty", "penalty_light"])
def test_x_momentum_of_block_and_plate_is_conserved(method):
    """(b) Σ m v_x + M V unchanged to round-off at every step. Bound: a step rounds each
    node's x velocity (prediction v + h f/m and the pass's correction: 4 roundings), the
    pass's sums over its n rows (the average's two sums and each row's force: 4 n + 4)
    and the two dot products of the check (2 N): 8 (N + n + 2) roundings a step on the
    largest momentum |M V| + Σ m |v_x|, added over the steps. The penalty's pass has the
    same count (each node's update and the part's one sum over n rows). ``penalty_light``:
    a plate as heavy as the block (the rows' coupling through 1/M is then of the order of
    their own 1/m_k), with V = 0.05 m/s; its "scaled" k_t keeps beta_t = 1 in
    Gershgorin's bound k_t h h_n (1/m_k + n/M)."""
    plate = RigidBody("plate", MASS, v_x=V) if method == "penalty_light" else None
    rows, s, sim, c, plate = _run(method.replace("_light", ""), N_STEPS, plate=plate)
    p = rows[:, 0] + plate.mass * rows[:, 2]
    p0 = plate.mass * V  # the block starts at rest
    n_nodes = COMM.allreduce(sim.integrator.mass.size // 2)
    scale = plate.mass * V + MASS * V
    bound = EPS * 8 * (n_nodes + c.n + 2) * scale * np.arange(1, N_STEPS + 1)
    drift = np.abs(p - p0)
    print(f"{method}: x momentum of block + plate within {drift.max():.3g} kg m/s of "
          f"{p0:.4g} (bound at the end {bound[-1]:.3g})")
    assert np.all(drift <= bound)
    assert rows[:, 4].max() > 0 and rows[-1, 3] > 0  # it slipped, and it sticks at the end
    print(f"{method}: ledger {s['energy_balance_error_rel']:.3g} (bound "
          f"{ledger(s['n_steps'], s['n_dofs']):.3g})")
    assert s["energy_balance_error_rel"] <= ledger(s["n_steps"], s["n_dofs"])
    assert s["friction"][0]["slip_work"] > 0.0
    if method.startswith("penalty"):
        assert c.friction.slides and s["friction"][0]["beta_t_max"] <= 1.0 + 4 * EPS


@pytest.mark.parametrize("ratio", [1.0, 3.0, 1000.0])
@pytest.mark.parametrize("method", ["film", "dme", "penalty"])
def test_block_dragged_by_a_plate(method, ratio):
    """(c) The closed form of the two-body Coulomb drag (docs/friction.md 11, "a light
    plate"): a plate of mass M = ratio m (free in x and y) at V_0 under the block at rest.
    In y the load F accelerates the pair, so the bottom's normal impulse is
    J_n = F t M / (M + m) + P_o, P_o the block's y momentum about the pair's centre of
    mass, |P_o| <= F H / c_L (energy: the oscillation's kinetic energy is at most the
    static strain energy F^2 H / (2 E A), and P_o^2 / (2 m) at most that). While every row
    slips the block's x impulse is μ J_n, so v̄ = a t within δ = μ F (H / c_L + h) / m,
    a = μ F M / ((M + m) m), and the plate's V = V_0 - m v̄ / M (x momentum, checked to
    round-off as in (b)); the gap g = V - v̄ closes at μ F / m (whatever M) within
    δ_g = (1 + m / M) δ. Hence, as for the heavy plate:
    - the slope over the slipping window is a within 2 δ over the window;
    - g falls to δ_g at t* = m V_0 / (μ F) within (2 δ_g + lead) / (μ F / m), lead the
      shear wave's particle velocity 2 μ p / (ρ c_s) by which the bottom leads the mean;
    - afterwards the mean lags the stuck bottom (which moves with the plate) by <= lead:
      |g| <= lead, i.e. v̄ within M lead / (M + m) and V within m lead / (M + m) of the
      common velocity v_c = M V_0 / (M + m).
    The penalty adds its elastic lag δ_p = 2 n μ 2F h_n / M (docs/friction.md 11, "the
    elastic slip in a drag") to δ and to the lead: at M = m it is 4.6 δ."""
    m_plate = ratio * MASS
    n_steps = 400  # the penalty's band at M = m reaches 350 steps (t* is 220)
    plate = RigidBody("plate", m_plate, v_x=V)
    rows, _, sim, c, plate = _run(method, n_steps, plate=plate)
    t = DT * np.arange(1, n_steps + 1)
    v_bar, v_plate = rows[:, 0] / MASS, rows[:, 2]
    gap = v_plate - v_bar
    n_nodes = COMM.allreduce(sim.integrator.mass.size // 2)
    bound = EPS * 8 * (n_nodes + c.n + 2) * (m_plate + MASS) * V * np.arange(1, n_steps + 1)
    drift = np.abs(rows[:, 0] + m_plate * v_plate - m_plate * V)
    assert np.all(drift <= bound)
    accel = MU * F * m_plate / ((m_plate + MASS) * MASS)
    closing = MU * F / MASS
    t_star, v_c = MASS * V / (MU * F), m_plate * V / (m_plate + MASS)
    delta = MU * F * (H / C_L + DT) / MASS
    lead = 2.0 * MU * P / (STEEL.density * C_S)
    delta_p = 2 * c.n * MU * 2 * F * DT / m_plate
    film_band = (delta, lead)
    if method == "penalty":
        delta, lead = delta + delta_p, lead + delta_p
    delta_g = (1.0 + MASS / m_plate) * delta
    first_stick = int(np.argmax(rows[:, 3] > 0))
    slipping = slice(0, first_stick)
    assert first_stick > 0 and np.all(rows[slipping, 3] == 0)
    off_line = np.abs(v_bar[slipping] - accel * t[slipping]).max()
    k1, k2 = int(np.ceil(2 * H / C_L / DT)), first_stick - 1
    measured = (v_bar[k2] - v_bar[k1]) / (t[k2] - t[k1])
    slope_tol = 2 * delta / (t[k2] - t[k1])
    reach = t[int(np.argmax(gap <= delta_g))]
    reach_tol = (2 * delta_g + lead) / closing
    after = t > t_star + reach_tol
    ring = np.abs(gap[after]).max()
    # the same figures against FILM's and DME's band (no δ_p), printed: is the lag seen?
    g_film = (1.0 + MASS / m_plate) * film_band[0]
    reach_film = t[int(np.argmax(gap <= g_film))]
    tol_film = (2 * g_film + film_band[1]) / closing
    print(f"{method} M = {ratio:g} m: x momentum within {drift.max():.3g} kg m/s (bound "
          f"{bound[-1]:.3g}); slope {measured:.6g} m/s^2 against a = {accel:.6g} (within "
          f"{abs(measured / accel - 1):.3g}, tolerance {slope_tol / accel:.3g}); off the line "
          f"by {off_line:.3g} m/s (δ = {delta:.3g}); gap closed at {reach:.5g} s against "
          f"t* = {t_star:.5g} s (within {abs(reach - t_star):.3g}, tolerance "
          f"{reach_tol:.3g}; at FILM's threshold {abs(reach_film - t_star):.3g} against "
          f"{tol_film:.3g}); "
          f"after it |g| <= {ring:.3g} m/s (lead {lead:.3g}, without δ_p {film_band[1]:.3g}), "
          f"v̄ - v_c = {v_bar[-1] - v_c:.3g}, V - v_c = {v_plate[-1] - v_c:.3g} at the end; "
          f"first stick at step {first_stick}; δ_p = {delta_p:.3g} m/s")
    assert off_line <= delta
    assert abs(measured - accel) <= slope_tol
    assert abs(reach - t_star) <= reach_tol
    assert ring <= lead
    assert np.all(np.abs(v_bar[after] - v_c) <= m_plate * lead / (m_plate + MASS))
    assert np.all(np.abs(v_plate[after] - v_c) <= MASS * lead / (m_plate + MASS))
    # the stick itself: FILM and DME give a stuck row's node the plate's V (a few roundings
    # of |V| <= V_0); the penalty's spring lets it slip at most δ_p = 3 n max c_i h_n / M,
    # the docs' bound, with c_i = μ λ_n,i the run's cone radii
    lag, c_max = rows[:, 5].max(), rows[:, 6].max()
    lag_bound = 3 * c.n * c_max * DT / m_plate if method == "penalty" else 8 * EPS * V
    print(f"{method} M = {ratio:g} m: stuck rows slip at most {lag:.3g} m/s (bound "
          f"{lag_bound:.3g}, 3 n max c_i h / M = {3 * c.n * c_max * DT / m_plate:.3g})")
    assert lag <= lag_bound and lag_bound < delta_p


@pytest.mark.parametrize("method", ["film", "dme", "penalty"])
def test_an_x_force_on_the_plate(method):
    """An external x force f_x on the plate (from rest, with friction): the x momentum of
    block + plate grows by Σ h f_x (its impulse) within test (b)'s bound, and the ledger,
    which books f_x's work by the kinetic identity of the plate's x slot and its 1/2 M V^2,
    closes within tests/roundoff.py's bound."""
    f_x = 0.5 * MU * F  # N: the plate accelerates the block through friction
    plate = RigidBody("plate", 1000.0 * MASS, force_x=lambda t: f_x)
    n = 200
    rows, s, sim, c, _ = _run(method, n, plate=plate)
    p = rows[:, 0] + plate.mass * rows[:, 2]
    impulse = f_x * DT * np.arange(1, n + 1)
    n_nodes = COMM.allreduce(sim.integrator.mass.size // 2)
    scale = float(np.abs(p).max())
    bound = EPS * 8 * (n_nodes + c.n + 2) * scale * np.arange(1, n + 1)
    print(f"{method}: x momentum within {np.abs(p - impulse).max():.3g} kg m/s of the "
          f"impulse {impulse[-1]:.4g} (bound {bound[-1]:.3g}); ledger "
          f"{s['energy_balance_error_rel']:.3g}; plate V = {plate.v_x:.4g} m/s")
    assert np.all(np.abs(p - impulse) <= bound)
    assert plate.v_x > 0.0 and rows[-1, 0] > 0.0
    assert s["energy_balance_error_rel"] <= ledger(s["n_steps"], s["n_dofs"])


def test_penalty_bound_has_the_part():
    """(d) A given tangential stiffness is checked against Gershgorin's bound with the
    part's inverse mass, beta_t = k_t h h_n (1/m_k + n/M) (docs/friction.md 11): on a
    plate as heavy as the block a k_t at beta_t = 1.2 on its lightest node alone (accepted
    on a fixed face: 1.2 < 4/3) passes 4/3 once the n/M is in, and is refused in one line;
    forced, it runs."""
    t = _run("penalty", 1, plate=wall_part())[3].friction
    m_k = t.mass[:-1].min()  # the lightest node of the face (kg)
    k_t = 1.2 * m_k / (DT * DT)
    fixed = _run("penalty", 1, plate=wall_part(), spring=k_t)[3].friction
    assert fixed.beta_max == pytest.approx(1.2, rel=8 * EPS)
    light = RigidBody("plate", MASS, v_x=V)
    with pytest.raises(InputError, match=r"beta_t = 1\.\d+ passes the stable bound 4/3"):
        _run("penalty", 1, plate=light, spring=k_t)
    forced = _run("penalty", 1, plate=RigidBody("plate", MASS, v_x=V), spring=k_t,
                  force=True)[3].friction
    beta = 1.2 * (1.0 + forced.lo.size * m_k / MASS)  # n rows on the face
    assert forced.beta_max == pytest.approx(beta, rel=8 * EPS) and beta > 4.0 / 3.0

# ----------------------------------------------------------------------------- scene files

@pytest.mark.skipif(COMM.size > 1, reason="launches its own runs")
@pytest.mark.parametrize("method", ["film", "penalty"])
def test_scene_key_velocity_x(tmp_path, method):
    """[rigid.NAME] velocity_x: a plane-strain punch pressed onto a block and moving
    sideways with friction runs from the command line; its history has the part's u_x and
    v_x, its energy table M V (momentum_x_punch), its contact_pairs.h5 the pairs' x, the
    ledger closes (the run's own check) and friction slows the punch, with FILM's friction
    and the penalty's. In an axisymmetric scene the key is refused in one line."""
    from scene_texts import RIGID, assert_refused, launch, read_history, replace

    text = replace(RIGID, "radius = 0.1\n", 'half_width = 0.1\nfriction = 0.3\n')
    text = replace(text, 'method = "dme"', f'method = "{method}"')
    text = replace(text, 'components = ["z"]', 'components = ["y"]')
    text = replace(text, "mass = 0.1\n", "mass = 0.1\nvelocity_x = 0.5\n")
    scene = tmp_path / "slide.toml"
    scene.write_text('geometry = "plane_strain"\nthickness = 0.01\n' + text)
    out = tmp_path / "out"
    proc = launch(["run", scene, "--out", out], timeout=600)
    assert proc.returncode == 0, proc.stderr[-2000:]
    h = read_history(out)
    assert h["punch_v_x"][0] <= 0.5 and h["punch_v_x"][-1] < 0.5  # friction drags it back
    assert np.all(np.diff(h["punch_u_x"]) > 0)
    e = np.genfromtxt(out / "energy.csv", delimiter=",", names=True)
    assert "momentum_x_punch" in e.dtype.names
    assert e["momentum_x_punch"][-1] == pytest.approx(0.1 * h["punch_v_x"][-1], rel=1e-15)
    # the summary and the console give the part's state at the end: the history's last row
    import json

    end = json.loads((out / "summary.json").read_text())["rigid_bodies"]["punch"]
    assert (end["v_x"], end["u_x"]) == (h["punch_v_x"][-1], h["punch_u_x"][-1])
    assert f"rigid punch: mass 0.1 kg, v_y {end['v']:.4g} m/s" in proc.stdout
    from impact_fenics.output import read_pairs  # its pairs are labelled x in plane strain

    pairs = read_pairs(str(out / "contact_pairs.h5"))
    assert "x" in pairs and "r" not in pairs and np.all(np.abs(pairs["x"]) <= 0.1 + 1e-12)
    if method != "film":
        return
    axi = tmp_path / "axi.toml"
    axi.write_text(replace(RIGID, "mass = 0.1\n", "mass = 0.1\nvelocity_x = 0.5\n"))
    assert_refused(["run", axi, "--out", tmp_path / "out_axi"],
                   "error: [rigid.punch] velocity_x: an axisymmetric rigid body moves along z "
                   "only (the axis)", tmp_path / "out_axi")
