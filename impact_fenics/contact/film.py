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
"""
from __future__ import annotations

import numpy as np

from ..errors import InputError


def solve_fast(gap: np.ndarray, d: np.ndarray, kappa: float, out: np.ndarray) -> np.ndarray:
    """Exact forces (N) for S = diag(d) + kappa 1 1', in O(n log n)."""
    np.divide(gap, d, out=out)
    np.negative(out, out=out)
    np.maximum(out, 0.0, out=out)  # the answer for kappa = 0, and force_i(F = 0)
    if kappa == 0.0 or not np.any(out):
        return out
    cand = np.flatnonzero(gap < 0.0)
    # candidate i carries force while F < -g~_i / kappa: sort by that break point
    order = cand[np.argsort(gap[cand], kind="stable")]
    a = np.cumsum(-gap[order] / d[order])
    w = np.cumsum(1.0 / d[order])
    total = a / (1.0 + kappa * w)  # F if exactly the first k candidates carry force
    breaks = -gap[order] / kappa
    next_break = np.append(breaks[1:], 0.0)
    k = int(np.argmax(total >= next_break))  # first k whose F leaves the others unloaded
    # On the active set A, g~_i + kappa F is a small difference of large numbers
    # (the light body's predicted overshoot). Writing g~_i = g_ref + delta_i gives
    # g~_i + kappa F = delta_i + (g_ref - kappa sum delta/d) / (1 + kappa sum 1/d)
    # without that cancellation.
    A = order[: k + 1]
    g_ref = float(gap[A].mean())
    delta = gap[A] - g_ref
    inv_d = 1.0 / d[A]
    base = (g_ref - kappa * float(delta @ inv_d)) / (1.0 + kappa * float(inv_d.sum()))
    out[:] = 0.0
    out[A] = np.maximum(-(delta + base) * inv_d, 0.0)
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
    """Forward-increment Lagrange multipliers; ``solver`` 'fast' (exact, O(n log n)) or 'dense'."""

    name = "film"

    def __init__(self, solver: str = "fast"):
        if solver not in ("fast", "dense"):
            raise InputError(f"film solver = '{solver}': use 'fast' or 'dense'")
        self.solver = solver
        self._solve = solve_fast if solver == "fast" else solve_dense
        self.info: dict[str, float | str] = {"solver": solver}

    def setup(self, c) -> None:
        self._d = c.s_diagonal()
        self._kappa = c.s_coupling()

    def correct(self, c) -> None:
        self._solve(c.gap, self._d, self._kappa, c.force)
        np.greater(c.force, 0.0, out=c.active)
        c.apply_forces(c.force)
