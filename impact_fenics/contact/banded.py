"""S = h_{n+1/2} h_n G M^-1 G' of node-to-segment constraints as a band, and the LCP solver.

G has one row per constraint with six entries: the slave's (r, z) dofs with
the normal n, the two master nodes' (r, z) dofs with -N_a n and -N_b n. Two
constraints couple only through a shared master node, so in the global order
(segments along the surface, then xi) S is banded with a bandwidth of about
the number of slaves on two neighbouring segments. Every solve on a set of
constraints is a band Cholesky factorisation of the principal submatrix (the
band of a principal submatrix in the same order is no wider): O(n w^2) for n
constraints and bandwidth w, i.e. O(n) at a fixed mesh ratio.

The linear complementarity problem of FILM (and of DME's positions),

    w = g~ + S lam >= 0,   lam >= 0,   lam . w = 0,

is solved by block principal pivoting (Judice & Pires 1994, Kostreva's
scheme): exchange every infeasible index while their number falls, with a
budget of three non-improving exchanges, then single pivots on the largest
infeasible index (Murty 1974), which is finite for a positive definite S.
"""
from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def gap_of(g0, cs, cc, u, out):
    """Linearised gaps g_i = g0_i + sum_k cc[i, k] u[cs[i, k]] (m)."""
    for i in range(g0.size):
        s = g0[i]
        for k in range(cs.shape[1]):
            s += cc[i, k] * u[cs[i, k]]
        out[i] = s
    return out


@njit(cache=True)
def apply_multipliers(lam, cs, cc, mass, free, dt, u, v, dt_u):
    """Forces G' lam (N) over one step: v += dt M^-1 G' lam, u += dt_u (that change), with
    ``dt`` the velocity step h_n and ``dt_u`` the position step h_{n+1/2} (s; equal under a
    constant step)."""
    for i in range(lam.size):
        f = lam[i]
        if f == 0.0:
            continue
        for k in range(cs.shape[1]):
            s = cs[i, k]
            if free[s] and cc[i, k] != 0.0:
                dv = dt * (cc[i, k] * f) / mass[s]
                v[s] += dv
                u[s] += dt_u * dv


@njit(cache=True)
def band_of_s(cs, cc, minv, dt, bw, band):
    """band[i, k] = S[i, i - k] for k = 0..bw (m/N), S = dt^2 G M^-1 G' (a constant step)."""
    band_of_s_steps(cs, cc, minv, dt, dt, bw, band)


@njit(cache=True)
def band_of_s_steps(cs, cc, minv, h, h_avg, bw, band):
    """band[i, k] = S[i, i - k] for k = 0..bw (m/N), S = h_{n+1/2} h_n G M^-1 G' (``h``,
    ``h_avg`` in s): a multiplier lam moves v by h_n M^-1 G' lam and u by h_{n+1/2} times
    that, so the gaps by S lam. Under a constant step (h = h_avg = dt) it is dt^2 to the bit:
    h * h_avg * s is evaluated as (h h_avg) s."""
    n = cs.shape[0]
    for i in range(n):
        for k in range(bw + 1):
            band[i, k] = 0.0
        for k in range(bw + 1):
            j = i - k
            if j < 0:
                break
            s = 0.0
            for p in range(cs.shape[1]):
                w = minv[cs[i, p]]
                if w == 0.0 or cc[i, p] == 0.0:
                    continue
                for q in range(cs.shape[1]):
                    if cs[j, q] == cs[i, p]:
                        s += cc[i, p] * cc[j, q] * w
            band[i, k] = h * h_avg * s


def bandwidth(cs: np.ndarray, cc: np.ndarray, minv: np.ndarray) -> int:
    """Largest |i - j| over constraints sharing a free dof with non-zero coefficients."""
    owner: dict[int, int] = {}
    bw = 0
    for i in range(cs.shape[0]):
        for p in range(cs.shape[1]):
            s = int(cs[i, p])
            if cc[i, p] == 0.0 or minv[s] == 0.0:
                continue
            if s in owner:
                bw = max(bw, i - owner[s])
            else:
                owner[s] = i
    return bw


