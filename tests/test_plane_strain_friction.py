"""Coulomb friction in plane strain (docs/plane_strain.md 3, docs/friction.md): the
tangential pass acts along x, the in-plane tangent, on the x dofs, as it acts along r
in axisymmetry; the masses carry the slab's measure (rho t A).

Oracles:

* a block on the wall (bottom facets on a fixed plane y = 0), pressed by a pressure p on
  its top: the x momentum P_x = Σ m v_x changes by h_n (Q + Σ λ_t) at every step (Q the
  applied x force), to the round-off of the sums. Pushed sideways by a traction q
  ramped with p at q = μ p / 4 it sticks (no constraint slips, the bottom's u_x stays 0).
  Started sliding at v0 with no q, every active constraint slips backwards (λ_t = -μ λ_n
  exactly, the clip), so Σ λ_t = -μ Σ λ_n, and with the y balance
  ΔP_y = h_n (Σ λ_n - F) (F = p w t the top's force) the closed form
  P_x + μ P_y = P_x0 - μ F t holds at every step until the first stick (reported);
  the ledger closes (tests/roundoff.py's bound), the slip work D > 0;
* the half model with friction: a rigid flat punch pressed into a block (ν = 0.3, so the
  surface slides outward under it against friction) and a striker hitting a target with
  node pairs and node to segment, half (symmetry = "x=0") against full, FILM and DME,
  the bound of tests/test_plane_strain_contact.py (72 n^2 eps of the largest u);
* a scene with friction (an oblique strike of two strips, node pairs, μ = 0.3) on 1, 2
  and 3 ranks: contact force, tangential force and slip work within 1e-10 of their
  largest values.
"""
import math
import os

import numpy as np
import pytest
from mpi4py import MPI

from impact_fenics import loads, meshing
from impact_fenics.bodies import Body, DeformableModel
from impact_fenics.contact import DME, FILM, RigidBody, pair_surfaces, rigid_face
from impact_fenics.contact.friction import N_SLIP, N_STICK, T_FORCE
from impact_fenics.contact.plane import plane_below, wall_part
from impact_fenics.contact.segments import node_to_segment
from impact_fenics.geometry import PLANE_STRAIN, Geometry
from impact_fenics.materials import LinearElastic
from impact_fenics.scenes import make_method
from impact_fenics.simulation import Settings, Simulation
from roundoff import EPS, ledger, rounding

COMM = MPI.COMM_WORLD
STEEL = LinearElastic(E=200e9, nu=0.3, density=7850.0)
C_L = math.sqrt(STEEL.E * (1 - STEEL.nu) / ((1 + STEEL.nu) * (1 - 2 * STEEL.nu)) / STEEL.density)
T = 0.01  # m, the slab's thickness
MU = 0.3
# nu = 0: a pressed block does not widen, so its bottom has no outward slip to resist
STEEL_NU0 = LinearElastic(E=200e9, nu=0.0, density=7850.0)


# ----------------------------------------------------------------------------- the block

WB, HB, HE = 0.02, 0.01, 0.0025  # m: the block's width, height and element size


