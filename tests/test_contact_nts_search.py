"""The bucket search and the re-pairing of node-to-segment contact (no time loop).

Oracle: the brute-force search the bucket search replaced, kept here as it was
(:func:`_project_all`, every slave projected onto every segment, O(N M)), with the
axis rule and the gap snapping of the set-up as they were. The bucket search runs the
same projection arithmetic on a subset of the segments in the same order, so the pairs
are compared exactly (segment, xi, normal, gap, kind, distance: ``array_equal``), on
(a) the set-up geometries of the node-to-segment tests, (b) seeded random
perturbations of a face, (c) a master face stretched to twice its radius (segments
longer than a cell, a Taylor foot) and (d) a slave sliding off the master's end and
back. The cost is counted, not timed: the projections the search makes, against a
bound per slave derived from the grid (:func:`_candidates_per_slave`).
"""
import numpy as np
import pytest
from mpi4py import MPI
from numba import njit

from impact_fenics.contact.segments import (END_TOLERANCE, FACE, VERTEX, Repairing, build,
                                           node_to_segment)
from roundoff import rounding
from test_contact_nts_geometry import FLAT, _constraints, _random_interface, _surface
from test_contact_nts_masters import SCENES


@njit(cache=True)
def _project_all(x, seg_nodes, node_xy, seg_normal, xi_tol, tie_tol, out_seg, out_xi, out_n,
                 out_g, out_kind, out_dist):
    """The brute-force search as it was: every slave ``x`` onto every segment."""
    for i in range(x.shape[0]):
        best = -1
        best_d = np.inf
        best_kind = 2
        for j in range(seg_nodes.shape[0]):
            pa = seg_nodes[j, 0]
            pb = seg_nodes[j, 1]
            tr = node_xy[pb, 0] - node_xy[pa, 0]
            tz = node_xy[pb, 1] - node_xy[pa, 1]
            length2 = tr * tr + tz * tz
            dr = x[i, 0] - node_xy[pa, 0]
            dz = x[i, 1] - node_xy[pa, 1]
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
            d = np.sqrt(pr * pr + pz * pz)
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


def _brute_force(c, slave_x, master_x, seg_normal):
    """(seg, xi, normal, gap, kind, dist) of every slave by the brute-force search, with
    the axis rule as the set-up applied it."""
    n = slave_x.shape[0]
    seg, kind = np.empty(n, np.int64), np.empty(n, np.int64)
    xi, g, dist, normal = np.empty(n), np.empty(n), np.empty(n), np.empty((n, 2))
    _project_all(slave_x, c.segments, master_x, seg_normal, c.xi_tol, c.tie_tol, seg, xi,
                 normal, g, kind, dist)
    point = (1.0 - xi)[:, None] * master_x[c.segments[seg, 0]] \
        + xi[:, None] * master_x[c.segments[seg, 1]]
    on_axis = (np.abs(slave_x[:, 0]) <= c.tie_tol) & (np.abs(point[:, 0]) <= c.tie_tol)
    if np.any(on_axis):
        sign = np.where(normal[on_axis, 1] >= 0.0, 1.0, -1.0)
        normal[on_axis] = np.stack([np.zeros_like(sign), sign], axis=1)
        g[on_axis] = sign * (slave_x[on_axis, 1] - point[on_axis, 1])
    return seg, xi, normal, g, kind, dist


def _current_normals(c, master_x):
    """Unit normals of the segments at ``master_x``, each on the side it had at set-up."""
    t = master_x[c.segments[:, 1]] - master_x[c.segments[:, 0]]
    length = np.sqrt(np.sum(t * t, axis=1))
    n = np.stack([t[:, 1], -t[:, 0]], axis=1) / length[:, None]
    t0 = c.master_xy[c.segments[:, 1]] - c.master_xy[c.segments[:, 0]]
    flip = c.seg_normal[:, 0] * t0[:, 1] - c.seg_normal[:, 1] * t0[:, 0] < 0.0
    n[flip] *= -1.0
    return n


