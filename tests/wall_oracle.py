"""The oracle of the fixed plane (impact_fenics/contact/plane.py): the former rigid wall.

The tests of the fixed plane compare one correction of it with this wall's own kernel,
kept here unchanged (its arithmetic is RigidWall's: one node at a time, each method a
closed form on the node's z):

Contact with a fixed rigid frictionless wall, the plane z = z_wall (normal +z): FILM, DME, penalty.

The body lies above the wall. Every node of the body's boundary is a
candidate, with its current position z = Z + u_z: a side node that folds onto
the wall (the mushroom of a Taylor bar) joins the active set the step it
reaches it. The wall has infinite mass, so each active node is corrected on
its own (the contact matrix is diagonal, S_ii = dt_{n+1/2} dt_avg / m_i), in
the normal (z) component only (frictionless):

* **FILM** (forward-increment Lagrange multiplier): the multiplier that puts a
  predicted penetration g~ = z~ - z_wall < 0 back on the wall,
  lambda_i = -m_i g~_i / (dt_{n+1/2} dt_avg) >= 0, i.e. u_z <- z_wall - Z and
  v_z <- v~_z - g~ / dt_{n+1/2}; a node whose prediction is open carries no
  force (lambda >= 0, g >= 0, lambda g = 0 exactly).
* **DME**: an active node joins the wall (infinite mass, restitution 0): its
  position is the wall's, its normal velocity the wall's (0).
* **Penalty** (paper eq. 5): a spring f_i = p_i max(0, -g~_i) (N) on the
  predicted penetration, in the velocity update of the step:
  v_z <- v~_z + dt_avg f_i / m_i, u_z <- u~_z + dt_{n+1/2} dt_avg f_i / m_i, so the
  committed gap is (1 - beta_i) g~_i with beta_i = p_i S_ii. Stability
  (contact/penalty.py, the isolated pair: the wall carries no stiffness, w = 0,
  so the bound is sharp) needs beta_i < 4/3; beta = 1 is FILM exactly. ``p`` is
  a stiffness in N/m, or ``"scaled"``: p_i = beta_target m_i / (dt_{n+1/2} dt_avg)
  with the current steps (beta_target = 1: FILM's correction as a spring).

None conserves what the wall does not: the wall takes momentum. The energy a
correction takes from the body (its kinetic change 1/2 (v^- + v) m (v - v~),
exactly the contact's share of the kinetic identity, see :func:`correct`) is
booked in ``contact_loss_local``: for FILM and DME it is the activation loss;
for penalty it is the spring's energy while the spring is loaded, returned
when the node leaves, so the summary splits it into the spring energy
1/2 p g~^2 of the active nodes (stored) and the rest (lost).
"""
from __future__ import annotations

import numpy as np
from numba import njit

_CODE = {"film": 0, "dme": 1, "penalty": 2}


def correct(nodes, Z, mass, z_wall, dt, dt_avg, method, p, f_int, u, v, force) -> tuple:
    """Correct the predicted penetrations of ``nodes`` (method 0 FILM, 1 DME, 2 penalty of
    stiffness ``p`` (N/m) per node). Returns (the energy the wall took from the body (J),
    the internal-work correction (J), number active, smallest predicted gap (m), spring
    energy 1/2 p g~^2 of the active nodes (J, penalty)); ``force`` receives the reaction
    m (v - v~) / dt_avg per node (N).

    With v^- = v~ + dt_avg f_int / m the velocity before the step, the kinetic energy of
    a node changes by 1/2 (v^- + v) m (v - v^-), split exactly into the internal force's
    dt_avg 1/2 (v^- + v) (-f_int) and the contact's 1/2 (v^- + v) m (v - v~): the energy
    taken is minus the latter, and the internal work booked with v~ gets
    dt_avg 1/2 (v - v~) f_int."""
    taken = 0.0
    w_fix = 0.0
    spring = 0.0
    n_active = 0
    g_min = np.inf
    for i in range(nodes.size):
        k = 2 * nodes[i] + 1
        gap = Z[i] + u[k] - z_wall
        if gap < g_min:
            g_min = gap
        if gap < 0.0:
            v_pred = v[k]
            if method == 0:
                v_new = v_pred - gap / dt
                u[k] = z_wall - Z[i]
            elif method == 1:
                v_new = 0.0
                u[k] = z_wall - Z[i]
            else:
                f = -p[i] * gap
                v_new = v_pred + dt_avg * f / mass[i]
                u[k] += dt * (v_new - v_pred)
                spring += 0.5 * p[i] * gap * gap
            v_old = v_pred + dt_avg * f_int[k] / mass[i]
            v[k] = v_new
            taken -= 0.5 * (v_old + v_new) * mass[i] * (v_new - v_pred)
            w_fix += 0.5 * dt_avg * (v_new - v_pred) * f_int[k]
            force[i] = mass[i] * (v_new - v_pred) / dt_avg
            n_active += 1
        else:
            force[i] = 0.0
    return taken, w_fix, n_active, g_min, spring


