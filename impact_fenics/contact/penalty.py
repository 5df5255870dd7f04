"""Penalty (paper eq. 5): a spring of stiffness p_i (N/m) on each predicted penetration.

    force_i = p_i * max(0, -g~_i)

Stability for persistent contact. With S = dt^2 G M^-1 G' (m/N; h_{n+1/2} h_n G M^-1 G'
under a varying step) and P = diag(p),
the corrected gaps are g = (I - S P) g~. Take an isolated pair (or a mode of
P^1/2 S P^1/2 with eigenvalue beta) and no elastic coupling. With y^n the gap
change of the last step, g^{n+1} = (1 - beta)(g^n + y^n) and
y^{n+1} = g^{n+1} - g^n, whose amplification matrix

    [[1 - beta, 1 - beta], [-beta, 1 - beta]]

has trace 2 (1 - beta) and determinant 1 - beta. The Jury conditions give
beta > 0 and 1 + trace + det = 4 - 3 beta > 0:

    0 < beta < 4/3.

At beta = 1 the matrix is nilpotent: the gap closes in one step (this is FILM).
For beta < 1 the roots are complex with |z|^2 = 1 - beta (the penalty damps);
at beta = 4/3 a root reaches z = -1, so above it the gap alternates sign every
step: a tied pair grows without bound, a unilateral contact chatters (opens
and closes on alternate steps) and gains energy.

An elastic body behind the node adds a mode stiffness w = dt^2 omega^2 in
[0, 4) (the explicit limit without contact). Then
g^{n+1} = (1 - beta)((1 - w) g^n + y^n): trace (1 - beta)(2 - w), determinant
1 - beta, and the Jury conditions are 0 < beta < 2,
1 + (1 - beta)(3 - w) > 0 and 1 + (1 - beta)(w - 1) > 0, i.e.

    beta < (4 - w)/(3 - w)   for 0 <= w <= 2,
    beta < w/(w - 1)         for 2 <= w < 4

(the two meet at beta = 2, w = 2; for 2 < w < 3 the first expression is
larger than the true limit and must not be used). Both are >= 4/3 and reach
it at w = 0 and w -> 4, so 4/3 is the bound that holds for every mode. It is
sharp for a rigid punch (the coupled mode has w = 0: the punch carries no
stiffness); for node pairs of two elastic bodies it is only sufficient: their
contact modes carry w > 0 at a realistic dt, and such pairs settle above 4/3
(measured in docs/results.md).

With a rigid punch, S = diag(d) + kappa 1 1' with kappa = dt^2 / m_p couples
every spring through the light punch: with a uniform p, beta_max = p *
lambda_max(S) >= p (mean d + n kappa) (the Rayleigh quotient of the vector of
ones) grows with the number of constraints, which a per-pair choice of p cannot
see. The ``scaled`` choice p_i = c / d_i puts every
pair at the same beta_ii = c and takes c from the coupled operator:
lambda_max(I + kappa w w') = 1 + kappa sum(1/d) with w_i = d_i^-1/2, so
beta_max = c (1 + kappa sum 1/d_i) = beta_target exactly.

Node to segment, S is banded (contact.banded) and symmetric positive definite but, with
positive off-diagonal entries where slaves share a master node, not an M-matrix:
``scaled`` puts every constraint at p_i = c / S_ii with c from Gershgorin's bound, so
that beta_max <= beta_target; a given p whose Gershgorin bound exceeds 4/3 is refused
at set-up unless forced. The forces move each row's six dofs by G' force. A set that
re-pairs in the time loop changes S at each re-pairing but keeps p: ``scaled`` then
takes each slave's p from the largest diagonal any of its rows can have,
S_ii <= dt^2 (1/m_s + 1/m_min) (m_min the lightest free master node, since
N_a^2 + N_b^2 <= 1), scaled by Gershgorin's bound at set-up; ``beta_max`` is the
largest Gershgorin bound of the rows the run used (their off-diagonal entries change
with the pairing). Under a varying step S scales with h_{n+1/2} h_n: a ``scaled`` or
``auto`` p scales with its inverse (the same beta at every step, as node pairs, whose p
is chosen again), a given p stays and its beta grows with the step (``beta_max`` keeps the
largest, which the loop checks at every change of step).
"""
from __future__ import annotations

import numpy as np
from numba import njit

from ..errors import InputError
from .banded import apply_multipliers, gershgorin_beta, gershgorin_of
from .state import apply_forces, is_banded