def _end_rule(c, seg, xi, kind, normal, gap, slave_x, master_x, end_tol=END_TOLERANCE):
    """The rule at the master face's ends, written again: a slave whose contact point is an
    end vertex (a node of one segment, off the axis) and that lies beyond it by at most
    ``end_tol`` of the end segment is on the face's continuation (kind FACE, the segment's
    normal, gap n . (x_s - x_end)); farther beyond, or with no segment (seg -1), it is
    released. Returns (released, kind, normal, gap), the last three new arrays."""
    count = np.bincount(c.segments.ravel(), minlength=c.master_xy.shape[0])
    normals = _current_normals(c, master_x)
    kind, normal, gap = kind.copy(), normal.copy(), gap.copy()
    out = seg < 0
    for i in np.flatnonzero((kind == VERTEX) & (seg >= 0)):
        a, b = c.segments[seg[i]]
        node = a if xi[i] == 0.0 else b
        if count[node] != 1 or abs(c.master_xy[node, 0]) <= c.tie_tol:
            continue
        # products summed as written (a BLAS dot, numpy's @, may fuse them: not the
        # kernel's rounding)
        t = master_x[b] - master_x[a]
        d = slave_x[i] - master_x[a]
        raw = (d[0] * t[0] + d[1] * t[1]) / (t[0] * t[0] + t[1] * t[1])
        if (raw - 1.0 if node == b else -raw) > end_tol:
            out[i] = True
            continue
        kind[i] = FACE
        normal[i] = normals[seg[i]]
        d = slave_x[i] - master_x[node]
        gap[i] = normal[i, 0] * d[0] + normal[i, 1] * d[1]
    return out, kind, normal, gap


def _assert_repairing_is_brute_force(c, pairing, slave_x, master_x):
    """The re-pairing at (slave_x, master_x) equals the brute-force search restricted to
    segments within reach (bit for bit), and releases exactly the slaves beyond an end."""
    p = pairing(slave_x, master_x)
    seg, xi, normal, g, kind, dist = _brute_force(c, slave_x, master_x,
                                                  _current_normals(c, master_x))
    near = dist <= c.reach
    released, kind, normal, g = _end_rule(c, np.where(near, seg, -1), xi, kind, normal, g,
                                          slave_x, master_x, pairing.end_tol)
    assert np.array_equal(p.seg[~near], np.full((~near).sum(), -1))
    for name, got, want in (("seg", p.seg, seg), ("xi", p.xi, xi), ("normal", p.normal, normal),
                            ("gap", p.gap, g), ("kind", p.kind, kind), ("dist", p.dist, dist)):
        assert np.array_equal(got[near], want[near]), name
    assert np.array_equal(p.active, ~released)
    assert np.array_equal(p.a[~released], c.segments[seg[~released], 0])
    assert np.array_equal(p.b[~released], c.segments[seg[~released], 1])
    return p


def _assert_build_is_brute_force(c, gap_tol):
    """build()'s pairs (the bucket search) equal the brute force's, gaps snapped to zero
    within ``gap_tol`` as the set-up does; and a re-pairing at the set-up positions
    gives the same pairs with the unsnapped gaps."""
    seg, xi, normal, g, kind, _ = _brute_force(c, c.slave_xy, c.master_xy, c.seg_normal)
    g0 = np.where(np.abs(g) <= gap_tol, 0.0, g)
    for name, got, want in (("seg", c.seg, seg), ("xi", c.xi, xi), ("normal", c.normal, normal),
                            ("g0", c.g0, g0), ("kind", c.kind, kind)):
        assert np.array_equal(got, want), name
    assert np.array_equal(_current_normals(c, c.master_xy), c.seg_normal)
    p = _assert_repairing_is_brute_force(c, Repairing(c), c.slave_xy, c.master_xy)
    assert np.array_equal(p.seg, c.seg) and np.array_equal(p.normal, c.normal)


def _default_gap_tol(c):
    lengths = np.linalg.norm(c.master_xy[c.segments[:, 1]] - c.master_xy[c.segments[:, 0]], axis=1)
    return 1e-6 * float(lengths.min())


# ----------------------------------------------------------------------------- (a) set-up

NOSE = [(0.0, 0.0), (0.05, 0.01), (0.1, 0.04)]
GEOMETRIES = {  # name: (slaves, master polyline, a point inside the master, build keywords)
    "flat": ([(0.125, 0.01), (0.1 + 1e-9, 0.0)], FLAT, (0.1, -1.0), {}),
    "over_a_node": ([(0.1, 0.0), (0.2, 0.02), (0.05, 0.0)], FLAT, (0.1, -1.0), {}),
    "convex": ([(0.13, 0.04)], [(0.0, 0.0), (0.1, 0.0), (0.1, -0.1)], (0.05, -0.05), {}),
    "concave": ([(2.1, 0.5), (2.0, 0.5)], [(1.0, 1.0), (2.0, 0.0), (3.0, 1.0)], (2.0, -1.0), {}),
    "axis_over_tip": ([(0.0, -0.002)], NOSE, (0.01, 0.05), {}),
    "axis_on_tip": ([(0.0, 0.0), (0.03, -0.001)], NOSE, (0.01, 0.05), {}),
    "snapped_gap": ([(0.15, -1e-9)], FLAT, (0.1, -1.0), {"gap_tol": 1e-8}),
}


