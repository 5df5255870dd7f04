"""Coulomb friction on node pairs, a rigid face and the wall (FILM, DME, penalty):
docs/friction.md.

Oracles:

* one pair by hand (section 8): the tangential kernels on a node pair, a node below a
  rigid part (a punch) and a node above one (the wall), against the closed forms of
  sections 2 and 3, in stick and in slip;
* r momentum and the cone on many random constraints: the correction leaves Σ m v_r
  unchanged to the round-off of its sum, |λ_t| <= μ λ_n exactly (the clip returns c),
  and inside the cone w_t^{n+1/2} = 0 within 4 EPS (|v~_p| + |v~_q|);
* the sliding block by hand: a node pressed on the wall by a constant load N and started
  at v0 along it slows by h μ N / m per step until it sticks; the stop step, the slip and
  the slip work D = μ N Σ h |w⁺| in closed form (constant μ) and against the law's
  recurrence (the decaying coefficient), FILM and DME, through a ContactSet;
* μ = 0 is today's path: a scene with friction = 0 equals the scene without the key, bit
  for bit (no tangential slots are made), FILM and DME, node pairs and the wall;
* DME = FILM with friction on node pairs (e = 0, mass-weighted positions, faces touching
  at t = 0), in stick and in slip, within the spread of a one-ulp change of the start;
* the ledger closes with friction (roundoff.ledger), D >= 0 and grows at every step;
* the penalty (docs/friction.md 4): one pair by hand (trial, return, s_e, D, R); under a
  steady tangential load it settles at s_e = (1 - beta_t) F / k_t (beta_t = 0.5, 1);
  the scaled penalty on the wall equals FILM within the spread of a one-ulp change;
* the refusals of what is not built (one line each), and a node pair that slips past half
  its facet warns once.
"""
import json
import math
import os

import numpy as np
import pytest
from mpi4py import MPI

from impact_fenics import cli
from impact_fenics.contact import DME, FILM, ContactSet, Penalty
from impact_fenics.contact.friction import (N_SLIP, N_STICK, RELEASE_LOSS, STORED,
                                            FrictionLaw, dme_tangential, film_tangential,
                                            friction_law, penalty_tangential)
from impact_fenics.contact.pairing import Constraints
from impact_fenics.contact.plane import _Host, wall_part
from impact_fenics.errors import InputError
from impact_fenics.report import console_lines
from roundoff import EPS, assert_runs_agree, assert_within_spread, ledger, one_ulp, rounding

COMM = MPI.COMM_WORLD
INF = np.inf


# ----------------------------------------------------------------------------- one pair

def _kernel(kind: str, lo, up, force, mass, v, h, law: FrictionLaw, v_now=None):
    """Run one tangential kernel on slots of masses ``mass`` (inf: fixed or a rigid part)
    with the predicted r velocities ``v``; returns (u, v, λ_t, state)."""
    n = len(lo)
    lo, up = np.asarray(lo, np.int64), np.asarray(up, np.int64)
    mass = np.asarray(mass, float)
    free = np.isfinite(mass)
    h_over_m = np.where(free, h / mass, 0.0)
    m_over_h = np.where(free, mass / h, 0.0)
    a = h_over_m[lo] + h_over_m[up]
    a_inv = np.where(a > 0.0, 1.0 / np.where(a > 0.0, a, 1.0), 0.0)
    v = np.array(v, float)
    u = np.zeros_like(v)
    v_now = v.copy() if v_now is None else np.asarray(v_now, float)
    lam, state = np.zeros(n), np.zeros(n, np.int8)
    active, force = np.ones(n, np.bool_), np.asarray(force, float)
    if kind == "film":
        film_tangential(lo, up, active, force, a_inv, h_over_m, h, law.static, law.dynamic,
                        law.decay, law.stick, v_now, u, v, lam, state)
    else:
        dme_tangential(lo, up, active, force, mass, m_over_h, h_over_m, h, law.static,
                       law.dynamic, law.decay, law.stick, np.zeros_like(v), v_now, u, v, lam,
                       state)
    return u, v, lam, state


@pytest.mark.parametrize("kind", ["film", "dme"])
@pytest.mark.parametrize("mu, sticks", [(0.5, True), (0.1, False)])
def test_one_pair_by_hand(kind, mu, sticks):
    """A node pair (lower p: 2 kg at +0.3 m/s, upper q: 3 kg at -0.2 m/s), h = 1e-4 s: the
    stick multiplier is λ* = -w~ / A = 0.5 / (h (1/2 + 1/3)) = 6000 N. Stick: the cone
    μ λ_n = 0.5 x 2e4 N holds it and both move at the momentum average; slip: the cone
    0.1 x 1e4 = 1000 N cuts it, λ_t = 1000 N and each velocity moves by h λ_t / m.
    Round-off: a few roundings (EPS x 8) of the multiplier and of the velocities."""
    m_p, m_q, vp, vq, h = 2.0, 3.0, 0.3, -0.2, 1e-4
    lam_star = (vp - vq) / (h * (1 / m_p + 1 / m_q))  # 6000 N, by hand
    fn = 2e4 if sticks else 1e4  # cone 1e4 N (stick) or 1e3 N (slip)
    u, v, lam, state = _kernel(kind, [0], [1], [fn], [m_p, m_q], [vp, vq], h,
                               FrictionLaw(mu, mu))
    tol = rounding(8, abs(lam_star))  # a few roundings of the multiplier's arithmetic
    if sticks:
        v_star = (m_p * vp + m_q * vq) / (m_p + m_q)  # both move as one: momentum average
        assert state[0] == 1 and abs(lam[0] - lam_star) <= tol
        assert abs(v[0] - v_star) <= rounding(8, 0.5) and abs(v[1] - v_star) <= rounding(8, 0.5)
    else:
        c = mu * fn
        assert state[0] == 2 and lam[0] == c  # on the cone, opposing the slip (w~ < 0)
        assert abs(v[1] - (vq + h * c / m_q)) <= rounding(4, 0.5)
        assert abs(v[0] - (vp - h * c / m_p)) <= rounding(4, 0.5)
        assert (v[1] - v[0]) < 0.0  # the slip keeps its sign within the step
    # positions: FILM moves them by h dv (from u~ = 0); DME sets u^n + h v (u^n = 0)
    assert np.allclose(u, h * (v - np.array([vp, vq])) if kind == "film" else h * v,
                       rtol=0, atol=rounding(8, h * 0.5))


