"""Node-to-segment geometry, the complementarity solver and one DME collision (no mesh).

Oracles: closed-form projections of points on segments (the edge cases of
contact/segments.py: snapping, one segment per slave, convex and concave
vertices, the axis, initial gaps, reach), invariance of the result under any
order of the input (what a partition changes), the Karush-Kuhn-Tucker
conditions of the complementarity problem, and Newton's law with momentum and
energy for one slave striking a segment. Round-off bounds count the roundings of the
computation on its largest magnitude (tests/roundoff.py); a difference of coordinates
that cancels digits counts them (|x| / |x - a| times).
"""
from types import SimpleNamespace

import numpy as np
import pytest

from impact_fenics.contact.banded import (apply_multipliers, band_of_s, bandwidth, dense_s,
                                          gershgorin_beta, lcp_bpp, lcp_dense)
from impact_fenics.contact import DME, FILM, Penalty
from impact_fenics.contact.segments import FACE, VERTEX, build
from impact_fenics.contact.state import SEGMENTS
from impact_fenics.errors import InputError
from roundoff import LIBM, rounding

# lcp_bpp (contact/banded.py) accepts an unloaded constraint with w >= -1e-13 max|g~|
ACCEPT = 1e-13


def _surface(points, inside):
    """Master polyline through ``points`` with the body on the side of ``inside`` (a point)."""
    xy = np.asarray(points, float)
    segs = np.stack([np.arange(len(xy) - 1), np.arange(1, len(xy))], axis=1)
    dofs = np.stack([100 + 2 * np.arange(len(xy)), 101 + 2 * np.arange(len(xy))], axis=1)
    return xy, dofs, segs, np.tile(np.asarray(inside, float), (len(segs), 1))


def _constraints(slaves, points, inside, **kw):
    xy, dofs, segs, ins = _surface(points, inside)
    s = np.asarray(slaves, float)
    sd = np.stack([2 * np.arange(len(s)), 2 * np.arange(len(s)) + 1], axis=1)
    return build(s, sd, xy, dofs, segs, ins, **kw)


FLAT = [(0.0, 0.0), (0.1, 0.0), (0.2, 0.0), (0.3, 0.0)]


def test_face_projection_and_snapping():
    c = _constraints([(0.125, 0.01), (0.1 + 1e-9, 0.0)], FLAT, (0.1, -1.0))
    assert c.kind.tolist() == [FACE, FACE]
    assert np.array_equal(c.normal, [[0, 1], [0, 1]])  # a horizontal segment: exact
    j, k = int(np.argmax(c.slave_xy[:, 0])), int(np.argmin(c.slave_xy[:, 0]))
    # xi = (x - a) . t / |t|^2: 4 roundings, x - a = 0.025 cancelling 0.225 / 0.025 of them
    assert c.xi[j] == pytest.approx(0.25, rel=rounding(4 * 0.225 / 0.025))
    assert c.g0[j] == pytest.approx(0.01, rel=rounding(4))  # (s - a) . n, n exact
    # 1e-8 of a segment from a node: snapped to the node, exactly one weight
    assert c.xi[k] in (0.0, 1.0)
    node = c.a[k] if c.xi[k] == 0.0 else c.b[k]
    assert np.array_equal(c.master_xy[node], [0.1, 0.0]) and c.g0[k] == 0.0


