"""Forward-increment Lagrange multipliers (paper eqs. 2-4), solved as a complementarity problem.

The multipliers are the contact forces (N) that make the corrected gaps
g = g~ + S force, S = dt^2 G M^-1 G' = diag(d) + kappa 1 1' (m/N), satisfy

    force >= 0,   g >= 0,   force . g = 0.

Node pairs between deformable bodies: kappa = 0, S is diagonal and
force_i = max(0, -g~_i / d_i). A rigid upper body of mass m_p couples every
constraint through kappa = dt^2 / m_p: given the total F = sum(force), each
force_i = max(0, -(g~_i + kappa F) / d_i) is a clipped function of F alone, and
F is the root of the decreasing function F -> sum_i force_i(F) - F. Sorting the
break points -g~_i / kappa finds it exactly in O(n log n) (``solver="fast"``).

``solver="dense"`` assembles S on the candidate set and factors it (what the
paper timed), dropping tensile multipliers and adding violated gaps until the
complementarity conditions hold.

Node to segment, S is banded (contact.banded): the same complementarity problem is
solved by block principal pivoting on the band of S (``solver="fast"``, O(n) per
iteration, reported as 'bpp') or with dense factors (``solver="dense"``); then
v += h_n M^-1 G' force, u += h_{n+1/2} h_n M^-1 G' force (S = h_{n+1/2} h_n G M^-1 G': dt^2
under a constant step). Iterations are counted.
"""
from __future__ import annotations

import numpy as np
from numba import njit

from ..errors import InputError
from .banded import Pivoting, apply_multipliers
from .state import apply_forces, is_banded


@njit(cache=True)
def solve_fast(gap, d, kappa, out, work=None, d_inv=None):
    """Exact forces (N) for S = diag(d) + kappa 1 1' (m/N), in O(n log n) (O(n) when
    every penetrating constraint carries force, the usual case under a punch).
    ``work``: an int buffer of length n, ``d_inv``: 1/d (N/m), set-up constants of a
    contact set (each allocated if not given)."""
    if work is None:
        if d_inv is None:
            return _solve_fast(gap, 1.0 / d, kappa, out, np.empty(gap.size, np.int64))
        return _solve_fast(gap, d_inv, kappa, out, np.empty(gap.size, np.int64))
    if d_inv is None:
        return _solve_fast(gap, 1.0 / d, kappa, out, work)
    return _solve_fast(gap, d_inv, kappa, out, work)


@njit(cache=True)
def _solve_fast(gap, d_inv, kappa, out, work):
    """solve_fast with 1/d (N/m) and the index buffer given."""
    n = gap.size
    k = 0
    a = 0.0  # sum of -g~_i / d_i over the candidates
    w = 0.0  # sum of 1 / d_i over them
    g_max = -np.inf
    for i in range(n):
        g = gap[i]
        out[i] = 0.0
        if g < 0.0:
            out[i] = -g * d_inv[i]  # the answer for kappa = 0
            work[k] = i
            k += 1
            a -= g * d_inv[i]
            w += d_inv[i]
            g_max = max(g_max, g)
    if kappa == 0.0 or k == 0:
        return out
    cand = work[:k]
    if g_max + kappa * a / (1.0 + kappa * w) <= 0.0:  # all candidates carry force
        return _loaded(gap, d_inv, kappa, cand, out)
    # candidate i carries force while F < -g~_i / kappa: sort by that break point
    order = cand[np.argsort(gap[cand], kind="mergesort")]  # allocates: the rare path
    a = 0.0
    w = 0.0
    m = k
    for j in range(k):
        i = order[j]
        a -= gap[i] * d_inv[i]
        w += d_inv[i]
        total = a / (1.0 + kappa * w)  # F if exactly the first j + 1 carry force
        next_break = -gap[order[j + 1]] / kappa if j + 1 < k else 0.0
        if total >= next_break:  # it leaves the others unloaded: the active set
            m = j + 1
            break
    return _loaded(gap, d_inv, kappa, order[:m], out)


