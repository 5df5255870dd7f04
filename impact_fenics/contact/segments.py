"""Node-to-segment geometry: slave nodes against the two-node boundary facets of a master body.

One-pass (the finer side as slave), frictionless, small strain: the search runs
once in the reference geometry and each slave node s gets one master segment
(nodes a, b), its parameter xi in [0, 1], the shape values N_a = 1 - xi,
N_b = xi, the unit normal n (pointing out of the master body) and the initial
gap g0 = n . (x_s - x_p) >= 0 (m), x_p = N_a x_a + N_b x_b. The linearised gap is

    g = g0 + n . (u_s - N_a u_a - N_b u_b)      (m; g >= 0 open, today's sign)

so both components (u_r, u_z) of the slave and master nodes enter.

Edge cases (each tested):

* xi within ``xi_tol`` of 0 or 1 is snapped to 0 or 1 (exact node-to-node
  weights when nodes match);
* one segment per slave: the closest one; distances equal within ``tie_tol``
  (a slave over a master node projects onto both neighbours) go to the face
  projection before a vertex one, then to the segment first in the global order
  (segments sorted by midpoint r, then z: the same order on every partition).
  Counting both would make S = dt^2 G M^-1 G' singular and double a penalty;
* a convex master vertex (the slave lies beyond both neighbouring segments'
  ends): the contact point is the vertex and the normal runs from the vertex
  to the slave, g0 = |x_s - x_v|;
* a concave vertex (the slave projects inside two segments): the closest
  projection, ties as above;
* the axis r = 0: a slave on the axis whose contact point is a master node
  on the axis (a tip, or a face starting there) gets n = (0, +-1) exactly,
  whatever the tilt of the segment chosen (by symmetry; both u_r are fixed there
  and the methods never move a fixed dof). In plane strain the same rule holds on
  a declared symmetry plane x = 0 only (``axis``; without one x = 0 is no
  different from any other x).

Initial gaps below -``gap_tol`` are refused (one line naming the node); gaps
within +-``gap_tol`` are set to zero. A slave farther than ``reach`` from every
master segment is refused. By default (:func:`default_reach`) the reach is the
longest master segment plus the depth of the two faces: the larger of the
master's extent along the slave face's normal and the slave's extent along the
master face's normal (each face's normal: the direction in which its nodes
spread least). Two faces that touch somewhere have every slave within that
depth of the master, plus a segment for the discretisation: a flat face on a
flat face keeps one segment, and the nodes of a flat block under a nose of
radius R (up to R (sqrt 2 - 1) from it) are within the nose's depth R; faces
apart by more than their depth (a group at the other end of a body) are refused.

The search (:class:`BucketSearch`) bins each master segment into every cell of a
uniform grid (cells of side the reach) that its bounding box, inflated by the reach,
touches, the grid spanning the masters' current boxes; a slave is projected onto the
segments of its own cell only, in the global order, with the rules above restricted
to segments within reach. Every segment within reach of a slave is in its cell, so
the pairs are exactly those of projecting every slave onto every segment within
reach (same arithmetic, same candidates, same order), at a cost that grows with the
number of contact nodes, not their product.

Re-pairing (:class:`Repairing`, for finite strain; in the time loop every few steps
when the set is told to, :meth:`~impact_fenics.contact.interface.ContactSet.set_repairing`):
the same search in a current configuration x = X + u, the segments' normals turned
with them, xi_tol and tie_tol of the set-up, the reach of the set-up or a shorter one
(:func:`repair_reach`, the time loop's). A slave whose closest point is an end vertex
of the master face (a node of one segment, off the axis) and which lies beyond it, or
which has no segment within reach, has no row (released); it stays in the list and is
paired again when it comes back. Current gaps are returned as they are (negative when
penetrating): the gaps of a step come from its prediction (:func:`rows_of_pairs`).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from ..bodies import R, Z, DeformableModel
from ..errors import InputError

FACE, VERTEX = 0, 1


@dataclass
class SegmentConstraints:
    """Replicated node-to-segment constraints in one global order (one per slave node).

    Node arrays: ``slave_xy`` (n, 2) and ``slave_dofs`` (n, 2) global (r, z) dofs;
    ``master_xy`` (m, 2), ``master_dofs`` (m, 2). Per constraint i (slave i):
    ``seg`` its segment, ``a``, ``b`` master node indices, ``xi``, ``normal``
    (n, 2), ``g0`` (m), ``kind`` FACE or VERTEX. ``segments`` (k, 2): master node
    indices of every segment, ``seg_normal`` (k, 2) their unit outward normals.
    """

    slave_xy: np.ndarray
    slave_dofs: np.ndarray
    master_xy: np.ndarray
    master_dofs: np.ndarray
    segments: np.ndarray
    seg: np.ndarray
    a: np.ndarray
    b: np.ndarray
    xi: np.ndarray
    normal: np.ndarray
    g0: np.ndarray
    kind: np.ndarray
    names: tuple[str, str]  # (slave group, master group)
    # the search's settings, for a re-pairing (:class:`Repairing`): the unit outward
    # normal of each segment (k, 2), the reach (m), xi_tol (relative), tie_tol (m)
    seg_normal: np.ndarray | None = None
    reach: float = np.inf
    xi_tol: float = 1e-6
    tie_tol: float = 0.0
    # whether x = 0 is a symmetry line (the axis r = 0, or a plane-strain half model's
    # declared plane): the axis rules apply there
    axis: bool = True

    @property
    def n(self) -> int:
        return int(self.seg.size)

    @property
    def r(self) -> np.ndarray:
        """Radius (m) of each slave node."""
        return self.slave_xy[:, 0]

    @property
    def dofs(self) -> np.ndarray:
        """Every global contact dof: the slaves' (r, z), then the masters' (r, z)."""
        return np.concatenate([self.slave_dofs.ravel(), self.master_dofs.ravel()])


# ----------------------------------------------------------------------------- the projection

@njit(cache=True, inline="always")
def _project_one(xs, zs, j, seg_nodes, node_xy, xi_tol):
    """Slave point (xs, zs) on segment j: (xi, kind, p_r, p_z, d), with (p_r, p_z) the
    vector (m) from the contact point to the slave and d (m) its length; xi is snapped
    to 0 or 1 within ``xi_tol``, kind is VERTEX beyond either end."""
    pa = seg_nodes[j, 0]
    pb = seg_nodes[j, 1]
    tr = node_xy[pb, 0] - node_xy[pa, 0]
    tz = node_xy[pb, 1] - node_xy[pa, 1]
    length2 = tr * tr + tz * tz
    dr = xs - node_xy[pa, 0]
    dz = zs - node_xy[pa, 1]
    xi = (dr * tr + dz * tz) / length2
    kind = FACE
    if xi < -xi_tol or xi > 1.0 + xi_tol:
        kind = VERTEX
    if xi < xi_tol:
        xi = 0.0
    elif xi > 1.0 - xi_tol:
        xi = 1.0
    pr = dr - xi * tr
    pz = dz - xi * tz
    return xi, kind, pr, pz, np.sqrt(pr * pr + pz * pz)


# ----------------------------------------------------------------------------- the bucket search
#
# A uniform grid of square cells of side h (the reach, m) over the masters' boxes
# inflated by the reach. Each segment is listed in every cell its inflated box
# touches, so every segment within reach of a point is listed in the point's cell
# (the segment's contact point lies in its box, the point within reach of it). The
# lists are one CSR pair: cell c holds entries[start[c]:start[c + 1]], segments in
# ascending global order. A slave is projected onto its own cell's segments only, in
# that order, with the rule of the brute-force search restricted to segments within
# reach: the same arithmetic on the same candidates in the same order, so the same
# pair, bit for bit, as projecting onto every segment within reach.


@njit(cache=True)
def _cell_range(lo, hi, origin, h, inflate, n):
    """First and last cell index (clipped to [0, n - 1]) touched by [lo, hi] inflated."""
    c0 = int(np.floor((lo - inflate - origin) / h))
    c1 = int(np.floor((hi + inflate - origin) / h))
    return max(c0, 0), min(c1, n - 1)


@njit(cache=True)
def _segment_cells(j, seg_nodes, node_xy, grid, inflate, nx, ny):
    """(ix0, ix1, iz0, iz1): the cells touched by segment j's box inflated by ``inflate``
    (m) in the grid ``grid`` = (r0, z0, h) of nx x ny cells."""
    a, b = seg_nodes[j, 0], seg_nodes[j, 1]
    i0, i1 = _cell_range(min(node_xy[a, 0], node_xy[b, 0]), max(node_xy[a, 0], node_xy[b, 0]),
                         grid[0], grid[2], inflate, nx)
    k0, k1 = _cell_range(min(node_xy[a, 1], node_xy[b, 1]), max(node_xy[a, 1], node_xy[b, 1]),
                         grid[1], grid[2], inflate, ny)
    return i0, i1, k0, k1


@njit(cache=True)
def _bin_count(seg_nodes, node_xy, grid, inflate, nx, ny, start):
    """Count into ``start[c]`` the segments listed in cell c (c = ix ny + iz);
    ``start[nx ny]`` = 0. Returns the number of entries."""
    for c in range(nx * ny + 1):
        start[c] = 0
    total = 0
    for j in range(seg_nodes.shape[0]):
        i0, i1, k0, k1 = _segment_cells(j, seg_nodes, node_xy, grid, inflate, nx, ny)
        for ix in range(i0, i1 + 1):
            for iz in range(k0, k1 + 1):
                start[ix * ny + iz] += 1
        total += (i1 - i0 + 1) * (k1 - k0 + 1)
    return total


@njit(cache=True)
def _bin_fill(seg_nodes, node_xy, grid, inflate, nx, ny, start, entries):
    """Turn the counts of :func:`_bin_count` into CSR offsets and list the segments,
    ascending within each cell (filled backwards from each cell's end)."""
    ncell = nx * ny
    acc = 0
    for c in range(ncell):
        acc += start[c]
        start[c] = acc  # the end of cell c
    start[ncell] = acc
    for j in range(seg_nodes.shape[0] - 1, -1, -1):
        i0, i1, k0, k1 = _segment_cells(j, seg_nodes, node_xy, grid, inflate, nx, ny)
        for ix in range(i0, i1 + 1):
            for iz in range(k0, k1 + 1):
                start[ix * ny + iz] -= 1
                entries[start[ix * ny + iz]] = j  # start[c] ends at cell c's beginning


@njit(cache=True)
def _pair_in_cells(x, seg_nodes, node_xy, seg_normal, xi_tol, tie_tol, reach, grid, nx, ny,
                   start, entries, out_seg, out_xi, out_n, out_g, out_kind, out_dist):
    """Closest segment within ``reach`` (m) of every slave point ``x`` (n, 2) among the
    segments of its cell. Writes the segment (-1: none within reach), xi, normal, signed
    gap (m), kind (FACE/VERTEX) and distance (m; inf: none). Returns the number of
    projections made (the search's cost)."""
    r0, z0, h = grid[0], grid[1], grid[2]
    made = 0
    for i in range(x.shape[0]):
        best = -1
        best_d = np.inf
        best_kind = 2
        out_xi[i] = 0.0
        out_n[i, 0] = 0.0
        out_n[i, 1] = 0.0
        out_g[i] = np.inf
        ix = int(np.floor((x[i, 0] - r0) / h))
        iz = int(np.floor((x[i, 1] - z0) / h))
        if 0 <= ix < nx and 0 <= iz < ny:
            c = ix * ny + iz
            for e in range(start[c], start[c + 1]):
                j = entries[e]
                xi, kind, pr, pz, d = _project_one(x[i, 0], x[i, 1], j, seg_nodes, node_xy, xi_tol)
                made += 1
                if d > reach:
                    continue
                # strictly closer, or tied and a face before a vertex (lower index wins
                # the remaining ties: segments come in the global order)
                if d < best_d - tie_tol or (d <= best_d + tie_tol and kind < best_kind):
                    best, best_d, best_kind = j, d, kind
                    out_xi[i] = xi
                    if kind == FACE:
                        out_n[i, 0] = seg_normal[j, 0]
                        out_n[i, 1] = seg_normal[j, 1]
                        out_g[i] = pr * seg_normal[j, 0] + pz * seg_normal[j, 1]
                    else:
                        out_n[i, 0] = pr / d
                        out_n[i, 1] = pz / d
                        out_g[i] = d
        out_seg[i] = best
        out_kind[i] = best_kind
        out_dist[i] = best_d
    return made


@njit(cache=True)
def _extent(node_xy, seg_nodes):
    """(r_min, z_min, r_max, z_max) in m of the segments' nodes."""
    rmin = zmin = np.inf
    rmax = zmax = -np.inf
    for j in range(seg_nodes.shape[0]):
        for k in range(2):
            p = seg_nodes[j, k]
            rmin = min(rmin, node_xy[p, 0])
            rmax = max(rmax, node_xy[p, 0])
            zmin = min(zmin, node_xy[p, 1])
            zmax = max(zmax, node_xy[p, 1])
    return rmin, zmin, rmax, zmax


class BucketSearch:
    """The closest master segment within ``reach`` (m) of each slave point, through a
    uniform grid of cells of side ``reach`` rebuilt at each call from the current
    masters' boxes (so a segment grown longer than a cell is still listed in every
    cell it reaches). Cost: the binning is linear in the segments, and each slave is
    projected onto its cell's segments only, those whose box inflated by the reach
    touches the cell: a bounded number for a face whose segments are not much shorter
    than the reach, so the search is linear in the number of contact nodes, not their
    product (``candidates`` counts the projections of the last call). A reach of many
    segments (the default reach on a curved face: its depth) puts the face in a few
    cells, and the cost is the brute force's again.

    Memory: the grid's offsets (one int64 a cell, plus one) and its entries (one a
    (segment, cell) pair) are kept between calls and grown only when a grid needs
    more; nothing else is allocated per call. The grid has about
    (extent_r / reach + 4)(extent_z / reach + 4) cells (the masters' extents, m); beyond
    ``cells_per_item`` x (segments + slaves) + 1024 cells (a face curved over an extent
    much larger than the reach) the cells are doubled until it fits, keeping memory
    linear at the price of more segments per cell. The pairs do not depend on the
    cell size (exact for any grid)."""

    cells_per_item = 64

    def __init__(self, reach: float):
        if not (np.isfinite(reach) and reach > 0.0):
            raise InputError(f"contact: reach must be a positive length (m), got {reach!r}")
        self.reach = float(reach)
        self.start = np.empty(0, np.int64)
        self.entries = np.empty(0, np.int64)
        self.grid = np.empty(3)  # (r0, z0, h) of the last grid, m
        self.inflate = 0.0  # m, the inflation of the segments' boxes in the last grid
        self.shape = (0, 0)
        self.candidates = 0

    def _build_grid(self, node_xy: np.ndarray, seg_nodes: np.ndarray, n_slaves: int) -> None:
        """Bin the segments into a grid over their current boxes."""
        rmin, zmin, rmax, zmax = _extent(node_xy, seg_nodes)
        scale = max(abs(rmin), abs(zmin), abs(rmax), abs(zmax))
        # the reach plus a margin above the round-off of a distance and of a box edge,
        # so that a segment at a computed distance <= reach is always listed
        inflate = self.reach * (1.0 + 1e-6) + 64.0 * np.finfo(float).eps * scale
        h = self.reach
        width, height = rmax - rmin + 2.0 * inflate, zmax - zmin + 2.0 * inflate
        cap = self.cells_per_item * (seg_nodes.shape[0] + n_slaves) + 1024
        while (width / h + 2.0) * (height / h + 2.0) > cap:
            h *= 2.0
        # one cell more than the width needs: a point on the far edge of the box
        # whose cell index rounds up stays in the grid
        nx, ny = int(width / h) + 2, int(height / h) + 2
        self.grid[0], self.grid[1], self.grid[2] = rmin - inflate, zmin - inflate, h
        self.shape = (nx, ny)
        if self.start.size < nx * ny + 1:
            self.start = np.empty(2 * (nx * ny + 1), np.int64)
        total = _bin_count(seg_nodes, node_xy, self.grid, inflate, nx, ny, self.start)
        if self.entries.size < total:
            self.entries = np.empty(2 * total, np.int64)
        _bin_fill(seg_nodes, node_xy, self.grid, inflate, nx, ny, self.start, self.entries)
        self.inflate = inflate

    def pair(self, x: np.ndarray, seg_nodes: np.ndarray, node_xy: np.ndarray,
             seg_normal: np.ndarray, xi_tol: float, tie_tol: float, out_seg: np.ndarray,
             out_xi: np.ndarray, out_n: np.ndarray, out_g: np.ndarray, out_kind: np.ndarray,
             out_dist: np.ndarray) -> None:
        """Closest segment within reach of every slave ``x`` (n, 2), m, among segments
        ``seg_nodes`` (k, 2) of nodes ``node_xy`` with unit outward normals
        ``seg_normal`` (k, 2), written into the ``out_*`` arrays (see
        :func:`_pair_in_cells`; ``xi_tol`` relative, ``tie_tol`` m: the rules of the
        module docstring)."""
        self._build_grid(node_xy, seg_nodes, x.shape[0])
        nx, ny = self.shape
        self.candidates = int(_pair_in_cells(
            x, seg_nodes, node_xy, seg_normal, xi_tol, tie_tol, self.reach, self.grid, nx, ny,
            self.start, self.entries, out_seg, out_xi, out_n, out_g, out_kind, out_dist))


@njit(cache=True)
def _axis_normals(x, seg_nodes, node_xy, seg, xi, axis_tol, normal, gap):
    """A slave on r = 0 whose contact point is a master node on r = 0 (a tip) takes the
    axial normal (0, +-1), the sign of the chosen one's z, and gap = n_z (z_s - z_p)."""
    for i in range(x.shape[0]):
        j = seg[i]
        if j < 0 or abs(x[i, 0]) > axis_tol:
            continue
        pa, pb = seg_nodes[j, 0], seg_nodes[j, 1]
        pr = (1.0 - xi[i]) * node_xy[pa, 0] + xi[i] * node_xy[pb, 0]
        if abs(pr) > axis_tol:
            continue
        pz = (1.0 - xi[i]) * node_xy[pa, 1] + xi[i] * node_xy[pb, 1]
        sign = 1.0 if normal[i, 1] >= 0.0 else -1.0
        normal[i, 0] = 0.0
        normal[i, 1] = sign
        gap[i] = sign * (x[i, 1] - pz)

def segment_normals(node_xy: np.ndarray, segments: np.ndarray, inside: np.ndarray) -> np.ndarray:
    """Unit normals (k, 2) of segments, pointing away from the points ``inside`` (k, 2)
    (the centroid of each segment's cell)."""
    t = node_xy[segments[:, 1]] - node_xy[segments[:, 0]]
    length = np.sqrt(np.sum(t * t, axis=1))
    n = np.stack([t[:, 1], -t[:, 0]], axis=1) / length[:, None]
    mid = 0.5 * (node_xy[segments[:, 1]] + node_xy[segments[:, 0]])
    flip = np.sum((mid - inside) * n, axis=1) < 0.0
    n[flip] *= -1.0
    return n


def thin_direction(xy: np.ndarray) -> np.ndarray | None:
    """The unit direction in which the points ``xy`` (n, 2) spread least (a straight
    face's normal), or None for fewer than two distinct points."""
    if xy.shape[0] < 2:
        return None
    c = xy - xy.mean(axis=0)
    w, v = np.linalg.eigh(c.T @ c)
    return v[:, 0] if w[1] > 0.0 else None


def default_reach(slave_xy: np.ndarray, master_xy: np.ndarray, longest: float) -> float:
    """The farthest master segment (m) a slave may use unless told: the ``longest`` master
    segment (m) plus the depth of the two faces, the larger of the master nodes' extent
    along the slave face's normal and the slave nodes' extent along the master face's
    normal (see the module docstring)."""
    depth = 0.0
    for face, other in ((slave_xy, master_xy), (master_xy, slave_xy)):
        n = thin_direction(face)
        if n is not None:
            depth = max(depth, float(np.ptp(other @ n)))
    return longest + depth


def build(slave_xy: np.ndarray, slave_dofs: np.ndarray, master_xy: np.ndarray,
          master_dofs: np.ndarray, segments: np.ndarray, inside: np.ndarray,
          names: tuple[str, str] = ("slave", "master"), reach: float | None = None,
          gap_tol: float | None = None, xi_tol: float = 1e-6,
          axis: bool = True, axes: tuple[str, str] = ("r", "z")) -> SegmentConstraints:
    """Constraints from replicated arrays (any order: sorted here into the global order).

    ``segments`` (k, 2) index ``master_xy``; ``inside`` (k, 2) a point inside the
    master body behind each segment. ``reach`` (m) defaults to :func:`default_reach`,
    ``gap_tol`` (m) to 1e-6 of the shortest segment; ``xi_tol`` is relative. ``axis``:
    x = 0 is a symmetry line (the axis of axisymmetry, a declared symmetry plane) and
    its rules apply; ``axes`` name the coordinates in its messages ((x, y) in plane
    strain)."""
    slave_xy = np.asarray(slave_xy, dtype=float)
    master_xy = np.asarray(master_xy, dtype=float)
    # sort keys rounded to 1e-9 of the extent: dof coordinates differ by round-off
    # between partitions, the order must not
    extent = float(np.ptp(np.concatenate([slave_xy, master_xy]), axis=0).max()) or 1.0

    def key(xy):
        return np.round(xy / (1e-9 * extent))

    ks = key(slave_xy)
    order_s = np.lexsort((ks[:, 1], ks[:, 0]))
    slave_xy, slave_dofs = slave_xy[order_s], np.asarray(slave_dofs)[order_s]
    km = key(master_xy)
    order_m = np.lexsort((km[:, 1], km[:, 0]))
    rank_m = np.empty_like(order_m)
    rank_m[order_m] = np.arange(order_m.size)
    master_xy, master_dofs = master_xy[order_m], np.asarray(master_dofs)[order_m]
    segments = rank_m[np.asarray(segments)]
    segments = np.sort(segments, axis=1)  # (lower, upper) node of each segment in node order
    mid = key(0.5 * (master_xy[segments[:, 0]] + master_xy[segments[:, 1]]))
    order_k = np.lexsort((mid[:, 1], mid[:, 0]))
    segments, inside = segments[order_k], np.asarray(inside)[order_k]
    lengths = np.linalg.norm(master_xy[segments[:, 1]] - master_xy[segments[:, 0]], axis=1)
    if np.any(lengths <= 0):
        raise InputError(f"master surface '{names[1]}' has a segment of zero length")
    reach = default_reach(slave_xy, master_xy, float(lengths.max())) if reach is None \
        else float(reach)
    gap_tol = 1e-6 * float(lengths.min()) if gap_tol is None else float(gap_tol)
    normals = segment_normals(master_xy, segments, inside)
    n = slave_xy.shape[0]
    seg, kind = np.empty(n, np.int64), np.empty(n, np.int64)
    xi, g0, dist = np.empty(n), np.empty(n), np.empty(n)
    normal = np.empty((n, 2))
    tie_tol = 1e-9 * float(lengths.min())
    BucketSearch(reach).pair(slave_xy, segments, master_xy, normals, xi_tol, tie_tol, seg, xi,
                             normal, g0, kind, dist)
    # the axis: a slave on r = 0 whose contact point is a master node on r = 0 (a tip)
    # takes the axial normal, whatever the tilt of the segment chosen
    if axis:
        _axis_normals(slave_xy, segments, master_xy, seg, xi, tie_tol, normal, g0)
    far = seg < 0
    if np.any(far):
        k = np.flatnonzero(far)[0]
        p = slave_xy[k]
        a, t = master_xy[segments[:, 0]], master_xy[segments[:, 1]] - master_xy[segments[:, 0]]
        foot = np.clip(np.sum((p - a) * t, axis=1) / np.sum(t * t, axis=1), 0.0, 1.0)
        away = float(np.min(np.linalg.norm(p - a - foot[:, None] * t, axis=1)))
        raise InputError(f"contact: {int(far.sum())} node(s) of '{names[0]}' have no segment of "
                         f"'{names[1]}' within reach {reach:.4g} m, first at "
                         f"({axes[0]}={p[0]:.6g}, {axes[1]}={p[1]:.6g}), {away:.4g} m away: "
                         "are these the faces that meet? (else give reach, m)")
    deep = g0 < -gap_tol
    if np.any(deep):
        k = np.flatnonzero(deep)[0]
        raise InputError(f"contact: '{names[0]}' penetrates '{names[1]}' initially by "
                         f"{-g0[k]:.4g} m (tolerance {gap_tol:.3g} m) at "
                         f"({axes[0]}={slave_xy[k, 0]:.6g}, {axes[1]}={slave_xy[k, 1]:.6g})")
    g0[np.abs(g0) <= gap_tol] = 0.0
    return SegmentConstraints(slave_xy=slave_xy, slave_dofs=slave_dofs, master_xy=master_xy,
                              master_dofs=master_dofs, segments=segments, seg=seg,
                              a=segments[seg, 0].copy(), b=segments[seg, 1].copy(), xi=xi,
                              normal=normal, g0=g0, kind=kind, names=names,
                              seg_normal=normals, reach=reach, xi_tol=xi_tol, tie_tol=tie_tol,
                              axis=axis)


# ----------------------------------------------------------------------------- re-pairing

@njit(cache=True)
def _oriented_normals(node_xy, seg_nodes, side, out):
    """Unit normals (k, 2) of the segments at ``node_xy``: the tangent b - a turned by
    -90 degrees, times ``side`` (+-1, fixed at set-up: a segment keeps its outside)."""
    for j in range(seg_nodes.shape[0]):
        a, b = seg_nodes[j, 0], seg_nodes[j, 1]
        tr = node_xy[b, 0] - node_xy[a, 0]
        tz = node_xy[b, 1] - node_xy[a, 1]
        length = np.sqrt(tr * tr + tz * tz)
        out[j, 0] = side[j] * tz / length
        out[j, 1] = -side[j] * tr / length


@njit(cache=True)
def _face_ends(x, node_xy, seg_normal, end_tol, seg, xi, kind, normal, gap, seg_nodes, end, a,
               b, active):
    """The rule at the ends of the master face. A slave whose contact point is the end
    vertex of the face (``end``: master nodes of one segment, off the axis) and which
    lies beyond it by at most ``end_tol`` of the end segment's length (its projection's
    xi in [-end_tol, 0) or (1, 1 + end_tol]) is on the face's continuation: kind FACE,
    xi at the end (0 or 1), the segment's normal and the signed gap n . (x_s - x_end)
    (m). Farther beyond, or with no segment within reach, it has no row (released).
    Writes the row's master nodes ``a``, ``b`` (-1 without a row) and ``active``."""
    for i in range(seg.shape[0]):
        j = seg[i]
        released = j < 0
        if not released and kind[i] == VERTEX:
            at_b = xi[i] != 0.0
            node = seg_nodes[j, 1] if at_b else seg_nodes[j, 0]
            if end[node]:
                pa, pb = seg_nodes[j, 0], seg_nodes[j, 1]
                tr = node_xy[pb, 0] - node_xy[pa, 0]
                tz = node_xy[pb, 1] - node_xy[pa, 1]
                raw = ((x[i, 0] - node_xy[pa, 0]) * tr + (x[i, 1] - node_xy[pa, 1]) * tz) / (
                    tr * tr + tz * tz)
                beyond = raw - 1.0 if at_b else -raw
                if beyond <= end_tol:
                    kind[i] = FACE
                    normal[i, 0] = seg_normal[j, 0]
                    normal[i, 1] = seg_normal[j, 1]
                    gap[i] = (seg_normal[j, 0] * (x[i, 0] - node_xy[node, 0])
                              + seg_normal[j, 1] * (x[i, 1] - node_xy[node, 1]))
                else:
                    released = True
        active[i] = not released
        a[i] = -1 if released else seg_nodes[j, 0]
        b[i] = -1 if released else seg_nodes[j, 1]


# the default of Repairing's end_tol: a slave within 1 % of the end segment's length
# beyond the master face's end stays on the face's continuation (see Repairing)
END_TOLERANCE = 0.01


@dataclass
class Pairs:
    """The pairs of one re-pairing, per slave (in the constraints' order): ``active``
    (has a row), ``seg`` (-1: none within reach), master nodes ``a``, ``b`` (-1 without
    a row), ``xi``, unit ``normal`` (n, 2), ``gap`` (m, the current signed gap
    n . (x_s - x_p), or the distance to a vertex), ``kind`` (FACE/VERTEX; 2 with no
    segment), ``dist`` (m, the distance to the contact point; inf with no segment)."""

    active: np.ndarray
    seg: np.ndarray
    a: np.ndarray
    b: np.ndarray
    xi: np.ndarray
    normal: np.ndarray
    gap: np.ndarray
    kind: np.ndarray
    dist: np.ndarray

    @classmethod
    def empty(cls, n: int) -> Pairs:
        return cls(active=np.zeros(n, bool), seg=np.empty(n, np.int64), a=np.empty(n, np.int64),
                   b=np.empty(n, np.int64), xi=np.empty(n), normal=np.empty((n, 2)),
                   gap=np.empty(n), kind=np.empty(n, np.int64), dist=np.empty(n))


class Repairing:
    """Re-pairs the slaves of ``c`` against its master segments in a current
    configuration (finite strain): positions x = X + u of the slaves and the masters
    (in the constraints' orders), the segments' normals turned with them (each keeps
    the outside it had at set-up), the closest segment within ``reach`` (m; the set-up
    reach unless given: a time loop gives :func:`repair_reach`) by the
    bucket search (:class:`BucketSearch`, ties as at set-up), the axis rule as at
    set-up. At the ends of the master face (an end vertex: the node of one segment;
    an end on the axis r = 0 is not an end, the face continues by symmetry) the face
    is continued by ``end_tol`` of its end segment's length (:func:`_face_ends`): a
    slave beyond the end by less keeps a row on the end segment with the face's
    normal, so that the sub-micron radial motion of a rim node where two faces of
    equal radius meet does not release and re-pair it on alternate steps; a slave
    farther beyond, or with no segment within reach, has no row (``active`` False):
    released, not lost, it is paired again when it comes back. A slave that slides off
    the face is released once it is ``end_tol`` of a segment past the edge: the end of
    a meshed face is resolved to a cell, and 1 % of one is well inside that. Gaps are
    not snapped nor checked (a current gap may be negative). Every array is kept
    between calls: a call allocates nothing but what a larger grid needs
    (:class:`BucketSearch`)."""

    def __init__(self, c: SegmentConstraints, reach: float | None = None,
                 end_tol: float = END_TOLERANCE):
        if c.seg_normal is None:
            raise ValueError("re-pairing needs constraints from build()")
        if not 0.0 <= end_tol < 1.0:
            raise InputError(f"contact: end_tolerance = {end_tol} must lie in [0, 1) (a "
                             "fraction of the end segment)")
        self.c = c
        self.end_tol = float(end_tol)
        self.reach = c.reach if reach is None else float(reach)
        self.search = BucketSearch(self.reach)
        t = c.master_xy[c.segments[:, 1]] - c.master_xy[c.segments[:, 0]]
        self.side = np.where(c.seg_normal[:, 0] * t[:, 1] - c.seg_normal[:, 1] * t[:, 0] >= 0.0,
                             1.0, -1.0)
        valence = np.bincount(c.segments.ravel(), minlength=c.master_xy.shape[0])
        self.end = (valence == 1) & ((np.abs(c.master_xy[:, 0]) > c.tie_tol) | (not c.axis))
        self.seg_normal = np.empty_like(c.seg_normal)
        self.pairs = Pairs.empty(c.n)

    def __call__(self, slave_x: np.ndarray, master_x: np.ndarray) -> Pairs:
        """Pairs (rewritten in place) at slave positions ``slave_x`` (n, 2) and master
        positions ``master_x`` (m, 2), m."""
        c, p = self.c, self.pairs
        _oriented_normals(master_x, c.segments, self.side, self.seg_normal)
        self.search.pair(slave_x, c.segments, master_x, self.seg_normal, c.xi_tol, c.tie_tol,
                         p.seg, p.xi, p.normal, p.gap, p.kind, p.dist)
        if c.axis:
            _axis_normals(slave_x, c.segments, master_x, p.seg, p.xi, c.tie_tol, p.normal,
                          p.gap)
        _face_ends(slave_x, master_x, self.seg_normal, self.end_tol, p.seg, p.xi, p.kind,
                   p.normal, p.gap, c.segments, self.end, p.a, p.b, p.active)
        return p


def repair_reach(c: SegmentConstraints) -> float:
    """The reach (m) of a re-pairing in the time loop: two of the longest master segments
    at set-up. A slave in contact lies within a fraction of a segment of its master (a
    step moves a node by far less than a cell), so two segments find it with room for
    the face's curvature, while the set-up's default (:func:`default_reach`, which adds
    the faces' depth: a nose's radius) would put a curved face in a few cells of the
    search and cost the brute force's O(N M). A slave farther than this has no row
    (released) until it comes within reach."""
    t = c.master_xy[c.segments[:, 1]] - c.master_xy[c.segments[:, 0]]
    return 2.0 * float(np.sqrt(np.max(np.sum(t * t, axis=1))))


@njit(cache=True)
def current_positions(xy0, u, first_slot, out):
    """x = X + u (m) of the nodes whose reference (r, z) are ``xy0`` (k, 2), with u read
    from the slots (2 (first_slot + k), 2 (first_slot + k) + 1) of ``u`` (m), into ``out``."""
    for k in range(xy0.shape[0]):
        out[k, 0] = xy0[k, 0] + u[2 * (first_slot + k)]
        out[k, 1] = xy0[k, 1] + u[2 * (first_slot + k) + 1]


@njit(cache=True)
def rows_of_pairs(active, a, b, xi, normal, gap, dist, reach, n_slave, u, cs, cc, g0):
    """The rows of G and the gaps' constants from a re-pairing (:class:`Pairs`), in place:
    slave i's row holds its (r, z) slots (2i, 2i + 1) with the normal n and its master
    nodes' slots with -N_a n, -N_b n (N_a = 1 - xi, N_b = xi; master node k has the slots
    2 (n_slave + k), + 1), and g0_i = g_i - G_i u (m) with g_i the pair's current gap and
    u the displacements (m) of the configuration it was found in, so that the step's
    gap g0 + G u~ = g_i + G (u~ - u). A released slave (not ``active``) keeps a row of
    zero coefficients on its own slots and a constant positive gap (its distance, or
    ``reach`` with no segment within reach): no force, no coupling, and its slots keep
    their place in the set, paired again when it comes back."""
    for i in range(active.size):
        s_r, s_z = 2 * i, 2 * i + 1
        if not active[i]:
            for k in range(3):
                cs[i, 2 * k] = s_r
                cs[i, 2 * k + 1] = s_z
            for k in range(6):
                cc[i, k] = 0.0
            g0[i] = dist[i] if np.isfinite(dist[i]) else reach
            continue
        ma, mb = 2 * (n_slave + a[i]), 2 * (n_slave + b[i])
        cs[i, 0], cs[i, 1], cs[i, 2], cs[i, 3], cs[i, 4], cs[i, 5] = s_r, s_z, ma, ma + 1, mb, \
            mb + 1
        na, nb = 1.0 - xi[i], xi[i]
        nr, nz = normal[i, 0], normal[i, 1]
        cc[i, 0], cc[i, 1] = nr, nz
        cc[i, 2], cc[i, 3] = -na * nr, -na * nz
        cc[i, 4], cc[i, 5] = -nb * nr, -nb * nz
        s = gap[i]
        for k in range(6):
            s -= cc[i, k] * u[cs[i, k]]
        g0[i] = s


# ----------------------------------------------------------------------------- from a model

def _slave_nodes(model: DeformableModel, name: str) -> tuple[np.ndarray, np.ndarray]:
    """(r, z) and global (r, z) dofs of the owned nodes of a facet group, on every rank."""
    dz = model.facet_dofs(name, Z)
    xy = model.dof_coordinates(dz)
    dofs = np.stack([model.to_global(dz - 1 + R), model.to_global(dz)], axis=1)
    xy = np.concatenate(model.comm.allgather(xy))
    dofs = np.concatenate(model.comm.allgather(dofs))
    return xy, dofs


def owned_coordinates(model: DeformableModel, nodes: np.ndarray) -> np.ndarray:
    """(r, z) in m (len(nodes), 2) of the global nodes ``nodes`` (block indices, sorted,
    unique, the same on every rank), each from the copy of the rank that owns it.

    A rank holding a node as a ghost maps it through another cell than its owner
    does, so the two copies may differ in the last bit: the owner's alone makes
    the result the same on every rank."""
    lo, hi = model.V.dofmap.index_map.local_range
    mine = nodes[(nodes >= lo) & (nodes < hi)]
    parts = model.comm.allgather((mine, model.node_xy[mine - lo]))
    got = np.concatenate([p[0] for p in parts])
    xy = np.concatenate([p[1].reshape(-1, 2) for p in parts])
    out = np.empty((nodes.size, 2))
    out[np.searchsorted(nodes, got)] = xy
    return out


def _master_segments(model: DeformableModel, name: str):
    """Every facet of group ``name`` as (xy of its two nodes, their global (r, z) dofs,
    the centroid of its cell), deduplicated, on every rank, every coordinate from its
    owner's copy (:func:`owned_coordinates`). Refuses facets that are not on the
    boundary of the mesh."""
    mesh = model.mesh
    top = mesh.topology
    top.create_connectivity(1, 2)
    top.create_connectivity(1, 0)
    top.create_connectivity(2, 0)
    f2c, f2v, c2v = top.connectivity(1, 2), top.connectivity(1, 0), top.connectivity(2, 0)
    facets = model.tmesh.facets(name)
    if model.comm.allreduce(facets.size) == 0:
        raise InputError(f"facet group '{name}' is empty")
    imap = model.V.dofmap.index_map
    ends, cell_nodes, interior = [], [], 0
    for f in facets:
        cells = f2c.links(f)
        if cells.size != 1:
            interior += 1
            continue
        cell = cells[0]
        cv = c2v.links(cell)
        cdofs = model.V.dofmap.cell_dofs(cell)
        blocks = np.array([cdofs[np.flatnonzero(cv == v)[0]] for v in f2v.links(f)])
        ends.append(imap.local_to_global(blocks.astype(np.int32)))
        cell_nodes.append(imap.local_to_global(np.asarray(cdofs, dtype=np.int32)))
    interior = model.comm.allreduce(interior)
    if interior:
        raise InputError(f"facet group '{name}': {interior} facet(s) lie inside the mesh, "
                         "not on a boundary (contact needs boundary facets)")
    n_cell = model.V.dofmap.dof_layout.num_dofs  # nodes of a cell
    ends = np.concatenate(model.comm.allgather(np.array(ends, dtype=np.int64).reshape(-1, 2)))
    cell_nodes = np.concatenate(model.comm.allgather(
        np.array(cell_nodes, dtype=np.int64).reshape(-1, n_cell)))
    # a facet shared with a ghost cell appears on two ranks: keep one copy
    _, first = np.unique(np.sort(ends, axis=1), axis=0, return_index=True)
    ends, cell_nodes = ends[first], cell_nodes[first]
    nodes = np.unique(np.concatenate([ends.ravel(), cell_nodes.ravel()]))
    xy = owned_coordinates(model, nodes)
    inside = xy[np.searchsorted(nodes, cell_nodes)].mean(axis=1)
    master_nodes, inverse = np.unique(ends.ravel(), return_inverse=True)
    node_xy = xy[np.searchsorted(nodes, master_nodes)]
    master_dofs = np.stack([2 * master_nodes + R, 2 * master_nodes + Z], axis=1)
    return node_xy, master_dofs, inverse.reshape(-1, 2), inside


def node_to_segment(model: DeformableModel, slave: str, master: str, reach: float | None = None,
                    gap_tol: float | None = None, xi_tol: float = 1e-6) -> SegmentConstraints:
    """Node-to-segment constraints: nodes of facet group ``slave`` (put the finer side
    here) against the segments of facet group ``master`` (see the module docstring for
    ``reach``, ``gap_tol`` in m and ``xi_tol``)."""
    slave_xy, slave_dofs = _slave_nodes(model, slave)
    master_xy, master_dofs, segments, inside = _master_segments(model, master)
    if np.intersect1d(slave_dofs[:, 1], master_dofs[:, 1]).size:
        raise InputError(f"contact: facet groups '{slave}' and '{master}' share nodes "
                         "(slave and master must belong to different bodies)")
    if slave_xy.shape[0] == 0:
        raise InputError(f"facet group '{slave}' has no node")
    return build(slave_xy, slave_dofs, master_xy, master_dofs, segments, inside,
                 (slave, master), reach, gap_tol, xi_tol, axis=model.geometry.held_first,
                 axes=model.geometry.axes)