def test_one_segment_per_slave_over_a_master_node_whatever_the_order():
    """A slave over a master node projects onto both neighbours: one is taken, the same
    for every order of the input (partition independence)."""
    slaves = [(0.1, 0.0), (0.2, 0.02), (0.05, 0.0)]
    ref = _constraints(slaves, FLAT, (0.1, -1.0))
    assert ref.n == 3  # one constraint per slave, not two
    rng = np.random.default_rng(3)
    xy, dofs, segs, ins = _surface(FLAT, (0.1, -1.0))
    for _ in range(5):
        pm, ps, pl = rng.permutation(len(xy)), rng.permutation(len(segs)), rng.permutation(3)
        inv = np.argsort(pm)
        s = np.asarray(slaves)[pl]
        c = build(s, np.stack([2 * pl, 2 * pl + 1], 1), xy[pm], dofs[pm],
                  inv[segs[ps]][:, ::-1], ins[ps])
        for f in ("slave_xy", "xi", "normal", "g0", "kind"):
            assert np.array_equal(getattr(c, f), getattr(ref, f)), f
        assert np.array_equal(c.master_dofs[c.a], ref.master_dofs[ref.a])
        assert np.array_equal(c.master_dofs[c.b], ref.master_dofs[ref.b])
    # the node at r = 0.1 is the end of the first segment (global order by midpoint r)
    k = int(np.flatnonzero(ref.slave_xy[:, 0] == 0.1)[0])
    assert ref.seg[k] == 0 and ref.xi[k] == 1.0


def test_convex_vertex_uses_the_vertex_and_the_direction_to_the_slave():
    corner = [(0.0, 0.0), (0.1, 0.0), (0.1, -0.1)]  # top and side of a block, body below-left
    c = _constraints([(0.13, 0.04)], corner, (0.05, -0.05))
    assert c.kind[0] == VERTEX
    # (s - x_v) / |s - x_v|: 0.13 - 0.1 cancels 0.23 / 0.03 of the digits, a norm (4 + LIBM)
    cancel = 0.23 / 0.03
    assert np.allclose(c.normal[0], [0.6, 0.8], atol=0, rtol=rounding((6 + LIBM) * cancel))
    assert c.g0[0] == pytest.approx(0.05, rel=rounding((4 + LIBM) * cancel))
    node = c.a[0] if c.xi[0] == 0.0 else c.b[0]
    assert np.array_equal(c.master_xy[node], [0.1, 0.0])


def test_concave_vertex_takes_the_closest_segment_and_breaks_ties_by_order():
    valley = [(1.0, 1.0), (2.0, 0.0), (3.0, 1.0)]  # body below the V
    c = _constraints([(2.1, 0.5), (2.0, 0.5)], valley, (2.0, -1.0))
    k_off = int(np.flatnonzero(c.slave_xy[:, 0] == 2.1)[0])
    # distances 0.4/sqrt2 (right) and 0.6/sqrt2 (left): the right segment; (s - a) . n
    # with n = t / |t| (4 + LIBM roundings), s - a = 0.1 cancelling 4.1 / 0.1 of the digits
    # (and 0.5 x n_z - 0.1 x n_r: 0.6 / 0.4 more)
    assert c.seg[k_off] == 1 and c.g0[k_off] == pytest.approx(
        0.4 / np.sqrt(2), rel=rounding((8 + LIBM) * 41 * 1.5))
    k_mid = 1 - k_off
    assert c.seg[k_mid] == 0  # tie: the first segment in the global order
    assert np.allclose(c.normal[k_mid], [1 / np.sqrt(2), 1 / np.sqrt(2)], atol=0,
                       rtol=rounding(4 + 2 * LIBM))


def test_axis_slave_over_a_tilted_tip_gets_an_axial_normal():
    nose = [(0.0, 0.0), (0.05, 0.01), (0.1, 0.04)]  # a convex tip on the axis, body above
    c = _constraints([(0.0, -0.002)], nose, (0.01, 0.05))
    assert c.kind[0] == VERTEX and c.normal[0].tolist() == [0.0, -1.0]
    assert c.g0[0] == pytest.approx(0.002, rel=rounding(4))  # (s - x_v) . n, n exact


def test_axis_slave_on_a_tilted_tip_gets_an_axial_normal():
    nose = [(0.0, 0.0), (0.05, 0.01), (0.1, 0.04)]
    c = _constraints([(0.0, 0.0), (0.03, -0.001)], nose, (0.01, 0.05))
    assert c.normal[0].tolist() == [0.0, -1.0] and c.g0[0] == 0.0 and c.xi[0] == 0.0
    assert c.kind[1] == FACE and c.normal[1, 0] > 0  # off the axis: the segment's tilt


