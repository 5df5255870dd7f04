"""A fixed plane z = z_wall below a body (normal +z), as a contact set with a fixed rigid part.

The body lies above the plane. Its candidates are nodes of its boundary with their
current heights z = Z + u_z: a side node that folds onto the plane (the mushroom of a
Taylor bar) joins the active set the step it reaches it. Constraint i is

    g_i = (Z_i - z_wall) + u_z,i >= 0      (m),

a node above the plane's slot (:class:`~.interface.ContactSet` with the rigid part
below its nodes). The plane is a fixed rigid part: zero inverse mass, so kappa = 0, S
is diagonal (S_ii = h_{n+1/2} h_n / m_i) and no method moves it. Each node is
corrected in its normal (z) component only (frictionless), by the set's kernels:
FILM puts a predicted penetration back on the plane, DME joins the node to it
(velocity 0, restitution 0), penalty pushes it with a spring p_i max(0, -g~_i) (N),
p in N/m or ``"scaled"`` (beta = ``beta_target`` at every step, p_i = beta m_i /
(h_{n+1/2} h_n)). Velocities move by h_n f / m, positions by h_{n+1/2} times that.

The set gathers the candidates on every rank (one Allgatherv), corrects them in one
compiled call and writes back the owned ones; :meth:`FixedPlane.step` then books, on
the owned candidates, the contact's share of the half-step scheme's kinetic identity
(state.kinetic_share): the energy the plane took (``contact_loss_local``), the
correction of the internal work booked with the prediction, the number active, the
reaction (N) and the springs' energy 1/2 p g~^2 (penalty: stored while loaded, returned
when the node leaves).
"""
from __future__ import annotations

import numpy as np
from dolfinx import fem, mesh as dmesh
from mpi4py import MPI

from ..errors import InputError
from ..geometry import AXISYMMETRIC_GEOMETRY
from .dme import DME
from .film import FILM
from .interface import ContactSet, RigidBody
from .pairing import Constraints
from .penalty import STABILITY_BOUND, Penalty
from .state import kinetic_share

METHODS = ("film", "dme", "penalty")


def boundary_nodes(V, n_owned_nodes: int) -> np.ndarray:
    """The owned nodes (local indices, sorted) on the exterior boundary of V's mesh: a
    plane's candidates (a side node that folds onto it joins the step it reaches it)."""
    mesh = V.mesh
    tdim = mesh.topology.dim
    mesh.topology.create_connectivity(tdim - 1, tdim)
    facets = dmesh.exterior_facet_indices(mesh.topology)
    nodes = fem.locate_dofs_topological(V, tdim - 1, facets)
    return np.sort(nodes[nodes < n_owned_nodes])


def plane_below(comm: MPI.Comm, nodes: np.ndarray, node_xy: np.ndarray, offset: int,
                z_wall: float, length: float) -> Constraints:
    """The constraints g_i = (Z_i - z_wall) + u_z,i >= 0 (m) of the owned ``nodes`` (their
    reference coordinates in ``node_xy``, m; owned dofs (r, z) pairs from global dof
    ``offset``) against the plane z = ``z_wall`` below them, in one global order on every
    rank (by r, then Z). Refused if the plane cuts the body (a node below it by more than
    1e-12 of the body's ``length``, m)."""
    xy = node_xy[nodes]
    dofs = offset + 2 * np.asarray(nodes, dtype=np.int64) + 1
    gap = comm.allreduce(float((xy[:, 1] - z_wall).min(initial=np.inf)), op=MPI.MIN)
    if gap < -1e-12 * length:
        raise InputError(f"the wall z = {z_wall:.6g} m cuts the body (its lowest boundary "
                         f"node is at z = {z_wall + gap:.6g} m): the body must start above it")
    if comm.size > 1:
        xy = np.concatenate(comm.allgather(xy)).reshape(-1, 2)
        dofs = np.concatenate(comm.allgather(dofs))
    order = np.lexsort((xy[:, 1], xy[:, 0]))
    xy, dofs = xy[order], dofs[order].astype(np.int64)
    return Constraints(r=xy[:, 0].copy(), b=xy[:, 1] - z_wall, lower=None, upper=dofs,
                       names=("boundary", "wall"))


def wall_part() -> RigidBody:
    """The plane as a rigid part: fixed (zero inverse mass: no method moves it)."""
    return RigidBody("wall", 1.0, fixed=True)