@pytest.mark.parametrize("kind", ["film", "dme"])
@pytest.mark.parametrize("side", ["punch", "wall"])
@pytest.mark.parametrize("mu, sticks", [(0.5, True), (0.1, False)])
def test_node_on_rigid_face_by_hand(kind, side, mu, sticks):
    """A node (1.5 kg, v~_r = 0.4 m/s) below a rigid part (a punch: the node is the lower
    slot) or above one (the wall: the upper slot); the rigid part has no r slot (zero
    inverse mass). Stick stops the node (the face has no tangential velocity): λ* =
    m v~ / h along -r on the node; slip applies μ λ_n against the motion."""
    m, vt, h = 1.5, 0.4, 1e-4
    stick_force = m * vt / h  # 6000 N on the node, along -r
    fn = 2e4 if sticks else 1e4
    if side == "punch":
        lo, up, mass, v0 = [0], [1], [m, INF], [vt, 0.0]
        node = 0
    else:
        lo, up, mass, v0 = [0], [1], [INF, m], [0.0, vt]
        node = 1
    u, v, lam, state = _kernel(kind, lo, up, [fn], mass, v0, h, FrictionLaw(mu, mu))
    node_force = lam[0] if node == 1 else -lam[0]  # +λ_t on the upper slot, -λ_t on the lower
    assert v[1 - node] == 0.0 and u[1 - node] == 0.0  # the rigid part's r slot never moves
    if sticks:
        assert state[0] == 1
        assert abs(node_force + stick_force) <= rounding(8, stick_force)
        assert abs(v[node]) <= rounding(4, vt)
    else:
        c = mu * fn
        assert state[0] == 2 and node_force == -c
        assert abs(v[node] - (vt - h * c / m)) <= rounding(4, vt)


@pytest.mark.parametrize("kind", ["film", "dme"])
@pytest.mark.parametrize("stick", [False, True])
def test_momentum_and_cone_random(kind, stick):
    """200 random node pairs (masses 0.5-2 kg, v~ within ±1 m/s, λ_n within 0-1e4 N,
    μ = 0.3, and some axis pairs whose r dofs are fixed): Σ m v_r unchanged to the
    round-off of the sum (each of the 400 terms rounds its product and its update:
    EPS x 8 per term on m |v|); |λ_t| <= μ λ_n exactly; in stick w_t^{n+1/2} = 0 within
    4 EPS (|v~_p| + |v~_q|) (one clip and one update each, docs/friction.md 8)."""
    rng = np.random.default_rng(7)
    n = 200
    mass = rng.uniform(0.5, 2.0, 2 * n)
    mass[[0, n]] = INF  # an axis pair: both r dofs fixed, no tangential row
    v = rng.uniform(-1.0, 1.0, 2 * n)
    v[[0, n]] = 0.0
    fn = rng.uniform(0.0, 1e4, n)
    h = 1e-4
    law = FrictionLaw(stick=True) if stick else FrictionLaw(0.3, 0.3)
    lo, up = np.arange(n), np.arange(n, 2 * n)
    u_c, v_c, lam, state = _kernel(kind, lo, up, fn, mass, v, h, law)
    free = np.isfinite(mass)
    p0, p1 = np.sum(mass[free] * v[free]), np.sum(mass[free] * v_c[free])
    assert abs(p1 - p0) <= rounding(8 * 2 * n, np.sum(mass[free] * np.abs(v[free])))
    if not stick:
        assert np.all(np.abs(lam) <= 0.3 * fn)
        assert np.any(state == 2) and np.any(state == 1)
        slip = state == 2
        assert np.all(np.abs(lam[slip]) == 0.3 * fn[slip])
        # the force opposes the slip, which keeps the sign of w~
        w_pred = v[up] - v[lo]
        w_new = v_c[up] - v_c[lo]
        assert np.all(lam[slip] * w_new[slip] <= 0.0)
        assert np.all(np.sign(w_new[slip]) == np.sign(w_pred[slip]))
    held = state == 1
    w_new = v_c[up] - v_c[lo]
    assert np.all(np.abs(w_new[held]) <= 4 * EPS * (np.abs(v[lo]) + np.abs(v[up]))[held])
    assert state[0] == 0 and lam[0] == 0.0  # the axis pair: no free r slot


