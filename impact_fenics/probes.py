"""Point probes: a field's value at a point (stresses in the cell that holds it: DG0, as
CST gives it).

A probe reads the six displacement dofs of its triangle's three nodes: each rank
copies the ones it owns into the history row (one compiled call for all probes,
no communication), the rows are summed over the ranks once per block of rows,
and the values follow from the dofs. In the cell of a linear body the stress is
:func:`~impact_fenics.cell_fields.triangle_strain` and the material's constant
stiffness D, the value a UFL Expression of the stress gives at the cell's
midpoint, to round-off. u_r and u_z are the P1 interpolation at the point,
sum_a w_a u_a with w_a the point's barycentric coordinates in its triangle (fixed at
set-up): the field's own value there, the same whichever of the cells touching a
point on a cell edge holds it.

In a quadrilateral (Q1) cell the row holds the eight dofs of its four nodes; u_r
and u_z are the Q1 interpolation at the point, sum_a N_a(xi) u_a with xi the
point's reference coordinates (the inverse bilinear map, :func:`.q1.reference_point`,
solved once at set-up: the weights N_a(xi) are fixed), and a linear body's stress is
D times the cell's ring-weighted mean strain (:func:`.q1.mean_strain`), the cell
value of the fields.

In the cell of a path-dependent body the row also holds the state of the cell's
three points (plastic strain, the material's variables, stress) as the owning
rank's last update left it, the update at the step's start. From the summed row
the block's finish runs the points' update at the row's displacement (the
force's own compiled cell kernel on that one cell: what the next step computes
there), so the probe's stress is the weighted mean of the point stresses
(:func:`~impact_fenics.cell_fields.point_mean_stress`), as in the fields, and
``eps_p_eq`` and ``yielded`` are of the same state: the mean equivalent plastic
strain of the points and 1 if one has yielded.

``r`` and ``z`` are node probes: the current position X + u (m) of the node nearest
the point among the nodes of the body whose cell holds it (a tie goes to the smaller
(r, z), the same on every partition). The rank that owns the node records its two
dofs; X is known on every rank from set-up.

A ``strain_gauge`` reads the axial strain over a gauge length l (m) centred at its point
(r, z), as a bonded gauge on a bar's surface does (r = the bar's radius R,
:func:`outer_radius`):

    eps = (u_z(r, z + l/2) - u_z(r, z - l/2)) / l        (-; compression negative)

each u_z the interpolation at the gauge's end, sum_a w_a u_z,a over the nodes of the
cell that holds it (barycentric weights on a triangle, N_a(xi) on a quadrilateral,
fixed at set-up): the row holds the u_z dofs of the lower end's cell, then the upper's.
Both ends lie in one body.

A ``section`` is the axial force (N, compression positive) through the plane z = const
of a row of a linear body's nodes, F_s = c . u (:mod:`.section`: the z force the cells
below exert on the plane's nodes, whose impulse with the other forces on the nodes at and
above the plane is their change of z momentum). The row holds the u of the dofs of c,
after the probes' cell dofs; the value is its dot product with c, in the same order on
every partition.
"""
from __future__ import annotations

import functools

import numpy as np
from mpi4py import MPI
from numba import njit

from . import q1
from .cell_fields import (STRESS_NAMES, point_mean_stress, stiffness_matrix, stress_outputs,
                          triangle_strain, von_mises)
from .compat import colliding_cells, geometry_dofs
from .errors import InputError
from .jit_watch import direct, load
from .section import section_body, section_row

PLASTIC_QUANTITIES = ("eps_p_eq", "yielded")
POSITION_QUANTITIES = ("r", "z")  # a node's current position X + u (m)
GAUGE = "strain_gauge"  # the axial strain over a gauge length (-)
GAUGE_LENGTH = 2e-3  # the default gauge length (m)
SECTION = "section"  # the axial force through a plane of nodes (N, compression positive)
QUANTITIES = (STRESS_NAMES + ("u_r", "u_z") + PLASTIC_QUANTITIES + POSITION_QUANTITIES
              + (GAUGE, SECTION))
