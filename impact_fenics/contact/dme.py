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

Case 3, node to segment (S = h_{n+1/2} h_n G M^-1 G' banded, contact.banded; dt^2 under
a constant step): the normal relative displacement is eliminated. Positions: the
M-orthogonal projection of u~ onto the active manifold g = 0 (the mass-weighted
position; centre of mass kept), u = u~ + h_{n+1/2} h_n M^-1 G' nu with nu >= 0 the
solution of FILM's complementarity problem (with coupled constraints the set that can
hold is found by the same pivoting; uncoupled it is g~ < 0, the paper's eq. 7).
Velocities: the M-orthogonal projection of v~ onto G v = -e G v~ on that set (Newton's
restitution on the normal relative velocity), v = v~ + h_n M^-1 G' phi with
S phi = -(1 + e) h_{n+1/2} G v~ where phi pushes;
where coupling would make some phi pull, the same pivoting solves
S phi + (1 + e) dt G v~ >= 0, phi >= 0 on the set instead (it reuses the band factor,
so the usual case costs one band solve). For one slave over a segment this is
m_eff = (1/m_s + sum N_i^2 / m_i)^-1. The reported force is phi (N, the momentum
change over h_n). With e = 0 and a constraint closed at step n (g~ = h_{n+1/2} G v~),
nu = phi and DME equals FILM exactly. Only the mass-weighted positions have this form.