def test_dme_equals_film_one_step():
    """DME's momentum average and FILM's multiplier are the same λ_t on a node pair (the
    arithmetic differs), in stick and in slip: 200 random pairs. DME forms v* - v~_q, a
    difference of velocities: its roundings are on |v~_p| + |v~_q|, times m / h in the
    multiplier; a few (EPS x 16) of them."""
    rng = np.random.default_rng(3)
    n = 200
    mass = rng.uniform(0.5, 2.0, 2 * n)
    v = rng.uniform(-1.0, 1.0, 2 * n)
    fn = rng.uniform(0.0, 1e4, n)
    lo, up = np.arange(n), np.arange(n, 2 * n)
    law = FrictionLaw(0.3, 0.3)
    _, v_f, lam_f, st_f = _kernel("film", lo, up, fn, mass, v, 1e-4, law)
    _, v_d, lam_d, st_d = _kernel("dme", lo, up, fn, mass, v, 1e-4, law)
    speeds = np.abs(v[up]) + np.abs(v[lo])
    assert np.array_equal(st_f, st_d)
    assert np.all(np.abs(lam_f - lam_d) <= rounding(16, (mass[lo] + mass[up]) / 1e-4 * speeds))
    assert np.all(np.abs(v_f[up] - v_d[up]) <= rounding(16, speeds))
    assert np.all(np.abs(v_f[lo] - v_d[lo]) <= rounding(16, speeds))


def test_friction_law_and_refusals():
    assert friction_law(0) .is_zero and friction_law(0.3) == FrictionLaw(0.3, 0.3)
    assert friction_law("stick").stick
    assert friction_law({"static": 0.3, "dynamic": 0.2, "decay": 5.0}) == FrictionLaw(0.3, 0.2, 5.0)
    for bad in (-0.1, "rough", {"dynamic": 0.2}, {"static": 0.3, "slope": 1}, True, math.nan,
                {"static": 0.3, "decay": -1.0}):
        with pytest.raises(InputError) as exc:
            friction_law(bad)
        assert "\n" not in str(exc.value)


# ----------------------------------------------------------------------------- sliding block

def _sliding_block(method, law: FrictionLaw, m=2.0, N=10.0, h=1e-3, v0=0.05, steps=40):
    """One node (r, z dofs 0, 1; owned by rank 0) on the wall z = 0, pushed down by N (N)
    and started at v0 (m/s) along r; every step predicts without contact and corrects
    with the set. Returns (r velocities after each step, states, λ_n, u_r, the set)."""
    mine = COMM.rank == 0
    mass = np.array([m, m]) if mine else np.zeros(0)
    u = np.zeros(mass.size)
    v = np.array([v0, 0.0]) if mine else np.zeros(0)
    host = _Host(COMM, 0 if mine else 2, mass, u, v, h)
    cons = Constraints(r=np.array([1.0]), b=np.array([0.0]), lower=None,
                       upper=np.array([1]), names=("node", "wall"))
    c = ContactSet(cons, host, method, wall_part())
    c.set_friction(law)
    c.initialize()
    vr, states, fn = [], [], []
    for _ in range(steps):
        if mine:
            v[1] += h * (-N / m)
            u += h * v
        c.step()
        host.n += 1
        vr.append(c.friction.v_now[0])
        states.append(int(c.friction.state[0]))
        fn.append(float(c.force[0]))
    return np.array(vr), np.array(states), np.array(fn), float(c.friction.u_now[0]), c


@pytest.mark.parametrize("method", ["film", "dme"])
def test_sliding_block_constant_mu(method):
    """w drops by δ = h μ N / m = 1.5e-3 m/s per step: v0 / δ = 33.3, so steps 1-33 slip
    (w⁺_k = v0 - k δ) and step 34 sticks (w~ = 5e-4 <= δ); then it stays stuck. The slip
    is h Σ_{k<=33} (v0 - k δ) and D = μ N times it. Round-off: each step rounds v by a
    few ulp of v0, summed over the steps (EPS x 4 x 40 on v0); the slip and D sum 33
    such terms (EPS x 4 x 40 x 33 on h v0 and μ N h v0)."""
    m, N, h, v0, mu = 2.0, 10.0, 1e-3, 0.05, 0.3
    meth = FILM("fast") if method == "film" else DME()
    vr, states, fn, u_r, c = _sliding_block(meth, FrictionLaw(mu, mu), m, N, h, v0)
    delta = h * mu * N / m
    k = np.arange(1, 34)
    assert np.all(np.abs(fn - N) <= rounding(8, N))  # λ_n = N at every step (FILM and DME)
    assert np.all(states[:33] == 2) and np.all(states[33:] == 1)  # the stop step: 34
    assert np.all(np.abs(vr[:33] - (v0 - k * delta)) <= rounding(4 * 40, v0))
    assert np.all(np.abs(vr[33:]) <= rounding(4 * 40, v0))
    slip = h * np.sum(v0 - k * delta)
    assert abs(u_r - slip) <= rounding(4 * 40 * 33, h * v0)
    D = mu * N * slip
    assert abs(c.friction.slip_work - D) <= rounding(4 * 40 * 33, mu * N * h * v0)
    assert c.friction.stats[N_STICK] == 1 and c.friction.stats[N_SLIP] == 0