# raw history entries per probe: u_r, u_z of the cell's three nodes (four on a mesh of
# quadrilaterals: RAW_Q1), of its one node first for r and z, u_z of the three (four)
# nodes of each end's cell for a gauge; a probe in a cell of a
# path-dependent body has its points' state after all of them (CellPoints.size)
RAW = 6
RAW_Q1 = 8
_U_R, _U_Z = QUANTITIES.index("u_r"), QUANTITIES.index("u_z")
_R = QUANTITIES.index("r")  # r, z: codes _R, _R + 1
_GAUGE = QUANTITIES.index(GAUGE)
_SECTION = QUANTITIES.index(SECTION)


def nearest_node(model, body: str, point: tuple[float, float]) -> tuple[int, np.ndarray | None]:
    """Local index of the node of ``body`` nearest ``point`` (r, z) in m and its (r, z), on
    the rank that owns it (-1 and None on the others); ties go to the smaller (r, z)
    (collective). The coordinates are the mesh's own (its geometry), not the dof
    coordinates, which the geometry map recomputes with round-off."""
    n_owned = model.n_owned // model.bs
    cells = model.tmesh.cells(body)
    # P1 and Q1: a cell's dofs are its vertices, in the order of its geometry's nodes
    nodes = model.cell_dofs[cells].ravel()
    xy = model.mesh.geometry.x[geometry_dofs(model.mesh)[cells].ravel(), :2]
    keep = nodes < n_owned
    nodes, xy = nodes[keep], xy[keep]
    best = (np.inf, np.inf, np.inf)
    if nodes.size:
        d2 = (xy[:, 0] - point[0]) ** 2 + (xy[:, 1] - point[1]) ** 2
        k = int(np.lexsort((xy[:, 1], xy[:, 0], d2))[0])
        best = (float(d2[k]), float(xy[k, 0]), float(xy[k, 1]))
    winner = min(model.comm.allgather(best))
    if nodes.size and best == winner:
        return int(nodes[k]), xy[k].copy()
    return -1, None


def locate_cell(mesh, point: tuple[float, float],
                axes: tuple[str, str] = ("r", "z")) -> tuple[int, bool]:
    """Local index of the cell holding ``point`` (r, z) in m, and whether this rank owns it
    (``axes`` name the coordinates in the message of a point outside the mesh).

    A point on a cell boundary belongs to the touching cell whose midpoint is
    smallest in (r, z): the same choice for every partition."""
    x = np.array([[point[0], point[1], 0.0]])
    n_owned = mesh.topology.index_map(mesh.topology.dim).size_local
    cells = colliding_cells(mesh, x).links(0)
    cells = np.asarray([c for c in cells if c < n_owned], dtype=np.int32)
    best = (np.inf, np.inf)
    if cells.size:
        mids = _midpoints(mesh, cells)
        k = int(np.lexsort((mids[:, 1], mids[:, 0]))[0])
        best = (float(mids[k, 0]), float(mids[k, 1]))
        cell = int(cells[k])
    winner = min(mesh.comm.allgather(best))
    if not np.isfinite(winner[0]):
        raise InputError(f"probe point ({axes[0]}={point[0]}, {axes[1]}={point[1]}) m lies "
                         "outside the mesh")
    mine = cells.size > 0 and best == winner
    return (cell if mine else -1), mine


def outer_radius(mesh, z: float) -> float:
    """The mesh's outer radius (m) at the height ``z`` (m): the largest r at which a cell
    meets the line z = const, where a surface gauge sits (collective; -inf if no cell
    does). A cell meets it on the segments between its nodes that cross it."""
    x = mesh.geometry.x[geometry_dofs(mesh)]  # (cells, nodes, 3)
    best = -np.inf
    n = x.shape[1]
    for a in range(n):
        for b in range(a + 1, n):
            ra, za, rb, zb = x[:, a, 0], x[:, a, 1], x[:, b, 0], x[:, b, 1]
            crossing = (za - z) * (zb - z) <= 0.0
            level = crossing & (za == zb)  # a segment along the line: its outer end
            if np.any(level):
                best = max(best, float(np.max(np.maximum(ra[level], rb[level]))))
            slant = crossing & (za != zb)
            if np.any(slant):
                r = ra[slant] + (z - za[slant]) * (rb[slant] - ra[slant]) / (zb[slant] - za[slant])
                best = max(best, float(np.max(r)))
    return mesh.comm.allreduce(best, op=MPI.MAX)


