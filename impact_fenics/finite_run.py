"""A finite-strain explicit run: Q1 mean-dilatation bodies, a variable time step, a rigid wall.

The scheme with the velocity at half steps (DESIGN 10):

    v^{n+1/2} = v^{n-1/2} + 1/2 (dt_{n-1/2} + dt_{n+1/2}) M^-1 (f_ext^n - f_int(u^n)),
    u^{n+1}   = u^n + dt_{n+1/2} v^{n+1/2},

with dt_{-1/2} := dt_{1/2}. With a constant step it is the modified Euler scheme
of the Integrator (v^{n+1} = v^n + dt a^n, u^{n+1} = u^n + dt v^{n+1}). The
kinetic identity holds exactly for any f and any steps:

    1/2 |v^{n+1/2}|_M^2 - 1/2 |v^{n-1/2}|_M^2 = 1/2 (v^{n-1/2} + v^{n+1/2}) . dt_avg f^n,

so the ledger books the internal work W_int = sum dt_avg 1/2 (v^- + v~) . f_int and
the wall's activation loss the same way, and K + W_int + L = K_0 to round-off.
The stored energy plus the plastic work equal W_int up to the time
discretisation (O(dt^2), reported as ``work_gap``): the trapezoid of a
nonquadratic energy is not exact.

**The step follows the deformation.** Every ``dt_interval`` steps (default 10)
the stable limit is re-estimated from the current cells,
dt_lim = min_cells L / c with L = A / (largest diagonal) (h / sqrt 2 for a square
of side h) and c the material's elastic dilatational speed, and the step is
``safety`` x dt_lim (default 0.5; tests compare it with the converged
2 / omega_max of the linearised operator). With a fixed ``dt`` instead, the run
stops (UnstableRunError, exit 3 in a demo) once the current limit falls below it.
Δt is recorded in the history and its range in the summary.

Under MPI each rank updates the points of its owned cells; f_int's ghost
entries are summed into their owners, and u's ghosts are refreshed before each
force evaluation, so every rank count gives the same numbers (to the order of
floating-point sums).
"""
from __future__ import annotations

import csv
from dataclasses import dataclass

import numpy as np
from dolfinx import fem, mesh as dmesh
from mpi4py import MPI
from numba import njit

from . import compat
from .contact.wall import RigidWall
from .errors import UnstableRunError, require
from .internal_force.finite import FiniteStrainForce

HISTORY_COLUMNS = ("step", "time", "dt", "dt_limit", "kinetic", "internal_work", "activation_loss",
                   "stored", "plastic_work", "balance_error", "work_gap", "n_active", "j_min",
                   "eps_p_max", "length", "face_radius")


def quad_bar(comm: MPI.Comm, radius: float, length: float, n_r: int, n_z: int) -> dmesh.Mesh:
    """A cylinder 0 <= r <= radius, 0 <= z <= length (m) of n_r x n_z bilinear quadrilaterals."""
    require(radius > 0 and length > 0, "bar radius and length must be > 0 (m)")
    require(n_r >= 1 and n_z >= 1, "n_r and n_z must be >= 1")
    return dmesh.create_rectangle(comm, [np.array([0.0, 0.0]), np.array([radius, length])],
                                  [n_r, n_z], cell_type=dmesh.CellType.quadrilateral)


@dataclass
class FiniteSettings:
    """t_end (s); dt (s) fixed, or None for the adaptive step safety x dt_lim, re-estimated
    every dt_interval steps; history every history_every steps (bounded: decimated in memory)."""

    t_end: float = 80e-6
    dt: float | None = None
    safety: float = 0.5
    dt_interval: int = 10
    history_every: int = 10
    max_steps: int = 10_000_000
    ledger: bool = True
    snapshots: int = 8  # field outputs over the run (with fields_path), plus t = 0


@njit(cache=True)
def velocity_update(coef, f, v, dt_avg) -> float:
    """v += dt_avg coef f (coef = -1/m, 0 on fixed dofs); returns dt_avg 1/2 (v^- + v~) . f (J)."""
    work = 0.0
    for i in range(coef.size):
        vo = v[i]
        vn = vo + dt_avg * coef[i] * f[i]
        v[i] = vn
        work += 0.5 * dt_avg * (vo + vn) * f[i]
    return work


@njit(cache=True)
def trapezoid_work(f, u, f_prev, u_prev) -> float:
    """1/2 (f_prev + f) . (u - u_prev) (J), and stores f, u as the previous ones."""
    work = 0.0
    for i in range(f.size):
        work += 0.5 * (f_prev[i] + f[i]) * (u[i] - u_prev[i])
        f_prev[i] = f[i]
        u_prev[i] = u[i]
    return work