@pytest.mark.parametrize("name", list(GEOMETRIES))
def test_set_up_pairs_are_the_brute_force_ones(name):
    slaves, points, inside, kw = GEOMETRIES[name]
    c = _constraints(slaves, points, inside, **kw)
    _assert_build_is_brute_force(c, kw.get("gap_tol", _default_gap_tol(c)))


@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize("ratio", [0.5, 1.0, 3.0])
def test_random_interface_pairs_are_the_brute_force_ones(seed, ratio):
    c = _random_interface(40, ratio, seed)[0]
    _assert_build_is_brute_force(c, _default_gap_tol(c))


def test_curved_face_in_the_default_reach_pairs_are_the_brute_force_ones():
    R, n = 0.02, 8
    theta = np.linspace(0.0, 0.5 * np.pi, n + 1)
    nose = np.stack([R * np.sin(theta), R - R * np.cos(theta)], axis=1)
    c = _constraints([(r, 0.0) for r in np.linspace(0.0, R, 13)], nose, (0.0, R))
    _assert_build_is_brute_force(c, _default_gap_tol(c))


@pytest.mark.parametrize("scene", list(SCENES))
def test_mesh_scene_pairs_are_the_brute_force_ones(scene):
    make, slave, master, reach = SCENES[scene]
    c = node_to_segment(make(MPI.COMM_WORLD), slave, master, reach=reach)
    _assert_build_is_brute_force(c, _default_gap_tol(c))


# ----------------------------------------------------------------------------- (b) perturbed


def _arc(radius, n, z0=0.0):
    """A quarter circle of ``n`` equal segments from the axis (r = 0, z = z0) up to
    r = radius, centre (0, z0 + radius): a nose, its body above."""
    theta = np.linspace(0.0, 0.5 * np.pi, n + 1)
    return np.stack([radius * np.sin(theta), z0 + radius - radius * np.cos(theta)], axis=1)


def _nose_over_arc(n_master, n_slave, radius=0.02, reach=None):
    """Slaves on a quarter circle of ``n_slave`` segments 1e-3 R below a nose of
    ``n_master`` (the master), same centre: non-matching, every slave near the nose."""
    xy, dofs, segs, ins = _surface(_arc(radius, n_master), (0.0, radius))
    slaves = _arc(radius * (1.0 + 1e-3), n_slave, -1e-3 * radius)
    sd = np.stack([2 * np.arange(len(slaves)), 2 * np.arange(len(slaves)) + 1], axis=1)
    return build(slaves, sd, xy, dofs, segs, ins, reach=reach)


@pytest.mark.parametrize("seed", range(5))
def test_perturbed_faces_are_paired_as_by_brute_force(seed):
    """Every node of both faces moved by up to 0.4 of a master segment (seeded): the
    pairs, normals turned with the segments, are the brute force's."""
    c = _nose_over_arc(16, 23)
    rng = np.random.default_rng(seed)
    ell = float(np.linalg.norm(c.master_xy[1] - c.master_xy[0]))
    pairing = Repairing(c)
    for _ in range(3):
        us = rng.uniform(-0.4, 0.4, c.slave_xy.shape) * ell
        um = rng.uniform(-0.4, 0.4, c.master_xy.shape) * ell
        us[c.slave_xy[:, 0] == 0.0, 0] = 0.0  # the axis keeps r = 0
        um[c.master_xy[:, 0] == 0.0, 0] = 0.0
        _assert_repairing_is_brute_force(c, pairing, c.slave_xy + us, c.master_xy + um)


# ----------------------------------------------------------------------------- (c) stretched