def test_initial_gaps_reach_and_penetration():
    c = _constraints([(0.15, -1e-9)], FLAT, (0.1, -1.0), gap_tol=1e-8)
    assert c.g0[0] == 0.0  # within the tolerance: zero
    with pytest.raises(InputError, match="penetrates .* initially by 1e-05 m"):
        _constraints([(0.15, -1e-5)], FLAT, (0.1, -1.0), gap_tol=1e-8)
    with pytest.raises(InputError, match="no segment of 'master' within reach"):
        _constraints([(0.15, 0.5)], FLAT, (0.1, -1.0))


# ----------------------------------------------------------------------------- the solver

def _random_interface(n_slave, ratio, seed):
    """A flat interface: n_slave slaves over a master face of about n_slave/ratio segments,
    random masses; returns the G entries in the global order."""
    rng = np.random.default_rng(seed)
    n_seg = max(1, int(n_slave / ratio))
    master = np.stack([np.linspace(0, 1, n_seg + 1), np.zeros(n_seg + 1)], 1)
    slaves = np.stack([np.sort(rng.uniform(0, 1, n_slave)), rng.uniform(0, 1e-3, n_slave)], 1)
    xy, dofs, segs, ins = _surface(master, (0.5, -1))
    c = build(slaves, np.zeros((n_slave, 2), int), xy, dofs, segs, ins)
    ns = n_slave
    s = np.arange(ns)
    cs = np.stack([2 * s, 2 * s + 1, 2 * (ns + c.a), 2 * (ns + c.a) + 1, 2 * (ns + c.b),
                   2 * (ns + c.b) + 1], 1)
    na, nb, nr, nz = 1 - c.xi, c.xi, c.normal[:, 0], c.normal[:, 1]
    cc = np.stack([nr, nz, -na * nr, -na * nz, -nb * nr, -nb * nz], 1)
    mass = rng.uniform(0.5, 2.0, 2 * (ns + len(xy)))
    return c, cs, cc, mass


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_block_pivoting_meets_the_complementarity_conditions(seed):
    _, cs, cc, mass = _random_interface(60, 0.4, seed)  # several slaves per segment
    minv = 1.0 / mass
    dt = 1e-3
    bw = bandwidth(cs, cc, minv)
    band = np.empty((cs.shape[0], bw + 1))
    band_of_s(cs, cc, minv, dt, bw, band)
    S = dense_s(band, bw)
    G = np.zeros((cs.shape[0], mass.size))
    np.add.at(G, (np.repeat(np.arange(cs.shape[0]), 6), cs.ravel()), cc.ravel())
    # an entry of S sums at most 6 x 6 products dt^2 c_i c_j / m (4 roundings each, 36
    # terms), each within the largest diagonal entry (Cauchy-Schwarz)
    assert np.allclose(S, dt ** 2 * (G / mass) @ G.T, rtol=0, atol=rounding(40, np.diag(S).max()))
    assert (S - np.diag(np.diag(S))).max() > 0  # positive off-diagonals: not an M-matrix
    rng = np.random.default_rng(seed)
    gap = rng.normal(0, 1e-6, cs.shape[0])
    n = gap.size
    lam, w = np.zeros(n), np.zeros(n)
    free = gap < 0
    it = lcp_bpp(band, bw, gap, lam, w, free, np.zeros(n, np.int64), np.zeros(n), np.zeros(n),
                 np.zeros((n, bw + 1)), 500, np.zeros(n + 1, bool), np.ones(n, bool))
    assert it > 0
    scale = np.abs(gap).max()
    w_check = gap + S @ lam
    # a banded solve (bandwidth bw) errs by about 4 (bw + 1) roundings a row times the
    # condition number of S on the loaded set; w_check adds 2 bw + 2 of its own
    loaded = lam > 0
    cond = np.linalg.cond(S[np.ix_(loaded, loaded)])
    w_round = rounding(4 * (bw + 1) * cond + 2 * bw + 2, scale) + ACCEPT * scale
    assert lam.min() >= 0 and w_check.min() >= -w_round
    assert np.abs(lam * w_check).max() <= w_round * np.abs(lam).max()
    lam_d = np.zeros(n)
    lcp_dense(S, gap, lam_d)
    # two solvers of the loaded set's system (the dense one: n roundings a row)
    assert np.allclose(lam, lam_d, rtol=0, atol=rounding((4 * (bw + 1) + n) * cond,
                                                         np.abs(lam).max()))