STABILITY_BOUND = 4.0 / 3.0


def lambda_max_diag_plus_rank_one(a: np.ndarray, kappa: float, z: np.ndarray) -> float:
    """Largest eigenvalue of diag(a) + kappa z z' (kappa >= 0), by bisection on the
    secular equation 1 = kappa sum z_i^2 / (lambda - a_i)."""
    top = float(a.max())
    if kappa == 0.0 or not np.any(z):
        return top
    lo, hi = top, top + kappa * float(z @ z)
    z2 = z * z
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if mid <= lo or mid >= hi:
            break
        if kappa * np.sum(z2 / (mid - a)) > 1.0:
            lo = mid
        else:
            hi = mid
    return hi


class Penalty:
    """Penalty contact. ``p``: a stiffness in N/m, ``"auto"`` (the paper's rule, see
    ``auto_reading``) or ``"scaled"`` (stability-scaled, beta_max = ``beta_target``).
    ``force``: node to segment, accept a Gershgorin bound above 4/3."""

    name = "penalty"
    jumps = False

    def __init__(self, p: float | str = "scaled", auto_reading: str = "mean_of_inverse",
                 beta_target: float = 1.0, force: bool = False):
        if isinstance(p, str) and p not in ("auto", "scaled"):
            try:
                p = float(p)
            except ValueError:
                raise InputError(f"penalty = '{p}': give a stiffness in N/m, 'auto' or 'scaled'")
        if not isinstance(p, str) and not p > 0:
            raise InputError(f"penalty = {p} N/m: must be > 0")
        if auto_reading not in ("mean_of_inverse", "inverse_of_mean"):
            raise InputError(f"auto_reading = '{auto_reading}': use 'mean_of_inverse' "
                             "or 'inverse_of_mean'")
        if not 0 < beta_target:
            raise InputError(f"beta_target = {beta_target}: must be > 0")
        self.choice = p
        self.auto_reading = auto_reading
        self.beta_target = beta_target
        self.forced = force
        self.info: dict[str, float | str] = {}

    def setup(self, c) -> None:
        """p from the set's S at its current steps; ``info["beta_max"]`` is the largest
        beta_max of every step the set was set up for so far (a step that follows the cells
        sets it up again at each re-estimate: the summary reports the run's largest, not the
        last, clipped step's)."""
        before = float(self.info.get("beta_max", 0.0))
        self._setup_pairs_or_band(c)
        self.info["beta_max"] = max(float(self.info["beta_max"]), before)

    def _setup_pairs_or_band(self, c) -> None:
        if is_banded(c):
            self._setup_banded(c)
            return
        d, kappa = c.d, c.kappa
        # the paper's sentence, both readings: an average of S's diagonal as p
        auto = {"mean_of_inverse": float(np.mean(1.0 / d)),
                "inverse_of_mean": float(1.0 / np.mean(d))}
        if self.choice == "scaled":
            scale = self.beta_target / (1.0 + kappa * float(np.sum(1.0 / d)))
            self.p = scale / d
        elif self.choice == "auto":
            self.p = np.full(c.n, auto[self.auto_reading])
        else:
            self.p = np.full(c.n, float(self.choice))
        sqrt_p = np.sqrt(self.p)
        beta_max = lambda_max_diag_plus_rank_one(self.p * d, kappa, sqrt_p)
        self.info = {"p_choice": str(self.choice), "p_min": float(self.p.min()),
                     "p_max": float(self.p.max()), "p_auto_mean_of_inverse": auto["mean_of_inverse"],
                     "p_auto_inverse_of_mean": auto["inverse_of_mean"],
                     "beta_max": beta_max, "beta_bound": STABILITY_BOUND}

    def _setup_banded(self, c) -> None:
        """p on a banded S (node to segment): beta_max by Gershgorin's row sums. A set that
        re-pairs (``repair_every`` > 0) scales p by the largest diagonal a row of its
        slave can have, S_ii <= h^2 (1/m_s + 1/m_min) with m_min the lightest free master
        node (N_a^2 + N_b^2 <= 1), instead of the set-up row's."""
        d = c.band[:, 0]
        if self.choice == "scaled" and getattr(c, "repair_every", 0):
            n_slave = c.constraints.slave_xy.shape[0]
            worst = float(c.minv[2 * n_slave:].max(initial=0.0))
            slave_minv = np.maximum(c.minv[0:2 * n_slave:2], c.minv[1:2 * n_slave:2])
            self.p = 1.0 / (c.dt * c.h_avg * (slave_minv + worst))
            self.p *= self.beta_target / gershgorin_beta(c.band, c.bw, self.p)
        elif self.choice == "scaled":
            self.p = 1.0 / d
            self.p *= self.beta_target / gershgorin_beta(c.band, c.bw, self.p)
        elif self.choice == "auto":
            mean = {"mean_of_inverse": lambda: np.mean(1.0 / d),
                    "inverse_of_mean": lambda: 1.0 / np.mean(d)}[self.auto_reading]
            self.p = np.full(c.n, float(mean()))
        else:
            self.p = np.full(c.n, float(self.choice))
        beta = gershgorin_beta(c.band, c.bw, self.p)
        if beta > STABILITY_BOUND * (1 + 1e-12) and not self.forced:
            raise InputError(f"penalty: beta_max <= {beta:.4g} (Gershgorin bound on "
                             f"dt^2 P^1/2 G M^-1 G' P^1/2) exceeds the stability limit 4/3: "
                             "lower p, use 'scaled', or force it")
        self.info = {"p_choice": str(self.choice), "p_min": float(self.p.min()),
                     "p_max": float(self.p.max()), "beta_max": beta,
                     "beta_bound": STABILITY_BOUND}
        # the step pair p was chosen at (s^2), and that p: a step change rescales from them
        self._hh, self._hh_setup, self._p_setup = c.dt * c.h_avg, c.dt * c.h_avg, self.p.copy()

    def rebanded(self, c) -> None:
        """S was rebuilt (a re-pairing, a new step): at a new step pair a ``scaled`` or
        ``auto`` p becomes the set-up's times h h_n (set-up) / h h_n (now), in place (S
        scales with h_{n+1/2} h_n); ``beta_max`` keeps the largest Gershgorin bound of the
        rows and steps the run has used (p is otherwise the set-up's)."""
        hh = c.dt * c.h_avg
        if hh != self._hh:
            self._hh = hh
            if isinstance(self.choice, str):  # 'scaled', 'auto': p ~ 1 / (h h_n)
                np.multiply(self._p_setup, self._hh_setup / hh, out=self.p)
        beta = gershgorin_of(c.band, c.bw, self.p)
        if beta > self.info["beta_max"]:
            self.info["beta_max"] = beta

    def kernel_calls(self, c) -> list:
        """(kernel, arguments) of every compiled call of :meth:`correct` on a banded S (the
        node-pair and rigid sets load theirs by one call)."""
        if not is_banded(c):
            return []
        return [(_penalty_banded, (c.gap, self.p, c.force, c.active, c.cs, c.cc, c.mass,
                                   c.free, c.dt, c.h_avg, c.u, c.v)),
                (gershgorin_of, (c.band, c.bw, self.p))]  # rebanded's bound

    def correct(self, c) -> None:
        if is_banded(c):
            _penalty_banded(c.gap, self.p, c.force, c.active, c.cs, c.cc, c.mass, c.free, c.dt,
                            c.h_avg, c.u, c.v)
            return
        _penalty(c.gap, self.p, c.force, c.active, c.lo, c.up, c.dt_over_m, c.dt, c.u, c.v)


@njit(cache=True)
def _penalty(gap, p, force, active, lo, up, dt_over_m, dt, u, v):
    """force_i = p_i max(0, -g~_i) (N), applied (``dt_over_m`` = dt / m per slot, s/kg)."""
    for i in range(gap.size):
        g = gap[i]
        active[i] = g < 0.0
        force[i] = -p[i] * g if g < 0.0 else 0.0
    apply_forces(force, lo, up, dt_over_m, dt, u, v)


@njit(cache=True)
def _penalty_banded(gap, p, force, active, cs, cc, mass, free, h, h_avg, u, v):
    """force_i = p_i max(0, -g~_i) (N), applied through G' (six dofs a row): v by h_n M^-1 G'
    force, u by h_{n+1/2} times that (``h``, ``h_avg``: h_{n+1/2}, h_n in s)."""
    for i in range(gap.size):
        active[i] = gap[i] < 0.0
        force[i] = -p[i] * gap[i] if active[i] else 0.0
    apply_multipliers(force, cs, cc, mass, free, h_avg, u, v, h)