@pytest.mark.parametrize("bulge", [0.0, 0.3])
def test_face_stretched_to_twice_its_radius_is_still_found(bulge):
    """A flat master face r <= R of 10 segments under a finer slave face, the reach (the
    cell) 1.5 segments; then the master stretched radially to 2 R (segments of 3/1.5 =
    2 cells), bulged by ``bulge`` segments at its middle, and the slaves spread to
    1.95 R just above it (a Taylor foot): every slave paired, as by brute force."""
    R, n = 0.01, 10
    ell = R / n
    master = np.stack([np.linspace(0.0, R, n + 1), np.zeros(n + 1)], axis=1)
    xy, dofs, segs, ins = _surface(master, (0.5 * R, -R))
    slaves = np.stack([np.linspace(0.0, R, 17), np.full(17, 0.1 * ell)], axis=1)
    sd = np.stack([2 * np.arange(17), 2 * np.arange(17) + 1], axis=1)
    c = build(slaves, sd, xy, dofs, segs, ins, reach=1.5 * ell)
    pairing = Repairing(c)
    _assert_repairing_is_brute_force(c, pairing, c.slave_xy, c.master_xy)
    r = c.master_xy[:, 0]
    master_x = np.stack([2.0 * r, bulge * ell * np.sin(np.pi * r / R)], axis=1)
    rs = 1.95 * c.slave_xy[:, 0]
    slave_x = np.stack([rs, bulge * ell * np.sin(np.pi * rs / (2 * R)) + 0.05 * ell], axis=1)
    p = _assert_repairing_is_brute_force(c, pairing, slave_x, master_x)
    lengths = np.linalg.norm(master_x[c.segments[:, 1]] - master_x[c.segments[:, 0]], axis=1)
    assert pairing.search.grid[2] == c.reach and lengths.min() > c.reach  # longer than a cell
    assert p.active.all() and np.all(p.kind == FACE)
    assert np.all(p.gap > 0.0)  # every slave above the face
    if bulge == 0.0:  # the slave on the axis over the face's axis node: the axial normal
        assert p.normal[0].tolist() == [0.0, 1.0]


# ----------------------------------------------------------------------------- (d) sliding off


def test_slave_sliding_off_the_end_is_released_and_paired_again():
    """One slave 0.1 segment above a flat master face r <= R (end at r = R, off the
    axis) slides out to 1.2 R and back: within the end tolerance past the end (half of
    it) it stays on the face's continuation; beyond it has no row but keeps its place;
    back over the face it is paired again, xi and gap by closed form."""
    R, n = 0.01, 10
    ell = R / n
    master = np.stack([np.linspace(0.0, R, n + 1), np.zeros(n + 1)], axis=1)
    xy, dofs, segs, ins = _surface(master, (0.5 * R, -R))
    c = build([(0.5 * R, 0.1 * ell)], [[0, 1]], xy, dofs, segs, ins, reach=2.0 * ell)
    pairing = Repairing(c)
    last = int(np.argmax(c.master_xy[c.segments[:, 1], 0]))  # the segment ending at R
    seen = []
    just_past = R + 0.5 * END_TOLERANCE * ell
    for r in (0.95 * R, just_past, 1.05 * R, 1.2 * R, 0.95 * R):
        slave = np.array([[r, 0.1 * ell]])
        p = _assert_repairing_is_brute_force(c, pairing, slave, c.master_xy)
        seen.append(bool(p.active[0]))
        if r == just_past:  # the face continued: its end, its normal, the height above it
            assert p.seg[0] == last and p.kind[0] == FACE and p.xi[0] == 1.0
            assert p.gap[0] == 0.1 * ell
        elif p.active[0]:
            assert p.seg[0] == last and p.kind[0] == FACE
            # xi = (r - r_a) / (r_b - r_a) on the stored coordinates: both differences
            # are exact (operands within a factor 2), (dr t_r) / (t_r t_r) rounds 3 times
            a, b = c.master_xy[c.segments[last], 0]
            assert p.xi[0] == pytest.approx((r - a) / (b - a), rel=rounding(4))
            assert p.gap[0] == 0.1 * ell  # (x - x_p) . n with n = (0, 1) exactly
        else:
            # beyond the end vertex (1.05 R), or beyond the reach, 2 segments (1.2 R)
            assert (p.seg[0] == last and p.kind[0] == VERTEX) or p.seg[0] == -1
    assert seen == [True, True, False, False, True]
    assert c.n == 1 and pairing.pairs.active.size == 1  # kept, never dropped