@njit(cache=True)
def _loaded(gap, d_inv, kappa, loaded, out):
    """Forces when exactly the constraints ``loaded`` carry force (``d_inv`` = 1/d, N/m).

    There g~_i + kappa F is a small difference of large numbers (a light body's
    predicted overshoot). With g~_i = g_ref + delta_i, g_ref their mean, it is evaluated
    as delta_i + (g_ref - kappa sum delta/d) / (1 + kappa sum 1/d), without that
    cancellation. sum delta/d is summed in the same pass as g_ref, about the first
    loaded gap g_0: sum (g~_i - g_0)/d + (g_0 - g_ref) sum 1/d (small terms only)."""
    m = loaded.size
    g_0 = gap[loaded[0]]
    g_sum = 0.0
    s_0 = 0.0
    w = 0.0
    for i in loaded:
        g = gap[i]
        g_sum += g
        s_0 += (g - g_0) * d_inv[i]
        w += d_inv[i]
    g_ref = g_sum / m
    s = s_0 + (g_0 - g_ref) * w
    base = (g_ref - kappa * s) / (1.0 + kappa * w)
    if m < gap.size:
        for i in range(gap.size):
            out[i] = 0.0
    for i in loaded:
        out[i] = max(-(gap[i] - g_ref + base) * d_inv[i], 0.0)
    return out


def solve_dense(gap: np.ndarray, d: np.ndarray, kappa: float, out: np.ndarray,
                max_iter: int = 100) -> np.ndarray:
    """Forces (N) by factoring S on an active set, updated until complementarity holds."""
    n = gap.size
    out[:] = 0.0
    active = gap < 0.0
    tol = 1e-14 * max(1.0, float(np.abs(gap).max(initial=0.0)))
    for _ in range(max_iter):
        idx = np.flatnonzero(active)
        out[:] = 0.0
        if idx.size:
            S = np.full((idx.size, idx.size), kappa)
            S[np.diag_indices(idx.size)] += d[idx]
            out[idx] = np.linalg.solve(S, -gap[idx])
        g = gap + d * out + kappa * out.sum()
        tensile = active & (out < 0.0)
        violated = ~active & (g < -tol)
        if not tensile.any() and not violated.any():
            np.maximum(out, 0.0, out=out)
            return out
        active = (active & ~tensile) | violated
    raise RuntimeError(f"FILM dense solver: no consistent active set after {max_iter} updates "
                       f"({n} constraints)")


class FILM:
    """Forward-increment Lagrange multipliers; ``solver`` 'fast' (exact: O(n log n) on a
    diagonal or rank-one S, pivoting on a banded one) or 'dense'."""

    name = "film"
    jumps = False

    def __init__(self, solver: str = "fast"):
        if solver not in ("fast", "dense"):
            raise InputError(f"film solver = '{solver}': use 'fast' or 'dense'")
        self.solver = solver
        self.info: dict[str, float | str] = {"solver": solver}

    def setup(self, c) -> None:
        if is_banded(c):
            solver = "bpp" if self.solver == "fast" else "dense"
            self.info = {"solver": solver}
            self.pivoting = Pivoting(c.band, c.bw, solver, self.name, self.info)

    def rebanded(self, c) -> None:
        """S was rebuilt (a re-pairing, a new step): the pivoting works on its new band."""
        self.pivoting.rebanded(c.band, c.bw, c.has_row)

    @property
    def iterations(self) -> int:
        """Iterations of the last step's pivoting (node to segment)."""
        return self.pivoting.iterations

    def kernel_calls(self, c) -> list:
        """(kernel, arguments) of every compiled call of :meth:`correct` on a banded S (the
        node-pair and rigid sets load theirs by one call)."""
        if not is_banded(c):
            return []
        return self.pivoting.kernel_calls(c.gap) + [
            (apply_multipliers, (c.force, c.cs, c.cc, c.mass, c.free, c.h_avg, c.u, c.v,
                                 c.dt))]

    def correct(self, c) -> None:
        if is_banded(c):
            lam = self.pivoting.solve(c.gap)
            c.force[:] = lam
            np.greater(lam, 0.0, out=c.active)
            c.apply_forces(c.force)
        elif self.solver == "fast":
            _film_fast(c.gap, c.d_inv, c.kappa, c.force, c.active, c.lo, c.up, c.dt_over_m,
                       c.dt, c.u, c.v, c.work)
        else:
            solve_dense(c.gap, c.d, c.kappa, c.force)
            np.greater(c.force, 0.0, out=c.active)
            c.apply_forces(c.force)


@njit(cache=True)
def _film_fast(gap, d_inv, kappa, force, active, lo, up, dt_over_m, dt, u, v, work):
    """solve_fast, then the forces applied (``dt_over_m`` = dt / m per slot, s/kg)."""
    _solve_fast(gap, d_inv, kappa, force, work)
    for i in range(gap.size):
        active[i] = force[i] > 0.0
    apply_forces(force, lo, up, dt_over_m, dt, u, v)