@njit(cache=True)
def bandwidth_of(cs, cc, minv, first):
    """:func:`bandwidth` compiled, with ``first`` (one int64 a slot) as its scratch: the
    first row that moves each slot (-1: none yet)."""
    for s in range(first.size):
        first[s] = -1
    bw = 0
    for i in range(cs.shape[0]):
        for p in range(cs.shape[1]):
            s = cs[i, p]
            if cc[i, p] == 0.0 or minv[s] == 0.0:
                continue
            if first[s] >= 0:
                bw = max(bw, i - first[s])
            else:
                first[s] = i
    return bw


@njit(cache=True)
def gershgorin_of(band, bw, p):
    """:func:`gershgorin_beta` compiled, without temporaries: the largest row sum of
    |P^1/2 S P^1/2| (-)."""
    n = band.shape[0]
    top = 0.0
    for i in range(n):
        row = band[i, 0] * p[i]
        for k in range(1, bw + 1):
            if i - k >= 0:
                row += abs(band[i, k]) * np.sqrt(p[i]) * np.sqrt(p[i - k])
            if i + k < n:
                row += abs(band[i + k, k]) * np.sqrt(p[i + k]) * np.sqrt(p[i])
        top = max(top, row)
    return top


@njit(cache=True)
def band_factor(band, bw, idx, m, L):
    """Cholesky S_AA = L L' of the principal submatrix on idx[:m] (sorted), in band
    form L[p, k] = L_(p, p-k). Returns False if S_AA is not positive definite."""
    for p in range(m):
        i = idx[p]
        q0 = max(0, p - bw)
        for q in range(q0, p + 1):
            dist = i - idx[q]
            s = band[i, dist] if dist <= bw else 0.0
            r0 = max(q0, q - bw)
            for r in range(r0, q):
                s -= L[p, p - r] * L[q, q - r]
            if q < p:
                L[p, p - q] = s / L[q, q - q]
            else:
                if s <= 0.0:
                    return False
                L[p, 0] = np.sqrt(s)
        for k in range(p - q0 + 1, bw + 1):
            L[p, k] = 0.0
    return True


@njit(cache=True)
def band_solve(L, bw, m, rhs, x):
    """x = (L L')^-1 rhs on the first m entries (rhs, x in subset order)."""
    for p in range(m):
        s = rhs[p]
        for r in range(max(0, p - bw), p):
            s -= L[p, p - r] * x[r]
        x[p] = s / L[p, 0]
    for p in range(m - 1, -1, -1):
        s = x[p]
        for r in range(p + 1, min(m, p + bw + 1)):
            s -= L[r, r - p] * x[r]
        x[p] = s / L[p, 0]


@njit(cache=True)
def band_matvec(band, bw, x, out):
    """out = S x (S symmetric, stored as its lower band)."""
    n = x.size
    for i in range(n):
        out[i] = band[i, 0] * x[i]
    for i in range(n):
        for k in range(1, min(bw, i) + 1):
            j = i - k
            out[i] += band[i, k] * x[j]
            out[j] += band[i, k] * x[i]


# The pivotings' tolerances are 1e-13 of their problem's scale, never below the least
# normal double: a problem whose values are all subnormal (the gaps of a wave's numerical
# precursor, 5e-321 m, ahead of the wave itself) would otherwise compare with a tolerance
# that underflows to 0 while the subnormals' few bits make w and lam change sign from one
# pivot to the next, and the pivoting cycles. Below it every value is 0 to the physics.
RELATIVE_TOL = 1e-13
TINY = float(np.finfo(np.float64).tiny)  # 2.2e-308


@njit(cache=True)
def tolerance(scale):
    """1e-13 ``scale``, or the least normal double if that is smaller (the unit's)."""
    return max(RELATIVE_TOL * scale, TINY)