def test_convex_corner_and_axis_tip_are_not_ends():
    """A slave beyond a convex corner (a node of two segments) and one on the axis below
    a tilted tip (a face's end on r = 0, continued by symmetry) keep their rows."""
    for name in ("convex", "axis_over_tip"):
        slaves, points, inside, _ = GEOMETRIES[name]
        c = _constraints(slaves, points, inside)
        p = Repairing(c)(c.slave_xy, c.master_xy)
        assert c.kind[0] == VERTEX and p.active[0] and np.array_equal(p.normal, c.normal)


# ----------------------------------------------------------------------------- the cost


def _candidates_per_slave(c, search, master_x):
    """A bound on the segments in one cell, for a face that is a convex polyline (the
    quarter circle). A segment is listed in a cell when its box inflated by ``inflate``
    touches it; the box lies within the segment's length of the segment, so the segment
    meets the square Q of side s = h + 2 inflate + 2 l_max around the cell. The part of
    a convex polyline inside a convex Q is at most Q's perimeter 4 s long, so at most
    4 s / l_min of its segments lie wholly inside Q; the others meet Q's boundary, whose
    4 sides each meet a convex polyline in at most 2 points, each on at most 2 segments
    (a node): at most 16 more."""
    lengths = np.linalg.norm(master_x[c.segments[:, 1]] - master_x[c.segments[:, 0]], axis=1)
    assert c.reach <= search.inflate <= c.reach * (1.0 + 2e-6)  # the reach and round-off
    s = search.grid[2] + 2.0 * search.inflate + 2.0 * lengths.max()
    return int(4.0 * s / lengths.min()) + 16


def test_candidate_projections_grow_with_the_nodes_not_their_product():
    """A nose of 16, 64 and 256 segments (refined 4x and 16x) over a non-matching arc of
    1.4 times as many slaves, the reach (the cell) two segments: the projections made
    are at most the bound per slave times the slaves (a constant, 48), while the brute
    force makes slaves x segments."""
    made = []
    for n in (16, 64, 256):
        ell = 2.0 * 0.02 * np.sin(0.25 * np.pi / n)
        c = _nose_over_arc(n, int(1.4 * n), reach=2.0 * ell)
        pairing = Repairing(c)
        p = _assert_repairing_is_brute_force(c, pairing, c.slave_xy, c.master_xy)
        # every slave has a row, the rim's too: it lies 1e-3 R outside the nose's end
        # node, along the end segment's normal (the segment runs along z there), so on
        # the face's continuation, not beyond its end by the end tolerance
        assert p.active.all()
        search = pairing.search
        assert search.grid[2] == c.reach  # cells of the reach (memory not capped)
        bound = _candidates_per_slave(c, search, c.master_xy)
        assert bound == 48
        assert search.candidates <= bound * c.n
        assert n == 16 or bound < c.segments.shape[0]  # refined: below the brute force's
        made.append(search.candidates / c.n)
    print(f"\nprojections per slave at 16, 64, 256 segments: {made} (bound 48)")


def test_a_re_pairing_reuses_its_arrays():
    """Two re-pairings of one geometry, the second after the master moved: the grid's
    arrays and the pairs are the same objects (nothing allocated when the grid fits)."""
    c = _nose_over_arc(16, 23)
    pairing = Repairing(c)
    p = pairing(c.slave_xy, c.master_xy)
    arrays = (pairing.search.start, pairing.search.entries, p.seg, p.normal, p.gap)
    q = pairing(c.slave_xy, c.master_xy + [0.0, 1e-5])
    assert q is p and all(a is b for a, b in zip(arrays, (pairing.search.start,
                                                          pairing.search.entries, q.seg,
                                                          q.normal, q.gap)))


def test_cells_enlarged_past_the_memory_cap_give_the_same_pairs():
    """The nose of 256 segments at a reach of two segments wants about 7,000 cells; with
    the cap lowered to its floor (1,024 cells) the cells are doubled until the grid
    fits: the pairs stay the brute force's, the projections grow."""
    ell = 2.0 * 0.02 * np.sin(0.25 * np.pi / 256)
    c = _nose_over_arc(256, 358, reach=2.0 * ell)
    pairing = Repairing(c)
    _assert_repairing_is_brute_force(c, pairing, c.slave_xy, c.master_xy)
    fine = pairing.search.candidates
    pairing.search.cells_per_item = 0
    _assert_repairing_is_brute_force(c, pairing, c.slave_xy, c.master_xy)
    nx, ny = pairing.search.shape
    assert pairing.search.grid[2] > c.reach and nx * ny <= 1024
    assert pairing.search.candidates > fine
