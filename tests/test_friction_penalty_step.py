"""The penalty's tangential spring on a finite-strain wall under a varying step.

The Taylor bar (scenes/taylor_bar.toml on an n_r = 2 mesh, 227 m/s) strikes the wall
with method = "penalty" and friction μ = 0.3, its step re-estimated every 3 steps
(cfl = 0.5). A "scaled" k_t = 1/(h A_ii) follows the step and each spring keeps its
force k_t s_e across a change (docs/friction.md 4.3). The oracles:

- at a constant step the rescale does nothing: a run whose springs are rescaled after
  every step at the unchanged step equals the plain run bit for bit;
- the ledger K + W_int + L = K_0 closes at every energy row within roundoff.ledger, and
  the cone |λ_t| <= μ λ_n holds at every row and step (to the rounding of the return,
  1e-12 relative);
- the release loss's jump at each change of step equals the stored energy the springs
  gave up, Σ ½ (k_t s_e² − k_t′ s_e′²), recomputed here from the springs before and after
  the change, and each spring's force is kept, k_t′ s_e′ = k_t s_e, both to a few
  roundings.

The same test runs unchanged on 1, 2 and 3 ranks (every rank holds the gathered rows).
"""
import numpy as np
import pytest
from mpi4py import MPI

from impact_fenics.contact.friction import PENALTY_T, RELEASE_LOSS, STORED
from impact_fenics.scene_file import build, read_scene
from roundoff import EPS, ledger

COMM = MPI.COMM_WORLD
MU = 0.3


def _scene(tmp, interval: int):
    text = open("scenes/taylor_bar.toml").read()
    text = text.replace('method = "film"', f'method = "penalty"\nfriction = {MU}')
    text = text.replace("n_r = 8", "n_r = 2").replace("t_end = 80e-6", "t_end = 6e-6")
    text = text.replace("dt_interval = 10", f"dt_interval = {interval}")
    path = tmp / f"penalty_{interval}.toml"
    if COMM.rank == 0:
        path.write_text(text)
    COMM.Barrier()
    return read_scene(str(path))


@pytest.fixture(scope="module")
def tmp(tmp_path_factory):
    path = tmp_path_factory.mktemp("penalty_step") if COMM.rank == 0 else None
    return COMM.bcast(path)


def _run(scene, attach=None):
    sim = build(scene, {"out": None, "quiet": True, "plots": False, "fields": False})
    wall = sim.contacts[-1]
    assert wall.friction is not None and wall.friction.kernel == PENALTY_T
    if attach is not None:
        attach(sim, wall, wall.friction)
    s = sim.run(extra=sim.scene_figures)
    assert s["status"] == "completed"
    return sim, s


def test_a_constant_step_rescales_nothing(tmp):
    """dt_interval past the run's steps: one step for the run. Rescaling the springs after
    every step at that step must leave the run bit for bit as it is."""
    scene = _scene(tmp, 100000)
    plain, s_plain = _run(scene)
    calls = []

    def attach(sim, wall, friction):
        step = wall.step

        def stepped(*args):
            w = step(*args)
            friction.set_step()  # the step unchanged: k_t' = k_t, nothing moves
            calls.append(1)
            return w
        wall.step = stepped
    again, s_again = _run(scene, attach)
    assert len(calls) == s_again["n_steps"] > 0
    assert s_plain["dt_range"][0] == s_plain["dt_range"][1]  # one step for the run
    assert np.array_equal(plain.integrator.u_owned, again.integrator.u_owned)
    assert np.array_equal(plain.integrator.v_owned, again.integrator.v_owned)
    a, b = plain.contacts[-1].friction, again.contacts[-1].friction
    assert np.array_equal(a.stats, b.stats) and np.array_equal(a.rows, b.rows)
    for col in ("balance_error", "total"):
        assert np.array_equal(plain.energy.data()[col], again.energy.data()[col])