@pytest.mark.parametrize("method", ["film", "dme"])
def test_sliding_block_decaying_mu(method):
    """μ = μ_d + (μ_s - μ_d) exp(-d_c |w^{n-1/2}|) with the previous step's speed (v0 at
    the first step): the recurrence v_k = v_{k-1} - h μ(v_{k-1}) N / m while the cone is
    cut, then stick, written here from the law (the kernel's exp against numpy's: 4 ulp,
    roundoff.LIBM, per step on μ). μ_s = 0.4, μ_d = 0.2, d_c = 20 s/m."""
    m, N, h, v0 = 2.0, 10.0, 1e-3, 0.05
    law = FrictionLaw(0.4, 0.2, 20.0)
    meth = FILM("fast") if method == "film" else DME()
    vr, states, fn, u_r, c = _sliding_block(meth, law, m, N, h, v0, steps=60)
    expect, slip_d, w = [], 0.0, v0
    stopped = False
    for _ in range(60):
        mu = law.dynamic + (law.static - law.dynamic) * math.exp(-law.decay * abs(w))
        if not stopped and w > h * mu * N / m:
            w_new = w - h * mu * N / m
            slip_d += h * mu * N * w_new
        else:
            w_new, stopped = 0.0, True
        expect.append(w_new)
        w = w_new
    expect = np.array(expect)
    assert np.array_equal(states == 1, expect == 0.0)  # the same stop step
    assert np.all(np.abs(vr - expect) <= rounding(8 * 60, v0))
    assert abs(c.friction.slip_work - slip_d) <= rounding(8 * 60 * 60, N * h * v0)


# ----------------------------------------------------------------------------- scenes

SCENE = """title = "steel on aluminium"
[mesh]
generator = "coaxial_bars"
radius = 0.01
striker_length = 0.04
target_length = 0.04
h = 0.002
structured = true
[materials.steel]
E = 200e9
nu = 0.3
density = 7850.0
[materials.alu]
E = 70e9
nu = 0.33
density = 2700.0
[bodies.striker]
material = "steel"
velocity = [0.0, {v0!r}]
[bodies.target]
material = "alu"
[[contact]]
lower = "striker_contact"
upper = "target_contact"
method = "{method}"
{friction}
[time]
t_end = 8e-6
cfl = 0.5
[output]
history_every = 1
energy_every = 1
fields = false
plots = false
"""

WALL_SCENE = """title = "bar on the wall"
[mesh]
generator = "quad_bar"
radius = 0.005
length = 0.02
n_r = 4
[materials.steel]
E = 200e9
nu = 0.3
density = 7850.0
[bodies.bar]
material = "steel"
velocity = [0.0, -5.0]
[wall]
z = 0.0
method = "{method}"
{friction}
[time]
t_end = 4e-6
cfl = 0.5
[output]
history_every = 1
energy_every = 1
fields = false
plots = false
"""


def _run(tmp, name: str, text: str):
    out = os.path.join(tmp, name)
    scene = os.path.join(tmp, f"{name}.toml")
    if COMM.rank == 0:
        with open(scene, "w") as f:
            f.write(text)
    COMM.barrier()
    assert cli.main(["run", scene, "--out", out, "--quiet"]) == 0
    history = np.genfromtxt(os.path.join(out, "history.csv"), delimiter=",", names=True)
    energy = np.genfromtxt(os.path.join(out, "energy.csv"), delimiter=",", names=True)
    return history, energy


@pytest.fixture(scope="module")
def tmp(tmp_path_factory):
    path = str(tmp_path_factory.mktemp("friction")) if COMM.rank == 0 else None
    return COMM.bcast(path)


@pytest.mark.parametrize("method", ["film", "dme", "penalty"])
@pytest.mark.parametrize("kind", ["pairs", "wall"])
def test_zero_friction_is_todays_path(tmp, method, kind):
    """friction = 0 makes no tangential slot, no pass and no column: the set built from
    the scene has none, and the run equals the one without the key, every column, bit
    for bit on one rank (roundoff.assert_runs_agree). On several ranks two runs of one
    scene in one process may be partitioned differently (measured on 3 ranks: one run
    in six differed by 1.9e-10 N of 33 kN, without any friction key): there they agree
    within the spread of a one-ulp change of v0."""
    from impact_fenics.scene_file import build, read_scene

    text = SCENE if kind == "pairs" else WALL_SCENE
    fmt = dict(method=method, v0=5.0)
    zero = text.format(friction="friction = 0.0", **fmt)
    path = os.path.join(tmp, f"zero_{kind}_{method}.toml")
    if COMM.rank == 0:
        with open(path, "w") as f:
            f.write(zero)
    COMM.barrier()
    sim = build(read_scene(path))
    assert all(c.friction is None for c in sim.contacts)
    h0, e0 = _run(tmp, f"none_{kind}_{method}", text.format(friction="", **fmt))
    h1, e1 = _run(tmp, f"zero_{kind}_{method}", zero)
    hu = eu = None
    if COMM.size > 1:
        fmt["v0"] = one_ulp(5.0)
        ulp = text.format(friction="", **fmt)
        if kind == "wall":
            ulp = ulp.replace("velocity = [0.0, -5.0]", f"velocity = [0.0, {-one_ulp(5.0)!r}]")
        hu, eu = _run(tmp, f"ulp_{kind}_{method}", ulp)
    assert h0.dtype.names == h1.dtype.names and "n_stick" not in h0.dtype.names
    for col in h0.dtype.names:
        if not col.startswith("cpu_"):
            assert_runs_agree(h1[col], h0[col], None if hu is None else hu[col], h0.size, col)
    for col in e0.dtype.names:
        assert_runs_agree(e1[col], e0[col], None if eu is None else eu[col], h0.size, col)


