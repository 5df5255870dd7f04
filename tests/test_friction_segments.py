"""Coulomb friction on node to segment (FILM, DME): docs/friction.md sections 1.1, 2, 3, 8.

Oracles:

* the box problem of the stick set (contact.friction_segments.box_bpp) against the same
  problem solved by enumerating every assignment of the rows to stick, slip at +c and
  slip at -c (3^n sets, dense solves): the unique solution of a positive definite box
  problem, from random starts, with and without a cone;
* node to segment on matched faces equals node pairs with friction (FILM, DME; μ = 0.3
  with slip at the rim, and "stick"), whole runs within the spread of a one-ulp change of
  the striker's speed (roundoff.assert_within_spread), equal stick and slip counts;
* on non-matching flat faces (3:2), at every active constraint and step: the cone
  |λ_t| <= μ λ_n, the slip opposing the force on it, w_t^{n+1/2} = 0 inside it within
  ε cond(A_FF) |w~|; the contact step's change of Σ m v_r and Σ m v_z is the impulse it
  puts on the axis's fixed components (zero away from the axis), to the round-off of the
  sum; the ledger closes (roundoff.ledger) and the slip work never falls; DME equals
  FILM there (e = 0, faces touching at t = 0);
* a curved master (a nose on a block), where the normal and tangential rows couple: the
  step's multipliers after the Tresca passes (counted) against the coupled problem
  solved by enumerating its sets, at every step with at most five candidate rows;
* contact_pairs.h5 with friction: per pair the tangential force and the stick/slip flag,
  summing and counting to the history's columns;
* the penalty (docs/friction.md 4) on node to segment: on matched faces it is the node
  pairs' penalty (above); a block on an inclined straight face sticks below the cone
  (s_e = -(1 - beta_t) F / k_t, beta_t = 1 and 0.5) and slides at the Coulomb limit
  |λ_t| = μ λ_n above it, its slip speed, slide, slip work, release loss and tangential
  work in closed form, the energy balance closing; on non-matching faces the cone holds
  exactly, the plastic slip opposes the force and is zero in stick, the ledger closes;
* the refusals of what is not built, one line each: a curved master with restitution
  e > 0, a tangential stiffness past the bound (the penalty on a curved master:
  tests/test_friction_penalty_segments.py).
"""
from __future__ import annotations

import itertools
import os

import numpy as np
import pytest
from mpi4py import MPI

from impact_fenics import cli
from impact_fenics.contact.banded import band_of_s, bandwidth, dense_s
from impact_fenics.contact.friction_segments import (OFF, SLIP_DOWN, SLIP_UP, STICK,
                                                     box_bpp)
from impact_fenics.contact.friction import N_SLIP, N_STICK, RELEASE_LOSS, STORED
from impact_fenics.errors import InputError
from roundoff import assert_within_spread, ledger, one_ulp, rounding
from test_friction import SCENE, _run

COMM = MPI.COMM_WORLD
PAIRS = 'lower = "striker_contact"\nupper = "target_contact"'
SEGMENTS = 'slave = "striker_contact"\nmaster = "target_contact"'


# ----------------------------------------------------------------------------- the box problem

def _enumerate(A: np.ndarray, wt: np.ndarray, cap: np.ndarray, tol: float) -> np.ndarray:
    """λ of the box problem by trying every set (stick, +c, -c) of the rows."""
    n = wt.size
    found = []
    for sets in itertools.product((STICK, SLIP_UP, SLIP_DOWN), repeat=n):
        s = np.array(sets)
        if np.any(np.isinf(cap) & (s != STICK)):
            continue
        lam = np.where(s == SLIP_UP, cap, np.where(s == SLIP_DOWN, -cap, 0.0))
        lam[np.isinf(lam)] = 0.0
        F = np.flatnonzero(s == STICK)
        if F.size:
            lam[F] = np.linalg.solve(A[np.ix_(F, F)], -(wt[F] + A[F] @ lam))
        w = wt + A @ lam
        if (np.all(np.abs(lam[F]) <= cap[F] + tol * np.abs(lam).max())
                and np.all(w[s == SLIP_UP] <= tol * np.abs(wt).max())
                and np.all(w[s == SLIP_DOWN] >= -tol * np.abs(wt).max())):
            found.append(lam)
    assert found, "no set solves the box problem"
    return found[0]