def _midpoints(mesh, cells: np.ndarray) -> np.ndarray:
    from dolfinx.mesh import compute_midpoints

    return compute_midpoints(mesh, mesh.topology.dim, cells)[:, :2]


@njit(cache=True)
def _record_at(u_owned, index, block, offset) -> None:
    """block[offset + k] = u_owned[index[k]] for the dofs this rank owns (index >= 0)."""
    for k in range(index.size):
        if index[k] >= 0:
            block[offset + k] = u_owned[index[k]]


@njit(cache=True)
def _record_points(eps_p, state, sigma, pos, row, start) -> None:
    """The state of the points of cell ``pos`` (eps_p (3, 4), state (3, n_state), sigma
    (3, 4)) into row[start:], in that order (:func:`_unpack_points` reads it back)."""
    k = start
    for q in range(eps_p.shape[1]):
        for i in range(eps_p.shape[2]):
            row[k] = eps_p[pos, q, i]
            k += 1
    for q in range(state.shape[1]):
        for i in range(state.shape[2]):
            row[k] = state[pos, q, i]
            k += 1
    for q in range(sigma.shape[1]):
        for i in range(sigma.shape[2]):
            row[k] = sigma[pos, q, i]
            k += 1


@njit(cache=True)
def _unpack_points(row, u_start, start, u, eps_p, state, sigma) -> None:
    """The nodal displacements row[u_start:u_start + u.size] into u and the points' state
    recorded by :func:`_record_points` at row[start:] into the one-cell arrays."""
    for i in range(u.size):
        u[i] = row[u_start + i]
    k = start
    for q in range(eps_p.shape[1]):
        for i in range(eps_p.shape[2]):
            eps_p[0, q, i] = row[k]
            k += 1
    for q in range(state.shape[1]):
        for i in range(state.shape[2]):
            state[0, q, i] = row[k]
            k += 1
    for q in range(sigma.shape[1]):
        for i in range(sigma.shape[2]):
            sigma[0, q, i] = row[k]
            k += 1


@njit(cache=True)
def _point_value(sigma, state, w, code, cells, mean) -> float:
    """The probe value ``code`` (QUANTITIES) of the one-cell point state: the weighted mean
    stress (Pa; ``mean`` (5, 1) scratch), the mean eps_bar_p or the yielded flag."""
    if code < 5:
        point_mean_stress(sigma, w, cells, mean)
        if code < 4:
            return mean[code, 0]
        return von_mises(mean[0, 0], mean[2, 0], mean[1, 0], mean[3, 0])
    n = state.shape[1]
    if code == 7:
        e = 0.0
        for q in range(n):
            e += state[0, q, 0]
        return e / n
    for q in range(n):
        if state[0, q, 0] > 0.0:
            return 1.0
    return 0.0


@njit(cache=True)
def _gauge_strain(q, w, length) -> float:
    """A gauge's strain (u_z(upper end) - u_z(lower end)) / length (-): the row ``q`` holds
    the u_z of the lower end's cell nodes then the upper's (m), ``w`` their interpolation
    weights at the ends, ``length`` the gauge length (m)."""
    half = w.size // 2
    lower = 0.0
    upper = 0.0
    for a in range(half):
        lower += w[a] * q[a]
        upper += w[half + a] * q[half + a]
    return (upper - lower) / length


@njit(cache=True)
def _section_force(raw, start, c, p, out) -> None:
    """out[i, p] = sum_j c[j] raw[i, start + j]: a section's force (N) from the u (m) of
    its dofs in each row and its coefficients c (N/m), summed in c's order."""
    for i in range(raw.shape[0]):
        f = 0.0
        for j in range(c.size):
            f += c[j] * raw[i, start + j]
        out[i, p] = f