@pytest.fixture(scope="module", params=["0.3", '"stick"'])
def bars(request, tmp):
    """FILM, DME and FILM with v0 one ulp faster (the spread of a one-ulp change), with
    friction μ = 0.3 (slip at the rim) or stick."""
    f = f"friction = {request.param}"
    tag = "stick" if "stick" in f else "mu"
    runs = {m: _run(tmp, f"bars_{tag}_{m}", SCENE.format(method=m, friction=f, v0=5.0))
            for m in ("film", "dme")}
    runs["ulp"] = _run(tmp, f"bars_{tag}_ulp", SCENE.format(method="film", friction=f,
                                                          v0=one_ulp(5.0)))
    return request.param, runs


def test_dme_equals_film_with_friction(bars):
    """DME and FILM with e = 0 and mass-weighted positions on faces touching at t = 0 are
    the same scheme (docs/friction.md 3): every history column and the energies agree
    within the spread of a one-ulp change of v0 (roundoff.assert_within_spread)."""
    law, runs = bars
    (hf, ef), (hd, ed), (hu, eu) = runs["film"], runs["dme"], runs["ulp"]
    n = hf.size
    for col in ("contact_force", "tangential_force", "slip_work", "tangential_loss"):
        assert_within_spread(hd[col], hf[col], hu[col], n, col)
    assert np.array_equal(hd["n_stick"], hf["n_stick"])
    assert np.array_equal(hd["n_slip"], hf["n_slip"])
    for col in ("kinetic", "strain", "contact_work"):
        assert_within_spread(ed[col], ef[col], eu[col], n, col)
    if law == '"stick"':
        # no slip: D is the round-off of w⁺ = 0 (within 4 EPS (|v~_p| + |v~_q|) <= 8 EPS
        # x 2 v0 a pair) times h |λ_t|, 6 pairs a step, |λ_t| below the largest normal
        # total (checked: the tangential totals are below it here)
        f_max = hf["contact_force"].max()
        assert np.abs(hf["tangential_force"]).max() < f_max
        assert not np.any(hf["n_slip"])
        assert hf["slip_work"][-1] <= n * 6 * hf["dt"][0] * f_max * rounding(8, 2 * 5.0)
    else:
        assert np.any(hf["n_slip"] > 0)  # μ = 0.3 slips (at the rim)
    assert np.any(np.abs(hf["tangential_force"]) > 0.0)


def test_ledger_with_friction(bars):
    """The balance closes to round-off with the tangential work in the contact work
    (roundoff.ledger on the run's steps and dofs), and the slip work never falls."""
    _, runs = bars
    for m in ("film", "dme"):
        h, e = runs[m]
        n_dofs = 2 * 6 * 21 * 2  # at most: two bars of 6 x 21 nodes, (r, z) each
        scale = np.abs(e["total"]).max()
        assert np.abs(e["balance_error"]).max() <= ledger(h.size, n_dofs) * scale
        assert np.all(np.diff(h["slip_work"]) >= 0.0) and h["slip_work"][0] >= 0.0


@pytest.mark.parametrize("method", ["film", "dme"])
def test_wall_with_friction(tmp, method):
    """A bar on the wall with μ = 0.3: its Poisson expansion pushes the face outward, the
    wall holds it back (a negative total tangential force on the body, along -r), the
    ledger closes."""
    h, e = _run(tmp, f"wall_mu_{method}", WALL_SCENE.format(method=method,
                                                          friction="friction = 0.3"))
    with open(os.path.join(tmp, f"wall_mu_{method}", "summary.json")) as f:
        whole = json.load(f)
    (summary,) = whole["friction"]
    assert summary["friction"] == "0.3" and summary["slip_work"] == h["slip_work"][-1]
    # the console says them too, one line per set
    (line,) = [x for x in console_lines(whole) if x.startswith("friction ")]
    assert f"slip work {summary['slip_work']:.4g} J" in line and "(0.3)" in line
    assert summary["peak_tangential_force"] == np.abs(h["tangential_force"]).max()
    assert np.any(h["n_stick"] + h["n_slip"] > 0)
    assert np.all(h["tangential_force"] <= 0.0) and h["tangential_force"].min() < 0.0
    scale = np.abs(e["total"]).max()
    assert np.abs(e["balance_error"]).max() <= ledger(h.size, 2 * 5 * 17) * scale


REFUSED = [
    (WALL_SCENE.format(method="penalty", friction="friction = 0.3\ntangential_penalty = 1e15"),
     "passes the stable bound 4/3"),
    (WALL_SCENE.format(method="film", friction="friction = -0.3"),
     "[wall] friction = -0.3: must be a finite number >= 0"),
    (WALL_SCENE.format(method="film", friction='friction = "rough"'),
     'give a coefficient >= 0, "stick"'),
]


