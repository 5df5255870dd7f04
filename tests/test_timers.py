"""Step timers: exact totals and a bounded, evenly spaced sample for the medians."""
import numpy as np

from impact_fenics.timers import PhaseTimers


def test_memory_does_not_grow_and_totals_are_exact():
    t = PhaseTimers(("a", "b"), capacity=64)
    buffer = t._sample
    n = 10_000
    for k in range(n):
        t.current[0] = 1.0
        t.current[1] = k
        t.record()
    assert t._sample is buffer and buffer.shape == (64, 2)  # no reallocation
    assert t.total()["a"] == n
    assert t.total()["b"] == n * (n - 1) / 2  # exact: integers below 2^53


def test_sample_is_evenly_spaced_over_the_run():
    # times equal to the step index: an evenly spaced sample of 0..n-1 has the
    # median of the whole run to within one stride (n / capacity at most 2 x that)
    cap, n = 128, 100_003
    t = PhaseTimers(("x",), capacity=cap)
    for k in range(n):
        t.current[0] = k
        t.record()
    stride = t._stride
    assert stride <= 2 * n / cap
    kept = t._sample[: t._n_sample, 0]
    assert np.array_equal(kept, np.arange(stride - 1, n, stride, dtype=float))
    assert abs(t.medians()["x"] - np.median(np.arange(n))) <= stride


def test_periodic_events_do_not_take_over_the_sample():
    # every 256th step (n a multiple of 256: a history block written out) costs 100 times a
    # step: they are 1/256 of the steps, so the median of the run is a plain step's, and
    # the sample's must be too, however long the run (the stride passes 256 here)
    cap, n = 128, 200_000
    t = PhaseTimers(("x",), capacity=cap)
    for k in range(n):
        t.current[0] = 100.0 if k % 256 == 0 else 1.0
        t.record()
    assert t._stride > 256
    assert t.medians()["x"] == 1.0
    assert t.total()["x"] == n + 99.0 * len(range(0, n, 256))


def test_block_booking_equals_booking_each_step():
    # the loop writes a step's phase times through the memoryview ``rows`` and books a
    # block at a time: the same totals, sample and medians as record() after every step
    # (the same additions in the same order: equal to the bit)
    rng = np.random.default_rng(7)
    times = rng.exponential(1e-5, size=(1000, 3))
    each, block = PhaseTimers(("a", "b", "c"), capacity=64), PhaseTimers(("a", "b", "c"),
                                                                          capacity=64, block=16)
    pos = 0
    for row in times:
        each.current[:] = row
        each.record()
        for i, v in enumerate(row):
            block.rows[pos + i] = float(v)
        pos += 3
        if pos == block.rows_end:
            block.book(pos)
            pos = 0
    block.book(pos)  # the last, partial block
    assert block.n_steps == each.n_steps == 1000
    assert np.array_equal(block.totals, each.totals)
    assert np.array_equal(block._sample, each._sample) and block._stride == each._stride
    assert block.medians() == each.medians()