@njit(cache=True)
def _values(raw, xy, point_w, D, code, pointwise, X, gauge_w, gauge_l, out, plane) -> None:
    """Probe values of each row of ``raw`` (rows x n_raw, RAW per probe first): u_r and u_z
    the interpolation sum_a point_w[p, a] u_a at the point (m); in the cell of a linear
    body a stress D eps (Pa), eps_p_eq and yielded 0; r and z the node's X[p] + u (m); a
    gauge's strain from its ends' barycentric weights gauge_w[p] and length gauge_l[p]
    (m); a section is left to :func:`_section_force`; the other values of a probe in a
    path-dependent body's cell (``pointwise`` true) are left to :class:`CellPoints`.
    ``plane``: plane strain, the strain out of the plane 0 (no hoop term u_r / r)."""
    for i in range(raw.shape[0]):
        for p in range(code.size):
            q = raw[i, RAW * p: RAW * p + RAW]
            c = code[p]
            if c == _SECTION:  # (Probes.values)
                continue
            if c == _GAUGE:
                out[i, p] = _gauge_strain(q, gauge_w[p], gauge_l[p])
            elif c >= _R:
                out[i, p] = X[p, c - _R] + q[c - _R]
            elif c == _U_R or c == _U_Z:
                k = c - _U_R
                out[i, p] = (point_w[p, 0] * q[k] + point_w[p, 1] * q[k + 2]
                             + point_w[p, 2] * q[k + 4])
            elif pointwise[p]:
                continue
            elif c > _U_Z:  # eps_p_eq, yielded
                out[i, p] = 0.0
            else:
                e = triangle_strain(xy[p, 0, 0], xy[p, 0, 1], xy[p, 1, 0], xy[p, 1, 1],
                                    xy[p, 2, 0], xy[p, 2, 1], q[0], q[1], q[2], q[3], q[4], q[5],
                                    plane)
                out[i, p] = stress_outputs(D[p], e[0], e[1], e[2], e[3])[c]


@njit(cache=True)
def _quad_values(raw, weights, dNdR, dNdZ, N, inv_R, w, dofs, eps, D, code, pointwise, X,
                 gauge_w, gauge_l, out) -> None:
    """:func:`_values` in Q1 cells (RAW_Q1 per probe first): u_r and u_z the Q1
    interpolation sum_a weights[p, a] u_a at the point (m); a linear body's stress D times
    the cell's mean strain (Pa; the one-cell geometry of probe p: dNdR[p], ... of
    :class:`.q1.QuadGeometry`); r and z the node's X[p] + u (m); a gauge's strain from
    its ends' weights N_a(xi) gauge_w[p] and length gauge_l[p] (m)."""
    for i in range(raw.shape[0]):
        for p in range(code.size):
            q = raw[i, RAW_Q1 * p: RAW_Q1 * p + RAW_Q1]
            c = code[p]
            if c == _SECTION:  # (Probes.values)
                continue
            if c == _GAUGE:
                out[i, p] = _gauge_strain(q, gauge_w[p], gauge_l[p])
            elif c >= _R:
                out[i, p] = X[p, c - _R] + q[c - _R]
            elif c == _U_R or c == _U_Z:
                k = c - _U_R
                out[i, p] = (weights[p, 0] * q[k] + weights[p, 1] * q[k + 2]
                             + weights[p, 2] * q[k + 4] + weights[p, 3] * q[k + 6])
            elif pointwise[p]:
                continue
            elif c > _U_Z:  # eps_p_eq, yielded
                out[i, p] = 0.0
            else:
                q1.mean_strain(dofs, dNdR[p: p + 1], dNdZ[p: p + 1], N, inv_R[p: p + 1],
                               w[p: p + 1], q, eps)
                out[i, p] = stress_outputs(D[p], eps[0, 0], eps[0, 1], eps[0, 2], eps[0, 3])[c]


def interpolation_weights(X: np.ndarray, point) -> np.ndarray:
    """The weights w_a of the nodes X (3 or 4, 2) (m) of a triangle (barycentric
    coordinates) or a quadrilateral (N_a(xi), xi the point's reference coordinates) at
    ``point`` (r, z) (m): u(point) = sum_a w_a u_a, exact for a linear field."""
    x = np.asarray(point, dtype=float)
    if X.shape[0] == 4:
        return q1.shape_functions(q1.reference_point(X, x)[None, :])[0][0]
    lam = np.linalg.solve(np.column_stack([X[1] - X[0], X[2] - X[0]]), x - X[0])
    return np.array([1.0 - lam[0] - lam[1], lam[0], lam[1]])