class FiniteFields:
    """XDMF fields on the reference mesh: displacement (m, nodal; Warp By Vector at scale 1
    shows the deformed body), and per cell the Cauchy stress sigma_rr, sigma_tt, sigma_zz,
    sigma_rz and von_mises (Pa, on the current configuration), eps_p_eq (-) and, for a
    material with one, the temperature (K)."""

    NAMES = ("sigma_rr", "sigma_tt", "sigma_zz", "sigma_rz", "von_mises", "eps_p_eq", "temperature")

    def __init__(self, run: "FiniteRun", path: str):
        from dolfinx import io

        self.run = run
        Q0 = compat.scalar_space(run.mesh, "DG", 0)
        self.fields = {k: fem.Function(Q0, name=k) for k in self.NAMES}
        n = run.force.geometry.dofs.shape[0]
        self.dofs = compat.cell_dofs(Q0).ravel()[run.force.geometry.cells[:n]].astype(np.intp)
        self.file = io.XDMFFile(run.comm, path, "w")
        self.file.write_mesh(run.mesh)

    def write(self, t: float) -> None:
        sig, eps, temp = self.run.force.cell_values()
        m = sig[:, :3].mean(axis=1)
        d = sig[:, :3] - m[:, None]
        vm = np.sqrt(1.5 * ((d * d).sum(axis=1) + 2.0 * sig[:, 3] ** 2))
        for k, vals in zip(self.NAMES, (sig[:, 0], sig[:, 1], sig[:, 2], sig[:, 3], vm, eps, temp)):
            self.fields[k].x.array[self.dofs] = vals
            self.fields[k].x.scatter_forward()
        self.run.u_fn.x.scatter_forward()
        self.file.write_function(self.run.u_fn, t)
        for f in self.fields.values():
            self.file.write_function(f, t)

    def close(self) -> None:
        self.file.close()