@pytest.mark.parametrize("stick", [False, True])
def test_box_problem_against_enumeration(stick):
    """40 random banded positive definite A (6 rows, each moving three of eight slots, as
    a slave and a segment's two nodes) with random w~ and cone radii: the pivoting's λ
    equals the enumerated solution within ε cond(A) |λ| times the roundings of a band
    Cholesky solve (2 (bw + 1) a row, twice) and the cone and complementarity hold."""
    rng = np.random.default_rng(7)
    n, width = 6, 3
    for trial in range(40):
        cs = (np.arange(n)[:, None] + np.arange(width)[None, :]).astype(np.int64)
        ct = rng.uniform(-1.0, 1.0, (n, width))
        minv = rng.uniform(0.5, 2.0, n + width)
        bw = bandwidth(cs, ct, minv)
        band = np.empty((n, bw + 1))
        band_of_s(cs, ct, minv, 1.0, bw, band)
        A = dense_s(band, bw)
        wt = rng.normal(size=n)
        cap = np.full(n, np.inf) if stick else rng.uniform(0.0, 1.0, n)
        lam, w = np.zeros(n), np.zeros(n)
        state = rng.choice([STICK, SLIP_UP, SLIP_DOWN], n).astype(np.int8)  # a random start
        if stick:
            state[:] = STICK
        it = box_bpp(band, bw, wt, cap, lam, w, state, np.zeros(n, np.int64), np.zeros(n),
                     np.zeros(n), np.zeros((n, bw + 1)), np.zeros(n + 1, np.bool_), 200)
        assert it > 0
        expect = _enumerate(A, wt, cap, 1e-12)
        scale = np.linalg.cond(A) * max(np.abs(expect).max(), 1.0)
        assert np.abs(lam - expect).max() <= rounding(4 * (bw + 1), scale), trial
        assert np.all(np.abs(lam) <= cap)  # the clip: exactly
        assert np.all(state != OFF)
        assert np.all(lam[state == SLIP_UP] == cap[state == SLIP_UP])
        assert np.all(w[state == SLIP_UP] <= 0.0) and np.all(w[state == SLIP_DOWN] >= 0.0)


# ----------------------------------------------------------------------------- whole runs

@pytest.fixture(scope="module")
def tmp(tmp_path_factory):
    path = str(tmp_path_factory.mktemp("friction_nts")) if COMM.rank == 0 else None
    return COMM.bcast(path)


@pytest.mark.parametrize("law", ["0.3", '"stick"'])
@pytest.mark.parametrize("method", ["film", "dme", "penalty"])
def test_matched_faces_equal_node_pairs(tmp, method, law):
    """Node to segment on matched faces (each slave on a master node, xi = 0 or 1, a flat
    face: A diagonal, the rows decoupled) is node pairs with friction: every column within
    the steps x the spread of a one-ulp change of v0 of the pair run; the same stick and
    slip counts; its ledger closes. The penalty too (scaled, normal and tangential): with
    A diagonal, Gershgorin's bound of h h_n K^1/2 T M^-1 T' K^1/2 is its diagonal, the
    node pairs' beta_t = k_t h h_n (1/m_s + 1/m_m), so the scaled k_t is theirs and the
    bound is theirs, 4/3; its release loss and spring energy agree too."""
    f = f"friction = {law}"
    tag = f"{method}_{'stick' if 'stick' in law else 'mu'}"
    hp, ep = _run(tmp, f"pairs_{tag}", SCENE.format(method=method, friction=f, v0=5.0))
    hu, eu = _run(tmp, f"ulp_{tag}", SCENE.format(method=method, friction=f, v0=one_ulp(5.0)))
    hs, es = _run(tmp, f"nts_{tag}", SCENE.format(method=method, friction=f,
                                                  v0=5.0).replace(PAIRS, SEGMENTS))
    n = hp.size
    for col in ("contact_force", "tangential_force"):
        assert_within_spread(hs[col], hp[col], hu[col], n, col)
    # D and L_t add h |λ_t| |w_t| a row each step, |w_t| <= 2 v0: under "stick" the pairs'
    # merge gives w⁺ = 0 exactly and the band solve its round-off, so the step's roundings
    # are those of terms of size h |Σ λ_t| 2 v0, not of the (zero) column
    work = hp["dt"][0] * np.abs(hp["tangential_force"]).max() * 2 * 5.0
    cols = ("slip_work", "tangential_loss") + (
        ("release_loss", "spring_energy") if method == "penalty" else ())
    for col in cols:
        assert_within_spread(hs[col], hp[col], hu[col], n, col,
                             max(work, np.abs(hp[col]).max()))
    assert np.array_equal(hs["n_stick"], hp["n_stick"])
    assert np.array_equal(hs["n_slip"], hp["n_slip"])
    assert hs["n_stick"].max() > 0 and np.any(np.abs(hs["tangential_force"]) > 0.0)
    assert np.any(hs["n_slip"] > 0) == ("stick" not in law)  # μ = 0.3 slips at the rim
    scale = np.abs(ep["total"]).max()
    for col in ("kinetic", "strain", "contact_work", "activation_loss"):
        assert_within_spread(es[col], ep[col], eu[col], n, col, scale)
    n_dofs = 2 * 6 * 21 * 2  # at most: two bars of 6 x 21 nodes, (r, z) each
    assert np.abs(es["balance_error"]).max() <= ledger(n, n_dofs) * scale


NONMATCHING = SCENE.replace('generator = "coaxial_bars"', 'generator = "coaxial_bars_sized"').replace(
    "h = 0.002", "h_striker = 0.003333333333333333\nh_target = 0.0022222222222222222").replace(
    PAIRS, 'slave = "target_contact"\nmaster = "striker_contact"')