@pytest.mark.parametrize("text, words", REFUSED, ids=["stiff", "negative", "word"])
def test_refused_in_one_line(tmp, text, words, capsys):
    """What is not built is refused in one line "error: ...", exit 2, nothing written."""
    path = os.path.join(tmp, "bad.toml")
    out = os.path.join(tmp, "bad")
    if COMM.rank == 0:
        with open(path, "w") as f:
            f.write(text)
    COMM.barrier()
    capsys.readouterr()
    try:
        code = cli.main(["run", path, "--out", out, "--quiet"])
    except SystemExit as exc:
        code = exc.code
    err = COMM.bcast(capsys.readouterr().err if COMM.rank == 0 else None)
    lines = [x for x in err.splitlines() if x.strip() and not x.startswith("warning: ")]
    assert code == 2, err
    assert len(lines) == 1 and lines[0].startswith("error: ") and words in lines[0], err
    assert "Traceback" not in err and not os.path.exists(out)
    COMM.barrier()


def test_node_pair_slip_past_half_a_facet_warns_once(capsys):
    """Two node pairs 1 cm apart (their facet), the upper nodes sliding at 1 m/s over the
    lower ones under μ = 0.01: once the relative r displacement passes 5 mm the run warns,
    once, naming the pair and pointing to node to segment (docs/friction.md 6)."""
    mine = COMM.rank == 0
    m, h, N = 1.0, 1e-4, 1.0
    # dofs: lower nodes (r, z) 0-3, upper nodes 4-7, all owned by rank 0
    mass = np.full(8, m) if mine else np.zeros(0)
    u = np.zeros(mass.size)
    v = np.array([0, 0, 0, 0, 1.0, 0, 1.0, 0]) if mine else np.zeros(0)
    host = _Host(COMM, 0 if mine else 8, mass, u, v, h)
    cons = Constraints(r=np.array([0.0, 0.01]), b=np.zeros(2), lower=np.array([1, 3]),
                       upper=np.array([5, 7]), names=("lower", "upper"))
    c = ContactSet(cons, host, FILM("fast"), None)
    c.set_friction(0.01)
    c.initialize()
    capsys.readouterr()
    for _ in range(80):  # 8 mm of slip at most
        if mine:
            v[[5, 7]] -= h * N / m
            v[[1, 3]] += h * N / m
            u += h * v
        c.step()
        host.n += 1
    err = COMM.bcast(capsys.readouterr().err if mine else None)
    lines = [x for x in err.splitlines() if "past half its facet" in x]
    assert len(lines) == 1 and "node to segment" in lines[0] and lines[0].startswith("warning:")
    assert c.friction.stats[N_SLIP] == 2


# ----------------------------------------------------------------------------- penalty

@pytest.mark.parametrize("mu, sticks", [(0.5, True), (0.1, False)])
def test_penalty_one_pair_by_hand(mu, sticks):
    """The pair of test_one_pair_by_hand with a committed elastic slip s_e = 1e-7 m and
    k_t = 3e7 N/m: the trial λ_tr = -k_t (s_e + h w~) = -3 + 1500 = 1497 N. Stick (cone
    1e4 N): λ_t = λ_tr, s_e += h w⁺. Slip (cone 1000 N): λ_t = 1000 N, Δs_p =
    (c - λ_tr) / k_t, s_e += h w⁺ - Δs_p, D = c |Δs_p|, and the release loss R stays 0
    (a return books D alone, docs/friction.md 5.1). A second step with the pair open
    (λ_n = 0) releases the spring: λ_t = 0, s_e = 0, and R = 1/2 k_t s_e^2, its stored
    energy, while D is unchanged."""
    m_p, m_q, vp, vq, h, k, s0 = 2.0, 3.0, 0.3, -0.2, 1e-4, 3e7, 1e-7
    fn = 2e4 if sticks else 1e4
    trial = -k * (s0 + h * (vq - vp))
    lo, up = np.array([0]), np.array([1])
    v = np.array([vp, vq])
    u, lam, state = np.zeros(2), np.zeros(1), np.zeros(1, np.int8)
    s_e, d_slip, stats = np.array([s0]), np.zeros(1), np.zeros(8)
    h_over_m = np.array([h / m_p, h / m_q])
    penalty_tangential(lo, up, np.ones(1, np.bool_), np.array([fn]), np.array([k]), h_over_m,
                       h, mu, mu, 0.0, False, v.copy(), u, v, lam, state, s_e, d_slip, stats)
    c = mu * fn
    f = trial if sticks else c
    dsp = 0.0 if sticks else (c - trial) / k
    tol = rounding(8, abs(trial))
    assert state[0] == (1 if sticks else 2) and abs(lam[0] - f) <= tol
    assert abs(v[1] - (vq + h * f / m_q)) <= rounding(8, 0.5)
    assert abs(v[0] - (vp - h * f / m_p)) <= rounding(8, 0.5)
    w_new = v[1] - v[0]
    assert abs(s_e[0] - (s0 + h * w_new - dsp)) <= rounding(8, h * 0.5)
    assert abs(d_slip[0] - c * abs(dsp)) <= rounding(8, c * abs(dsp))
    assert stats[RELEASE_LOSS] == 0.0  # the return books nothing into R
    stored = 0.5 * k * s_e[0] ** 2
    assert abs(stats[STORED] - stored) <= rounding(4, stored)
    # the release: the committed spring's energy 1/2 k_t s_e^2 (3 roundings) into R
    penalty_tangential(lo, up, np.ones(1, np.bool_), np.zeros(1), np.array([k]), h_over_m,
                       h, mu, mu, 0.0, False, v.copy(), u, v, lam, state, s_e, d_slip, stats)
    assert lam[0] == 0.0 and state[0] == 0 and s_e[0] == 0.0 and d_slip[0] == 0.0
    assert abs(stats[RELEASE_LOSS] - stored) <= rounding(4, stored)
    assert stats[STORED] == 0.0