def _block_on_wall(method: str, p, q, v0: float, n_steps: int, material=STEEL):
    """A block x in [0, WB], y in [0, HB] on the wall y = 0 (its bottom facets), a
    traction (q(t), -p(t)) on its top (Pa), started at (v0, 0) m/s, friction MU. Returns
    per step (after the contact step): P_x, P_y (kg m/s), h_n (s), Σ λ_t, Σ λ_n (N), the
    stick and slip counts, 1 where some λ_t pushes the block forward (+x); with the applied (x, y) force per Pa of the top and the
    largest |u_x| of the bottom nodes at the end, and the summary."""
    tmesh = meshing.block(WB, HB, h=HE, comm=COMM)
    model = DeformableModel(tmesh, [Body("block", material)], geometry=Geometry(PLANE_STRAIN, T))
    x_load = loads.SurfaceLoad(model, "top", q, traction=(1.0, 0.0))
    y_load = loads.SurfaceLoad(model, "top", p, traction=(0.0, -1.0))
    dt = 0.3 * HE / C_L
    sim = Simulation(model, Settings(dt=dt, n_steps=n_steps, out=None, quiet=True),
                     loads=[x_load, y_load], initial_velocity={"block": (v0, 0.0)})
    bottom = np.unique(model.facet_dofs("bottom", 1) // 2)
    cons = plane_below(COMM, bottom, model.node_xy, model.offset, 0.0, model.length_scale)
    c = sim.add_contact(cons, FILM() if method == "film" else DME(restitution=0.0),
                        rigid=wall_part())
    c.set_friction(MU)
    mass = sim.integrator.mass
    rows = []
    step = c.step

    def recorded():
        w = step()
        v = sim.integrator.v_owned
        px = COMM.allreduce(float(np.dot(mass[0::2], v[0::2])))
        py = COMM.allreduce(float(np.dot(mass[1::2], v[1::2])))
        st = c.friction.stats
        loaded = c.active & (c.force > 0.0)  # the rows with a cone (docs/friction.md 1)
        rows.append((px, py, c.h_avg, st[T_FORCE], float(np.sum(c.force[loaded])),
                     st[N_STICK], st[N_SLIP], float(np.any(c.friction.lam[loaded] > 0.0))))
        return w

    c.step = recorded
    summary = sim.run()
    fx = COMM.allreduce(float(np.sum(x_load.force[x_load.dofs % 2 == 0])))
    fy = COMM.allreduce(float(np.sum(y_load.force[y_load.dofs % 2 == 1])))
    u = sim.integrator.u_owned
    ux_bottom = COMM.allreduce(float(np.abs(u[2 * bottom]).max(initial=0.0)), op=MPI.MAX)
    m_x = COMM.allreduce(float(mass[0::2].sum()))
    return np.array(rows), (fx, fy), ux_bottom, m_x, summary, sim


@pytest.mark.parametrize("method", ["film", "dme"])
def test_block_sticks_below_the_cone(method):
    """p and q = μ p / 4 ramped together over 30 transit times: no constraint slips, the
    bottom's u_x stays 0 (a stuck node's correction zeroes w_t to 4 EPS (|v~_p| + |v~_q|),
    so each step moves it by at most 8 EPS of a step's displacement, itself below the
    largest |u|: n 8 EPS |u|_max over the n steps), and
    ΔP_x = h_n (Q + Σ λ_t) at every step, the round-off of the sums (EPS x the nodes x the
    largest momentum and impulse)."""
    n = 400
    dt = 0.3 * HE / C_L
    t_rise = n * dt
    p_peak = 100e6
    p = loads.Trapezoid(p_peak, t_rise, 1.0, 2.0)
    q = loads.Trapezoid(0.25 * MU * p_peak, t_rise, 1.0, 2.0)
    rows, (fx, fy), ux, m_x, summary, sim = _block_on_wall(method, p, q, 0.0, n, STEEL_NU0)
    px, py, h, lt, ln, n_stick, n_slip, forward = rows.T
    # the scheme's precursor of the load meets the bottom first (a few steps in which the
    # normal force is below 1e-14 of the final one, its ratio to the tangential one that
    # of the discrete tails: DME slips a node there); from 1e-6 of the final force on,
    # nothing slips
    loaded = ln > 1e-6 * ln[-1]
    assert n_stick[loaded].min() > 0 and not n_slip[loaded].any()
    # Q at step k is q(t^k), t^k = k dt (fixed dt): ΔP_x = h (q(t^k) fx + Σ λ_t)
    times = np.arange(n) * dt
    qk = np.array([q(t) for t in times]) * fx
    dp = np.diff(np.r_[0.0, px])
    err = np.abs(dp - h * (qk + lt)).max()
    n_nodes = (round(WB / HE) + 1) * (round(HB / HE) + 1)
    scale = np.abs(px).max() + (h * (np.abs(qk) + np.abs(lt))).max()
    print(f"stick ({method}): {int(n_stick.max())} constraints stuck, ΔP_x - h (Q + Σλ_t) "
          f"within {err:.3g} of {scale:.3g} kg m/s; bottom |u_x| {ux:.3g} m; final Σλ_t "
          f"{lt[-1]:.4g} N against -Q {-qk[-1]:.4g} N; ledger "
          f"{summary['energy_balance_error_rel']:.3g}")
    assert err <= rounding(4 * n_nodes, scale)
    u_scale = float(np.abs(sim.integrator.u_owned).max(initial=0.0))
    u_scale = COMM.allreduce(u_scale, op=MPI.MAX)
    assert ux <= n * rounding(8, u_scale)
    assert summary["energy_balance_error_rel"] <= ledger(summary["n_steps"], summary["n_dofs"])


@pytest.mark.parametrize("method", ["film", "dme"])
def test_block_slides_at_the_coulomb_limit(method):
    """Started at v0 = 5 m/s under a constant p = 20 MPa (the shear wave that friction
    sends up, μ p / (ρ c_s) = 0.24 m/s, is small beside v0, so the bottom keeps sliding):
    ΔP_x = h_n Σ λ_t at every step (no other x force), to the round-off of the sums;
    while every active constraint slips backwards, Σ λ_t = -μ Σ λ_n (each λ_t is -μ λ_n
    exactly: the clip; the sum's round-off), and P_x + μ P_y = P_x0 - μ F t (F = p's
    force, t = Σ h_n) to the round-off of the running sums (EPS x the steps x the nodes x
    the momentum scale); the first step with a sticking (or forward-slipping) constraint is reported beside
    the stop that the sums predict for a rigid block, t_stop = P_x0 / (μ F)."""
    n = 400
    p_val = 20e6
    v0 = 5.0
    rows, (fx, fy), _, m_x, summary, sim = _block_on_wall(
        method, loads.Constant(p_val), loads.Constant(0.0), v0, n)
    px, py, h, lt, ln, n_stick, n_slip, forward = rows.T
    px0 = m_x * v0
    n_nodes = (round(WB / HE) + 1) * (round(HB / HE) + 1)
    dp = np.diff(np.r_[px0, px])
    scale_p = px0 + (h * np.abs(lt)).max()
    assert np.abs(dp - h * lt).max() <= rounding(4 * n_nodes, scale_p)
    force = -fy * p_val  # N, the top's force (down)
    stuck = np.flatnonzero((n_stick > 0) | (forward > 0))  # (DME may reverse a slip at once)
    first = int(stuck[0]) if stuck.size else n
    assert first > 100 and ln[:first].max() > force
    sl = slice(0, first)
    n_face = round(WB / HE) + 1
    assert np.abs(lt[sl] + MU * ln[sl]).max() <= rounding(2 * n_face, MU * np.abs(ln).max())
    t = np.cumsum(h)
    closed = px0 - MU * force * t
    got = px + MU * py
    err = np.abs(got - closed)[sl].max()
    scale = px0 + MU * np.abs(py).max()
    t_stop = px0 / (MU * force)
    print(f"slide ({method}): every active constraint slips backwards for {first} steps "
          f"(t = {t[first - 1] * 1e6:.3g} us; a rigid block's stop P_x0 / (mu F) = "
          f"{t_stop * 1e6:.3g} us); P_x + mu P_y against P_x0 - mu F t within {err:.3g} of "
          f"{scale:.3g} kg m/s; D {summary['friction'][0]['slip_work']:.4g} J; ledger "
          f"{summary['energy_balance_error_rel']:.3g}")
    assert err <= rounding(first * 4 * n_nodes, scale)
    assert summary["friction"][0]["slip_work"] > 0.0
    assert summary["energy_balance_error_rel"] <= ledger(summary["n_steps"], summary["n_dofs"])


# ----------------------------------------------------------------------------- half model

W, L_S, L_T = 0.01, 0.02, 0.03  # m: the half width, the striker's and the target's length
N_STEPS = 150
MU_PUNCH = 0.02  # low enough that the face slips outward near the punch's edge


def _gathered(model, sim, body_of=None):
    """(node x, y, body, u) of every node, gathered over the ranks."""
    xy = model.node_xy[: model.n_owned // 2]
    body = np.zeros((xy.shape[0], 1))
    if body_of is not None:
        body[model.body_dofs(body_of, 1) // 2] = 1.0
    u = sim.integrator.u_vec.array.reshape(-1, 2)
    nodes = COMM.allgather((np.hstack([xy, body]), u))
    return np.concatenate([a for a, _ in nodes]), np.concatenate([b for _, b in nodes])


def _impact(kind: str, method: str, half: bool):
    """A striker (5 m/s along y, nu = 0.3) on a target with friction MU (FILM, DME, or the
    penalty with its scaled normal and tangential springs), node pairs or node to segment (4 against 6 intervals per W), half or full: (nodes, u, contact force and
    tangential force per step)."""
    if kind == "pairs":
        tmesh = meshing.coaxial_bars(radius=W if half else 2 * W, striker_length=L_S,
                                     target_length=L_T, h=W / 4, structured=True, comm=COMM)
    else:
        tmesh = meshing.coaxial_bars_sized(radius=W if half else 2 * W, striker_length=L_S,
                                           target_length=L_T, h_striker=W / 4,
                                           h_target=W / 6, structured=True, comm=COMM)
    if not half:
        tmesh.mesh.geometry.x[:, 0] -= W
    model = DeformableModel(tmesh, [Body("striker", STEEL), Body("target", STEEL)],
                            geometry=Geometry(PLANE_STRAIN, T, "x=0" if half else None))
    dt = 0.3 * (W / 6) / C_L
    sim = Simulation(model, Settings(dt=dt, n_steps=N_STEPS, out=None, quiet=True),
                     initial_velocity={"striker": (0.0, 5.0)})
    if kind == "pairs":
        cons = pair_surfaces(model, "striker_contact", "target_contact")
    else:
        cons = node_to_segment(model, "target_contact", "striker_contact")
    c = sim.add_contact(cons, make_method(method))
    c.set_friction(MU)
    forces = []
    step = c.step

    def recorded():
        w = step()
        forces.append((float(np.sum(np.where(c.active, c.force, 0.0))),
                       float(np.abs(c.friction.lam).sum())))
        return w

    c.step = recorded
    sim.run()
    xy, u = _gathered(model, sim, "target")
    return xy, u, np.array(forces)


def _punch(method: str, half: bool):
    """A rigid flat punch of half-width W/2 pressed into a block 2W x W (nu = 0.3: the
    surface spreads outward under it, against friction MU_PUNCH), its bottom held in y; the half
    x in [0, W] with symmetry = "x=0" takes half the punch's mass and force."""
    share = 0.5 if half else 1.0
    tmesh = meshing.block(W * (1 if half else 2), W, h=W / 8, comm=COMM)
    if not half:
        tmesh.mesh.geometry.x[:, 0] -= W
    model = DeformableModel(tmesh, [Body("block", STEEL)],
                            geometry=Geometry(PLANE_STRAIN, T, "x=0" if half else None))
    pulse = loads.Trapezoid(peak=1.0, t_rise=2e-6, t_fall=1.0, t_end=2.0)
    punch = RigidBody("punch", share * 0.02,
                      force=lambda time: -share * 200e6 * W * T * pulse(time))
    sim = Simulation(model, Settings(dt=0.3 * (W / 8) / C_L, n_steps=N_STEPS, out=None,
                                     quiet=True), fixed=[model.facet_dofs("bottom", 1)])
    c = sim.add_contact(rigid_face(model, "top", W / 2, "punch"),
                        FILM() if method == "film" else DME(restitution=0.0), rigid=punch)
    c.set_friction(MU_PUNCH)
    summary = sim.run()
    xy, u = _gathered(model, sim)
    return xy, u, punch.u, summary


def _compare(xy_h, u_h, xy_f, u_f):
    """The half's nodes against the full model's right half: (largest |Δu|, largest |u|)."""
    key = lambda xy: np.lexsort((np.round(xy[:, 0] / 1e-7), np.round(xy[:, 1] / 1e-7),
                                 xy[:, 2]))
    right = xy_f[:, 0] >= -1e-12
    xy_f, u_f = xy_f[right], u_f[right]
    a, b = key(xy_h), key(xy_f)
    assert np.allclose(xy_h[a], xy_f[b], rtol=0, atol=1e-12)
    return float(np.abs(u_h[a] - u_f[b]).max()), float(np.abs(u_f).max())


@pytest.mark.parametrize("kind, method", [("pairs", "film"), ("pairs", "dme"),
                                          ("pairs", "penalty"), ("segments", "film"),
                                          ("segments", "dme")])
def test_half_model_with_friction_equals_the_full_one(kind, method):
    """Half against full with friction: one computation in exact arithmetic (on x = 0 the
    full model's tangential multiplier is zero by symmetry where the half holds u_x), so
    (the penalty on node to segment is not: its scaled springs come from Gershgorin row
    sums over the band, which on x = 0 differ between the half and the full model),
    round-off alone, bounded as in tests/test_plane_strain_contact.py: 72 n^2 eps of the
    largest u, and of the largest force for the normal and tangential totals (linear in
    the state within a step's stick/slip sets, which the run shows to be the same)."""
    xy_h, u_h, f_h = _impact(kind, method, half=True)
    xy_f, u_f, f_f = _impact(kind, method, half=False)
    assert f_h[:, 1].max() > 0.0, "no friction force"
    err, scale = _compare(xy_h, u_h, xy_f, u_f)
    bound = 72 * N_STEPS ** 2 * EPS
    f_err = np.abs(f_f - 2.0 * f_h).max(axis=0)
    f_scale = np.abs(f_f).max(axis=0)
    print(f"{kind}, {method}, mu = {MU}: half against full, u within {err:.3g} m of "
          f"{scale:.3g} m, the normal total within {f_err[0]:.3g} N of {f_scale[0]:.4g} N, "
          f"Σ|λ_t| within {f_err[1]:.3g} N of {f_scale[1]:.4g} N")
    assert err <= bound * scale
    assert np.all(f_err <= bound * f_scale)


@pytest.mark.parametrize("method", ["film", "dme"])
def test_rigid_punch_half_model_with_friction(method):
    """The rigid punch with friction, half against full (the punch's displacement too),
    72 n^2 eps of the largest u; both ledgers within tests/roundoff.py's bound and the
    slip work of the full model twice the half's, the same bound."""
    xy_h, u_h, p_h, s_h = _punch(method, half=True)
    xy_f, u_f, p_f, s_f = _punch(method, half=False)
    assert p_h < 0.0
    err, scale = _compare(np.hstack([xy_h[:, :2], np.zeros((len(xy_h), 1))]), u_h,
                          np.hstack([xy_f[:, :2], np.zeros((len(xy_f), 1))]), u_f)
    err, scale = max(err, abs(p_h - p_f)), max(scale, abs(p_f))
    d_h, d_f = s_h["friction"][0]["slip_work"], s_f["friction"][0]["slip_work"]
    print(f"rigid punch with friction, {method}: half against full, u within {err:.3g} m "
          f"of {scale:.3g} m; slip work {d_f:.4g} J = 2 x {d_h:.4g} J within "
          f"{abs(d_f - 2 * d_h):.3g}; ledgers {s_h['energy_balance_error_rel']:.3g}, "
          f"{s_f['energy_balance_error_rel']:.3g}")
    assert d_h > 0.0
    assert err <= 72 * N_STEPS ** 2 * EPS * scale
    assert abs(d_f - 2 * d_h) <= 72 * N_STEPS ** 2 * EPS * d_f
    for s in (s_h, s_f):
        assert s["energy_balance_error_rel"] <= ledger(s["n_steps"], s["n_dofs"])


# ----------------------------------------------------------------------------- ranks

@pytest.mark.skipif(COMM.size > 1, reason="launches its own runs (serial and under mpirun)")
def test_scene_with_friction_on_1_2_3_ranks(tmp_path):
    """scenes/plane_strain_impact.toml made oblique and frictional (the whole strips, no
    symmetry plane, nu = 0.3, the striker at (1, 5) m/s, friction = 0.1): it runs from the
    command line, its faces stick and slip, and on 2 and 3 ranks the contact force, the
    tangential force and the slip work are within 1e-10 of their largest serial values
    (the partitions reorder each step's sums; every rank takes the tangential decisions
    on the same gathered data)."""
    from scene_texts import ROOT, assert_ranks_agree, launch, read_history, replace

    with open(os.path.join(ROOT, "scenes", "plane_strain_impact.toml")) as f:
        text = f.read()
    text = replace(text, 'symmetry = "x=0"        #', "#")
    text = replace(text, "nu = 0.0 ", "nu = 0.3 ")
    text = replace(text, "velocity = [0.0, 5.0]", "velocity = [1.0, 5.0]")
    text = replace(text, 'method = "film"             # penalty | film | dme',
                   'method = "film"\nfriction = 0.1')
    text = replace(text, "t_end = 3e-5 ", "t_end = 1e-5 ")
    scene = tmp_path / "oblique.toml"
    scene.write_text(text)
    out = tmp_path / "n1"
    proc = launch(["run", scene, "--out", out, "--quiet"], timeout=600)
    assert proc.returncode == 0, proc.stderr[-2000:]
    h = read_history(out)
    assert h["n_stick"].max() > 0 and h["n_slip"].max() > 0 and h["slip_work"][-1] > 0.0
    assert_ranks_agree(scene, str(tmp_path), h,
                       ("contact_force", "tangential_force", "slip_work"), "(N, N, J)")
