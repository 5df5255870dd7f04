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


def _progress_lines(monkeypatch, capsys, terminal: bool, seconds_per_step: float,
                    n_steps: int = 2000) -> str:
    """A run of ``n_steps`` steps at ``seconds_per_step`` of wall time each (a clock the
    test moves), the loop looking at the steps Progress asks for; its printed output."""
    from impact_fenics import schedule

    clock = [0.0]
    monkeypatch.setattr(schedule.console, "on_terminal", lambda: terminal)
    monkeypatch.setattr(schedule.time, "perf_counter", lambda: clock[0])
    p = schedule.Progress(n_steps, 1e-6, quiet=False)
    due = p.due
    for n in range(1, n_steps + 1):
        clock[0] = n * seconds_per_step
        if n >= due:
            due = p.update(n)
    p.done()
    return capsys.readouterr().out


def test_progress_into_a_file_is_a_line_every_30_s(monkeypatch, capsys):
    """Into a file (a batch job's log): a whole line each 30 s of wall time, none in a run
    shorter than that; on a terminal the one line rewritten (carriage returns)."""
    # 200 s: the loop looks every 5 s of steps, so lines come 30 to 35 s apart: 5 or 6
    out = _progress_lines(monkeypatch, capsys, False, 0.1)
    lines = out.splitlines()
    assert 5 <= len(lines) <= 6 and all(line.startswith("progress: step ") for line in lines)
    assert "\r" not in out
    assert _progress_lines(monkeypatch, capsys, False, 0.01) == ""  # 20 s: none
    terminal = _progress_lines(monkeypatch, capsys, True, 0.01)
    assert terminal.count("\r") >= 30 and terminal.endswith("\n")