class FiniteRun:
    """One finite-strain body on a quadrilateral mesh, u_r = 0 on the axis, optionally a wall."""

    def __init__(self, mesh: dmesh.Mesh, material, settings: FiniteSettings,
                 velocity: tuple[float, float] = (0.0, 0.0), wall: str | None = None,
                 z_wall: float = 0.0, fixed_z: np.ndarray | None = None):
        require(mesh.topology.cell_type == dmesh.CellType.quadrilateral,
                "finite strain runs on quadrilateral meshes (Q1 mean dilatation)")
        require(getattr(material, "finite", False), "the material must be a finite-strain one")
        self.mesh, self.material, self.settings = mesh, material, settings
        self.comm = mesh.comm
        self.V = compat.vector_space(mesh, "Lagrange", 1)
        imap = self.V.dofmap.index_map
        self.n_owned_nodes = imap.size_local
        self.n_owned = 2 * imap.size_local
        self.node_xy = self.V.tabulate_dof_coordinates()[:, :2].copy()
        n_local_nodes = self.node_xy.shape[0]
        cells = np.arange(mesh.topology.index_map(2).size_local, dtype=np.int32)
        self.u_fn = fem.Function(self.V, name="displacement")
        self.u = self.u_fn.x.array  # owned + ghost
        self.u_owned = self.u[: self.n_owned]
        self.force = FiniteStrainForce(self.V, self.node_xy, cells, material, self.u_fn)
        # lumped mass (kg) per node, summed over ranks, on both components
        m_fn = fem.Function(self.V)
        m_nodes = self.force.geometry.lumped_mass(material.density, n_local_nodes)
        m_fn.x.array[0::2] = m_nodes
        m_fn.x.array[1::2] = m_nodes
        compat.scatter_add(m_fn.x)
        self.mass = m_fn.x.array[: self.n_owned].copy()
        hi = self.node_xy.max(axis=0) if n_local_nodes else np.full(2, -np.inf)
        lo = self.node_xy.min(axis=0) if n_local_nodes else np.full(2, np.inf)
        self.comm.Allreduce(MPI.IN_PLACE, hi, op=MPI.MAX)
        self.comm.Allreduce(MPI.IN_PLACE, lo, op=MPI.MIN)
        length, r_max = float(hi[1] - lo[1]), float(hi[0])
        self.length0, self.radius0 = length, r_max
        owned_xy = self.node_xy[: self.n_owned_nodes]
        free = np.ones(self.n_owned, dtype=bool)
        free[2 * np.flatnonzero(np.abs(owned_xy[:, 0]) <= 1e-12 * max(r_max, 1e-300))] = False
        if fixed_z is not None:
            free[2 * np.asarray(fixed_z) + 1] = False
        self.free = free
        self.coef = np.where(free, -1.0 / self.mass, 0.0)
        self.v = np.zeros(self.n_owned)
        self.v[0::2], self.v[1::2] = velocity
        self.v[~free] = 0.0
        self.wave_speed = material.wave_speed()
        # the wall: every owned boundary node is a candidate
        self.wall = None
        if wall is not None:
            tdim = mesh.topology.dim
            mesh.topology.create_connectivity(tdim - 1, tdim)
            facets = dmesh.exterior_facet_indices(mesh.topology)
            nodes = fem.locate_dofs_topological(self.V, tdim - 1, facets)
            nodes = np.sort(nodes[nodes < self.n_owned_nodes])
            self.wall = RigidWall(nodes, self.node_xy[nodes, 1], self.mass[2 * nodes + 1], wall, z_wall)
        # tracked nodes: the top of the axis (0, Z_max) and the lower corner (R, Z_min); the
        # length is measured from the wall (from Z_min without one)
        self._top = self._owned_node(0.0, float(hi[1]))
        self._corner = self._owned_node(r_max, float(lo[1]))
        self._z_base = z_wall if wall is not None else float(lo[1])
        self._f_prev = np.zeros(self.n_owned)
        self._u_prev = np.zeros(self.n_owned)

    def _owned_node(self, r: float, z: float) -> int:
        """The owned node at (r, z) (m), or -1 if another rank owns it."""
        xy = self.node_xy[: self.n_owned_nodes]
        if xy.size == 0:
            return -1
        d = np.hypot(xy[:, 0] - r, xy[:, 1] - z)
        k = int(np.argmin(d))
        return k if d[k] <= 1e-9 * max(self.length0, 1e-300) else -1

    # ------------------------------------------------------------ measures (every rank)
    def dt_limit(self) -> float:
        """Current stable estimate min L / c (s) over all ranks (before the safety factor)."""
        return self.comm.allreduce(self.force.length_min_local(), op=MPI.MIN) / self.wave_speed

    def tracked(self) -> tuple[float, float]:
        """(current length = z of the top axis node above the wall (m), current r of the node
        that started at (R, Z_min) (m))."""
        vals = np.array([-np.inf, -np.inf])
        if self._top >= 0:
            vals[0] = self.node_xy[self._top, 1] + self.u[2 * self._top + 1] - self._z_base
        if self._corner >= 0:
            vals[1] = self.node_xy[self._corner, 0] + self.u[2 * self._corner]
        self.comm.Allreduce(MPI.IN_PLACE, vals, op=MPI.MAX)
        return float(vals[0]), float(vals[1])

    def kinetic(self) -> float:
        return self.comm.allreduce(0.5 * float(np.dot(self.mass, self.v * self.v)))

    def eps_p_max(self) -> float:
        local = float(self.force.state[..., 0].max()) if self.force.state.size else 0.0
        return self.comm.allreduce(local, op=MPI.MAX)

    # ------------------------------------------------------------ the run
    def run(self, history_csv: str | None = None, fields_path: str | None = None) -> dict:
        """Step to t_end; history rows into ``history_csv`` and fields into ``fields_path``
        (XDMF) when given (rank 0 writes the CSV; the XDMF is collective)."""
        s, comm = self.settings, self.comm
        fields = FiniteFields(self, fields_path) if fields_path else None
        next_snapshot = 0.0
        clock = MPI.Wtime()
        require(s.t_end > 0, f"t_end = {s.t_end} s: must be > 0")
        require(s.dt is None or s.dt > 0, f"dt = {s.dt} s: must be > 0")
        require(0 < s.safety <= 1 and s.dt_interval >= 1, "safety in (0, 1], dt_interval >= 1")
        cap = 4096
        hist = np.zeros((cap, len(HISTORY_COLUMNS)))
        n_rows, stride = 0, s.history_every
        K0 = self.kinetic()
        w_int = loss = w_trap = 0.0
        t, dt_prev, dt_lim = 0.0, None, self.dt_limit()
        dts = [np.inf, 0.0]
        n = 0
        self.status = "running"
        while t < s.t_end * (1.0 - 1e-12):
            if n >= s.max_steps:
                raise UnstableRunError(f"more than {s.max_steps} steps before t_end = {s.t_end} s")
            if n % s.dt_interval == 0:
                dt_lim = self.dt_limit()
            if s.dt is None:
                dt = s.safety * dt_lim
            else:
                dt = s.dt
                if dt > dt_lim:
                    raise UnstableRunError(
                        f"run stopped at step {n} (t = {t:.6g} s): the fixed dt = {dt:.4g} s is above "
                        f"the current stable limit {dt_lim:.4g} s (elements flattened); use the "
                        "adaptive step (dt = None) or a smaller dt")
            dt = min(dt, s.t_end - t)
            dt_avg = dt if dt_prev is None else 0.5 * (dt_prev + dt)
            self.u_fn.x.scatter_forward()
            f = self.force.compute(dt_prev if dt_prev is not None else dt)
            w_trap += trapezoid_work(f, self.u_owned, self._f_prev, self._u_prev)
            if fields is not None and t >= next_snapshot * (1.0 - 1e-12):
                fields.write(t)  # u^n and the state of the force just computed at u^n
                next_snapshot += s.t_end / max(s.snapshots, 1)
            record = n % stride == 0
            if record:
                stored = comm.allreduce(self.force.stored_energy_local()) if s.ledger else 0.0
                wp = comm.allreduce(self.force.plastic_work_local)
                kin = self.kinetic()  # v^{n-1/2}
                wi = comm.allreduce(w_int)
                ls = comm.allreduce(loss)
                length, radius = self.tracked()
                n_act = comm.allreduce(self.wall.n_active_local) if self.wall else 0
                row = [n, t, dt, dt_lim, kin, wi, ls, stored, wp, kin + wi + ls - K0,
                       comm.allreduce(w_trap) - stored - wp, n_act, self.force.j_min,
                       self.eps_p_max(), length, radius]
                if n_rows == cap:  # keep memory bounded: every other row, double the stride
                    hist[: cap // 2] = hist[0:cap:2]
                    n_rows, stride = cap // 2, 2 * stride
                hist[n_rows] = row
                n_rows += 1
            w_int += velocity_update(self.coef, f, self.v, dt_avg)
            self.u_owned += dt * self.v
            if self.wall is not None:
                before = self.wall.activation_loss_local
                w_int += self.wall.step(self.u_owned, self.v, dt, dt_avg, f)
                loss += self.wall.activation_loss_local - before
            t += dt
            dt_prev = dt
            dts[0], dts[1] = min(dts[0], dt), max(dts[1], dt)
            n += 1
            if not np.isfinite(self.v[:8]).all():
                raise UnstableRunError(f"run diverged at step {n} (t = {t:.6g} s): velocity not finite")
        # the final state: force at u^N so that the state and the stored energy are current
        self.u_fn.x.scatter_forward()
        f = self.force.compute(dt_prev)
        w_trap += trapezoid_work(f, self.u_owned, self._f_prev, self._u_prev)
        if fields is not None:
            fields.write(t)
            fields.close()
        self.n_steps, self.t = n, t
        wall_time = comm.allreduce(MPI.Wtime() - clock, op=MPI.MAX)
        K = self.kinetic()
        stored = comm.allreduce(self.force.stored_energy_local())
        wp = comm.allreduce(self.force.plastic_work_local)
        wi, ls = comm.allreduce(w_int), comm.allreduce(loss)
        length, radius = self.tracked()
        self.history = {c: hist[:n_rows, i].copy() for i, c in enumerate(HISTORY_COLUMNS)}
        self.status = "completed"
        summary = {
            "status": self.status, "n_steps": n, "t_end": t, "n_ranks": comm.size,
            "n_cells": comm.allreduce(self.force.geometry.dofs.shape[0]),
            "dt_min": comm.allreduce(dts[0], op=MPI.MIN), "dt_max": comm.allreduce(dts[1], op=MPI.MAX),
            "dt_rule": "fixed" if s.dt is not None else
            f"{s.safety} x min(A / max diagonal) / c, every {s.dt_interval} steps",
            "initial_kinetic": K0, "kinetic": K, "stored_elastic": stored, "plastic_work": wp,
            "internal_work": wi, "activation_loss": ls,
            "kinetic_identity_error": (K + wi + ls - K0) / K0 if K0 else K + wi + ls,
            "work_gap": (comm.allreduce(w_trap) - stored - wp),
            "final_length": length, "final_face_radius": radius, "eps_p_max": self.eps_p_max(),
            "j_min": self.force.j_min, "wall_time": wall_time,
        }
        summary["element_steps_per_second"] = summary["n_cells"] * n / max(wall_time, 1e-300)
        if history_csv and comm.rank == 0:
            with open(history_csv, "w", newline="") as fh:
                w = csv.writer(fh)
                w.writerow(HISTORY_COLUMNS)
                w.writerows(np.column_stack([self.history[c] for c in HISTORY_COLUMNS]).tolist())
        return summary