class _Checks:
    """Wraps a set's tangential pass: after each step, the cone, the slip's direction,
    stick's w = 0 and the contact step's momentum change, on the pass's own numbers."""

    def __init__(self, c):
        self.c, self.f = c, c.friction
        self.step, self.f.step = self.f.step, self.checked
        self.rows = self.slips = self.sticks = 0
        r_slots = np.zeros(c.n_slots, bool)
        r_slots[0::2] = True
        self.r_slots = r_slots & c.free
        self.z_slots = ~r_slots & c.free

    def checked(self) -> float:
        c, f = self.c, self.f
        w_t = self.step()
        lam, cap, state = f.lam, f.cap, f.state
        on = state != OFF
        assert np.all(lam[~on] == 0.0)
        assert np.all(np.abs(lam[on]) <= cap[on])  # exactly: the solver's clip
        slip = (state == SLIP_UP) | (state == SLIP_DOWN)
        assert np.all(np.abs(lam[slip]) == cap[slip])
        assert np.all(lam[slip] * f.w_next[slip] <= 0.0)  # the slip opposes the force
        stick = np.flatnonzero(state == STICK)
        if stick.size:
            A = dense_s(f.band, f.bw)[np.ix_(stick, stick)]
            # a band solve and the rows' sums: 4 (bw + 1) roundings, amplified by cond(A_FF)
            tol = rounding(4 * (f.bw + 1), np.linalg.cond(A) * np.abs(f.wt[stick]).max())
            # and w = T v itself: six products and sums on terms of size |t_k| |v_k|, the
            # velocities' own roundings (v += h f / m per pass) as many again
            tv = (np.abs(f.ct) * np.abs(c.v[c.cs])).sum(axis=1)[stick].max()
            tol += rounding(12, tv)
            assert np.abs(f.w_next[stick]).max() <= tol
        # the contact step's momentum change per slot (kg m/s), normal and tangential (on
        # a curved master the pass solves the normal problem again)
        dp = c.mass * (c.v - c.v_pred)
        # the terms that round: m |v| and m |v~| and each slot's impulses h_n |G' λ_n| and
        # h_n |T' λ_t| (a face's normals hold the geometry's round-off, n_r ~ 1e-17, so
        # the normal and tangential impulses on r cancel to far below their size)
        p = (np.abs(c.mass * c.v) + np.abs(c.mass * c.v_pred)
             + c.h_avg * (_dense_rows(c, np.abs(c.cc)).T @ np.abs(c.force)
                          + _dense_rows(c, np.abs(f.ct)).T @ np.abs(lam)))
        # the impulse h_n (λ_n n + λ_t t) on a fixed component (the axis: u_r = 0) is the
        # support's reaction, not the body's: Σ m Δv over the free slots balances it
        held = ~c.free[c.cs]
        for first, slots in ((0, self.r_slots), (1, self.z_slots)):
            coef_t = np.where(held[:, first::2], f.ct[:, first::2], 0.0).sum(axis=1)
            coef_n = np.where(held[:, first::2], c.cc[:, first::2], 0.0).sum(axis=1)
            support = c.h_avg * (np.dot(lam, coef_t) + np.dot(c.force, coef_n))
            # each slot's v += h f / m (twice) and the difference v - v~: 2 + 2 roundings of
            # its terms, then the sum of the slots' terms one rounding each
            bound = rounding(4 + slots.sum(), p[slots].sum() + abs(support))
            assert abs(dp[slots].sum() + support) <= bound
        self.rows += int(on.sum())
        self.slips += int(slip.sum())
        self.sticks += stick.size
        return w_t


@pytest.mark.parametrize("method", ["film", "dme"])
def test_nonmatching_flat_faces_cone_momentum_ledger(tmp, method):
    """3:2 flat faces, the finer target's nodes as slaves, μ = 0.3: the checks of
    :class:`_Checks` at every step, rows in stick and in slip; the ledger closes and the
    slip work never falls."""
    from impact_fenics.scene_file import build, read_scene

    out = os.path.join(tmp, f"nonmatching_{method}")
    text = NONMATCHING.format(method=method, friction="friction = 0.3", v0=5.0).replace(
        "[output]\n", f'[output]\ndir = "{out}"\n')
    path = os.path.join(tmp, f"nonmatching_{method}.toml")
    if COMM.rank == 0:
        with open(path, "w") as fh:
            fh.write(text)
    COMM.barrier()
    sim = build(read_scene(path))
    c = sim.contacts[0]
    assert c.bw > 0  # slaves share master nodes: A is banded, not diagonal
    checks = _Checks(c)
    sim.run()
    assert checks.sticks > 0 and checks.slips > 0
    h, e = sim.history.data(), sim.energy.data()
    scale = np.abs(np.asarray(e["total"])).max()
    n_dofs = 2 * 13 * 19 * 2  # at most: the finer bar's nodes, twice, (r, z) each
    assert np.abs(np.asarray(e["balance_error"])).max() <= ledger(sim.n_steps, n_dofs) * scale
    assert np.all(np.diff(np.asarray(h["slip_work"])) >= 0.0)
    assert c.friction.info["tangential_iterations_max"] >= 1


def test_nonmatching_dme_equals_film(tmp):
    """With e = 0 on faces touching at t = 0, DME's ν = φ and its tangential problem is
    FILM's (docs/friction.md 3): whole runs within the spread of a one-ulp change of v0."""
    runs = {}
    for name, m, v0 in (("film", "film", 5.0), ("dme", "dme", 5.0), ("ulp", "film",
                                                                    one_ulp(5.0))):
        runs[name] = _run(tmp, f"nm_{name}", NONMATCHING.format(
            method=m, friction="friction = 0.3", v0=v0))
    (hf, ef), (hd, ed), (hu, eu) = runs["film"], runs["dme"], runs["ulp"]
    n = hf.size
    for col in ("contact_force", "tangential_force", "slip_work"):
        assert_within_spread(hd[col], hf[col], hu[col], n, col)
    assert np.array_equal(hd["n_stick"], hf["n_stick"])
    assert np.array_equal(hd["n_slip"], hf["n_slip"])
    assert np.any(hf["n_slip"] > 0)