class _Host:
    """What a contact set reads of the loop that drives it: the owned displacement and
    velocity (m, m/s) and lumped masses (kg, per dof), the first owned global dof
    (``offset``) and their number, the communicator, the step's start time and index."""

    def __init__(self, comm: MPI.Comm, offset: int, mass: np.ndarray, u_owned: np.ndarray,
                 v_owned: np.ndarray, dt: float, fixed: np.ndarray | None = None):
        self.model = self  # (comm, offset, n_owned: what the gather reads of a model)
        self.geometry = AXISYMMETRIC_GEOMETRY  # the finite-strain wall's bodies: (r, z)
        self.comm, self.offset, self.n_owned = comm, int(offset), int(mass.size)
        self.mass, self.u_owned, self.v_owned = mass, u_owned, v_owned
        self.dt, self.t, self.n = float(dt), 0.0, 0
        fixed = np.zeros(0, dtype=np.int64) if fixed is None else np.asarray(fixed, np.int64)
        self.fixed = fixed[fixed < self.n_owned]  # owned dofs held by the body (the axis's r)


class FixedPlane:
    """The plane z = ``z_wall`` (m) against owned local ``nodes`` (owned node indices of a
    vector P1/Q1 space, reference coordinates ``node_xy``, m) of a body whose owned dofs
    are (r, z) pairs from global dof ``offset``, lumped masses ``mass`` (kg, per owned
    dof) and state ``u_owned``, ``v_owned``; ``method`` 'film', 'dme' or 'penalty' with
    ``penalty`` a stiffness in N/m or 'scaled' (beta = ``beta_target``); ``dt`` the first
    step (s; :meth:`step` sets each step's), ``length`` (m) the body's (the cut check's
    scale, :func:`plane_below`)."""

    def __init__(self, comm: MPI.Comm, nodes: np.ndarray, node_xy: np.ndarray, offset: int,
                 mass: np.ndarray, u_owned: np.ndarray, v_owned: np.ndarray, method: str = "dme",
                 z_wall: float = 0.0, penalty: float | str = "scaled", beta_target: float = 1.0,
                 dt: float = 1.0, length: float = 1.0, friction=None,
                 fixed: np.ndarray | None = None):
        if method not in METHODS:
            raise InputError(f"wall method = '{method}': use one of {', '.join(METHODS)}")
        if isinstance(penalty, str) and penalty != "scaled":
            raise InputError(f"wall penalty = '{penalty}': give a stiffness in N/m or 'scaled'")
        if not isinstance(penalty, str) and not penalty > 0:
            raise InputError(f"wall penalty = {penalty} N/m: must be > 0")
        if not 0 < beta_target < STABILITY_BOUND:
            raise InputError(f"wall beta_target = {beta_target}: must lie in (0, 4/3)")
        self.method, self.z_wall = method, float(z_wall)
        self.penalty, self.beta_target = penalty, float(beta_target)
        self.nodes = np.ascontiguousarray(nodes, dtype=np.int64)
        self.mass = mass[2 * self.nodes + 1].copy()  # kg, the owned candidates'
        cons = plane_below(comm, self.nodes, node_xy, offset, self.z_wall, length)
        self._xy = node_xy[self.nodes].copy()  # m, the candidates' reference (r, z)
        self._node_r = np.array(node_xy[:, 0])  # m, every local node's reference r
        chosen = {"film": lambda: FILM("fast"), "dme": lambda: DME(),
                  "penalty": lambda: Penalty(penalty, beta_target=beta_target)}[method]()
        self._host = _Host(comm, offset, mass, u_owned, v_owned, dt, fixed)
        self.set = ContactSet(cons, self._host, chosen, wall_part())
        if friction is not None:
            if method == "penalty":
                raise InputError("[wall] friction with method = \"penalty\": the tangential "
                                 "spring is not built for a finite-strain body (use film or dme)")
            self.set.set_friction(friction)
        self.friction = self.set.friction  # the tangential pass (contact/friction.py) or None
        self.set.initialize()
        from ..jit_watch import load

        load(kinetic_share, self.set._local, self.set._pos, mass, 1.0, *self._share_rows())
        if self.friction is not None:
            # the r slots' masses as they are (the pass keeps inf on a held r dof, which
            # the kinetic share would multiply by its zero velocity change)
            f = self.friction
            self._r_mass = np.ones(f.mass.size)
            f._gather(mass, mass, self._r_mass[:self.set.n_deformable],
                      np.empty(self.set.n_deformable))
            load(kinetic_share, f._local, f._pos, mass, 1.0, *self._r_share_rows())
        self.contact_loss_local = 0.0  # J, energy the plane took (cumulative, this rank)
        self.spring_energy_local = 0.0  # J, 1/2 p g~^2 of the active nodes (penalty)
        self.n_active_local = 0
        self.force_local = 0.0  # total reaction (N), this rank

    def _share_rows(self) -> tuple:
        c = self.set
        return c.mass, c.u_pred, c.v_pred, c.v_now, c.b, c.lo, c.up, c.p, c.active

    def _r_share_rows(self) -> tuple:
        c, f = self.set, self.friction
        return (self._r_mass, f.u_pred, f.v_pred, f.v_now, c.b, c.lo, c.up, c.p, c.active[:0])

    def beta_max_local(self, dt: float, dt_avg: float) -> float:
        """Largest beta_i = p_i dt dt_avg / m_i (-) of a penalty plane (0 for another
        method; the set is replicated: every rank gives the same)."""
        if self.method != "penalty":
            return 0.0
        if isinstance(self.penalty, str):
            return self.beta_target
        self.set.set_step(dt, dt_avg)
        return self.set.penalty_beta()

    def step(self, u: np.ndarray, v: np.ndarray, dt: float, dt_avg: float,
             f_int: np.ndarray) -> float:
        """Correct the predicted (u, v) (the owned arrays given at set-up, m and m/s) for the
        step dt = h_{n+1/2} (s), ``dt_avg`` = h_n the velocity update's step and ``f_int``
        the internal force (N) of the step. Returns the correction of the internal work
        booked with the prediction (J)."""
        c = self.set
        c.set_step(dt, dt_avg)
        c.step()
        self._host.n += 1
        taken, w_fix, n, force, spring = c.kinetic_share(f_int)
        if self.friction is not None:  # the r slots' share: the tangential pass's
            f = self.friction
            taken_r, w_fix_r, _, _, _ = kinetic_share(f._local, f._pos, f_int, dt_avg,
                                                      *self._r_share_rows())
            taken += taken_r
            w_fix += w_fix_r
        self.contact_loss_local += taken
        self.spring_energy_local = spring
        self.n_active_local = n
        self.force_local = force
        return w_fix

    def contact_radius(self, u: np.ndarray) -> float:
        """The current r (m) of the outermost node in contact (active on the plane) over all
        ranks, from the owned displacement ``u`` (m); 0 with none."""
        c = self.set
        z_dofs = c._local[c.active[c._pos]]  # owned z dofs of the active constraints
        r = self._node_r[(z_dofs - 1) // 2] + u[z_dofs - 1]
        return self._host.comm.allreduce(float(r.max(initial=0.0)), op=MPI.MAX)

    def foot_radius(self, u: np.ndarray, h: float) -> float:
        """The largest current r (m) of any candidate node within ``h`` (m) of the plane
        (z - z_wall <= h) over all ranks, from the owned displacement ``u`` (m)."""
        z = self._xy[:, 1] + u[2 * self.nodes + 1] - self.z_wall
        r = self._xy[:, 0] + u[2 * self.nodes]
        near = r[z <= h]
        return self._host.comm.allreduce(float(near.max(initial=0.0)), op=MPI.MAX)


def contact_radius(cset, node_xy: np.ndarray, u: np.ndarray, comm: MPI.Comm) -> float:
    """The current r (m) of the outermost node in contact (active) with the plane of the
    set ``cset`` (:func:`plane_below`'s constraints) over all ranks, from the owned
    displacement ``u`` (m) and the local nodes' reference ``node_xy`` (m); 0 with none."""
    z_dofs = cset._local[cset.active[cset._pos]]  # owned z dofs of the active constraints
    r = node_xy[(z_dofs - 1) // 2, 0] + u[z_dofs - 1]
    return comm.allreduce(float(r.max(initial=0.0)), op=MPI.MAX)


def foot_radius(nodes: np.ndarray, node_xy: np.ndarray, u: np.ndarray, z_wall: float, h: float,
                comm: MPI.Comm) -> float:
    """The largest current r (m) of the owned ``nodes`` within ``h`` (m) of the plane
    z = ``z_wall`` (m) (z - z_wall <= h) over all ranks, from the owned displacement ``u``
    (m) and the reference ``node_xy`` (m)."""
    z = node_xy[nodes, 1] + u[2 * nodes + 1] - z_wall
    r = node_xy[nodes, 0] + u[2 * nodes]
    return comm.allreduce(float(r[z <= h].max(initial=0.0)), op=MPI.MAX)
