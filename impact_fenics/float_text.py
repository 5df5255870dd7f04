"""Decimal text of float64 values that reads back exactly, compiled (CSV rows in blocks).

Each value is written with 17 significant digits (trailing zeros dropped) in
the layout of C's ``%.17g``: positional for decimal exponents -4 <= k < 17,
``d.ddde+XX`` otherwise; ``nan``, ``inf``, ``-inf``, ``0`` and ``-0`` as such.
Seventeen digits identify every double: for x in [10^k, 10^(k+1)) a unit of
the 17th digit is 10^(k-16) < ulp(x) / 1.11 (ulp(x) > 2^-53 x), so a decimal
within 0.55 of that unit from x is nearer to x than to either neighbour (at a
power of two the lower neighbour is ulp/2 away: 0.5 x 10^(k-16) < 2^-54 x
still holds with the same margin), and a correctly rounding reader (C's
strtod, numpy, pandas) returns x.

The digits are D = round(x 10^q), q = 16 - k, from the exact 117-bit product
of the 53-bit significand with a 64-bit significand of 10^q rounded to
nearest (relative error < 2^-64, built here with exact integers): D is off
by less than 0.5 + 0.006 units, within the bound above; it equals ``%.17g``'s
correctly rounded digits except within 0.006 units of a tie.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

# 10^q ~ POW_SIG[q - Q_MIN] * 2^POW_EXP[q - Q_MIN], POW_SIG in [2^63, 2^64): q covers
# x from the smallest subnormal (4.9e-324, q = 340) to the largest double (q = -292)
Q_MIN, Q_MAX = -300, 345
MAX_CHARS = 24  # "-1.2345678901234567e-308"
_TENS = np.array([10 ** i for i in range(18)], dtype=np.int64)


def _powers() -> tuple[np.ndarray, np.ndarray]:
    sig = np.zeros(Q_MAX - Q_MIN + 1, dtype=np.uint64)
    exp = np.zeros(Q_MAX - Q_MIN + 1, dtype=np.int64)
    for i, q in enumerate(range(Q_MIN, Q_MAX + 1)):
        if q >= 0:
            v = 10 ** q
            b = v.bit_length() - 64  # v = c 2^b with c of 64 bits, rounded to nearest
            c = (v + (1 << (b - 1))) >> b if b > 0 else v << -b
        else:
            d = 10 ** -q
            b = -(d.bit_length() + 63)  # 2^-b / d in (2^63, 2^64), rounded to nearest
            c = ((1 << (1 - b)) + d) // (2 * d)
        if c == 1 << 64:  # rounded up to 2^64: exactly 2^63 x 2
            c >>= 1
            b += 1
        sig[i], exp[i] = c, b
    return sig, exp


POW_SIG, POW_EXP = _powers()
# 10.0 ** k as doubles (rounded; 0 and inf at the ends) for the first guess of the exponent
P10_MIN = -330
POW10 = np.array([float(f"1e{k}") for k in range(P10_MIN, 312)])


@njit(cache=True)
def _mul(a, b):
    """(hi, lo) of the 128-bit product of two uint64."""
    u32 = np.uint64(0xFFFFFFFF)
    s32 = np.uint64(32)
    a_lo, a_hi = a & u32, a >> s32
    b_lo, b_hi = b & u32, b >> s32
    ll = a_lo * b_lo
    lh = a_lo * b_hi
    hl = a_hi * b_lo
    hh = a_hi * b_hi
    mid = (ll >> s32) + (lh & u32) + (hl & u32)
    lo = (ll & u32) | (mid << s32)
    hi = hh + (lh >> s32) + (hl >> s32) + (mid >> s32)
    return hi, lo


@njit(cache=True)
def _scaled(m, e2, q, sig, exp):
    """m 2^e2 10^q as (its integer part, the first bit after the point), uint64 (the value
    must lie below 2^63)."""
    c = sig[q - Q_MIN]
    hi, lo = _mul(m, c)
    s = -(e2 + exp[q - Q_MIN])  # shift right by s (s >= 1 for the 17-digit range)
    one = np.uint64(1)
    if s >= 128:
        return np.uint64(0), np.uint64(0)
    if s > 64:
        r = hi >> np.uint64(s - 64)
        half = (hi >> np.uint64(s - 65)) & one
    elif s == 64:
        r = hi
        half = lo >> np.uint64(63)
    else:
        r = (lo >> np.uint64(s)) | (hi << np.uint64(64 - s))
        half = (lo >> np.uint64(s - 1)) & one
    return r, half


@njit(cache=True)
def _digits(d, nz, point, out, pos):
    """The nz digits of d into out[pos:], with a '.' after the first ``point`` of them if
    any follow; returns the new position."""
    end = pos + nz + (1 if point < nz else 0)
    p = end
    ten = np.uint64(10)
    for i in range(nz - 1, -1, -1):
        p -= 1
        out[p] = 48 + np.int64(d % ten)
        d //= ten
        if i == point and point < nz:
            p -= 1
            out[p] = 46
    return end


@njit(cache=True)
def _put(x, value_bits, out, pos, sig, exp, pow10):
    """Write the text of the double ``x`` (its bits ``value_bits``) into out[pos:]; return
    the new position."""
    neg = (value_bits >> np.uint64(63)) != np.uint64(0)
    biased = np.int64((value_bits >> np.uint64(52)) & np.uint64(0x7FF))
    frac = value_bits & np.uint64(0xFFFFFFFFFFFFF)
    if biased == 0x7FF:
        if frac != np.uint64(0):
            out[pos], out[pos + 1], out[pos + 2] = 110, 97, 110  # nan
            return pos + 3
        if neg:
            out[pos] = 45
            pos += 1
        out[pos], out[pos + 1], out[pos + 2] = 105, 110, 102  # inf
        return pos + 3
    if neg:
        out[pos] = 45  # '-'
        pos += 1
        x = -x
    if x < 1e16 and x == math.floor(x):  # an integer (0 too): its digits, exact
        i = np.int64(x)
        n = 1
        while n < 17 and i >= _TENS[n]:
            n += 1
        for j in range(n - 1, -1, -1):
            out[pos + j] = 48 + i % 10
            i //= 10
        return pos + n
    if biased == 0:
        m, e2, b = frac, np.int64(-1074), np.int64(math.frexp(x)[1])
    else:
        m, e2, b = frac | np.uint64(1 << 52), biased - 1075, biased - 1022
    # k = floor(log10 x): x in [2^(b-1), 2^b) gives k_est or k_est + 1; one comparison
    # with a (rounded) power of ten, then the exact check below
    k = np.int64(math.floor((b - 1) * 0.30102999566398120))
    if x >= pow10[k - P10_MIN + 1]:
        k += 1
    # the exponent k with 10^k <= x < 10^(k+1): then 10^16 <= x 10^(16-k) < 10^17 before
    # rounding; a rounding up to 10^17 carries into the next exponent (as in C)
    lo17, hi17 = np.uint64(10 ** 16), np.uint64(10 ** 17)
    r, half = _scaled(m, e2, 16 - k, sig, exp)
    if r >= hi17:
        k += 1
        r, half = _scaled(m, e2, 16 - k, sig, exp)
    elif r < lo17:
        k -= 1
        r, half = _scaled(m, e2, 16 - k, sig, exp)
    d = r + half
    if d == hi17:
        k += 1
        d = lo17
    # drop the trailing zeros: d keeps its nz significant digits
    ten = np.uint64(10)
    nz = 17
    while d % ten == np.uint64(0):
        d //= ten
        nz -= 1
    if -4 <= k < 17:
        if k >= 0:
            if nz <= k + 1:  # an integer part only, zeros after the digits
                pos = _digits(d, nz, nz, out, pos)
                for i in range(k + 1 - nz):
                    out[pos] = 48
                    pos += 1
                return pos
            return _digits(d, nz, k + 1, out, pos)
        out[pos], out[pos + 1] = 48, 46  # "0."
        pos += 2
        for i in range(-k - 1):
            out[pos] = 48
            pos += 1
        return _digits(d, nz, nz, out, pos)
    pos = _digits(d, nz, 1, out, pos)
    out[pos] = 101  # 'e'
    out[pos + 1] = 45 if k < 0 else 43
    pos += 2
    a = -k if k < 0 else k
    if a >= 100:
        out[pos] = 48 + a // 100
        pos += 1
    out[pos] = 48 + (a // 10) % 10
    out[pos + 1] = 48 + a % 10
    return pos + 2


@njit(cache=True, nogil=True)  # (a worker thread formats while the loop steps)
def _rows(values, bits, out, sig, exp, pow10):
    """CSV text of the rows of ``values`` (rows x columns; ``bits`` the same memory as
    uint64) into ``out``; returns the number of bytes."""
    pos = 0
    for i in range(bits.shape[0]):
        for j in range(bits.shape[1]):
            if j:
                out[pos] = 44  # ','
                pos += 1
            pos = _put(values[i, j], bits[i, j], out, pos, sig, exp, pow10)
        out[pos] = 10  # '\n'
        pos += 1
    return pos


def buffer_for(rows: int, columns: int) -> np.ndarray:
    """A byte buffer large enough for :func:`format_rows` of rows x columns values."""
    return np.empty(rows * columns * (MAX_CHARS + 1) + rows, dtype=np.uint8)


def format_rows(values: np.ndarray, out: np.ndarray) -> memoryview:
    """CSV lines (columns joined by ',', each row ending in a newline) of a 2-D float64
    array, written into the byte buffer ``out`` (see :func:`buffer_for`); returns a view
    of the bytes written."""
    values = np.ascontiguousarray(values, dtype=np.float64)
    n = _rows(values, values.view(np.uint64), out, POW_SIG, POW_EXP, POW10)
    return memoryview(out)[:n]


def text(value: float) -> str:
    """The text of one value (what :func:`format_rows` writes for it)."""
    out = buffer_for(1, 1)
    return bytes(format_rows(np.array([[value]]), out)).decode()[:-1]


def load() -> None:
    """Load (or compile) the formatter now, at set-up, not at the first block in a loop."""
    format_rows(np.zeros((1, 1)), buffer_for(1, 1))