@pytest.mark.parametrize("beta", [1.0, 0.5])
def test_penalty_steady_tangential_load(beta):
    """A node on the wall under a constant normal load N and a tangential load F inside
    the cone: the spring settles at s_e = (1 - beta_t) F / k_t with λ_t = -F and w⁺ = 0
    (docs/friction.md 4: the drift of a trial built on the last force is excluded). The
    recurrence's transient decays as sqrt(1 - beta_t)^n (its matrix [[1 - b, -b],
    [1 - b, 1 - b]] on (w⁺, s_e / h) has determinant 1 - b): below 1e-30 after 200
    steps at beta_t = 0.5, none at 1. Round-off: a step's (EPS x 32) on F and F / k_t."""
    m, N, F, h = 2.0, 10.0, 1.0, 1e-3
    k = beta * m / h ** 2
    mine = COMM.rank == 0
    mass = np.array([m, m]) if mine else np.zeros(0)
    u, v = np.zeros(mass.size), np.zeros(mass.size)
    host = _Host(COMM, 0 if mine else 2, mass, u, v, h)
    cons = Constraints(r=np.array([1.0]), b=np.array([0.0]), lower=None,
                       upper=np.array([1]), names=("node", "wall"))
    c = ContactSet(cons, host, Penalty("scaled"), wall_part())
    c.set_friction(1.0, "scaled" if beta == 1.0 else k)
    c.initialize()
    for _ in range(200):
        if mine:
            v[1] += h * (-N / m)
            v[0] += h * F / m
            u += h * v
        c.step()
        host.n += 1
    t = c.friction
    assert abs(t.beta_max - beta) <= rounding(8, beta)
    assert abs(t.s_e[0] - (1.0 - beta) * F / k) <= rounding(32, F / k)
    assert abs(t.lam[0] + F) <= rounding(32, F) and t.state[0] == 1
    assert abs(t.v_now[0]) <= rounding(32, h * F / m)


def test_penalty_scaled_wall_equals_film(tmp):
    """On the wall, the scaled penalty (beta = 1 per node, normal and tangential) is FILM
    (docs/friction.md 4, contact.md): with μ = 0.3 every history column agrees within
    the spread of a one-ulp change of v0; its spring energy is zero at beta_t = 1 (the
    spring returns to zero at every step) and the ledger closes."""
    f = "friction = 0.3"
    hf, ef = _run(tmp, "pw_film", WALL_SCENE.format(method="film", friction=f))
    hp, ep = _run(tmp, "pw_pen", WALL_SCENE.format(method="penalty", friction=f))
    hu, _ = _run(tmp, "pw_ulp", WALL_SCENE.format(method="film", friction=f).replace(
        "velocity = [0.0, -5.0]", f"velocity = [0.0, {-one_ulp(5.0)!r}]"))
    n = hf.size
    assert np.any(hf["n_slip"] > 0) and np.any(hf["n_stick"] > 0)
    for col in ("wall_force", "tangential_force"):
        assert_within_spread(hp[col], hf[col], hu[col], n, col)
    assert np.array_equal(hp["n_stick"], hf["n_stick"])
    assert np.array_equal(hp["n_slip"], hf["n_slip"])
    # the spring's energy is the round-off of s_e = 0 (a step's roundings of the energy)
    assert np.all(hp["spring_energy"] <= rounding(32, np.abs(ep["total"]).max()))
    # D's terms c |Δs_p| >= 0; R's only releases (>= 0) at this constant step
    assert np.all(np.diff(hp["release_loss"]) >= 0.0) and np.all(np.diff(hp["slip_work"]) >= 0.0)
    scale = np.abs(ep["total"]).max()
    assert np.abs(ep["balance_error"]).max() <= ledger(n, 2 * 5 * 17) * scale


PUNCH_SCENE = """title = "punch with friction"
[mesh]
generator = "punch_block"
width = 6.5
depth = 0.3
h_surface = 0.05
grading = 0.1
h_max = 0.5
[materials.steel]
E = 200e9
nu = 0.3
density = 7850.0
[bodies.block]
material = "steel"
[rigid.punch]
mass = 0.1
velocity = 0.0
[[fixed]]
facet = "bottom"
components = ["z"]
[[contact]]
surface = "surface"
rigid = "punch"
radius = 0.5
method = "{method}"
friction = 0.2
[[loads]]
rigid = "punch"
pulse = "trapezoid"
peak = {peak!r}
area = 0.7853981633974483
t_rise = 1e-5
t_fall = 9e-5
t_end = 1e-4
[time]
dt = 3.64e-7
n_steps = 120
[output]
history_every = 1
energy_every = 1
fields = false
plots = false
"""


