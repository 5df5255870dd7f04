"""The loop's step counters give the steps of their modulo definitions (the loop kept as
short as its step).

The run's loop keeps the next output, field, per-pair, divergence-check and agreement
step as counters (schedule.Schedule) instead of testing n % every at each step. The
oracle is the definition they replace: output and per-pair rows at n % every == 0 and
at the last step; fields (state n + 1) at (n + 1) % every == 0 and the last step; checks
and agreements at (n + 1) % every == 0 and the last step. Every combination of every
and run length below, including every > steps and steps = 1, must give the same steps.
"""
from impact_fenics.schedule import Schedule


def _steps(schedule: Schedule, n_steps: int) -> list[int]:
    due = []
    for n in range(n_steps):
        if n == schedule.next:  # the loop asks only when a counter says so
            assert schedule.due(n)
            due.append(n)
        else:
            assert not schedule.due(n)
    return due


def test_counters_match_the_modulo_definitions():
    for n_steps in (1, 2, 3, 7, 16, 17, 64, 100, 129):
        last = n_steps - 1
        for every in (1, 2, 3, 5, 16, 25, 64, 200):
            at_zero = [n for n in range(n_steps) if n % every == 0 or n == last]
            at_end = [n for n in range(n_steps) if (n + 1) % every == 0 or n == last]
            assert _steps(Schedule(0, every, last), n_steps) == at_zero, (n_steps, every)
            assert _steps(Schedule(every - 1, every, last), n_steps) == at_end, (n_steps, every)
        assert _steps(Schedule.never(last), n_steps) == []