The set velocity is independent of the set position at an activation (a
jump); the interface encodes it and books its energy.
"""
from __future__ import annotations

import numpy as np
from numba import njit

from ..errors import InputError
from .banded import Pivoting, lcp_bpp
from .state import is_banded


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
        if not is_banded(c):
            return
        if self.positions != "mass_weighted":
            raise InputError("dme positions = 'paper' has no node-to-segment form: "
                             "use 'mass_weighted'")
        # the velocity problem reuses the position problem's band factor
        self.info = {"restitution": self.e, "positions": self.positions}
        self.pivoting = Pivoting(c.band, c.bw, "bpp", self.name, self.info)
        self.phi = np.zeros(c.n)
        self.vgap = np.zeros(c.n)
        self.vfree = np.zeros(c.n, dtype=np.bool_)
        self.vw = np.zeros(c.n)

    def rebanded(self, c) -> None:
        """S was rebuilt (a re-pairing, a new step): the pivoting works on its new band."""
        self.pivoting.rebanded(c.band, c.bw, c.has_row)

    def kernel_calls(self, c) -> list:
        """(kernel, arguments) of every compiled call of :meth:`correct` on a banded S (the
        node-pair and rigid sets load theirs by one call)."""
        if not is_banded(c):
            return []
        ws = self.pivoting
        return ws.kernel_calls(c.gap) + [
            (_velocity_gaps, (ws.free, c.cs, c.cc, c.v_pred, self.e, c.dt, self.vgap, self.vfree)),
            (lcp_bpp, (c.band, c.bw, self.vgap, self.phi, self.vw, self.vfree, ws.idx, ws.rhs,
                       ws.sol, ws.L, ws.max_iter, ws.factored, ws.free)),
            (_segments, (ws.lam, self.phi, ws.free, c.cs, c.cc, c.mass, c.free, c.dt,
                         c.h_avg, c.u, c.v, c.force, c.active))]

    def correct(self, c) -> None:
        if is_banded(c):
            self._correct_banded(c)
        elif c.rigid is None:
            _pairs(c.gap, c.b, c.lo, c.up, c.mass, c.h_avg, self.e,
                   self.positions == "mass_weighted", c.u, c.v, c.force, c.active)
        else:
            _cluster(c.gap, c.b, c.nodes, c.body, c.side, c.mass, c.m_over_dt, c.dt, c.u_now,
                     c.u, c.v, c.force, c.active, c.work)


    def _correct_banded(self, c) -> None:
        """Case 3: positions by nu, velocities by phi (see the module's text)."""
        ws = self.pivoting
        nu = ws.solve(c.gap)
        _velocity_gaps(ws.free, c.cs, c.cc, c.v_pred, self.e, c.dt, self.vgap, self.vfree)
        it = lcp_bpp(c.band, c.bw, self.vgap, self.phi, self.vw, self.vfree, ws.idx, ws.rhs,
                     ws.sol, ws.L, ws.max_iter, ws.factored, ws.free)
        if it < 0:
            raise RuntimeError(f"dme: velocity pivoting did not converge ({c.n} constraints)")
        _segments(nu, self.phi, ws.free, c.cs, c.cc, c.mass, c.free, c.dt, c.h_avg, c.u,
                  c.v, c.force, c.active)


@njit(cache=True)
def _pairs(gap, b, lo, up, mass, h_avg, e, mass_weighted, u, v, force, active):
    """Case 2: each penetrating pair moves as one (momentum, restitution, positions); the
    reported force (N) is the momentum change over the velocity step ``h_avg`` (h_n, s)."""
    for i in range(gap.size):
        active[i] = gap[i] < 0.0
        force[i] = 0.0
        if not active[i]:
            continue
        p, q = lo[i], up[i]
        share = mass[p] / (mass[p] + mass[q])  # momentum weight of the lower node
        rel = v[q] - v[p]  # approach velocity (m/s), < 0 when closing
        v_mean = v[p] + (1.0 - share) * rel
        force[i] = -(1.0 + e) * share * mass[q] * rel / h_avg
        v[p] = v_mean + (1.0 - share) * e * rel
        v[q] = v_mean - share * e * rel
        w = share if mass_weighted else 0.5
        x = w * u[p] + (1.0 - w) * (u[q] + b[i])  # on the manifold u_lo = u_up + b
        u[p] = x
        u[q] = x - b[i]


@njit(cache=True)
def _merged_velocity(members, k, nodes, body, mass, v):
    """The velocity of a rigid body and the nodes of the first ``k`` constraints of
    ``members`` moving as one: v_c = (m_p v~_p + sum m_i v~_i) / (m_p + sum m_i) (m/s), the
    momentum average (paper eq. 8), summed in the order of ``members``. A fixed body
    (infinite mass) keeps its own velocity. The merge DME's cluster and the tie share."""
    if mass[body] == np.inf:
        return v[body]
    momentum = mass[body] * v[body]
    total = mass[body]
    for j in range(k):
        node = nodes[members[j]]
        momentum += mass[node] * v[node]
        total += mass[node]
    return momentum / total


@njit(cache=True)
def _join(members, k, b, nodes, body, side, m_over_dt, dt, u_now, v_c, u, v, force, active):
    """Move the body and the nodes of the first ``k`` constraints of ``members`` as one at
    v_c (m/s): the body to u_p^n + dt v_c, each node onto it, u_i = u_p + side b_i (m), its
    reaction force_i = m_i (side (v~_i - v_c)) / h_n (N, compressive-positive; the row
    ``m_over_dt``). The placement DME's cluster and the tie share."""
    u_body = u_now[body] + dt * v_c
    v[body] = v_c
    u[body] = u_body
    for j in range(k):
        i = members[j]
        node = nodes[i]
        active[i] = True
        force[i] = m_over_dt[node] * (side * (v[node] - v_c))
        v[node] = v_c
        u[node] = u_body + side * b[i]


@njit(cache=True)
def _cluster(gap, b, nodes, body, side, mass, m_over_dt, dt, u_now, u, v, force, active, work):
    """Case 1: the largest consistent set of penetrating nodes moves with the body.
    ``nodes``: each constraint's node slot; ``side`` +1 for a body above its nodes, -1
    below (the gap is b + side (u_body - u_node)); ``m_over_dt``: m / h_n per slot
    (kg/s); ``dt`` the position step h_{n+1/2} (s); ``work``: an int buffer of length n.
    A fixed body (infinite mass) keeps its velocity: the cluster's is the body's."""
    fixed = mass[body] == np.inf
    v_min = np.inf  # of side x v: the node most ready to leave the body
    n_cand = 0
    for i in range(gap.size):
        if gap[i] < 0.0:
            work[n_cand] = i
            n_cand += 1
            v_min = min(v_min, side * v[nodes[i]])
    cand = work[:n_cand]
    v_c = _merged_velocity(cand, n_cand, nodes, body, mass, v)
    if v_min >= side * v_c:  # no candidate would pull: all join (the usual case)
        order = cand
        k = cand.size
    elif fixed:  # the body's velocity is given: each candidate joins unless it pulls
        k = 0
        for j in range(n_cand):
            if side * v[nodes[cand[j]]] >= side * v_c:
                cand[k] = cand[j]
                k += 1
        order = cand
    else:
        # fastest towards the body first (allocates: rare)
        order = cand[np.argsort(-side * v[nodes[cand]], kind="mergesort")]
        momentum = mass[body] * v[body]
        total = mass[body]
        k = 0
        for j in range(order.size):
            node = nodes[order[j]]
            # holding it would pull: it and all slower stay free
            if side * v[node] < side * (momentum / total):
                break
            momentum += mass[node] * v[node]
            total += mass[node]
            k += 1
        v_c = momentum / total  # _merged_velocity of the first k, in the same order
    if k < gap.size:
        for i in range(gap.size):
            active[i] = False
            force[i] = 0.0
    _join(order, k, b, nodes, body, side, m_over_dt, dt, u_now, v_c, u, v, force, active)


@njit(cache=True)
def _velocity_gaps(held, cs, cc, v_pred, e, dt, vgap, vfree):
    """Case 3's velocity problem on the held set: w = (1 + e) dt G v~ + S phi >= 0,
    phi >= 0, phi . w = 0 (G v >= -e G v~: Newton's law where the constraint pushes;
    ``dt`` the position step h_{n+1/2} (s), the factor of S = h_{n+1/2} h_n G M^-1 G' that
    v = v~ + h_n M^-1 G' phi lacks). Zero off the held set; the held set is the start."""
    for i in range(held.size):
        vgap[i] = 0.0
        vfree[i] = held[i]
        if held[i]:
            gv = 0.0
            for k in range(cs.shape[1]):
                gv += cc[i, k] * v_pred[cs[i, k]]
            vgap[i] = (1.0 + e) * dt * gv


@njit(cache=True)
def _segments(nu, phi, held, cs, cc, mass, slot_free, h, h_avg, u, v, force, active):
    """Case 3: positions u~ + h_{n+1/2} h_n M^-1 G' nu, velocities v~ + h_n M^-1 G' phi
    (``h``, ``h_avg``: h_{n+1/2}, h_n in s); force = phi (N)."""
    for i in range(nu.size):
        active[i] = held[i]
        force[i] = phi[i]
        if not held[i]:
            continue
        for k in range(cs.shape[1]):
            s = cs[i, k]
            if slot_free[s] and cc[i, k] != 0.0:
                v[s] += h_avg * (cc[i, k] * phi[i]) / mass[s]
                u[s] += h * h_avg * (cc[i, k] * nu[i]) / mass[s]