def test_ledger_cone_and_the_booked_rescale(tmp):
    rows, changes = [], []

    def attach(sim, wall, friction):
        step, set_step = wall.step, friction.set_step

        def stepped(*args):
            w = step(*args)
            on = wall.active.astype(bool) & (wall.force > 0.0)
            rows.append((np.abs(friction.lam[on]), MU * wall.force[on],
                         np.abs(friction.lam[~on]).max(initial=0.0)))
            return w

        def rescaled():
            k, s_e = friction.k_t.copy(), friction.s_e.copy()
            r, e = friction.stats[RELEASE_LOSS], friction.stats[STORED]
            set_step()
            changes.append((k, s_e, friction.k_t.copy(), friction.s_e.copy(),
                            friction.stats[RELEASE_LOSS] - r, e, friction.stats[STORED], r))
        wall.step = stepped
        friction.set_step = rescaled
    sim, s = _run(_scene(tmp, 3), attach)
    # the ledger at every energy row (roundoff.ledger: the finite-strain bar's steps
    # and dofs), on the initial kinetic energy as its scale
    balance = np.abs(sim.energy.data()["balance_error"])
    assert balance.max() <= ledger(s["n_steps"], s["n_dofs"]) * s["energy_initial"]
    # the cone at every step (the return puts |λ_t| = c exactly but for its rounding)
    assert len(rows) == s["n_steps"]
    slipped = 0
    for lam, cap, off in rows:
        assert np.all(lam <= cap * (1 + 1e-12)) and off == 0.0
        slipped += int(np.sum(lam >= cap * (1 - 1e-12)))
    assert slipped > 0  # the cone is reached: the return is exercised
    # the booked change at each change of step, from the springs before and after: each
    # term ½ k s² has 3 roundings and the sums n - 1 more, on terms of at most the
    # stored energies, so 8 n EPS (E_s + E_s') bounds both sides' roundings; the booked
    # change is read as the difference of the cumulative R, which rounds it on |R|
    # (2 roundings: the sum and the difference)
    lo, hi = min(s["dt_range"]), max(s["dt_range"])
    assert lo < hi  # the step did change
    moved = 0
    for k, s_e, k2, s_e2, booked, before, after, r in changes:
        recomputed = np.sum(0.5 * k * s_e ** 2) - np.sum(0.5 * k2 * s_e2 ** 2)
        scale = np.sum(0.5 * k * s_e ** 2) + np.sum(0.5 * k2 * s_e2 ** 2)
        tol = 8 * k.size * EPS * scale
        assert abs(booked - recomputed) <= tol + 2 * EPS * abs(r), (booked, recomputed)
        assert abs(after - np.sum(0.5 * k2 * s_e2 ** 2)) <= tol
        assert abs(before - np.sum(0.5 * k * s_e ** 2)) <= tol
        # the force kept: k' s' = k s to 2 roundings of the larger (a product, a quotient)
        held = (k2 > 0.0) & (k > 0.0)
        assert np.all(np.abs(k2 * s_e2 - k * s_e)[held]
                      <= 4 * EPS * np.abs(k * s_e)[held])
        moved += int(np.any(k2 != k) and np.any(s_e != 0.0))
    assert moved > 0  # a change of step met loaded springs
    if COMM.rank == 0:
        w = s["friction"][0]
        print(f"steps {s['n_steps']}, dt {lo:.4g}..{hi:.4g} s, changes with loaded springs "
              f"{moved}, balance {balance.max():.3g} J (bound "
              f"{ledger(s['n_steps'], s['n_dofs']) * s['energy_initial']:.3g} J), release loss "
              f"{w['release_loss']:.4g} J, spring {w['spring_energy']:.4g} J, slip work "
              f"{w['slip_work']:.4g} J, rows at the cone {slipped}")


