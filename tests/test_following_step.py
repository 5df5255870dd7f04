"""A run to t_end under a step that follows a limit (stepping.FollowingStep) in the
small-strain driver. A fixed dt: its steps are listed at set-up (the last one clipped to
t_end), and the run stops, as a diverged run (UnstableRunError, exit 3 from the command
line), at the step whose re-estimated limit falls below dt. The adaptive step: the run
finds its last step as it goes (the one that reaches t_end), and every schedule of
outputs ends there; a penalty's beta is checked at each re-estimated step.

The limit here is given by the test (a bound policy; a finite-strain body's cells give it
in a scene): a constant one, then one that falls at a chosen re-estimation.

Oracles:

* Exact equivalence: the run equals, table for table and array for array, the run of the
  same steps listed one by one (stepping.StepSequence, whose ledger test_varying_step
  holds to round-off against the kinetic identity), and its steps sum to t_end within
  the rounding of that sum.
* A stopped run leaves the state of the last step taken: u and v equal those of the
  listed run of the steps before the stop, bit for bit (nothing half-stepped).
* A penalty is checked at set-up at every (h_{n+1/2}, h_n) of the listed steps; under the
  adaptive step at each re-estimation: a p stable at the first step stops the run at the
  re-estimation that makes the step too large for it.
* The adaptive step's run equals the run of its steps written out in the test (h =
  safety x the limit of the last estimate, the last step clipped), and its energy rows
  are at every energy_every steps and at the last.
"""
import numpy as np
import pytest
from mpi4py import MPI

from impact_fenics import meshing, scenes
from impact_fenics.bodies import Body, DeformableModel
from impact_fenics.contact import Penalty
from impact_fenics.contact.pairing import pair_surfaces
from impact_fenics.errors import InputError, UnstableRunError
from impact_fenics.materials import LinearElastic
from impact_fenics.simulation import Settings, Simulation
from impact_fenics.stepping import FollowingStep, StepSequence
from roundoff import rounding
from test_varying_step import _limit

COMM = MPI.COMM_WORLD
INTERVAL = 10  # steps between re-estimations of the limit
N_FULL = 37  # full steps before the clipped one


def _model() -> DeformableModel:
    tm = meshing.coaxial_bars(radius=0.1, striker_length=0.4, target_length=0.4, h=0.04)
    steel = LinearElastic(nu=0.3)
    return DeformableModel(tm, [Body("striker", steel), Body("target", steel)])


def _bars(policy, method="film", model=None) -> Simulation:
    """The coaxial steel bars of scenes.bar_impact, the striker at 5 m/s, under ``policy``."""
    model = model or _model()
    sim = Simulation(model, Settings(energy_every=1, output_every=1000, quiet=True),
                     initial_velocity={"striker": (0.0, 5.0)}, policy=policy)
    sim.add_contact(pair_surfaces(model, "striker_contact", "target_contact"),
                    method if not isinstance(method, str) else scenes.make_method(method))
    return sim


class _Falling:
    """A limit (s) that stays at ``limit`` for the set-up's estimate and the first
    ``keep`` re-estimations, then falls to ``factor`` x ``limit`` (every rank calls it the
    same number of times: the policy re-estimates on the same steps everywhere)."""

    def __init__(self, limit: float, keep: int = 10**9, factor: float = 0.3):
        self.limit, self.keep, self.factor, self.calls = limit, keep, factor, 0

    def __call__(self) -> float:
        self.calls += 1
        return self.limit if self.calls <= 1 + self.keep else self.factor * self.limit


def _following(limit: float, dt: float, t_end: float, keep: int = 10**9) -> FollowingStep:
    return FollowingStep(_Falling(limit, keep), t_end, dt=dt, interval=INTERVAL)