def test_nonmatching_flat_faces_penalty(tmp):
    """The penalty with μ = 0.3 on the 3:2 flat faces (slaves share master nodes: A is
    banded): the scaled k_t puts Gershgorin's bound of h h_n K^1/2 A K^1/2 at 1 (the
    coupled rows lower each k_t below 1 / (h A_ii)); at every step and loaded row the cone
    holds exactly (the clip returns c), a row on it has a plastic slip opposing its force
    (λ_t Δs_p <= 0) and a row inside it none (Δs_p = 0 exactly); the ledger closes and the
    slip work and the release loss never fall."""
    from impact_fenics.scene_file import build, read_scene

    out = os.path.join(tmp, "nonmatching_penalty")
    text = NONMATCHING.format(method="penalty", friction="friction = 0.3", v0=5.0).replace(
        "[output]\n", f'[output]\ndir = "{out}"\n')
    path = os.path.join(tmp, "nonmatching_penalty.toml")
    if COMM.rank == 0:
        with open(path, "w") as fh:
            fh.write(text)
    COMM.barrier()
    sim = build(read_scene(path))
    c = sim.contacts[0]
    f = c.friction
    assert c.bw > 0 and f.penalty
    assert abs(f.beta_max - 1.0) <= rounding(4 * (f.bw + 1))
    a = f.band[:, 0]
    assert np.all(f.k_t[a > 0] < 1.0 / (c.dt * a[a > 0]))  # the coupling lowers each k_t
    step, seen = f.step, {"stick": 0, "slip": 0}

    def checked():
        w_t = step()
        on = f.state != OFF
        assert np.all(f.lam[~on] == 0.0)
        assert np.all(np.abs(f.lam[on]) <= f.cap[on])
        slip = (f.state == SLIP_UP) | (f.state == SLIP_DOWN)
        assert np.all(np.abs(f.lam[slip]) == f.cap[slip])
        assert np.all(f.lam[slip] * f.dsp[slip] <= 0.0)
        assert np.all(f.dsp[f.state == STICK] == 0.0)
        seen["stick"] += int(np.sum(f.state == STICK))
        seen["slip"] += int(slip.sum())
        return w_t

    f.step = checked
    sim.run()
    assert seen["stick"] > 0 and seen["slip"] > 0, seen
    h, e = sim.history.data(), sim.energy.data()
    scale = np.abs(np.asarray(e["total"])).max()
    n_dofs = 2 * 13 * 19 * 2  # at most: the finer bar's nodes, twice, (r, z) each
    assert np.abs(np.asarray(e["balance_error"])).max() <= ledger(sim.n_steps, n_dofs) * scale
    # D's terms c |Δs_p| are >= 0; R's are releases (1/2 k_t s_e^2 >= 0) only: a return
    # books D alone, and a constant step rescales nothing (docs/friction.md 5.1)
    for col in ("slip_work", "release_loss"):
        assert np.all(np.diff(np.asarray(h[col])) >= 0.0)


NOSE = """title = "nose on a block"
[mesh]
generator = "nosed_striker_on_block"
nose_radius = 0.02
shank_length = 0.03
block_width = 0.06
block_depth = 0.04
h_striker = 0.005
h_block = 0.004
[materials.steel]
E = 200e9
nu = 0.3
density = 7850.0
[bodies.striker]
material = "steel"
velocity = [0.0, -20.0]
[bodies.block]
material = "steel"
[[contact]]
slave = "block_contact"
master = "nose"
method = "{method}"
friction = 0.2
[time]
cfl = 0.9
t_end = 1e-6
"""


@pytest.mark.parametrize("text, words", [
    (NOSE.format(method="dme").replace('method = "dme"', 'method = "dme"\nrestitution = 0.5'),
     "curved master face with restitution e > 0 is not built yet"),
    (SCENE.format(method="penalty", friction="friction = 0.2\ntangential_penalty = 1e15",
                  v0=5.0).replace(PAIRS, SEGMENTS), "passes the stable bound 4/3")],
    ids=["curved-restitution", "penalty-past-bound"])
def test_refused_in_one_line(tmp, text, words, capsys):
    """What is not built is refused in one line "error: ...", exit 2, nothing written."""
    path = os.path.join(tmp, "bad.toml")
    out = os.path.join(tmp, "bad")
    if COMM.rank == 0:
        with open(path, "w") as fh:
            fh.write(text)
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


# ----------------------------------------------------------------------------- a curved master

def _dense_rows(c, coef):
    """The rows of G (``coef`` = c.cc) or T (its tangent rows) as a dense (n, slots) array."""
    out = np.zeros((c.n, c.n_slots))
    np.add.at(out, (np.repeat(np.arange(c.n), c.cs.shape[1]), c.cs.ravel()), coef.ravel())
    return out