class _QuadCells:
    """The Q1 data of the probes' cells, on every rank: the interpolation weights N_a(xi)
    (n, 4) at each point and the one-cell geometry of :class:`.q1.QuadGeometry`."""

    def __init__(self, n: int):
        self.weights = np.zeros((n, 4))
        self.dNdR = np.zeros((n, 4, 4))
        self.dNdZ = np.zeros((n, 4, 4))
        self.inv_R = np.zeros((n, 4))
        self.w = np.zeros((n, 4))
        self.N = np.ascontiguousarray(q1.shape_functions(q1.GAUSS)[0])
        self.dofs = np.arange(4).reshape(1, 4)  # one cell's nodes, numbered 0..3
        self.eps = np.zeros((1, 4))  # its mean strain (scratch)

    def fill(self, k: int, cell_nodes: np.ndarray, node_xy: np.ndarray, cell: int, point,
             geometry) -> None:
        """Probe k's entries from its cell (local index) on the owning rank."""
        g = q1.QuadGeometry(cell_nodes, node_xy, np.array([cell], dtype=np.int32), geometry)
        self.weights[k] = interpolation_weights(node_xy[g.dofs[0]], point)
        self.dNdR[k], self.dNdZ[k] = g.dNdR[0], g.dNdZ[0]
        self.inv_R[k], self.w[k] = g.inv_R[0], g.w[0]

    def arrays(self) -> tuple:
        return (self.weights, self.dNdR, self.dNdZ, self.inv_R, self.w)


class CellPoints:
    """The points of one cell of a path-dependent body, known on every rank: their
    geometry (copied from the owning rank) and the update of their state at a given
    displacement by the force's compiled cell kernel (:attr:`~.internal_force.quadrature.
    QuadratureForce.cell_kernel`), on one-cell arrays of the types the force's own
    arrays have (no new compilation)."""

    def __init__(self, force, pos: int, comm: MPI.Comm):
        """``pos``: the cell's position in ``force.cells`` on the rank that owns it, -1 on
        the others."""
        g = force.geometry
        geo = [np.zeros((1,) + a.shape[1:]) for a in (g.dNdr, g.dNdz, g.inv_r, g.w)]
        for a, src in zip(geo, (g.dNdr, g.dNdz, g.inv_r, g.w)):
            if pos >= 0:
                a[0] = src[pos]
            comm.Allreduce(MPI.IN_PLACE, a, op=MPI.SUM)
        self.dNdr, self.dNdz, self.inv_r, self.w = geo
        self.N = g.N
        n_nodes = g.dofs.shape[1]  # 3 on triangles, 4 on quadrilaterals
        self.dofs = np.arange(n_nodes, dtype=g.dofs.dtype).reshape(1, n_nodes)
        self.params, self.dt = force.params, force.dt
        n_points, n_comp = force.qs.eps_p.shape[1:]
        ns = force.qs.state.shape[2]
        self.u, self.f = np.zeros(2 * n_nodes), np.zeros(2 * n_nodes)
        # one cell's state in the layout of the force's (the kernel's arrays)
        one = type(force.qs)(1, ns, n_points, force.qs.by_component)
        self.eps_p, self.state, self.sigma = one.eps_p, one.state, one.sigma
        self._kernel_arrays = one.kernel_arrays
        self.work = np.zeros_like(force.work)
        self.size = n_points * (2 * n_comp + ns)  # raw floats of the state
        self._cells = np.zeros(1, dtype=np.int64)
        self._mean = np.zeros((5, 1))
        self._update = direct(force.cell_kernel, *self._arguments())

    def _arguments(self) -> tuple:
        return (self.params, self.dt, self.dofs, self.dNdr, self.dNdz, self.N, self.inv_r, self.w,
                self.u, self.f, *self._kernel_arrays, self.work)

    def value(self, row: np.ndarray, u_start: int, start: int, code: int) -> float:
        """Probe value ``code`` of a summed raw row: the nodal displacements at
        row[u_start:], the points' state at row[start:], updated at that displacement."""
        _unpack_points(row, u_start, start, self.u, self.eps_p, self.state, self.sigma)
        self._update(*self._arguments())
        return _point_value(self.sigma, self.state, self.w, code, self._cells, self._mean)


