"""history.csv's numbers read back exactly (the history is written without a per-step cost).

The compiled formatter (impact_fenics.float_text) writes 17 significant digits; the
oracle is the reader, not the writer: numpy's loadtxt (and Python's float(), both
correctly rounding strtod) must give back the identical float64, bit for bit, for
every value a history can hold: zeros of both signs, integers (steps, counts),
subnormals, the extremes of the range, values next to powers of ten and of two
(where a 17-digit decimal is closest to the rounding boundary), random bit patterns
over the whole range, NaN and the infinities. The text's layout is C's "%.17g" (so
spreadsheets and pandas read it as before): for values that are exact short decimals
it is the same text, and elsewhere it differs from C's correctly rounded digits by at
most one unit in the 17th digit (a tie within the 2^-64 relative error of the power
of ten used, see the module docstring). A Table written in blocks holds one row per
row filled, whatever the block size.
"""
import io
import os

import numpy as np
import pytest
from mpi4py import MPI

from impact_fenics import float_text, output


def _edge_values() -> np.ndarray:
    tiny, big = np.nextafter(0.0, 1.0), np.finfo(float).max
    normal = np.finfo(float).tiny
    vals = [0.0, -0.0, 1.0, -1.0, 7.0, 255.0, 2.0 ** 53, 2.0 ** 53 + 2, 1e15, 1e16, 1e17,
            tiny, -tiny, 3 * tiny, normal, np.nextafter(normal, 0.0), np.nextafter(normal, 1.0),
            1e-300, -1e-300, 1e300, big, -big, np.nextafter(big, 0.0), 0.1, 1 / 3, 2 / 3,
            3.64e-7, 1e-6 * 123, 5e-324, 1e-5, 1e-4, 9.999999999999999e-5, 1e22, 1e23]
    for p in range(-307, 309):  # each side of every power of ten
        x = 10.0 ** p
        vals += [x, np.nextafter(x, 0.0), np.nextafter(x, np.inf)]
    for p in range(-1074, 1024, 7):  # powers of two and their lower neighbours
        x = np.ldexp(1.0, p)
        vals += [x, np.nextafter(x, 0.0)]
    return np.array(vals)


def _random_values(n: int = 60_000) -> np.ndarray:
    rng = np.random.default_rng(20261123)
    bits = rng.integers(0, 2 ** 63, n, dtype=np.uint64)  # every exponent, both signs below
    bits[::2] |= np.uint64(1 << 63)
    x = bits.view(np.float64)
    scaled = rng.standard_normal(n) * 10.0 ** rng.integers(-12, 12, n)  # a history's range
    return np.concatenate([x[np.isfinite(x)], scaled])


def _round_trip(values: np.ndarray, columns: int = 7) -> tuple[np.ndarray, str]:
    values = np.concatenate([values, np.zeros(-values.size % columns)]).reshape(-1, columns)
    text = bytes(float_text.format_rows(values, float_text.buffer_for(*values.shape))).decode()
    back = np.loadtxt(io.StringIO(text), delimiter=",", ndmin=2)
    return values, back, text


def test_every_value_reads_back_bit_for_bit():
    for values in (_edge_values(), _random_values()):
        written, back, text = _round_trip(values)
        assert back.shape == written.shape
        assert np.array_equal(written.view(np.uint64), back.view(np.uint64))  # -0 stays -0
        tokens = text.replace("\n", ",").split(",")[:-1]
        assert all(float(t) == v or (t == "-0" and v == 0) for t, v in
                   zip(tokens, written.ravel()))  # Python's reader agrees


def test_nan_and_infinities():
    values = np.array([[np.nan, np.inf, -np.inf, -np.nan]])
    _, back, text = _round_trip(values.ravel(), columns=4)
    assert text == "nan,inf,-inf,nan\n"
    assert np.isnan(back[0, 0]) and np.isnan(back[0, 3]) and back[0, 1] == np.inf \
        and back[0, 2] == -np.inf