@njit(cache=True)
def lcp_bpp(band, bw, gap, lam, w, free, idx, rhs, sol, L, max_iter, factored, allowed):
    """Block principal pivoting for w = gap + S lam >= 0, lam >= 0, lam . w = 0 on the
    constraints ``allowed`` (bool, n; the others keep lam = 0 and are not checked).

    ``free`` (bool, n) holds the starting set of loaded constraints on entry
    (gap < 0 is the usual start) and the loaded set on exit. Writes lam (N) and
    w (m; zero on the loaded set, computed only when some allowed constraint is
    unloaded). ``factored`` (bool, n + 1): the set whose factor L holds, its last entry
    True when L is valid; a set equal to it is not factored again (S is fixed in
    small strain, so a persistent contact factors once). Returns the number of
    iterations (linear solves), -1 if none converged."""
    n = gap.size
    scale = 0.0
    for i in range(n):
        scale = max(scale, abs(gap[i]))
    tol_w = tolerance(scale)
    best = n + 1
    budget = 3
    for it in range(1, max_iter + 1):
        m = 0
        for i in range(n):
            if free[i]:
                idx[m] = i
                rhs[m] = -gap[i]
                m += 1
        if m > 0:
            same = factored[n]
            if same:
                for i in range(n):
                    if factored[i] != free[i]:
                        same = False
                        break
            if not same:
                if not band_factor(band, bw, idx, m, L):
                    factored[n] = False
                    return -1
                for i in range(n):
                    factored[i] = free[i]
                factored[n] = True
            band_solve(L, bw, m, rhs, sol)
        for i in range(n):
            lam[i] = 0.0
        lam_max = 0.0
        for p in range(m):
            lam[idx[p]] = sol[p]
            lam_max = max(lam_max, abs(sol[p]))
        checked = False  # w is needed only where lam = 0 is allowed to be checked
        for i in range(n):
            if allowed[i] and not free[i]:
                checked = True
                break
        if checked:
            band_matvec(band, bw, lam, w)
            for i in range(n):
                w[i] += gap[i]
        tol_lam = tolerance(lam_max)
        count = 0
        last = -1
        for i in range(n):
            if (free[i] and lam[i] < -tol_lam) or (not free[i] and allowed[i] and w[i] < -tol_w):
                count += 1
                last = i
        if count == 0:
            for i in range(n):
                if free[i]:
                    w[i] = 0.0
                    lam[i] = max(lam[i], 0.0)
            return it
        if count < best:
            best = count
            budget = 3
        elif budget > 0:
            budget -= 1
        else:  # single pivot on the largest infeasible index (finite for S > 0)
            free[last] = not free[last]
            continue
        for i in range(n):
            if (free[i] and lam[i] < -tol_lam) or (not free[i] and allowed[i] and w[i] < -tol_w):
                free[i] = not free[i]
    return -1


def dense_s(band: np.ndarray, bw: int) -> np.ndarray:
    """The full S (m/N) from its band (for the dense solver and the tests)."""
    n = band.shape[0]
    S = np.zeros((n, n))
    for k in range(bw + 1):
        i = np.arange(k, n)
        S[i, i - k] = band[i, k]
        S[i - k, i] = band[i, k]
    return S


def lcp_dense(S: np.ndarray, gap: np.ndarray, lam: np.ndarray, max_iter: int = 200) -> int:
    """The same pivoting with a dense factorisation of S_AA (what the paper timed).
    Returns the iterations."""
    n = gap.size
    free = gap < 0.0
    tol_w = tolerance(float(np.abs(gap).max(initial=0.0)))
    best, budget = n + 1, 3
    for it in range(1, max_iter + 1):
        lam[:] = 0.0
        A = np.flatnonzero(free)
        if A.size:
            lam[A] = np.linalg.solve(S[np.ix_(A, A)], -gap[A])
        w = gap + S @ lam
        tol_lam = tolerance(float(np.abs(lam).max(initial=0.0)))
        bad = (free & (lam < -tol_lam)) | (~free & (w < -tol_w))
        if not bad.any():
            np.maximum(lam, 0.0, out=lam)
            return it
        count = int(bad.sum())
        if count < best:
            best, budget = count, 3
        elif budget > 0:
            budget -= 1
        else:
            k = np.flatnonzero(bad)[-1]
            free[k] = ~free[k]
            continue
        free ^= bad
    raise RuntimeError(f"dense LCP: no solution after {max_iter} pivots ({n} constraints)")