def test_gershgorin_bounds_the_largest_eigenvalue():
    _, cs, cc, mass = _random_interface(40, 0.5, 4)
    minv = 1.0 / mass
    bw = bandwidth(cs, cc, minv)
    band = np.empty((cs.shape[0], bw + 1))
    band_of_s(cs, cc, minv, 1e-3, bw, band)
    p = 1.0 / band[:, 0]
    S = dense_s(band, bw)
    lam_max = np.linalg.eigvalsh(np.sqrt(p)[:, None] * S * np.sqrt(p)[None, :]).max()
    # LAPACK's eigenvalue: O(n) roundings of |A| (n = 40); the row sums: 2 bw + 1 terms
    assert lam_max <= gershgorin_beta(band, bw, p) * (1 + rounding(40 + 2 * bw + 1))


# ----------------------------------------------------------------------------- one collision

def _one_slave_set(xi, e_normal, v_slave, v_master):
    """One slave (slots 0, 1) over a segment (nodes at slots 2..5), inclined normal."""
    n = np.asarray(e_normal, float) / np.linalg.norm(e_normal)
    mass = np.array([2.0, 2.0, 1.0, 1.0, 3.0, 3.0])
    cs = np.array([[0, 1, 2, 3, 4, 5]])
    cc = np.array([[n[0], n[1], -(1 - xi) * n[0], -(1 - xi) * n[1], -xi * n[0], -xi * n[1]]])
    dt = 1e-6
    minv = 1.0 / mass
    band = np.empty((1, 1))
    band_of_s(cs, cc, minv, dt, 0, band)
    v = np.concatenate([v_slave, v_master]).astype(float)
    u = np.zeros(6)
    u_pred = u + dt * v
    c = SimpleNamespace(kind=SEGMENTS, n=1, bw=0, band=band, cs=cs, cc=cc, mass=mass,
                        free=np.ones(6, bool), dt=dt, h_avg=dt, u=u_pred.copy(), v=v.copy(), u_pred=u_pred, v_pred=v.copy(),
                        force=np.zeros(1), active=np.zeros(1, bool), g0=np.zeros(1))
    c.gap = np.array([float(cc[0] @ u_pred[cs[0]])])
    c.apply_forces = None
    return c, n


