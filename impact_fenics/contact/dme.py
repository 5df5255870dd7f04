"""Direct manifold elimination (paper Section 2.3): active constraints are eliminated.

Active constraints are those with a predicted penetration, g~ < 0 (paper eq. 7).

Case 1, rigid upper body (paper eq. 8): the active nodes join the body as one
rigid cluster. Its velocity is the momentum average of the predicted
velocities, v_c = (m_p v~_p + sum m_i v~_i) / (m_p + sum m_i), i.e. the cluster
acceleration is the total force over the total mass; the body moves to
u_p^n + dt v_c and each active node onto it, u_i = u_p + b_i. While the cluster
persists this is exactly FILM. At an activation with an open gap g^n the node
jumps by g^n onto the body: against the elastic forces of its loaded
neighbours, so DME gains strain energy where FILM dissipates (the ledger books
the jump). A mass-weighted cluster position (keeping the centre of mass, as in
case 2) does worse with a light body: it shifts the whole loaded cluster and
leaves released nodes penetrating, so case 1 keeps eq. (8). A node is released when the
reaction needed to hold it, m_i (v~_i - v_c) / dt (N, the quantity FILM calls
the multiplier), would pull: sorting the candidates by v~_i finds the largest
consistent cluster in O(n log n).

Case 2, two deformable bodies: each active pair moves as one. Velocities come
from momentum and Newton's restitution law, v'_up - v'_lo = -e (v~_up - v~_lo),
e in [0, 1]; positions from the mass-weighted average of the predicted ones,
which keeps the centre of mass and, while the pair stays closed,
u^{n+1} = u^n + dt v^{n+1}. ``positions="paper"`` uses the paper's eq. (9) equal
weights instead. The holding reaction of a closed pair is compressive exactly when its
predicted gap is negative, so detection and release coincide.

The set velocity is independent of the set position at an activation (a
jump); the interface encodes it and books its energy.
"""
from __future__ import annotations

import numpy as np

from ..errors import InputError


class DME:
    """Direct manifold elimination. For node pairs (case 2): ``restitution`` e in [0, 1]
    and ``positions`` 'mass_weighted' or 'paper' (the equal weights of eq. 9)."""

    name = "dme"
    jumps = True

    def __init__(self, restitution: float = 0.0, positions: str = "mass_weighted"):
        if not 0.0 <= restitution <= 1.0:
            raise InputError(f"restitution = {restitution}: must lie in [0, 1]")
        if positions not in ("mass_weighted", "paper"):
            raise InputError(f"dme positions = '{positions}': use 'mass_weighted' or 'paper'")
        self.e = float(restitution)
        self.positions = positions
        self.info: dict[str, float | str] = {"restitution": self.e, "positions": positions}

    def setup(self, c) -> None:
        if c.rigid is None:
            total = c.m_lo + c.m_up
            self._w_lo = c.m_lo / total if self.positions == "mass_weighted" else np.full(c.n, 0.5)
            self._share_lo = c.m_lo / total  # momentum weights
            self._mu = c.m_lo * c.m_up / total  # reduced mass (kg)
        self._rel = np.empty(c.n)
        self._x = np.empty(c.n)

    def correct(self, c) -> None:
        np.less(c.gap, 0.0, out=c.active)
        c.force.fill(0.0)
        if not c.active.any():
            return
        if c.rigid is None:
            self._pairs(c)
        else:
            self._cluster(c)

    def _pairs(self, c) -> None:
        a = c.active
        dt = c.dt
        rel = self._rel  # approach velocity v~_up - v~_lo (m/s), < 0 when closing
        np.subtract(c.v_up, c.v_lo, out=rel)
        # velocities: v_mean from momentum, then the restitution split
        v_mean = c.v_lo[a] + (1.0 - self._share_lo[a]) * rel[a]
        k = self.e * rel[a]
        c.force[a] = -(1.0 + self.e) * self._mu[a] * rel[a] / dt
        c.v_lo[a] = v_mean + (1.0 - self._share_lo[a]) * k
        c.v_up[a] = v_mean - self._share_lo[a] * k
        # positions on the manifold u_lo = u_up + b
        x = self._w_lo[a] * c.u_lo[a] + (1.0 - self._w_lo[a]) * (c.u_up[a] + c.b[a])
        c.u_lo[a] = x
        c.u_up[a] = x - c.b[a]

    def _cluster(self, c) -> None:
        dt = c.dt
        v_p = c.rigid_state[1]  # predicted velocity
        m_p = c.rigid.mass
        cand = np.flatnonzero(c.active)
        order = cand[np.argsort(-c.v_lo[cand], kind="stable")]
        m = c.m_lo[order]
        mom = m_p * v_p + np.cumsum(m * c.v_lo[order])
        mass = m_p + np.cumsum(m)
        v_before = np.concatenate(([v_p], (mom / mass)[:-1]))  # cluster velocity before adding k
        keep = c.v_lo[order] >= v_before
        k = int(np.argmin(keep)) if not keep.all() else keep.size
        members = order[:k]
        v_c = float(mom[k - 1] / mass[k - 1])
        c.active[:] = False
        c.active[members] = True
        c.force[members] = c.m_lo[members] * (c.v_lo[members] - v_c) / dt
        u_rigid = c.rigid.u + dt * v_c  # the body keeps u_p^n + dt v_c; nodes move onto it
        c.set_upper_rigid(v_c, u_rigid)
        c.v_lo[members] = v_c
        c.u_lo[members] = u_rigid + c.b[members]
