"""The step policy (impact_fenics.stepping), on limits scripted here.

Oracles (exact: each is the rule's own arithmetic on numbers chosen here, done once):

* constant: h = cfl x limit (one product), or dt; ceil(t_end / h) steps; a dt above the
  limit refused in one line naming the limiting body, run when forced;
* following: the limit asked for at set-up and at every step n > 0 with n % interval
  == 0, and at no other; h = safety x the limit (one product); h_n = 1/2 (h_{n-1/2} +
  h_{n+1/2}), h at the first step; the last step t_end - t; the range of h without that
  clipped step; the smallest limit seen; a fixed dt run to the step whose re-estimate
  falls below it, then stopped with the step and the two numbers in the message.
"""
import pytest

from impact_fenics.errors import InputError, UnstableRunError
from impact_fenics.stepping import ConstantStep, FollowingStep, count_steps


def test_count_steps():
    assert count_steps(0.1, 7, None) == 7
    assert count_steps(0.1, None, 1.0) == 10  # 1.0 / 0.1 = 10.000000000000002: not 11
    assert count_steps(0.25, None, 2.6) == 11
    for bad in ((0.1, 0, None), (0.1, None, 0.05), (0.0, 5, None), (None, 5, None)):
        with pytest.raises(InputError):
            count_steps(*bad)


def test_constant_step():
    p = ConstantStep(None, 0.9, 3e-6, n_steps=20)
    assert p.h == 0.9 * 3e-6 and p.n_steps == 20
    assert all(p.next(n, n * p.h) == p.h for n in range(20))
    assert ConstantStep(2e-6, None, 3e-6, t_end=1e-5).n_steps == 5
    with pytest.raises(InputError, match=r"dt = 4e-06 s is above the stable limit 3e-06 s "
                                         r"\(element bound on 2/omega_max, body 'stiff'\)"):
        ConstantStep(4e-6, None, 3e-6, n_steps=3, limiting="stiff")
    assert ConstantStep(4e-6, None, 3e-6, n_steps=3, force=True).h == 4e-6
    with pytest.raises(InputError, match="cfl = -1"):
        ConstantStep(None, -1.0, 3e-6, n_steps=3)


class _Limits:
    """A limit (s) that falls by 0.8 at each estimate, counting when it is asked for."""

    def __init__(self, start: float):
        self.value, self.asked, self.given = start, [], []
        self.n = 0

    def __call__(self) -> float:
        self.asked.append(self.n)
        value = self.value
        self.given.append(value)
        self.value *= 0.8
        return value


def _run(policy, limits, t_end):
    t, n, steps = 0.0, 0, []
    while t < t_end * (1.0 - 1e-12):
        limits.n = n
        h = policy.next(n, t)
        steps.append((n, h, policy.h_avg, policy.limit, policy.renewed))
        t += h
        n += 1
    return t, steps


def test_following_step_re_estimates_every_interval_and_clips_the_last_step():
    limits = _Limits(1e-3)
    policy = FollowingStep(limits, t_end=5e-3, safety=0.5, interval=3)  # the h sum to 7.5e-3
    assert policy.first() == 0.5 * 1e-3
    t, steps = _run(policy, limits, 5e-3)
    n_steps = len(steps)
    assert limits.asked == [0] + [n for n in range(1, n_steps) if n % 3 == 0]
    seen = limits.given
    h_prev = None
    for n, h, h_avg, limit, renewed in steps[:-1]:
        assert renewed == (n > 0 and n % 3 == 0)
        assert limit == seen[n // 3] and h == 0.5 * limit
        assert h_avg == (h if h_prev is None else 0.5 * (h_prev + h))
        h_prev = h
    # the last step is what is left of t_end, below the rule's h; the range leaves it out
    n, h, h_avg, limit, _ = steps[-1]
    t_before = sum(s[1] for s in steps[:-1])  # t accumulated in the same order
    assert h == 5e-3 - t_before < 0.5 * limit and h_avg == 0.5 * (h_prev + h)
    rule = [s[1] for s in steps[:-1]]
    assert policy.h_range == [min(rule), max(rule)]
    assert policy.smallest == min(seen) and policy.start == 1e-3
    assert t == t_before + h


def test_fixed_step_stops_once_the_limit_falls_below_it():
    limits = _Limits(1e-3)
    dt = 0.6e-3  # limits 1e-3, 0.8e-3, 0.64e-3, 0.512e-3: the fourth estimate (n = 6) is below
    policy = FollowingStep(limits, t_end=1.0, dt=dt, interval=2)
    t = 0.0
    for n in range(6):
        limits.n = n
        assert policy.next(n, t) == dt
        t += dt
    limits.n = 6
    with pytest.raises(UnstableRunError, match=r"run stopped at step 6 \(t = 0\.0036 s\): the fixed "
                                               r"dt = 0\.0006 s is above the current stable limit "
                                               r"0\.000512 s"):
        policy.next(6, t)