def _coulomb_by_enumeration(c, mu, candidates):
    """The coupled normal-tangential problem of FILM with friction, from the step's
    prediction, by trying every set of the ``candidates`` rows (open; closed and stick;
    closed and slipping at ±μ λ_n), the others open: every (λ_n, λ_t) that satisfies
    g = g~ + S_nn λ_n + S_nt λ_t >= 0 ⊥ λ_n >= 0 and the box of w = w~ + A_tn λ_n + A_tt λ_t
    (docs/friction.md 1, 1.1) within ``slack`` of their scales."""
    G, T = _dense_rows(c, c.cc), _dense_rows(c, c.friction.ct)
    minv = c.minv
    h, hb = c.dt, c.h_avg
    K = np.block([[h * hb * (G * minv) @ G.T, h * hb * (G * minv) @ T.T],
                  [hb * (T * minv) @ G.T, hb * (T * minv) @ T.T]])
    n = c.n
    rhs0 = np.concatenate([c.g0 + G @ c.u_pred, T @ c.v_pred])
    no_free = c.friction.no_free
    found = []
    for sets in itertools.product(range(4), repeat=len(candidates)):
        kind = np.zeros(n, int)  # 0 open, 1 stick, 2 slip +, 3 slip -
        kind[candidates] = sets
        if np.any(no_free & (kind > 1)):
            continue
        closed = np.flatnonzero(kind > 0)
        stick = np.flatnonzero((kind == 1) & ~no_free)
        # unknowns λ_n (closed), λ_t (stick); λ_t = ±μ λ_n on slipping rows
        P = np.zeros((2 * n, closed.size + stick.size))
        for j, i in enumerate(closed):
            P[i, j] = 1.0
            if kind[i] > 1:
                P[n + i, j] = mu if kind[i] == 2 else -mu
        for j, i in enumerate(stick):
            P[n + i, closed.size + j] = 1.0
        eqs = np.concatenate([closed, n + stick])
        if eqs.size == 0:
            x = np.zeros(0)
        else:
            M = (K @ P)[eqs]
            if np.linalg.matrix_rank(M) < eqs.size:
                continue
            x = np.linalg.solve(M, -rhs0[eqs])
        lam = P @ x
        res = rhs0 + K @ lam
        ln, lt, g, w = lam[:n], lam[n:], res[:n], res[n:]
        s_l = max(np.abs(lam).max(initial=0.0), 1e-300)
        s_g = max(np.abs(rhs0[:n]).max(), 1e-300)
        s_w = max(np.abs(rhs0[n:]).max(), 1e-300)
        slack = 1e-10
        ok = (np.all(ln[closed] >= -slack * s_l) and np.all(g[kind == 0] >= -slack * s_g)
              and np.all(np.abs(lt[stick]) <= mu * ln[stick] + slack * s_l)
              and np.all(w[kind == 2] <= slack * s_w) and np.all(w[kind == 3] >= -slack * s_w))
        if ok:
            found.append((ln, lt))
    return found


NOSE_FINE = NOSE.replace("h_striker = 0.005", "h_striker = 0.0025").replace(
    "h_block = 0.004", "h_block = 0.0016666666666666668").replace(
    "velocity = [0.0, -20.0]", "velocity = [0.0, -60.0]").replace(
    "t_end = 1e-6", "t_end = 1.2e-5").replace("friction = 0.2", "friction = {mu}")


MU = 0.05  # small enough that the rim of the contact slips


def test_curved_master_against_enumeration(tmp):
    """A nose (R = 2 cm) on a block, FILM with μ = 0.05: the normal and tangential rows
    couple (G M^-1 T' != 0), so the step iterates (the Tresca passes, counted). At every
    step with at most five candidate rows (a row loaded, or predicted to penetrate), the
    step's (λ_n, λ_t) is the one solution of the coupled problem found by enumerating
    every set, within 1e-12 of the largest multiplier: the passes stop once a pass changes
    λ by at most 1e-13 of it, and the enumeration's dense solves round to ε cond(K) (of
    order 1e2 here: K's rows scale by h and the segment's N_a, N_b)."""
    from impact_fenics.scene_file import build, read_scene

    out = os.path.join(tmp, "nose_enum")
    text = NOSE_FINE.format(method="film", mu=MU) + (
        f'[output]\ndir = "{out}"\nhistory_every = 1\nenergy_every = 1\nfields = false\n'
        'plots = false\n')
    path = os.path.join(tmp, "nose_enum.toml")
    if COMM.rank == 0:
        with open(path, "w") as fh:
            fh.write(text)
    COMM.barrier()
    sim = build(read_scene(path))
    c = sim.contacts[0]
    f = c.friction
    assert f.coupled
    step, seen = f.step, {"steps": 0, "checked": 0, "slip": 0, "stick": 0, "passes": []}

    def checked():
        w_t = step()
        seen["steps"] += 1
        g_pred = c.g0 + _dense_rows(c, c.cc) @ c.u_pred
        candidates = np.flatnonzero((c.force > 0.0) | (g_pred < 0.0))
        if 0 < candidates.size <= 5:
            found = _coulomb_by_enumeration(c, MU, candidates)
            assert len(found) == 1, len(found)
            ln, lt = found[0]
            scale = max(np.abs(ln).max(), np.abs(lt).max())
            assert np.abs(c.force - ln).max() <= 1e-12 * scale
            assert np.abs(f.lam - lt).max() <= 1e-12 * scale
            seen["checked"] += 1
        seen["slip"] += int(np.sum(f.state >= SLIP_UP))
        seen["stick"] += int(np.sum(f.state == STICK))
        seen["passes"].append(f.passes)
        return w_t

    f.step = checked
    sim.run()
    assert seen["checked"] >= 10 and seen["stick"] > 0 and seen["slip"] > 0, seen
    assert max(seen["passes"]) > 1 and f.info["tresca_unsettled"] == 0
    e = sim.energy.data()
    scale = np.abs(np.asarray(e["total"])).max()
    n_dofs = 2 * 2 * 600  # at most: the two bodies' nodes, (r, z) each
    assert np.abs(np.asarray(e["balance_error"])).max() <= ledger(sim.n_steps, n_dofs) * scale
    if COMM.rank == 0:
        print(f"\ncurved master: {seen['checked']} steps of {seen['steps']} against the "
              f"enumeration; Tresca passes per step: max {max(seen['passes'])}, mean "
              f"{np.mean(seen['passes']):.2f}; row-steps in stick {seen['stick']}, in slip "
              f"{seen['slip']}")