def test_layout_is_that_of_printf_17g():
    # exact short decimals give C's text exactly; any value is at most one unit of the
    # 17th digit from C's correctly rounded one
    exact = [0.0, -0.0, 1.0, 25.0, 400.0, 0.5, 0.25, 1e-4 * 0 + 0.0001, 1e16, 1e17, 1e22,
             2.0 ** 60, 123456.5, -3.0, 0.125]
    for v in exact:
        assert float_text.text(v) == "%.17g" % v, v
    for v in np.concatenate([_edge_values(), _random_values(5000)]):
        mine, c = float_text.text(v), "%.17g" % v
        if mine != c:
            m_digits = mine.lstrip("-").split("e")[0].replace(".", "").lstrip("0")
            c_digits = c.lstrip("-").split("e")[0].replace(".", "").lstrip("0")
            assert abs(int(m_digits.ljust(17, "0")) - int(c_digits.ljust(17, "0"))) == 1, (v, mine, c)


def test_table_in_blocks_holds_every_row(tmp_path):
    comm = MPI.COMM_WORLD
    path = comm.bcast(str(tmp_path / "t.csv"), root=0) if comm.rank == 0 else comm.bcast(None)
    rng = np.random.default_rng(3)
    rows = rng.standard_normal((37, 3)) * 1e-3
    rows[:, 0] = np.arange(37)
    table = output.Table(path, ["step", "a", "b"], comm, capacity=8)
    for r in rows[:20]:
        table.row()[:] = r
    for r in rows[20:]:  # the per-step path: offsets into the memoryview
        j = table.next_row()
        for i, v in enumerate(r):
            table.cells[j + i] = float(v)
    table.close()
    comm.barrier()
    data = table.data()
    assert np.array_equal(np.column_stack([data[c] for c in ("step", "a", "b")]), rows)
    if comm.rank == 0:
        with open(path) as f:
            assert f.readline() == "step,a,b\n"
            assert f.readline().startswith("0,")
    assert os.path.getsize(path) > 0


def test_a_table_formatted_on_its_worker_thread_is_the_same_file(tmp_path_factory):
    # the oracle is the same rows written by the caller's thread: the worker's file is
    # byte for byte that file (blocks in order, each block's rows copied before the
    # block is reused), whatever the blocks in flight
    comm = MPI.COMM_WORLD
    base = comm.bcast(str(tmp_path_factory.mktemp("async_table")), root=0)
    rng = np.random.default_rng(5)
    rows = rng.standard_normal((53, 3))
    files = []
    for asynchronous in (False, True):
        path = os.path.join(base, f"t_{asynchronous}.csv")
        table = output.Table(path, ["step", "a", "b"], comm, capacity=4,
                             asynchronous=asynchronous)
        assert (table._worker is not None) == (asynchronous and comm.rank == 0)
        for r in rows:
            table.row()[:] = r
        table.close()
        files.append(path)
    comm.barrier()
    with open(files[0], "rb") as f:
        synchronous = f.read()
    with open(files[1], "rb") as f:
        assert f.read() == synchronous
    assert np.array_equal(np.loadtxt(files[1], delimiter=",", skiprows=1), rows)


@pytest.mark.skipif(MPI.COMM_WORLD.size > 1, reason="under MPI the failing rank aborts "
                    "every rank (errors.output_failed): not observable in the test process")
def test_a_table_worker_write_error_raises_one_line(tmp_path):
    # the worker's descriptor swapped for a read-only one (EBADF, as ENOSPC or EIO would
    # come): close raises OutputError naming the file and the cause, and ends the thread
    from impact_fenics.errors import OutputError

    path = str(tmp_path / "t.csv")
    table = output.Table(path, ["step", "a"], MPI.COMM_WORLD, capacity=4, asynchronous=True)
    os.close(table._fd)
    table._fd = os.open(path, os.O_RDONLY)
    for k in range(6):
        table.row()[:] = (k, 0.5 * k)
    with pytest.raises(OutputError) as err:
        table.close()
    message = str(err.value)
    assert "t.csv" in message and "failed" in message and "\n" not in message
    assert table._worker is None