def _built(tmp):
    sim = build(_scene(tmp, 3), {"out": None, "quiet": True, "plots": False, "fields": False})
    wall = sim.contacts[-1]
    return sim, wall, wall.friction


@pytest.mark.parametrize("factor", [0.8, 1.25])
def test_a_change_of_step_keeps_each_springs_force(tmp, factor):
    """At β_t = 1 the scaled spring ends each step at s_e = 0 but for round-off (it is
    FILM's stick), so the run above rescales round-off: here the springs are loaded by
    hand (random s_e on the rows with k_t > 0) and the set's step changed by ``factor``
    (k_t grows at 0.8, falls at 1.25): the force k_t s_e is kept to 2 roundings, the
    booked R jump is Σ ½ (k_t s_e² − k_t′ s_e′²) (signed: >= 0 iff k_t grows) to 8 n EPS
    of the stored energies (see above), and the stored column is E_s′."""
    sim, wall, friction = _built(tmp)
    rng = np.random.default_rng(7)
    on = friction.k_t > 0.0
    assert on.any()
    friction.s_e[on] = rng.uniform(-1e-6, 1e-6, int(on.sum()))  # m
    friction.stats[STORED] = float(np.sum(0.5 * friction.k_t * friction.s_e ** 2))
    k, s_e = friction.k_t.copy(), friction.s_e.copy()
    r = friction.stats[RELEASE_LOSS]
    assert r == 0.0  # (nothing run: the jump is R itself, no rounding on a cumulative R)
    wall.set_step(factor * wall.dt, factor * wall.h_avg)
    k2, s_e2 = friction.k_t, friction.s_e
    assert np.all((k2[on] > k[on]) if factor < 1 else (k2[on] < k[on]))
    assert np.all(np.abs(k2 * s_e2 - k * s_e) <= 4 * EPS * np.abs(k * s_e))
    e0, e1 = np.sum(0.5 * k * s_e ** 2), np.sum(0.5 * k2 * s_e2 ** 2)
    tol = 8 * k.size * EPS * (e0 + e1)
    booked = friction.stats[RELEASE_LOSS] - r
    assert abs(booked - (e0 - e1)) <= tol
    assert (booked > 0.0) == (factor < 1.0)
    # force kept: E_s' = E_s k_t / k_t' (here per row: E_s' / E_s = factor^2 exactly but
    # for roundings, k_t = 1/(h h_n ...) with both steps scaled)
    assert abs(e1 - factor ** 2 * e0) <= tol
    assert abs(friction.stats[STORED] - e1) <= tol


def test_a_given_stiffness_past_the_bound_stops_the_run(tmp):
    """A k_t in N/m stays at a change of step; its β_t = k_t h h_n (1/m_lo + 1/m_up)
    grows with the step: set at 1.3 (under 4/3) and the step made 1.1 times longer
    (β_t = 1.3 x 1.21 = 1.57) the run stops in one line (UnstableRunError, exit 3),
    unless forced; k_t and s_e are unchanged."""
    from impact_fenics.errors import UnstableRunError

    sim, wall, friction = _built(tmp)
    a_max = 1.0 / friction.a_inv[friction.a_inv > 0.0].min()  # the largest A_ii
    friction.stiffness = 1.3 / (wall.dt * a_max)  # N/m
    friction.set_step()
    assert abs(friction.beta_max - 1.3) <= 8 * EPS
    on = friction.k_t > 0.0
    friction.s_e[on] = 1e-7
    k, s_e = friction.k_t.copy(), friction.s_e.copy()
    with pytest.raises(UnstableRunError, match="passes the stable bound 4/3 .* the run stops"):
        wall.set_step(1.1 * wall.dt, 1.1 * wall.h_avg)
    assert np.array_equal(k, friction.k_t) and np.array_equal(s_e, friction.s_e)
    friction.forced = True
    wall.set_step(1.2 * wall.dt, 1.2 * wall.h_avg)
    assert friction.beta_max > 4.0 / 3.0