@pytest.mark.parametrize("method", ["film", "dme"])
def test_curved_master_cone_momentum_ledger(tmp, method):
    """The nose with μ = 0.05, FILM and DME: the checks of :class:`_Checks` at every step
    after the Tresca passes (the tangential problem is solved last, so the cone holds
    exactly), rows in stick and in slip, every step settled; the ledger closes."""
    from impact_fenics.scene_file import build, read_scene

    out = os.path.join(tmp, f"nose_{method}")
    text = NOSE_FINE.format(method=method, mu=MU) + (
        f'[output]\ndir = "{out}"\nhistory_every = 1\nenergy_every = 1\nfields = false\n'
        'plots = false\n')
    path = os.path.join(tmp, f"nose_{method}.toml")
    if COMM.rank == 0:
        with open(path, "w") as fh:
            fh.write(text)
    COMM.barrier()
    sim = build(read_scene(path))
    c = sim.contacts[0]
    checks = _Checks(c)
    sim.run()
    assert checks.sticks > 0 and checks.slips > 0
    info = c.friction.info
    assert info["tresca_passes_max"] > 1 and info["tresca_unsettled"] == 0
    e = sim.energy.data()
    scale = np.abs(np.asarray(e["total"])).max()
    n_dofs = 2 * 2 * 600  # at most: the two bodies' nodes, (r, z) each
    assert np.abs(np.asarray(e["balance_error"])).max() <= ledger(sim.n_steps, n_dofs) * scale
    if COMM.rank == 0:
        print(f"\nnose {method}: Tresca passes max {info['tresca_passes_max']}, mean "
              f"{info['tresca_passes_total'] / sim.n_steps:.2f}; balance "
              f"{np.abs(np.asarray(e['balance_error'])).max():.3g} J of {scale:.3g} J")


@pytest.mark.parametrize("kind", ["pairs", "segments"])
@pytest.mark.parametrize("method", ["film", "dme"])
def test_contact_pairs_file_with_friction(tmp, method, kind):
    """contact_pairs.h5 of a set with friction (μ = 0.3, a row every step) holds each
    pair's tangential force and its stick/slip flag: per row they sum and count to the
    history's tangential_force (within the rounding of a sum of the pairs' |λ_t|, in
    another order), n_stick and n_slip; |λ_t| <= μ λ_n at every pair (exactly: the clip);
    a pair that is neither has λ_t = 0."""
    from impact_fenics.output import read_pairs

    text = SCENE.format(method=method, friction="friction = 0.3", v0=5.0).replace(
        "history_every = 1", "history_every = 1\npairs_every = 1")
    if kind == "segments":
        text = text.replace(PAIRS, SEGMENTS)
    name = f"pairs_file_{method}_{kind}"
    h, _ = _run(tmp, name, text)
    if COMM.rank == 0:
        p = read_pairs(os.path.join(tmp, name, "contact_pairs.h5"))
        row = {int(s): j for j, s in enumerate(h["step"])}
        js = [row[int(s)] for s in p["step"]]
        lam, flag = p["tangential_force"], p["slip_state"]
        assert np.all(np.abs(lam) <= 0.3 * p["force"])
        assert np.all(lam[flag == 0] == 0.0)
        sums = lam.sum(axis=1)
        bound = rounding(lam.shape[1], np.abs(lam).sum(axis=1))
        assert np.all(np.abs(sums - h["tangential_force"][js]) <= bound)
        assert np.array_equal((flag == 1).sum(axis=1), h["n_stick"][js])
        assert np.array_equal((flag == 2).sum(axis=1), h["n_slip"][js])
        assert (flag == 2).any() and (flag == 1).any()
    COMM.barrier()


# ----------------------------------------------------------------------------- the penalty