@pytest.mark.parametrize("e", [0.0, 0.5, 1.0])
def test_dme_collision_obeys_newton_momentum_and_energy(e):
    """Round-off: the impulse is -(1 + e) m_eff (G v) with G v a 6-term product (12
    roundings) and m_eff = 1 / (G M^-1 G') (16 more); each velocity changes by G_i
    impulse / m_i (3): about 32 roundings of the largest |v| (velocities of order 1,
    masses 1 to 3, no cancellation beyond that); positions likewise of the largest |u|."""
    c, n = _one_slave_set(0.3, (0.3, 1.0), v_slave=(0.2, -1.0), v_master=(0.0, 0.5, 0.1, 0.4))
    v0 = c.v.copy()
    rel = lambda v: float(c.cc[0] @ v)  # noqa: E731  normal relative velocity
    assert rel(v0) < 0 and c.gap[0] < 0
    m = DME(restitution=e)
    m.setup(c)
    m.correct(c)
    assert c.active[0]
    v_scale = np.abs(v0).max()
    v_round = rounding(32, v_scale)  # the error of a velocity
    assert abs(rel(c.v) + e * rel(v0)) <= rounding(6 * 32 + 12, v_scale)  # G v: |G_i| <= 1
    mass = c.mass.sum()
    p0 = [np.sum(c.mass[k::2] * v0[k::2]) for k in (0, 1)]
    p1 = [np.sum(c.mass[k::2] * c.v[k::2]) for k in (0, 1)]
    assert np.allclose(p1, p0, rtol=0, atol=rounding(40, mass * v_scale))
    # the impulse with m_eff = (1/m_s + sum N_i^2/m_i)^-1, and kinetic energy: lost
    # (1 - e^2)/2 m_eff rel^2 (none at e = 1)
    m_eff = 1.0 / (1 / 2.0 + 0.7 ** 2 / 1.0 + 0.3 ** 2 / 3.0)
    assert c.force[0] * c.dt == pytest.approx(-(1 + e) * m_eff * rel(v0), rel=rounding(32))
    ke = lambda v: 0.5 * np.sum(c.mass * v * v)  # noqa: E731
    # sum m v dv over the velocities' errors, and the sums' own roundings
    assert ke(v0) - ke(c.v) == pytest.approx(0.5 * (1 - e * e) * m_eff * rel(v0) ** 2, rel=0,
                                             abs=v_round * mass * v_scale + rounding(8, ke(v0)))
    # positions: on the manifold g = 0, the centre of mass unchanged
    u_scale = max(np.abs(c.u).max(), np.abs(c.u_pred).max())
    assert abs(float(c.cc[0] @ c.u)) <= rounding(6 * 32 + 12, u_scale)
    assert np.allclose([np.sum(c.mass[k::2] * c.u[k::2]) for k in (0, 1)],
                       [np.sum(c.mass[k::2] * c.u_pred[k::2]) for k in (0, 1)], rtol=0,
                       atol=rounding(40, mass * u_scale))


def test_film_holds_the_gap_and_keeps_momentum():
    c, n = _one_slave_set(0.6, (-0.2, 1.0), v_slave=(0.0, -2.0), v_master=(0.1, 0.0, 0.0, 0.3))
    c.apply_forces = lambda lam: apply_multipliers(lam, c.cs, c.cc, c.mass, c.free, c.dt, c.u,
                                                   c.v, c.dt)
    v0 = c.v.copy()
    m = FILM()
    m.setup(c)
    m.correct(c)
    # as for DME: 32 roundings of a corrected value, G u a 6-term product
    u_scale = max(np.abs(c.u).max(), np.abs(c.u_pred).max())
    assert abs(float(c.cc[0] @ c.u)) <= rounding(6 * 32 + 12, u_scale)
    assert m.iterations == 1
    assert np.allclose([np.sum(c.mass[k::2] * c.v[k::2]) for k in (0, 1)],
                       [np.sum(c.mass[k::2] * v0[k::2]) for k in (0, 1)], rtol=0,
                       atol=rounding(40, c.mass.sum() * np.abs(v0).max()))


def test_penalty_above_the_stability_bound_is_refused_unless_forced():
    """beta = p S_ii for one constraint (Gershgorin is exact there): 2 > 4/3 is refused,
    'scaled' puts beta at 1."""
    c, _ = _one_slave_set(0.3, (0.3, 1.0), v_slave=(0.0, -1.0), v_master=(0, 0, 0, 0))
    p = 2.0 / c.band[0, 0]
    with pytest.raises(InputError, match="exceeds the stability limit 4/3"):
        Penalty(p).setup(c)
    forced = Penalty(p, force=True)
    forced.setup(c)
    # p = 2 / S_11, beta = p S_11 through the Gershgorin row sum: a few roundings (8)
    assert forced.info["beta_max"] == pytest.approx(2.0, rel=rounding(8))
    scaled = Penalty("scaled")
    scaled.setup(c)
    assert scaled.info["beta_max"] == pytest.approx(1.0, rel=rounding(8))
    with pytest.raises(InputError, match="must be > 0"):
        Penalty(-1.0)


