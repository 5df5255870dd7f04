"""The floor of a step: the bytes it moves over the core's bandwidth, or its arithmetic over
the core's rate, whichever is larger (a roofline with one point per step).

Measured in the run, on every rank at once (so under MPI with the ranks sharing the memory
bus), the slowest rank counting:

- bandwidth: the STREAM triad a_i = b_i + s c_i compiled by numba on three arrays of
  at least 32 MiB each (far larger than any cache); 24 bytes per entry as STREAM counts
  them (the write-allocate of a is not counted, nor is it in the steps' bytes);
- arithmetic rate: eight nested multiply-adds v = a v + b (2 flops each) of every entry
  of an in-cache array, compiled (and vectorised) by numba: the rate a kernel can reach
  (eight independent scalar chains, what a loop that does not vectorise gets, is kept
  beside it);
- a transcendental function's cost: log, exp, sqrt, cbrt of an in-cache array, summed,
  less the same loop summing the array, in seconds per call.

How a step's bytes are counted (:func:`nbytes`, :func:`small_strain_bytes`,
:func:`finite_strain_bytes`): every array the step reads once and every array it writes
once, at its size on this rank, as if each entry crossed the memory bus exactly once
(perfect reuse of the gathered u and of the scattered f in the cache; no
write-allocate). Per point: the state read and written (plastic strain, equivalent
plastic strain, stress; at finite strain the elastic left Cauchy-Green tensor), the
geometry read (shape-function gradients, 1/r, weights; dofs as integers); per dof: u
gathered, f zeroed, summed into and read back, and the vector updates (velocity,
position, the work trapezoid). Scratch arrays of one point or one cell stay in the
cache and are not counted. The linear step's bytes: the matrix (values and column
indices), MatMultAdd's three vectors and AXPY's three.

How a step's arithmetic is counted (:data:`POINT_FLOPS`): the adds and multiplies per
point of the kernel and its material update, counted by hand from the source (an
estimate, to about a third), plus its calls of log, exp, sqrt and cbrt, each at its
measured cost.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

TRIAD_MIN_ENTRIES = 1 << 22  # 32 MiB per array: far above any L3 of one core's share
TRANSCENDENTAL_ENTRIES = 2048  # 16 KiB: in L1
FUNCTIONS = ("log", "exp", "sqrt", "cbrt")

# Adds, multiplies and divisions (one flop each) and the calls of FUNCTIONS per quadrature
# point of each kernel with its material update, counted by hand from the source: (every
# point, the extra of a point that yields); a cell's shared work is divided among its points.
# Small strain (3 points a triangle): the strains (shared by the cell's points) and the hoop
# strain, the trial stress, its deviator and norm, the stress weighted into the cell's sums;
# yielding: the square root, the return, the plastic strain and the plastic work.
# Finite strain (2x2 points a quadrilateral, axisymmetric; counted on the source of
# internal_force/finite.py and materials/hencky.py as they are, in the regimes of the
# benchmark's bar, where every point takes the series branches):
#   F through the reference cell (internal_force/finite.py, cell_deformation): the node
#   differences and their values at the two rows and columns of points, 32 a cell (8 a
#   point); per point J^-1 (4 numbers) times du/dxi, the hoop stretch from 1 / R, J and
#   1 / J: 28; J_bar 2.25; the F-bar ratio and its cube root by the binomial series in
#   Estrin's scheme, 29 (no library call); F_bar 5: 72.25 together;
#   the Hencky trial (hencky.log_strains): b_e = F a F' 21, mean, half difference, d^2,
#   F_tt^2 a_tt, u = d^2 / m^2 with 1 / m 12, eps_m from ln(m^2 - d^2) and g from atanh's
#   series 18, the hoop log strain and det b_e 2: 53 and 2 logarithms; the stress and q^2
#   (hencky.stresses) 19; the yield check 3; tau 5;
#   after the update: the plastic work 2, m_bar 4.5, tau_eff 9, w F^-1 6 (one reciprocal
#   1 / J_q a point, made with F), P 12, the hoop term 7, P J^-T 12, its row and column sums
#   4, the hoop sums 8, the node values 6 and the nodes' sums 5: 75.5.
#   Every point of finite J2: 72.25 + 53 + 19 + 3 + 5 + 75.5 = 227.75 -> 228, 2 logarithms
#   (the table before the reference cell and the series counted 185 with 3 square roots,
#   3 logarithms and a cube root: the eigen split by a square root and 1 / d, and the
#   library's cbrt). Yielding, finite J2: 1 / (3 mu + H) and 1 / q^2 beside the square
#   root, the flow factor k 11; the deviator scaled (hencky.scale_deviator) 14; the
#   plastic work 4 and eps_bar_p 1; b_e back (hencky.set_returned_state): w^2 and the
#   series of cosh and sinh / w 25, exp(2 eps_m) and its products 3, a = F^-1 b_e F^-T
#   34, the hoop entry det b_e / (e^(4 eps_m) F_tt^2) 4 (one division where there were
#   two in a row, the same count: a division is one flop here): 96, a square root and an
#   exponential (the table before: 70 and 3 exponentials).
#   Johnson-Cook, every point: as finite J2 with its yield check (A + B eps^n) Theta and
#   rho c_p, 4: 229, 2 logarithms. Yielding: the square root; its return's start (the
#   three bounds: a rate exp, a power (log + exp)) 19; one evaluation of the flow stress
#   (a power and a rate logarithm) 14; the flow factor 4 and the deviator 14; the plastic
#   work 7, eps_bar_p 1, the temperature 3 and its thermal factor (a power) 4; b_e back as
#   finite J2's 66: 132, a square root, 4 logarithms, 5 exponentials. A point that needs
#   more iterations does more, so the count is a lower bound, as a floor's must be.
#   Neo-Hookean: F, J_bar, F-bar 72.25, ln J and tau 25, after the update 75.5: 173, a
#   logarithm.
POINT_FLOPS = {
    "j2_small_strain": ({"flops": 65}, {"flops": 45, "sqrt": 1}),
    "dp_small_strain": ({"flops": 80, "sqrt": 1}, {"flops": 70, "sqrt": 1}),
    "j2_finite_strain": ({"flops": 228, "log": 2}, {"flops": 96, "sqrt": 1, "exp": 1}),
    "jc_finite_strain": ({"flops": 229, "log": 2},
                         {"flops": 132, "sqrt": 1, "log": 4, "exp": 5}),
    "nh_finite_strain": ({"flops": 173, "log": 1}, {}),
}


@njit(cache=True)
def _triad(a, b, c, s):
    for i in range(a.size):
        a[i] = b[i] + s * c[i]


@njit(cache=True)
def _fma_chains(n, a, b):
    """Eight independent chains of x = a x + b, n times each: 16 n flops."""
    x0 = x1 = x2 = x3 = x4 = x5 = x6 = x7 = 1.0
    for _ in range(n):
        x0 = a * x0 + b
        x1 = a * x1 + b
        x2 = a * x2 + b
        x3 = a * x3 + b
        x4 = a * x4 + b
        x5 = a * x5 + b
        x6 = a * x6 + b
        x7 = a * x7 + b
    return x0 + x1 + x2 + x3 + x4 + x5 + x6 + x7


@njit(cache=True)
def _polynomial(x, y, a, b, reps):
    """y = 8 nested multiply-adds of x, entry by entry (the compiler may vectorise it),
    ``reps`` times over the in-cache x: 16 flops an entry a repeat."""
    for _ in range(reps):
        for i in range(x.size):
            v = x[i]
            v = a * v + b
            v = a * v + b
            v = a * v + b
            v = a * v + b
            v = a * v + b
            v = a * v + b
            v = a * v + b
            v = a * v + b
            y[i] = v


@njit(cache=True)
def _sum_of(kind, x):
    """sum_i f(x_i) for f = identity (0), log, exp, sqrt, cbrt (1-4)."""
    s = 0.0
    if kind == 0:
        for i in range(x.size):
            s += x[i]
    elif kind == 1:
        for i in range(x.size):
            s += math.log(x[i])
    elif kind == 2:
        for i in range(x.size):
            s += math.exp(x[i])
    elif kind == 3:
        for i in range(x.size):
            s += math.sqrt(x[i])
    else:
        for i in range(x.size):
            s += np.cbrt(x[i])
    return s


def machine_rates(ctx) -> dict:
    """The triad bandwidth (GB/s, one rank's), the arithmetic rate (Gflop/s) and the cost of
    each of FUNCTIONS (s per call), measured once per run (kept on ``ctx``)."""
    cached = getattr(ctx, "_roofline_rates", None)
    if cached is not None:
        return cached
    n = max(ctx.mode.stream_n, TRIAD_MIN_ENTRIES)
    a, b, c = np.zeros(n), np.full(n, 1.0), np.full(n, 2.0)
    t_triad = ctx.median(lambda: _triad(a, b, c, 1e-9))
    del a, b, c
    m = 1 << 20
    t_chains = ctx.median(lambda: _fma_chains(m, 0.999999, 1e-7))
    x = np.linspace(0.5, 1.5, TRANSCENDENTAL_ENTRIES)  # exp, log of O(1): the usual range
    y = np.empty_like(x)
    reps = m // x.size
    t_simd = ctx.median(lambda: _polynomial(x, y, 0.999999, 1e-7, reps))
    t_sum = ctx.median(lambda: _sum_of(0, x))
    cost = {f: max(ctx.median(lambda k=k: _sum_of(k, x)) - t_sum, 0.0) / x.size
            for k, f in enumerate(FUNCTIONS, start=1)}
    rates = {"triad_entries": n, "triad_gbs": 24.0 * n / t_triad / 1e9,
             "gflops": 16.0 * reps * x.size / t_simd / 1e9,
             "gflops_scalar_chains": 16.0 * m / t_chains / 1e9, "seconds_per_call": cost,
             "definition": "triad_gbs: a = b + s c over arrays of triad_entries float64, 24 B "
                           "an entry, one rank's (all ranks at once, the slowest); gflops: "
                           "8 nested multiply-adds of each entry of an in-cache array (the "
                           "compiler vectorises it: the core's rate, the floor's); "
                           "gflops_scalar_chains: 8 independent scalar multiply-add chains "
                           "(what a loop the compiler cannot vectorise gets); seconds_per_call: "
                           "an in-cache loop summing f(x) less one summing x, per entry"}
    ctx._roofline_rates = rates
    return rates


def nbytes(read=(), written=()) -> int:
    """Bytes of ``read`` arrays read once and ``written`` arrays written once (the size of
    an array in both lists counts twice)."""
    return int(sum(a.nbytes for a in read) + sum(a.nbytes for a in written))


def vector_update_bytes(n_owned: int, n_local: int) -> int:
    """Per step of the small-strain integrator's vectors (bytes): u gathered (local), f
    zeroed, summed into and read back (local: 8 + 16), the velocity update reading coef, f,
    u, v, f_prev, u_prev and writing v, f_prev, u_prev (owned: 72), the position update
    u += dt v (owned: 24)."""
    return 8 * (1 + 1 + 2) * n_local + (72 + 24) * n_owned


def small_strain_bytes(force, n_owned: int) -> int:
    """Bytes the small-strain path-dependent step moves on this rank: the state at the
    points (plastic strain, state, stress) read and written, the cell geometry read (dofs,
    dN/dr, dN/dz, 1/r, w), and :func:`vector_update_bytes`."""
    g, qs = force.geometry, force.qs
    state = (qs.eps_p, qs.state, qs.sigma)
    return (nbytes(read=state + (g.dofs, g.dNdr, g.dNdz, g.inv_r, g.w), written=state)
            + vector_update_bytes(n_owned, force.f.x.array.size))


def finite_strain_bytes(force, n_owned: int) -> int:
    """Bytes the finite-strain step moves on this rank: the state at the points (b_e and
    the equivalent plastic strain) read and written, the Kirchhoff stress written, the
    cell geometry read (dofs, J^-1, 1 / R, w, the cell volume), u gathered and f
    zeroed, summed into and read back (local: 32), the trapezoid work reading f, u,
    f_prev, u_prev and writing f_prev, u_prev (owned: 48), the velocity update reading
    coef, f, v and writing v (32), the position update (24)."""
    g = force.geometry
    return (nbytes(read=(force.state, g.dofs, g.dxi, g.inv_R, g.w, g.volume),
                   written=(force.state, force.tau))
            + 32 * force.f.x.array.size + (48 + 32 + 24) * n_owned)


def linear_bytes(step_bytes_per_dof: float, n_dofs: int, ranks: int) -> float:
    """Bytes of the linear step on one rank (the matrix and the vectors, evenly shared)."""
    return step_bytes_per_dof * n_dofs / ranks


def linear_arithmetic(nnz: float, n_dofs: int, ranks: int) -> dict:
    """MatMultAdd (2 flops a nonzero and an add a row) and AXPY (2 a dof), one rank's."""
    return {"flops": (2.0 * nnz + 3.0 * n_dofs) / ranks}


def point_arithmetic(kernel: str, n_points: int, yielded: float) -> dict:
    """POINT_FLOPS of ``kernel`` on ``n_points`` points of which the fraction ``yielded``
    yields."""
    every, extra = POINT_FLOPS[kernel]
    return {k: every.get(k, 0) * n_points + extra.get(k, 0) * yielded * n_points
            for k in ("flops",) + FUNCTIONS}


def floor(rates: dict, bytes_: float, arithmetic: dict) -> dict:
    """The floor of a step moving ``bytes_`` and doing ``arithmetic`` (flops and calls of
    FUNCTIONS) on one rank: memory = bytes / triad bandwidth, compute = flops / rate +
    calls x cost; the floor is the larger, and which it is."""
    memory = bytes_ / (rates["triad_gbs"] * 1e9)
    compute = arithmetic.get("flops", 0.0) / (rates["gflops"] * 1e9) + sum(
        arithmetic.get(f, 0) * rates["seconds_per_call"][f] for f in FUNCTIONS)
    return {"bytes": float(bytes_), "arithmetic": {k: float(v) for k, v in arithmetic.items()},
            "memory_seconds": memory, "compute_seconds": compute,
            "floor_seconds": max(memory, compute),
            "bound": "memory" if memory >= compute else "compute"}


def with_ratio(record: dict, seconds: float) -> dict:
    """``record`` (a :func:`floor`) with the measured step time and its ratio to the floor."""
    out = dict(record)
    out["seconds"] = seconds
    out["over_floor"] = seconds / record["floor_seconds"] if record["floor_seconds"] > 0 else None
    return out


def floor_cell(rec: dict | None) -> str:
    """'2.4 (memory)': the table's '× the floor' cell."""
    if not rec or rec.get("over_floor") is None:
        return "-"
    return f"{rec['over_floor']:.1f} ({rec['bound']})"


def rates_line(rates: dict) -> str:
    """The console line of the measured rates the floors stand on."""
    c = rates["seconds_per_call"]
    return (f"   floor: the larger of bytes / {rates['triad_gbs']:.1f} GB/s (numba STREAM triad, "
            f"one rank) and flops / {rates['gflops']:.2f} Gflop/s (vectorised; scalar "
            f"{rates['gflops_scalar_chains']:.2f}) + calls x (log "
            f"{1e9 * c['log']:.1f}, exp {1e9 * c['exp']:.1f}, sqrt {1e9 * c['sqrt']:.1f}, cbrt "
            f"{1e9 * c['cbrt']:.1f} ns); (memory) or (compute): which is larger")