def _block_on_incline(theta: float, mu: float, stiffness, n_steps: int, method=None):
    """A block (one slave node, m = 2 kg, both components free) resting on a fixed straight
    master segment inclined at ``theta`` (rad) to r, under gravity g = 10 m/s^2 along -z,
    h = 1e-3 s, the penalty with friction μ and tangential stiffness ``stiffness`` (N/m or
    "scaled"), or ``method`` (a contact method) in its place. Returns the set, the per-step
    (λ_n, λ_t, w_t^{n+1/2}, slide along t, s_e, the cumulative tangential arrival loss L_t)
    and the kinetic energy and the gravity's work by the half-step kinetic identity
    (rank 0's numbers, broadcast)."""
    from impact_fenics.contact.plane import _Host
    from impact_fenics.contact.segments import FACE, SegmentConstraints
    from impact_fenics.contact import ContactSet, Penalty

    m, g, h = 2.0, 10.0, 1e-3
    tr, tz = np.cos(theta), np.sin(theta)  # the face's tangent t = (n_z, -n_r)
    nr, nz = -tz, tr  # its outward (upward) normal
    a_xy, b_xy = np.array([1.0, 0.0]), np.array([1.0 + 0.2 * tr, 0.2 * tz])
    s_xy = 0.5 * (a_xy + b_xy)  # the block on the face, at mid-segment: g0 = 0
    mine = COMM.rank == 0
    mass = np.full(6, m) if mine else np.zeros(0)
    u, v = np.zeros(mass.size), np.zeros(mass.size)
    host = _Host(COMM, 0 if mine else 6, mass, u, v, h,
                 fixed=np.array([2, 3, 4, 5]) if mine else None)
    cons = SegmentConstraints(
        slave_xy=s_xy[None, :], slave_dofs=np.array([[0, 1]]),
        master_xy=np.stack([a_xy, b_xy]), master_dofs=np.array([[2, 3], [4, 5]]),
        segments=np.array([[0, 1]]), seg=np.array([0]), a=np.array([0]), b=np.array([1]),
        xi=np.array([0.5]), normal=np.array([[nr, nz]]), g0=np.array([0.0]),
        kind=np.array([FACE]), names=("block", "incline"))
    c = ContactSet(cons, host, Penalty("scaled") if method is None else method)
    c.set_friction(mu, stiffness)
    c.initialize()
    rows, kinetic, gravity = [], 0.0, 0.0
    for _ in range(n_steps):
        if mine:
            v_old = v[1]
            v[1] += h * (-g)
            u[:2] += h * v[:2]
        c.step()
        host.n += 1
        f = c.friction
        if mine:
            # gravity's work by the kinetic identity of the step: f . (v^{n-1/2} + v^{n+1/2}) h / 2,
            # its v^{n+1/2} the corrected one (the contact's share is booked by the set)
            gravity += -m * g * 0.5 * (v_old + v[1]) * h
            kinetic = 0.5 * m * (v[0] ** 2 + v[1] ** 2)
            rows.append((c.force[0], f.lam[0], tr * v[0] + tz * v[1], tr * u[0] + tz * u[1],
                         f.s_e[0], f.tangential_loss))
    rows, kinetic, gravity = COMM.bcast((np.array(rows), kinetic, gravity))
    return c, rows, kinetic, gravity, (m, g, h)


@pytest.mark.parametrize("stiffness", ["scaled", "half"])
def test_penalty_block_sticks_below_the_cone(stiffness):
    """tan θ = 0.5 μ (μ = 0.5): the block sticks. The normal penalty (scaled, beta = 1)
    carries λ_n = m g cos θ from the first step; the tangential spring holds the
    down-slope load F = m g sin θ with λ_t = F (along +t, up the slope) and settles at
    s_e = -(1 - beta_t) F / k_t with w = 0 (docs/friction.md 4): at once at beta_t = 1, as
    sqrt(1 - beta_t)^n at beta_t = 0.5 (below 1e-30 after 300 steps; its transient
    overshoots F by a quarter, so the cone is set at twice F to stay inside). Its bound on the
    segment is the node pairs' (one row: Gershgorin's sum is the diagonal, beta_t =
    k_t h h_n / m). Round-off: a step's roundings (32) on F, F / k_t and h g."""
    mu, n = 0.5, 300
    theta = np.arctan(0.5 * mu)
    m, g, h = 2.0, 10.0, 1e-3
    k = 0.5 * m / h ** 2 if stiffness == "half" else "scaled"
    beta = 0.5 if stiffness == "half" else 1.0
    c, rows, _, _, _ = _block_on_incline(theta, mu, k, n)
    F, N = m * g * np.sin(theta), m * g * np.cos(theta)
    k_t = m / h ** 2 * beta
    assert abs(c.friction.beta_max - beta) <= rounding(8, beta)
    ln, lt, w, _, s_e, _ = rows.T
    assert np.all(np.abs(ln - N) <= rounding(32, N))
    assert np.all(np.abs(lt) < mu * ln)  # inside the cone: stick at every step
    assert abs(lt[-1] - F) <= rounding(32, F)
    assert abs(w[-1]) <= rounding(32, h * g)
    # the load acts down the slope (along -t): the spring is stretched the other way
    assert abs(s_e[-1] + (1.0 - beta) * F / k_t) <= rounding(32, F / k_t)
    assert c.friction.stats[N_STICK] == 1 and c.friction.slip_work == 0.0