def test_the_default_reach_takes_a_curved_faces_slaves_and_refuses_faces_apart():
    """A nose of radius R (a quarter circle in 8 segments, tip on the axis at z = 0, centre
    at (0, R)) over the flat face z = 0, r <= R: the slave under the rim is R (sqrt 2 - 1)
    from the nose (closed form, plus at most the segments' sagitta R (1 - cos(pi / 32))),
    beyond the longest segment 2 R sin(pi / 32), and in the default reach (that segment plus
    the nose's depth R along the face's normal). The face lowered by 2 R, farther than
    that depth and a segment: refused. (Two flat faces apart: the test above.)"""
    R, n = 0.02, 8
    theta = np.linspace(0.0, 0.5 * np.pi, n + 1)
    nose = np.stack([R * np.sin(theta), R - R * np.cos(theta)], axis=1)
    face = [(r, 0.0) for r in np.linspace(0.0, R, 13)]
    c = _constraints(face, nose, (0.0, R))
    assert c.n == 13
    rim = int(np.argmax(c.slave_xy[:, 0]))
    gap = R * (np.sqrt(2.0) - 1.0)
    assert gap > 2 * R * np.sin(np.pi / 32)  # beyond the longest segment
    # (45 degrees is a vertex of the nose: the distance is the closed form, to the
    # round-off of a few operations on coordinates of size R)
    assert gap - 1e-14 * R <= c.g0[rim] <= gap + R * (1.0 - np.cos(np.pi / 32)) + 1e-14 * R
    with pytest.raises(InputError, match="no segment of 'master' within reach"):
        _constraints([(r, -2.0 * R) for r, _ in face], nose, (0.0, R))


def _recorded_problem(name: str):
    """(band, bw, gap) of a complementarity problem recorded from a run (tests/data: float.hex,
    exact)."""
    import os

    rows, bw = [], 0
    with open(os.path.join(os.path.dirname(__file__), "data", name)) as f:
        for line in f:
            if line.startswith("bw "):
                bw = int(line.split()[1])
            elif not line.startswith("#"):
                rows.append([float.fromhex(x) for x in line.split()])
    table = np.array(rows)
    return np.ascontiguousarray(table[:, 1:]), bw, np.ascontiguousarray(table[:, 0])


def test_block_pivoting_of_subnormal_gaps():
    """A problem recorded where a run stopped ("dme: complementarity pivoting did not
    converge"): DME's positions on the finite SHPB specimen's faces (41 constraints) at a
    step where every predicted gap was subnormal, at most 5.3e-321 m (the wave's numerical
    precursor ahead of it). The tolerance 1e-13 max|g~| underflowed to 0 and the
    subnormals' few bits flipped signs from pivot to pivot: no start converged in 1000
    pivots. Now (banded.tolerance) it converges and meets complementarity to the least
    normal double, below which every value is 0 to the physics. The test's own
    w = g~ + S lam in subnormal arithmetic rounds by at most 2^-1074 an operation
    (absolute), 2 bw + 2 operations a row: far below that."""
    band, bw, gap = _recorded_problem("subnormal_pivoting.txt")
    n = gap.size
    tiny = np.finfo(float).tiny
    assert np.abs(gap).max() < tiny and (gap < 0).sum() == 13
    for start in (gap < 0, np.ones(n, bool), np.zeros(n, bool)):
        lam, w, free = np.zeros(n), np.zeros(n), start.copy()
        it = lcp_bpp(band, bw, gap, lam, w, free, np.zeros(n, np.int64), np.zeros(n),
                     np.zeros(n), np.zeros((n, bw + 1)), 1000, np.zeros(n + 1, bool),
                     np.ones(n, bool))
        assert it > 0
        w_check = gap + dense_s(band, bw) @ lam
        assert lam.min() >= 0.0 and w_check.min() >= -tiny
        assert np.abs(lam * w_check).max() <= tiny * max(np.abs(lam).max(), 1.0)
