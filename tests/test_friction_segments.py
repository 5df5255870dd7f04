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
  ε cond(A_FF) |w~|; the pass's change of Σ m v_r and Σ m v_z is the impulse it puts on
  the axis's fixed components (zero away from the axis), to the round-off of the sum; the ledger closes (roundoff.ledger) and the slip work never falls; DME equals
  FILM there (e = 0, faces touching at t = 0);
* the refusals of what is not built, one line each: a curved master face (the normal and
  tangential rows couple: the Tresca iteration), the penalty on node to segment.
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
from roundoff import EPS, assert_within_spread, ledger, one_ulp, rounding
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
@pytest.mark.parametrize("method", ["film", "dme"])
def test_matched_faces_equal_node_pairs(tmp, method, law):
    """Node to segment on matched faces (each slave on a master node, xi = 0 or 1, a flat
    face: A diagonal, the rows decoupled) is node pairs with friction: every column within
    the steps x the spread of a one-ulp change of v0 of the pair run; the same stick and
    slip counts; its ledger closes."""
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
    for col in ("slip_work", "tangential_loss"):
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
    stick's w = 0 and the pass's momentum change, on the pass's own numbers."""

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
        v0 = c.v.copy()
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
            assert np.abs(f.w_next[stick]).max() <= tol
        dp = c.mass * (c.v - v0)  # the pass's momentum change per slot (kg m/s)
        p = np.abs(c.mass * c.v) + np.abs(c.mass * v0)
        # the impulse h_n λ_i t on a fixed component (the axis: u_r = 0) is the support's
        # reaction, not the body's: Σ m Δv over the free slots balances it
        held = ~c.free[c.cs]
        for first, slots in ((0, self.r_slots), (1, self.z_slots)):
            coef = np.where(held[:, first::2], f.ct[:, first::2], 0.0).sum(axis=1)
            support = c.h_avg * np.dot(lam, coef)
            # each slot's v += h f / m and the difference v - v0 round on |v| (2 roundings
            # of m |v|), then the sum of the slots' terms one rounding each
            bound = rounding(2 + slots.sum(), p[slots].sum() + abs(support))
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
    (NOSE.format(method="film"), "friction on a curved master face"),
    (SCENE.format(method="penalty", friction="friction = 0.2", v0=5.0).replace(PAIRS, SEGMENTS),
     "built for film and dme (not yet the penalty)")], ids=["curved", "penalty"])
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
