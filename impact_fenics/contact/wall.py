"""Contact with a fixed rigid frictionless wall, the plane z = z_wall (normal +z), by FILM or DME.

The body lies above the wall. Every node of the body's boundary is a
candidate, with its current position z = Z + u_z: a side node that folds onto
the wall (the mushroom of a Taylor bar) joins the active set the step it
reaches it. The wall has infinite mass, so each active node is corrected on
its own (the contact matrix is diagonal), in the normal (z) component only
(frictionless):

* **FILM** (forward-increment Lagrange multiplier): the multiplier that puts a
  predicted penetration g~ = z~ - z_wall < 0 back on the wall,
  lambda_i = -m_i g~_i / (dt_{n+1/2} dt_avg) >= 0, i.e. u_z <- z_wall - Z and
  v_z <- v~_z - g~ / dt_{n+1/2}; a node whose prediction is open carries no
  force (lambda >= 0, g >= 0, lambda g = 0 exactly).
* **DME**: an active node joins the wall (infinite mass, restitution 0): its
  position is the wall's, its normal velocity the wall's (0).

Both touch nothing but the z dofs of predicted-penetrating nodes and conserve
nothing the wall does not: the wall takes momentum. The energy the correction
removes, the activation loss, is booked exactly (see :func:`correct`): a node
resting on the wall (v^- = v = 0) books none, a node arriving books the
kinetic energy its normal velocity loses.
"""
from __future__ import annotations

import numpy as np
from numba import njit

METHODS = ("film", "dme")


@njit(cache=True)
def correct(nodes, Z, mass, z_wall, dt, dt_avg, dme, f_int, u, v, force) -> tuple:
    """Project the predicted penetrations of ``nodes`` onto the wall. Returns (activation
    loss (J), the internal-work correction (J), number active, smallest predicted gap (m));
    ``force`` receives the reaction m (v - v~) / dt_avg per node (N).

    With v^- = v~ + dt_avg f_int / m the velocity before the step, the kinetic energy of
    a node changes by 1/2 (v^- + v) m (v - v^-), split exactly into the internal force's
    dt_avg 1/2 (v^- + v) (-f_int) and the contact's 1/2 (v^- + v) m (v - v~): the loss
    is minus the latter, and the internal work booked with v~ gets dt_avg 1/2 (v - v~) f_int."""
    loss = 0.0
    w_fix = 0.0
    n_active = 0
    g_min = np.inf
    for i in range(nodes.size):
        k = 2 * nodes[i] + 1
        gap = Z[i] + u[k] - z_wall
        if gap < g_min:
            g_min = gap
        if gap < 0.0:
            v_pred = v[k]
            v_new = 0.0 if dme else v_pred - gap / dt
            v_old = v_pred + dt_avg * f_int[k] / mass[i]
            u[k] = z_wall - Z[i]
            v[k] = v_new
            loss -= 0.5 * (v_old + v_new) * mass[i] * (v_new - v_pred)
            w_fix += 0.5 * dt_avg * (v_new - v_pred) * f_int[k]
            force[i] = mass[i] * (v_new - v_pred) / dt_avg
            n_active += 1
        else:
            force[i] = 0.0
    return loss, w_fix, n_active, g_min


class RigidWall:
    """The wall z = ``z_wall`` (m) against owned local boundary ``nodes`` of reference heights
    ``Z`` (m) and lumped masses ``mass`` (kg); ``method`` 'film' or 'dme'."""

    def __init__(self, nodes: np.ndarray, Z: np.ndarray, mass: np.ndarray, method: str = "dme",
                 z_wall: float = 0.0):
        if method not in METHODS:
            from ..errors import InputError

            raise InputError(f"wall method = '{method}': use one of {', '.join(METHODS)}")
        self.nodes = np.ascontiguousarray(nodes, dtype=np.int64)
        self.Z = np.ascontiguousarray(Z, dtype=np.float64)
        self.mass = np.ascontiguousarray(mass, dtype=np.float64)
        self.method = method
        self.z_wall = float(z_wall)
        self.impulse = np.zeros(self.nodes.size)
        self.activation_loss_local = 0.0
        self.n_active_local = 0
        self.gap_min_local = np.inf
        self.force_local = 0.0  # total reaction (N), this rank

    def step(self, u: np.ndarray, v: np.ndarray, dt: float, dt_avg: float,
             f_int: np.ndarray) -> float:
        """Correct the predicted (u, v) (owned arrays, m and m/s) for the step dt_{n+1/2} (s);
        ``dt_avg`` the velocity update's step and ``f_int`` the internal force (N) of the
        step. Returns the correction of the internal work booked with the prediction (J)."""
        loss, w_fix, n, g = correct(self.nodes, self.Z, self.mass, self.z_wall, dt, dt_avg,
                                    self.method == "dme", f_int, u, v, self.impulse)
        self.activation_loss_local += loss
        self.n_active_local = n
        self.gap_min_local = g
        self.force_local = float(self.impulse.sum())
        return w_fix