class RigidWall:
    """The wall z = ``z_wall`` (m) against owned local boundary ``nodes`` of reference heights
    ``Z`` (m) and lumped masses ``mass`` (kg); ``method`` 'film', 'dme' or 'penalty' with
    ``penalty`` a stiffness in N/m or 'scaled' (beta = ``beta_target`` at every step)."""

    def __init__(self, nodes: np.ndarray, Z: np.ndarray, mass: np.ndarray, method: str = "dme",
                 z_wall: float = 0.0, penalty: float | str = "scaled", beta_target: float = 1.0):
        # (the arguments are the tests' own: the plane checks a user's)
        self.nodes = np.ascontiguousarray(nodes, dtype=np.int64)
        self.Z = np.ascontiguousarray(Z, dtype=np.float64)
        self.mass = np.ascontiguousarray(mass, dtype=np.float64)
        self.method = method
        self.z_wall = float(z_wall)
        self.penalty = penalty
        self.beta_target = float(beta_target)
        self.p = np.zeros(self.nodes.size)  # N/m, per node (penalty)
        if method == "penalty" and not isinstance(penalty, str):
            self.p[:] = float(penalty)
        self.impulse = np.zeros(self.nodes.size)
        self.contact_loss_local = 0.0  # J, energy the wall took (cumulative, this rank)
        self.spring_energy_local = 0.0  # J, 1/2 p g~^2 of the active nodes (penalty)
        self.n_active_local = 0
        self.force_local = 0.0  # total reaction (N), this rank

    def beta_max_local(self, dt: float, dt_avg: float) -> float:
        """Largest beta_i = p_i dt dt_avg / m_i (-) of a penalty wall on this rank (0 without)."""
        if self.method != "penalty" or self.nodes.size == 0:
            return 0.0
        if isinstance(self.penalty, str):
            return self.beta_target
        return float(np.max(self.p / self.mass)) * dt * dt_avg

    def step(self, u: np.ndarray, v: np.ndarray, dt: float, dt_avg: float,
             f_int: np.ndarray) -> float:
        """Correct the predicted (u, v) (owned arrays, m and m/s) for the step dt_{n+1/2} (s);
        ``dt_avg`` the velocity update's step and ``f_int`` the internal force (N) of the
        step. Returns the correction of the internal work booked with the prediction (J)."""
        if self.method == "penalty" and isinstance(self.penalty, str):
            np.multiply(self.mass, self.beta_target / (dt * dt_avg), out=self.p)
        taken, w_fix, n, _, spring = correct(self.nodes, self.Z, self.mass, self.z_wall, dt,
                                             dt_avg, _CODE[self.method], self.p, f_int, u, v,
                                             self.impulse)
        self.contact_loss_local += taken
        self.spring_energy_local = spring
        self.n_active_local = n
        self.force_local = float(self.impulse.sum())
        return w_fix


def standalone_plane(Z, mass, u, v, method, z_wall=0.0, penalty="scaled", beta_target=1.0):
    """The fixed plane (contact/plane.py) on len(Z) nodes of this rank alone: heights ``Z``
    (m), masses ``mass`` (kg), the owned (r, z) arrays ``u``, ``v`` it corrects in place; the
    nodes' radii increase with their index, so the set's order is theirs."""
    from mpi4py import MPI

    from impact_fenics.contact.plane import FixedPlane

    n = len(Z)
    xy = np.stack([np.arange(n) * 1e-3, np.asarray(Z, dtype=float)], axis=1)
    per_dof = np.repeat(np.asarray(mass, dtype=float), 2)
    return FixedPlane(MPI.COMM_SELF, np.arange(n), xy, 0, per_dof, u, v, method, z_wall,
                      penalty=penalty, beta_target=beta_target)