def test_a_fixed_dt_to_t_end_is_the_run_of_its_listed_steps():
    model = _model()
    limit = _limit(model)
    dt = 0.5 * limit
    t_end = (N_FULL + 0.4) * dt  # the last step clipped to 0.4 dt
    policy = _following(limit, dt, t_end)
    steps = policy.fixed_steps()
    assert len(steps) == N_FULL + 1 and steps[:-1] == [dt] * N_FULL
    # the last step: t_end less the sum of the others, each sum rounded once
    assert abs(steps[-1] - 0.4 * dt) <= rounding(2 * N_FULL, t_end)
    follow = _bars(policy, model=model)
    listed = _bars(StepSequence(steps))
    assert follow.n_steps == listed.n_steps == N_FULL + 1
    s_follow, s_listed = follow.run(), listed.run()
    assert s_follow["status"] == s_listed["status"] == "completed"
    for name in ("history", "energy"):
        a, b = getattr(follow, name).data(), getattr(listed, name).data()
        for col in (c for c in a if not c.startswith("cpu_")):  # (not the timings)
            np.testing.assert_array_equal(a[col], b[col], err_msg=f"{name}.{col}")
    for a, b in ((follow.integrator.u_owned, listed.integrator.u_owned),
                 (follow.integrator.v_owned, listed.integrator.v_owned)):
        assert COMM.allreduce(int(np.count_nonzero(a != b))) == 0
    # t_end reached: N + 1 roundings of a sum of steps up to t_end
    assert abs(follow.integrator.t - t_end) <= rounding(N_FULL + 1, t_end)
    assert abs(s_follow["t_end"] - t_end) <= rounding(N_FULL + 1, t_end)


def test_a_fixed_dt_above_the_reestimated_limit_stops_the_run():
    model = _model()
    limit = _limit(model)
    dt = 0.5 * limit
    t_end = (N_FULL + 0.4) * dt
    keep = 1  # the limit falls to 0.3 limit < dt at the second re-estimation: step 20
    stop = 2 * INTERVAL
    sim = _bars(_following(limit, dt, t_end, keep=keep), model=model)
    with pytest.raises(UnstableRunError, match=f"run stopped at step {stop} .* fixed dt"):
        sim.run()
    assert sim.status == "diverged" and sim.summary["stopped_at_step"] == stop
    before = _bars(StepSequence([dt] * stop))
    before.run()
    for a, b in ((sim.integrator.u_owned, before.integrator.u_owned),
                 (sim.integrator.v_owned, before.integrator.v_owned)):
        assert COMM.allreduce(int(np.count_nonzero(a != b))) == 0


def test_a_penalty_is_checked_at_set_up_over_the_fixed_steps():
    """beta grows with h h_n: a p at beta = 1 under dt = 0.4 x the limit passes, the same p
    under dt = 0.9 x the limit (beta about 5 > 4/3) is refused at set-up in one line. (A
    fixed dt keeps its step when the limit is re-estimated; the clipped last step only
    lowers h and h_n, so the full steps decide.)"""
    model = _model()
    limit = _limit(model)
    probe = _bars(_following(limit, 0.4 * limit, 20.5 * 0.4 * limit), Penalty(1e9), model)
    p = 1e9 / probe.contacts[0].method.info["beta_max"]  # beta = 1 at 0.4 x the limit
    ok = _bars(_following(limit, 0.4 * limit, 20.5 * 0.4 * limit), Penalty(p))
    assert ok.contacts[0].method.info["beta_max"] <= 4.0 / 3.0
    with pytest.raises(InputError, match="beta_max = .* is above the stable bound"):
        _bars(_following(limit, 0.9 * limit, 20.5 * 0.9 * limit), Penalty(p))


class _Stepwise:
    """A limit (s) that takes ``limit`` x ``factors[k]`` at its k-th estimate (k = 0 at
    set-up, then one every INTERVAL steps; the last factor kept after)."""

    def __init__(self, limit: float, factors):
        self.limit, self.factors, self.calls = limit, list(factors), 0

    def __call__(self) -> float:
        f = self.factors[min(self.calls, len(self.factors) - 1)]
        self.calls += 1
        return self.limit * f


SAFETY = 0.5
FACTORS_T = (1.0, 0.7, 0.9, 0.6, 0.8)  # the limit falls and rises between estimates