@pytest.mark.parametrize("ratio", [1.25, 3.0])
def test_penalty_block_slides_at_the_coulomb_limit(ratio):
    """tan θ = ratio x μ (μ = 0.3): the block slides down the slope with the tangential
    force on the cone, |λ_t| = μ λ_n at every step, λ_n = m g cos θ (the scaled normal
    penalty, beta = 1), so its slip speed is the closed form w_k = -k h g (sin θ - μ cos θ)
    (k = 1, 2, ...) and the slide h Σ w_k. The scaled spring (beta_t = 1) keeps s_e = 0,
    so each step's plastic slip is the step's slip h w_k: the slip work D = μ N |slide|
    in closed form, and the release loss R stays 0 (nothing is released, the step is
    constant; a return books D alone, docs/friction.md 5.1). The energy balance closes to
    round-off: the kinetic energy equals gravity's work plus the set's contact work (the
    one booking); its tangential share W_t = -(D + R + L_t + the stored energy, zero
    here) is the closed form -W_t = D - μ N h |w_n| / 2, and the arrival loss after k
    steps is FILM's closed form L_t = -μ N h |w_k| / 2 (docs/friction.md 5.1: the
    telescoped 1/2 h λ_t (w_k - w_(k-1)); once 1/2 m w_k^2 a step went to R and L_t gave
    it back). Round-off: the closed-form sums over n steps, a step's roundings (32) on
    each term."""
    mu, n = 0.3, 200
    theta = np.arctan(ratio * mu)
    c, rows, kinetic, gravity, (m, g, h) = _block_on_incline(theta, mu, "scaled", n)
    N = m * g * np.cos(theta)
    ln, lt, w, slide, s_e, loss = rows.T
    k = np.arange(1, n + 1)
    w_exact = -k * h * g * (np.sin(theta) - mu * np.cos(theta))
    # λ_n = p (-n . u~): the gap is a sum of terms of the size of the slide |u|, times the
    # scaled p = m / h^2, on top of a step's roundings of N
    assert np.all(np.abs(ln - N) <= rounding(32, N + m / h ** 2 * np.abs(slide)))
    assert np.all(lt == mu * ln)  # on the cone exactly (the clip), opposing the slip (w < 0)
    assert np.all(np.abs(w - w_exact) <= rounding(32 * k, h * g * k))
    slide_exact = h * np.cumsum(w_exact)
    assert np.all(np.abs(slide - slide_exact) <= rounding(32 * n, np.abs(slide_exact).max()))
    assert np.all(np.abs(s_e) <= rounding(32 * n, h * np.abs(w_exact).max()))
    f = c.friction
    d_exact = mu * N * abs(slide_exact[-1])
    # the kinetic scale 1/2 m Σ w_k^2: the booking's force m/h (v - v~) cancels to ε |w|
    # per step, so its work rounds by ε m w_k^2 a step (what a return once booked as R)
    kin = 0.5 * m * np.sum(w_exact ** 2)
    assert abs(f.slip_work - d_exact) <= rounding(32 * n, d_exact)
    assert f.stats[RELEASE_LOSS] == 0.0  # no release, no change of step: nothing booked
    assert f.stats[N_SLIP] == 1 and f.stats[STORED] <= rounding(32 * n, kin)
    # the one ledger: K = W_gravity + W_contact to the roundings of n steps of each
    assert abs(kinetic - gravity - c.contact_work) <= rounding(32 * n, kinetic)
    # the tangential work, W_t = -(D + R + E_s + L_t), is the trapezoid of λ_t = μ N over
    # the slip speeds, -W_t = μ N h Σ (|w_(k-1)| + |w_k|) / 2 = D - μ N h |w_n| / 2: the
    # dissipation is D
    w_t = -(f.slip_work + f.stats[RELEASE_LOSS] + f.stats[STORED] + f.tangential_loss)
    assert abs(-w_t - (d_exact - 0.5 * mu * N * h * abs(w_exact[-1]))) <= rounding(
        32 * n, kin + d_exact)
    # L_t after every step k: -μ N h |w_k| / 2 (the telescoped K_t + X_t), within the
    # roundings of k steps on the kinetic scale and the slip work so far
    d_k = mu * N * np.abs(h * np.cumsum(w_exact))
    kin_k = 0.5 * m * np.cumsum(w_exact ** 2)
    assert np.all(np.abs(loss + 0.5 * mu * N * h * np.abs(w_exact))
                  <= rounding(32 * k, kin_k + d_k))
    if COMM.rank == 0:
        print(f"\nincline tan θ = {ratio} μ: D = {f.slip_work:.6g} J (μ N |slide| "
              f"{d_exact:.6g}), R = {f.stats[RELEASE_LOSS]:.6g} J, L_t = {f.tangential_loss:.6g}"
              f" J (-μ N h |w_n| / 2 = {-0.5 * mu * N * h * abs(w_exact[-1]):.6g} J, largest "
              f"step error {np.abs(loss + 0.5 * mu * N * h * np.abs(w_exact)).max():.3g} J), "
              f"K = {kinetic:.6g} J")


def test_penalty_segment_stiffness_past_the_bound_is_refused():
    """A given k_t whose beta_t (Gershgorin's bound on h h_n K^1/2 T M^-1 T' K^1/2; one row:
    k_t h^2 / m) passes 4/3 is refused in one line."""
    with pytest.raises(InputError, match="passes the stable bound 4/3"):
        _block_on_incline(0.1, 0.3, 1.5 * 2.0 / 1e-3 ** 2, 1)