def test_moving_rigid_face_film_equals_dme(tmp):
    """A punch (a moving rigid part, 0.1 kg) pushed into a block, μ = 0.2: its nodes stick
    under the punch and slip at its rim; DME's cluster and FILM's coupled multipliers are
    the same normal correction (e = 0) and the tangential passes agree in stick and slip:
    every friction column within the spread of a one-ulp change of the load (the run
    starts at rest); the ledger closes."""
    hf, ef = _run(tmp, "punch_film", PUNCH_SCENE.format(method="film", peak=200e6))
    hd, ed = _run(tmp, "punch_dme", PUNCH_SCENE.format(method="dme", peak=200e6))
    hu, _ = _run(tmp, "punch_ulp", PUNCH_SCENE.format(method="film", peak=one_ulp(200e6)))
    n = hf.size
    assert np.any(hf["n_slip"] > 0) and np.any(hf["n_stick"] > 0)
    for col in ("punch_force", "tangential_force", "slip_work"):
        assert_within_spread(hd[col], hf[col], hu[col], n, col)
    assert np.array_equal(hd["n_stick"], hf["n_stick"])
    assert np.array_equal(hd["n_slip"], hf["n_slip"])
    for e in (ef, ed):
        assert np.abs(e["balance_error_rel"]).max() <= ledger(n, 3200)  # 3156 dofs


def _previous_step(t) -> float:
    """The tangential pass as it was before it became one compiled call (kept here only
    to compare against): the gather, the method's kernel and the commit, three calls."""
    from impact_fenics.contact.friction import (DME_T, FILM_T, PENALTY_T, STORED,
                                                _commit_tangential)

    c, law, integ = t.c, t.law, t.c.integrator
    nd = c.n_deformable
    t._gather(integ.u_owned, integ.v_owned, t.u_pred[:nd], t.v_pred[:nd])
    t.u[:] = t.u_pred
    t.v[:] = t.v_pred
    before = t.stats[RELEASE_LOSS] + t.stats[STORED]
    common = (law.static, law.dynamic, law.decay, law.stick)
    if t.kernel == FILM_T:
        film_tangential(t.lo, t.up, c.active, c.force, t.a_inv, t.h_over_m, c.dt, *common,
                        t.v_now, t.u, t.v, t.lam, t.state)
    elif t.kernel == DME_T:
        dme_tangential(t.lo, t.up, c.active, c.force, t.mass, t.m_over_h, t.h_over_m, c.dt,
                       *common, t.u_now, t.v_now, t.u, t.v, t.lam, t.state)
    else:
        penalty_tangential(t.lo, t.up, c.active, c.force, t.k_t, t.h_over_m, c.dt, *common,
                           t.v_now, t.u, t.v, t.lam, t.state, t.s_e, t.d_slip, t.stats)
    change = t.stats[RELEASE_LOSS] + t.stats[STORED] - before
    w_t, _ = _commit_tangential(t._local, t._pos, integ.u_owned, integ.v_owned, c.dt, c.h_avg,
                                t.m_over_h, t.u, t.v, t.v_pred, t.u_now, t.v_now, t.f_prev,
                                t.ku_prev, t.jump, t.lo, t.up, t.lam, t.state, t.stats,
                                t.slip_limit, t.kernel == PENALTY_T, t.d_slip, change)
    return w_t


def _both_paths(t, checked: list):
    """The step of tangential pass ``t`` run twice from the same state, the previous
    three calls and then the one call; appends to ``checked`` whether the two left the
    same u, v (owned), slots, rows, flags, stats and W_t, bit for bit."""
    step = t.step

    def both() -> float:
        integ = t.c.integrator
        kept = (integ.u_owned, integ.v_owned, t.slots, t.rows, t.stats, t.state)
        before = [a.copy() for a in kept]
        w_old = _previous_step(t)
        after_old = [a.copy() for a in kept]
        for a, b in zip(kept, before):
            a[...] = b
        w_new = step()
        checked.append(w_new == w_old
                       and all(np.array_equal(a, b) for a, b in zip(kept, after_old)))
        return w_new
    return both


@pytest.mark.parametrize("method", ["film", "dme", "penalty"])
@pytest.mark.parametrize("kind", ["pairs", "wall", "punch"])
def test_one_call_pass_equals_three_calls(tmp, method, kind):
    """The tangential pass as one compiled call (gather, kernel, commit inside it) is the
    same arithmetic as the three calls it replaced, in the same order: at every step of
    a run, both from the same state leave u, v, the slots, every pair's λ_t and flag, the
    friction stats and W_t bit for bit equal (exact equivalence, on the run's own
    partition, so on any number of ranks). Node pairs, the wall and a moving rigid face;
    μ = 0.3 (0.2 under the punch), stick and slip both present."""
    from impact_fenics.scene_file import build, read_scene

    if kind == "punch":
        if method == "penalty":
            pytest.skip("the punch is run with FILM and DME, as its other test")
        text = PUNCH_SCENE.format(method=method, peak=200e6).replace("n_steps = 120",
                                                                     "n_steps = 60")
    else:
        text = (SCENE if kind == "pairs" else WALL_SCENE).format(
            method=method, friction="friction = 0.3", v0=5.0)
    path = os.path.join(tmp, f"one_call_{kind}_{method}.toml")
    if COMM.rank == 0:
        with open(path, "w") as f:
            f.write(text)
    COMM.barrier()
    sim = build(read_scene(path), {"out": None, "quiet": True})
    sets = [c for c in sim.contacts if c.friction is not None]
    assert sets
    checked: list = []
    for c in sets:  # the pass as a call of its own, outside the set's one compiled call
        c.friction.step, c.friction.folds = _both_paths(c.friction, checked), False
    sim.run()
    slipped = np.asarray(sim.history.data()["n_slip"], dtype=float)
    assert len(checked) == len(sets) * slipped.size and all(checked)  # every step
    assert np.any(slipped > 0)  # some pair slipped at some step