def _expected_steps(limit: float, factors, t_end: float) -> list[float]:
    """The steps of the adaptive policy, written out here: h = SAFETY x the limit of the
    last estimate (one every INTERVAL steps), the last clipped to t_end, t summed as the
    loop sums it."""
    steps, t = [], 0.0
    while t < t_end * (1.0 - 1e-12):
        f = factors[min(len(steps) // INTERVAL, len(factors) - 1)]
        steps.append(min(SAFETY * limit * f, t_end - t))
        t += steps[-1]
    return steps


def test_a_step_that_follows_the_limit_ends_at_t_end_with_every_output():
    """The adaptive step (dt = None): the run ends when t reaches t_end, its energy rows at
    every energy_every steps and at the last one; the run equals that of its steps listed
    here (_expected_steps), table for table and array for array."""
    model = _model()
    limit = _limit(model)
    t_end = sum(SAFETY * limit * f for f in FACTORS_T[:4]) * INTERVAL + 3.3 * SAFETY * limit * 0.8
    steps = _expected_steps(limit, FACTORS_T, t_end)
    assert len(steps) == 4 * INTERVAL + 4  # 3 full steps at the last estimate, then the clip
    policy = FollowingStep(_Stepwise(limit, FACTORS_T), t_end, dt=None, safety=SAFETY,
                           interval=INTERVAL)

    def run(policy, model=None):
        model = model or _model()
        sim = Simulation(model, Settings(energy_every=7, output_every=1000, quiet=True),
                         initial_velocity={"striker": (0.0, 5.0)}, policy=policy)
        sim.add_contact(pair_surfaces(model, "striker_contact", "target_contact"),
                        scenes.make_method("dme"))
        return sim, sim.run()

    follow, s_follow = run(policy, model)
    listed, s_listed = run(StepSequence(steps))
    assert s_follow["status"] == "completed" and s_follow["n_steps"] == len(steps)
    rows = follow.energy.data()["step"]  # (a row is labelled by the step that made it)
    np.testing.assert_array_equal(rows, list(range(0, len(steps), 7)) + [len(steps) - 1])
    for name in ("history", "energy"):
        a, b = getattr(follow, name).data(), getattr(listed, name).data()
        for col in (c for c in a if not c.startswith("cpu_")):  # (not the timings)
            np.testing.assert_array_equal(a[col], b[col], err_msg=f"{name}.{col}")
    for a, b in ((follow.integrator.u_owned, listed.integrator.u_owned),
                 (follow.integrator.v_owned, listed.integrator.v_owned)):
        assert COMM.allreduce(int(np.count_nonzero(a != b))) == 0
    n = len(steps)  # t_end reached: n roundings of a sum of steps up to t_end
    assert abs(follow.integrator.t - t_end) <= rounding(n, t_end)
    assert abs(s_follow["t_end"] - t_end) <= rounding(n, t_end)
    assert s_follow["dt_range"] == [SAFETY * limit * 0.6, SAFETY * limit * 1.0]


def test_a_penalty_is_checked_when_the_step_is_reestimated():
    """A p at beta = 1 under the first step (0.5 x the limit) is accepted at set-up; the
    limit's estimate at step 10 lets the step grow to 0.9 x the limit, where beta is about
    (0.9 / 0.5)^2 > 4/3: the run stops there (UnstableRunError, exit 3), before the step."""
    model = _model()
    limit = _limit(model)
    t_end = 30 * SAFETY * limit
    probe = _bars(_following(limit, SAFETY * limit, t_end), Penalty(1e9), model)
    p = 1e9 / probe.contacts[0].method.info["beta_max"]  # beta = 1 at 0.5 x the limit
    policy = FollowingStep(_Stepwise(limit, (1.0, 1.8)), t_end, dt=None, safety=SAFETY,
                           interval=INTERVAL)
    sim = _bars(policy, Penalty(p))
    assert sim.contacts[0].method.info["beta_max"] <= 4.0 / 3.0
    with pytest.raises(UnstableRunError, match=f"run stopped at step {INTERVAL} .*beta_max"):
        sim.run()
    assert sim.status == "diverged" and sim.summary["stopped_at_step"] == INTERVAL