def gershgorin_beta(band: np.ndarray, bw: int, p: np.ndarray) -> float:
    """Upper bound on lambda_max(P^1/2 S P^1/2) (Gershgorin's row sums)."""
    n = band.shape[0]
    sp = np.sqrt(p)
    rows = band[:, 0] * p
    for k in range(1, bw + 1):
        i = np.arange(k, n)
        off = np.abs(band[i, k]) * sp[i] * sp[i - k]
        rows[i] += off
        rows[i - k] += off
    return float(rows.max(initial=0.0))


class Pivoting:
    """The complementarity problem w = g~ + S lam >= 0, lam >= 0, lam . w = 0 of a banded
    S (m/N), with its scratch arrays (allocated once) and its iteration counts in
    ``info``: FILM's multipliers and DME's positions on node-to-segment constraints.

    ``solver`` 'bpp': block principal pivoting on the band (O(n) per iteration), started
    from the last step's loaded set joined with g~ < 0, the band factor of that set kept;
    'dense': factors of the dense S (for comparison), started from g~ < 0. ``name``: the
    method's, for the one-line failure."""

    max_iter = 1000

    def __init__(self, band: np.ndarray, bw: int, solver: str, name: str, info: dict):
        n = band.shape[0]
        self.band, self.bw, self.solver, self.name, self.info = band, bw, solver, name, info
        self.lam = np.zeros(n)
        self.w = np.zeros(n)
        self.free = np.zeros(n, dtype=np.bool_)
        self.start = np.zeros(n, dtype=np.bool_)
        self.everywhere = np.ones(n, dtype=np.bool_)
        self.idx = np.zeros(n, dtype=np.int64)
        self.rhs = np.zeros(n)
        self.sol = np.zeros(n)
        self.L = np.zeros((n, bw + 1))
        self.factored = np.zeros(n + 1, dtype=np.bool_)  # the set L factors, valid flag
        self.S = dense_s(band, bw) if solver == "dense" else None
        self.iterations = 0
        info.update({"bandwidth": int(bw), "iterations_max": 0, "iterations_total": 0})

    def rebanded(self, band: np.ndarray, bw: int, rows: np.ndarray) -> None:
        """S was rebuilt (a re-pairing, or a new step): its band is ``band`` (at least
        bw + 1 columns, the ones past bw unread) of bandwidth ``bw``, ``rows`` (bool) the
        constraints that have a row (a released one has none: a zero row of S, out of the
        warm start's loaded set). The kept factor no longer holds; the factor's rows grow
        only when the band does."""
        self.band, self.bw = band, bw
        if self.S is not None:  # the dense comparison solver keeps S whole (it allocates)
            self.S = dense_s(band, bw)
        np.logical_and(self.free, rows, out=self.free)
        self.factored[-1] = False
        if self.L.shape[1] < band.shape[1]:
            self.L = np.zeros(band.shape)
        self.info["bandwidth"] = max(int(self.info["bandwidth"]), int(bw))

    def kernel_calls(self, gap: np.ndarray) -> list:
        """(kernel, arguments) of :meth:`solve`, for loading at set-up."""
        if self.solver == "dense":
            return []  # lcp_dense is numpy and LAPACK: nothing to compile
        return [(lcp_bpp, (self.band, self.bw, gap, self.lam, self.w, self.free, self.idx,
                           self.rhs, self.sol, self.L, self.max_iter, self.factored,
                           self.everywhere))]

    def solve(self, gap: np.ndarray) -> np.ndarray:
        """The multipliers lam (N) for the predicted gaps ``gap`` (m); counts iterations."""
        if self.solver == "dense":
            it = lcp_dense(self.S, gap, self.lam, self.max_iter)
            np.greater(self.lam, 0.0, out=self.free)
        else:
            # warm start: last step's loaded set and every predicted penetration
            np.less(gap, 0.0, out=self.start)
            np.logical_or(self.free, self.start, out=self.free)
            it = lcp_bpp(self.band, self.bw, gap, self.lam, self.w, self.free, self.idx,
                         self.rhs, self.sol, self.L, self.max_iter, self.factored,
                         self.everywhere)
            if it < 0:
                raise RuntimeError(f"{self.name}: complementarity pivoting did not converge in "
                                   f"{self.max_iter} iterations ({gap.size} constraints)")
        self.iterations = it
        info = self.info
        info["iterations_total"] += it
        if it > info["iterations_max"]:
            info["iterations_max"] = it
        return self.lam