class Probes:
    """Cell values at points: ``quantity`` in QUANTITIES (stresses in Pa, u_r, u_z in m)
    of the cell holding each point (r, z) in m (u_r, u_z interpolated at the point);
    r and z (m) the current position of the node nearest the point; a strain_gauge's axial
    strain (-) over its length centred at the point; a section's force (N, compression
    positive) through the plane z of the point (its r is not read)."""

    def __init__(self, model, specs: list[tuple], plastic_forces=()):
        """``specs``: (name, point (r, z) in m, quantity) per probe, a gauge's with its
        length (m) fourth (GAUGE_LENGTH if absent)."""
        geometry = model.geometry
        self.plane = geometry.plane  # plane strain: eps_out = 0 in a P1 cell's stress
        for name, _, quantity in (tuple(spec[:3]) for spec in specs):
            if quantity not in self.quantities(geometry):
                raise InputError(f"probe '{name}': unknown quantity '{quantity}' "
                                 f"(use {', '.join(self.quantities(geometry))})")
        # the internal names of the quantities (plane strain names its slots x, out, y)
        probes = [(spec[0], spec[1], geometry.internal(spec[2])) for spec in specs]
        self.names = [name for name, _, _ in probes]
        self.points = [pt for _, pt, _ in probes]
        self.comm: MPI.Comm = model.comm
        mesh = model.mesh
        n = len(probes)
        quad = getattr(model, "quadrilateral", False)
        self.width = width = RAW_Q1 if quad else RAW  # raw entries of a probe's cell dofs
        self._quad = _QuadCells(n) if quad else None
        self.n_raw = width * n
        self.xy = np.zeros((n, width // 2, 2))
        self.point_w = np.zeros((n, 3))  # a triangle's barycentric weights at the point
        self.D = np.zeros((n, 4, 4))
        self.code = np.zeros(n, dtype=np.int64)
        self.midpoints = np.zeros((n, 2))  # (r, z) in m of each probe's cell
        self.X = np.zeros((n, 2))  # (r, z) in m of the node of an r or z probe
        self.gauge_w = np.zeros((n, width))  # a gauge's weights: lower end, upper end
        self.gauge_l = np.ones(n)  # a gauge's length (m)
        dofs = np.zeros(width * n, dtype=np.int64)  # global unrolled dofs
        scene = model.dofs.local_to_scene()  # local unrolled dof -> its global index
        cell_nodes = model.cell_dofs
        forces = {f.body: f for f in plastic_forces}
        owned_pos = {}  # probe -> position of its cell in its force's cells (owning rank)
        bodies = list(model.bodies.values())
        which = np.full(n, -1, dtype=np.int64)  # body of each probe cell
        unused = np.zeros(width * n, dtype=np.bool_)  # raw entries no rank records
        sections = []  # (probe, the scene dofs of its c, c)
        for k, (name, point, quantity) in enumerate(probes):
            if quantity not in QUANTITIES:
                raise InputError(f"probe '{name}': unknown quantity '{quantity}' "
                                 f"(use {', '.join(QUANTITIES)})")
            self.code[k] = QUANTITIES.index(quantity)
            if quantity == GAUGE:  # (collective)
                length = float(specs[k][3]) if len(specs[k]) > 3 else GAUGE_LENGTH
                which[k] = self._gauge(k, name, point, length, model, dofs, scene, bodies)
                continue
            if quantity == SECTION:  # (collective)
                try:
                    body = section_body(model, float(point[1]))
                except InputError as exc:
                    raise InputError(f"probe '{name}': {exc}") from None
                which[k] = [b.name for b in bodies].index(body)
                sections.append((k, *section_row(model, body, float(point[1]))))
                unused[width * k: width * (k + 1)] = True
                continue
            cell, mine = locate_cell(mesh, point, model.geometry.axes)
            if mine:
                nodes = cell_nodes[cell].astype(np.int32)
                self.midpoints[k] = model.node_xy[nodes].mean(axis=0)
            if mine and quantity not in POSITION_QUANTITIES:
                dofs[width * k: width * (k + 1)] = scene[np.column_stack([2 * nodes,
                                                                          2 * nodes + 1]).ravel()]
                self.xy[k] = model.node_xy[nodes]
                if quad:
                    self._quad.fill(k, model.cell_dofs, model.node_xy, cell, point,
                                    model.geometry)
                else:
                    self.point_w[k] = interpolation_weights(self.xy[k], point)
            if mine:
                which[k] = next(b for b, body in enumerate(bodies)
                                if cell in model.tmesh.cells(body.name))
                force = forces.get(bodies[which[k]].name)
                if force is not None:
                    owned_pos[k] = int(np.searchsorted(force.cells, cell))
        self.comm.Allreduce(MPI.IN_PLACE, which, op=MPI.MAX)
        for k, (_, point, quantity) in enumerate(probes):
            if quantity in POSITION_QUANTITIES:  # the node's u_r, u_z, its X
                unused[width * k + 2: width * (k + 1)] = True
                node, X = nearest_node(model, bodies[which[k]].name, point)
                if X is not None:
                    dofs[width * k: width * k + 2] = scene[2 * node: 2 * node + 2]
                    self.X[k] = X
        for arr in ((dofs, self.xy, self.point_w, self.midpoints, self.X, self.gauge_w)
                    + (self._quad.arrays() if quad else ())):
            self.comm.Allreduce(MPI.IN_PLACE, arr, op=MPI.SUM)
        # probes of a stress or a plastic quantity in the cell of a path-dependent body:
        # (probe, its CellPoints, where its points' state starts in a raw row) on every
        # rank; (the force's state, the cell's position, that start) of those this rank owns
        self.pointwise = np.zeros(n, dtype=np.bool_)
        self._points: list[tuple[int, CellPoints, int]] = []
        self._plastic: list[tuple] = []
        for k, (name, _, quantity) in enumerate(probes):
            material = bodies[which[k]].material
            force = forces.get(bodies[which[k]].name)
            if quantity in PLASTIC_QUANTITIES and not plastic_forces:
                raise InputError(f"probe '{name}': {quantity} needs a path-dependent body in "
                                 "the run (it reads 0 in the cells of linear bodies)")
            if (self.code[k] in (_U_R, _U_Z, _GAUGE, _SECTION)
                    or quantity in POSITION_QUANTITIES):
                continue
            if force is not None:
                pos = owned_pos.get(k, -1)
                cell_points = CellPoints(force, pos, self.comm)  # (collective)
                self._points.append((k, cell_points, self.n_raw))
                if pos >= 0:
                    self._plastic.append((force.qs, pos, self.n_raw))
                self.pointwise[k] = True
                self.n_raw += cell_points.size
            elif self.code[k] < len(STRESS_NAMES):
                D = stiffness_matrix(material)
                if D is None:
                    raise InputError(f"probe '{name}': {quantity} of body "
                                     f"'{bodies[which[k]].name}' needs a material with a constant "
                                     "(elastic) stiffness")
                self.D[k] = D
        # the sections' dofs after the points' states: (probe, start in a raw row, c)
        self._sections: list[tuple[int, int, np.ndarray]] = []
        section_dofs = []
        for k, global_dofs, c in sections:
            self._sections.append((k, self.n_raw, c))
            section_dofs.append(global_dofs)
            self.n_raw += c.size
        owned = (dofs >= model.offset) & (dofs < model.offset + model.n_owned) & ~unused
        index = np.full(self.n_raw, -1, dtype=np.int64)
        index[: width * n] = np.where(owned, dofs - model.offset, -1)
        for (_, start, c), g in zip(self._sections, section_dofs):
            mine = (g >= model.offset) & (g < model.offset + model.n_owned)
            index[start: start + c.size] = np.where(mine, g - model.offset, -1)
        self._index = index
        # load the compiled calls now, not in the first timed step: the recorder, and the
        # values with ``out`` of its own and a column slice of a wider block, as a history
        # table passes it (a view numpy does not call contiguous)
        self.recorder(np.zeros(model.n_owned), np.zeros(self.n_raw))(0)
        for out in (np.zeros((1, n)), np.zeros((2, n + 2))[:, 1: n + 1]):
            self._load_values(np.zeros((1, self.n_raw)), out)

    @staticmethod
    def quantities(geometry) -> tuple[str, ...]:
        """The quantities a probe of a scene of ``geometry`` may record, by their names
        there (plane strain: sigma_xx, sigma_yy, sigma_out, sigma_xy, u_x, u_y, x, y)."""
        return tuple(geometry.public(q) for q in QUANTITIES)

    def _gauge(self, k: int, name: str, point: tuple[float, float], length: float, model,
               dofs: np.ndarray, scene: np.ndarray, bodies: list) -> int:
        """Gauge k centred at ``point`` (r, z) (m) of ``length`` (m): the u_z dofs of its
        ends' cells into dofs[width k:] and their weights into gauge_w[k] on the rank
        that owns each cell; the index of the body that holds both ends (collective)."""
        if not length > 0.0:
            raise InputError(f"probe '{name}': the gauge length must be > 0 m (it is {length!r})")
        self.gauge_l[k] = length
        half = self.width // 2
        held = []
        for j, z in enumerate((point[1] - 0.5 * length, point[1] + 0.5 * length)):
            try:
                cell, mine = locate_cell(model.mesh, (point[0], z), model.geometry.axes)
            except InputError:
                a, b = model.geometry.axes
                raise InputError(f"probe '{name}': the gauge's end ({a}={point[0]!r}, {b}={z!r}) m "
                                 "lies outside the mesh") from None
            body = -1
            if mine:
                nodes = model.cell_dofs[cell].astype(np.int32)
                start = self.width * k + half * j
                dofs[start: start + half] = scene[2 * nodes + 1]
                self.gauge_w[k, half * j: half * (j + 1)] = interpolation_weights(
                    model.node_xy[nodes], (point[0], z))
                body = next(b for b, bd in enumerate(bodies)
                            if cell in model.tmesh.cells(bd.name))
            held.append(self.comm.allreduce(body, op=MPI.MAX))
        if held[0] != held[1]:
            raise InputError(f"probe '{name}': the gauge's ends lie in two bodies "
                             f"({bodies[held[0]].name} and {bodies[held[1]].name}); "
                             "put it within one")
        return held[0]

    def _load_values(self, raw: np.ndarray, out: np.ndarray) -> None:
        for _, start, c in self._sections[:1]:
            load(_section_force, raw, start, c, 0, out)
        if self._quad is None:
            load(_values, raw, self.xy, self.point_w, self.D, self.code, self.pointwise, self.X,
                 self.gauge_w, self.gauge_l, out, self.plane)
        else:
            qc = self._quad
            load(_quad_values, raw, qc.weights, qc.dNdR, qc.dNdZ, qc.N, qc.inv_R, qc.w,
                 qc.dofs, qc.eps, self.D, self.code, self.pointwise, self.X, self.gauge_w,
                 self.gauge_l, out)

    def recorder(self, u_owned: np.ndarray, block: np.ndarray):
        """``record(offset)``: the probe dofs this rank owns (m), and the points' state of
        the probe cells of path-dependent bodies it owns, into block[offset: offset +
        n_raw] (a flat block of rows, zero elsewhere; ``offset`` a Python int), for the
        u_owned of the run; one compiled call without such cells (~0.25 us)."""
        fill = functools.partial(direct(_record_at, u_owned, self._index, block, 0),
                                 u_owned, self._index, block)
        if not self._plastic:
            return fill
        plastic = self._plastic

        def record(offset: int) -> None:
            fill(offset)
            for qs, pos, start in plastic:
                _record_points(qs.eps_p, qs.state, qs.sigma, pos, block, offset + start)
        return record

    def values(self, raw: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        """Probe values (rows x probes) of summed raw rows (rows x n_raw)."""
        if out is None:
            out = np.empty((raw.shape[0], self.code.size))
        raw = np.ascontiguousarray(raw)
        if self._quad is None:
            _values(raw, self.xy, self.point_w, self.D, self.code, self.pointwise, self.X,
                    self.gauge_w, self.gauge_l, out, self.plane)
        else:
            qc = self._quad
            _quad_values(raw, qc.weights, qc.dNdR, qc.dNdZ, qc.N, qc.inv_R, qc.w, qc.dofs,
                         qc.eps, self.D, self.code, self.pointwise, self.X, self.gauge_w,
                         self.gauge_l, out)
        for k, start, c in self._sections:
            _section_force(raw, start, c, k, out)
        for k, cell_points, start in self._points:
            code = int(self.code[k])
            for i in range(raw.shape[0]):
                out[i, k] = cell_points.value(raw[i], self.width * k, start, code)
        return out


def arrival_time(t: np.ndarray, y: np.ndarray, level: float) -> float:
    """First time (s) at which the history y(t) reaches ``level``, linearly interpolated
    (NaN if it never does or starts there)."""
    k = int(np.argmax(y >= level))
    if k == 0:
        return float("nan")
    return float(t[k - 1] + (level - y[k - 1]) * (t[k] - t[k - 1]) / (y[k] - y[k - 1]))
