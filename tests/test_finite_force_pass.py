"""The fused finite-strain force pass against the one it replaced: force, stress and state
to round-off.

The pass computes each point's F-bar factor (J_bar / J_q)^(1/3) (plane strain: ^(1/2))
for the cell's four points in a loop of their own, from one reciprocal 1 / J_q a point
(ratio J_bar (1 / J_q), and 1 / det of the (r, z) block = F_tt / J_q in P) and one
1 / R (F_tt and the hoop term), where the previous pass took the quotient J_bar / J_q, its
root inside the loop of the point updates, the block's determinant again in P and two
quotients by R. The same quantities, other roundings: class (b)
of tests/roundoff.py. The pass also takes F and the force through the reference cell
(Grad u = (du/dxi, du/deta) J^-1 from the node differences; f_a = sum_q P J^-T : dN_a/dxi)
where the previous summed u_a Grad N_a and P Grad N_a: F too is the same quantity in other
roundings (:func:`gradient_roundings`). The previous pass is kept below, as it was (with
its cube root), as the oracle.

Cases: a distorted Q1 mesh touching the axis (cells with an axis edge), for every finite
material (Hencky J2 with points yielding and points elastic, Johnson-Cook, neo-Hookean)
and both geometries, under F = I (u = 0: equal eigenvalues everywhere), a uniform
dilatation (equal in-plane eigenvalues; in axisymmetry F_tt = F_rr too), and random
fields of small (elastic) and large (yielding) strain. Every check runs on data made the
same on every rank.
"""
import math

import numpy as np
import pytest
from numba import njit

from impact_fenics.geometry import Geometry, PLANE_STRAIN
from impact_fenics.internal_force.finite import THIRD, WORK, kernels
from impact_fenics.materials import FiniteJ2, JohnsonCook, NeoHookean
from impact_fenics.q1 import GAUSS, QuadGeometry, shape_functions
from roundoff import LIBM, rounding
from test_johnson_cook_return import root_tolerance

_PREVIOUS: dict = {}


@njit(cache=True, error_model="numpy")
def previous_cube_root(x: float) -> float:
    """The kernel's cube root before its binomial series branch (|x - 1| <= 1/64), verbatim:
    within 3 ulp (the Newton steps from the series of x^(-1/3) near 1, Halley's iteration
    on [1/8, 8], numpy's cbrt elsewhere)."""
    e = x - 1.0
    if -0.125 <= e <= 0.125:
        r = 1.0 + e * (-THIRD + e * (2.0 / 9.0 + e * (-14.0 / 81.0)))
        r = r + r * (1.0 - x * r * r * r) * THIRD
        r = r + r * (1.0 - x * r * r * r) * THIRD
        r2 = r * r
        y = x * r2
        return y - (y * y * y - x) * r2 * THIRD
    if 0.125 <= x <= 8.0:
        y = (1.0 + 2.0 * x) / (2.0 + x)
        y3 = y * y * y
        y = y * (y3 + 2.0 * x) / (2.0 * y3 + x)
        y3 = y * y * y
        y = y * (y3 + 2.0 * x) / (2.0 * y3 + x)
        return y - (y * y * y - x) / (3.0 * y * y)
    return np.cbrt(x)


def previous_kernel(update, n_state: int, point_copy: bool, plane: bool):
    """The force pass before the F-bar factors had their own loop (verbatim)."""
    key = (update, n_state, point_copy, plane)
    if key in _PREVIOUS:
        return _PREVIOUS[key]

    @njit(fastmath=False, error_model="numpy")
    def force(params, dt, dofs, dNdR, dNdZ, N, R, w, volume, u, f, state, tau, Fq, Jq, fbar, work,
              point_state, point_tau):
        wp = 0.0
        j_min = np.inf
        c_min = -1
        for c in range(dofs.shape[0]):
            # the cell's nodal displacements, read once for its four points
            k0, k1, k2, k3 = 2 * dofs[c, 0], 2 * dofs[c, 1], 2 * dofs[c, 2], 2 * dofs[c, 3]
            u0r, u1r, u2r, u3r = u[k0], u[k1], u[k2], u[k3]
            u0z, u1z, u2z, u3z = u[k0 + 1], u[k1 + 1], u[k2 + 1], u[k3 + 1]
            jbar = 0.0
            for q in range(4):
                g0, g1, g2, g3 = dNdR[c, q, 0], dNdR[c, q, 1], dNdR[c, q, 2], dNdR[c, q, 3]
                h0, h1, h2, h3 = dNdZ[c, q, 0], dNdZ[c, q, 1], dNdZ[c, q, 2], dNdZ[c, q, 3]
                frr = 1.0 + (g0 * u0r + g1 * u1r + g2 * u2r + g3 * u3r)
                frz = h0 * u0r + h1 * u1r + h2 * u2r + h3 * u3r
                fzr = g0 * u0z + g1 * u1z + g2 * u2z + g3 * u3z
                fzz = 1.0 + (h0 * u0z + h1 * u1z + h2 * u2z + h3 * u3z)
                if plane:
                    Fq[q, 0], Fq[q, 1], Fq[q, 2], Fq[q, 3], Fq[q, 4] = frr, frz, fzr, fzz, 1.0
                    Jq[q] = frr * fzz - frz * fzr
                else:
                    ftt = 1.0 + (N[q, 0] * u0r + N[q, 1] * u1r + N[q, 2] * u2r
                                 + N[q, 3] * u3r) / R[c, q]
                    Fq[q, 0], Fq[q, 1], Fq[q, 2], Fq[q, 3], Fq[q, 4] = frr, frz, fzr, fzz, ftt
                    Jq[q] = (frr * fzz - frz * fzr) * ftt
                jbar += w[c, q] * Jq[q]
                if Jq[q] < j_min:
                    j_min = Jq[q]
                    c_min = c
            jbar /= volume[c]
            if jbar <= 0.0 or j_min <= 0.0:
                return wp, j_min, c_min
            m_bar = 0.0
            for q in range(4):
                if plane:  # the in-plane block scaled, F_bar_out = 1
                    alpha = math.sqrt(jbar / Jq[q])
                    for i in range(4):
                        fbar[i] = alpha * Fq[q, i]
                    fbar[4] = 1.0
                else:
                    alpha = previous_cube_root(jbar / Jq[q])
                    for i in range(5):
                        fbar[i] = alpha * Fq[q, i]
                if point_copy:
                    for i in range(n_state):
                        point_state[i] = state[c, q, i]
                    wp += w[c, q] * update(fbar, point_state, params, dt, point_tau, work)
                    for i in range(n_state):
                        state[c, q, i] = point_state[i]
                    for i in range(4):
                        tau[c, q, i] = point_tau[i]
                else:
                    wp += w[c, q] * update(fbar, state[c, q], params, dt, tau[c, q], work)
                if plane:
                    m_bar += w[c, q] * (tau[c, q, 0] + tau[c, q, 2])
                else:
                    m_bar += w[c, q] * (tau[c, q, 0] + tau[c, q, 1] + tau[c, q, 2])
            m_bar /= jbar * volume[c]
            f0r = f1r = f2r = f3r = f0z = f1z = f2z = f3z = 0.0
            for q in range(4):
                t0, t1, t2, t3 = tau[c, q, 0], tau[c, q, 1], tau[c, q, 2], tau[c, q, 3]
                frr, frz, fzr, fzz, ftt = Fq[q, 0], Fq[q, 1], Fq[q, 2], Fq[q, 3], Fq[q, 4]
                if plane:
                    # tau_eff = tau - 1/2 tr2 tau I2 + 1/2 J m_bar2 I2 (in-plane block only)
                    shift = 0.5 * Jq[q] * m_bar - 0.5 * (t0 + t2)
                    trr, ttt, tzz, trz = t0 + shift, 0.0, t2 + shift, t3
                else:
                    p = (t0 + t1 + t2) / 3.0
                    shift = Jq[q] * m_bar / 3.0 - p  # tau_eff = tau - p I + J m_bar / 3 I
                    trr, ttt, tzz, trz = t0 + shift, t1 + shift, t2 + shift, t3
                # w_q F^-1 of the (r, z) block; P = tau_eff F^-T, P_ij = sum_k tau_ik Finv_jk
                wq = w[c, q]
                scale = wq / (frr * fzz - frz * fzr)
                i00, i01, i10, i11 = fzz * scale, -frz * scale, -fzr * scale, frr * scale
                prr = trr * i00 + trz * i01
                prz = trr * i10 + trz * i11
                pzr = trz * i00 + tzz * i01
                pzz = trz * i10 + tzz * i11
                ptt = 0.0 if plane else wq * ttt / (ftt * R[c, q])  # no hoop term in plane
                g0, g1, g2, g3 = dNdR[c, q, 0], dNdR[c, q, 1], dNdR[c, q, 2], dNdR[c, q, 3]
                h0, h1, h2, h3 = dNdZ[c, q, 0], dNdZ[c, q, 1], dNdZ[c, q, 2], dNdZ[c, q, 3]
                f0r += prr * g0 + prz * h0 + ptt * N[q, 0]
                f1r += prr * g1 + prz * h1 + ptt * N[q, 1]
                f2r += prr * g2 + prz * h2 + ptt * N[q, 2]
                f3r += prr * g3 + prz * h3 + ptt * N[q, 3]
                f0z += pzr * g0 + pzz * h0
                f1z += pzr * g1 + pzz * h1
                f2z += pzr * g2 + pzz * h2
                f3z += pzr * g3 + pzz * h3
            # the cell's force, summed over its points, added once per node
            f[k0] += f0r
            f[k1] += f1r
            f[k2] += f2r
            f[k3] += f3r
            f[k0 + 1] += f0z
            f[k1 + 1] += f1z
            f[k2 + 1] += f2z
            f[k3 + 1] += f3z
        return wp, j_min, c_min

    _PREVIOUS[key] = force
    return force


# ---------------------------------------------------------------- the cases
MATERIALS = {
    "j2": FiniteJ2(E=200e9, nu=0.3, density=7850.0, yield_stress=300e6, hardening=2e9),
    "johnson_cook": JohnsonCook(E=200e9, nu=0.3, density=7850.0, A=300e6, B=2e9),
    "neo_hookean": NeoHookean(E=200e9, nu=0.3, density=7850.0),
}


def mesh(plane: bool, n_r: int = 4, n_z: int = 5):
    """A distorted grid of quadrilaterals on [0, 0.5] x [0, 1] m (the first column on the
    axis in axisymmetry), dolfinx's vertex order: (node indices (n, 4), node coordinates)."""
    rng = np.random.default_rng(7)
    r, z = np.meshgrid(np.linspace(0.0, 0.5, n_r + 1), np.linspace(0.0, 1.0, n_z + 1),
                       indexing="ij")
    xy = np.stack([r.ravel(), z.ravel()], axis=1)
    inner = (xy[:, 0] > 0.0) & (xy[:, 0] < 0.5) & (xy[:, 1] > 0.0) & (xy[:, 1] < 1.0)
    xy[inner] += 0.02 * rng.uniform(-1.0, 1.0, (inner.sum(), 2))
    node = np.arange(xy.shape[0]).reshape(n_r + 1, n_z + 1)
    cells = np.array([[node[i, j], node[i + 1, j], node[i, j + 1], node[i + 1, j + 1]]
                      for i in range(n_r) for j in range(n_z)])
    return cells, xy


def displacements(xy):
    """{name: u (2 per node, m)}: none, an in-plane dilatation (F = 0.97 I in the plane;
    in axisymmetry u_r / R = -0.03 too), and random fields of 1e-4 (elastic) and 5e-3
    (yielding) strain on the distorted mesh."""
    rng = np.random.default_rng(26)
    h = 0.1
    out = {"identity": np.zeros(xy.size), "dilatation": (-0.03 * xy).ravel()}
    for name, strain in (("elastic", 1e-4), ("yielding", 5e-3)):
        out[name] = strain * h * rng.standard_normal(xy.size)
    return out


def run_pass(fn, material, g, u, state0, new: bool):
    """(f, state, tau, plastic work, J_min) of one call of the pass ``fn`` from ``state0``;
    ``new``: the pass of the package, which reads J^-1 (dxi) and 1 / R at the points, where
    the previous read Grad N_a (dNdR, dNdZ) and R."""
    n = g.dofs.shape[0]
    state, tau = state0.copy(), np.zeros((n, 4, 4))
    f = np.zeros(u.size)
    n_state = state0.shape[-1]
    grads = (g.dxi, g.N, g.inv_R) if new else (g.dNdR, g.dNdZ, g.N, g.R)
    wp, j_min, _ = fn(material.params(), 1e-7, g.dofs, *grads, g.w, g.volume,
                      u, f, state, tau, np.zeros((4, 8)), np.zeros(4), np.zeros(5),
                      np.zeros(WORK), np.zeros(n_state), np.zeros(4))
    return f, state, tau, wp, j_min


def gradient_roundings(g, u) -> float:
    """Roundings (in EPS, on F ~ 1) between the two passes' F at a point. The previous pass
    sums u_a Grad N_a with Grad N_a = J^-T dN_a/dxi made at set-up (3 roundings on the scale
    sum_b |dN_a/dxi_b| |J^-1_b.|, then 4 products and 4 sums); the new one takes the node
    differences (1), their values at the point (3) and their product with J^-1 (3): 18 on
    the scale s = sum_a |u_a| sum_b |dN_a/dxi_b| (|J^-1_b0| + |J^-1_b1|), the largest
    over the points (J^-1 is the same array in both). s is not the strain: it counts
    |u_a|, which the sums cancel down to the gradient."""
    dN = shape_functions(GAUSS)[1]  # (q, a, b)
    inv = g.dxi.reshape(-1, 4, 2, 2)  # (c, q, b, x)
    uu = np.abs(u.reshape(-1, 2)).sum(axis=1)[g.dofs]  # (c, a)
    s = np.einsum("ca,qab,cqb->cq", uu, np.abs(dN), np.abs(inv).sum(axis=3))
    return 18.0 * float(s.max())


def bounds(material, g, u, tau):
    """Round-off bounds of (f (N), tau (Pa), the state's b_e entries (-), eps_bar_p (-)).

    The F-bar factor of the new pass takes 2 roundings for its ratio where the previous took
    1, and each cube root is within 3 ulp (the new one's, 1 ulp in its series branch near 1;
    the previous one, :func:`previous_cube_root`, kept as it was) (plane strain: sqrt, 1): the factors differ by at most 8 EPS relative, so F_bar by 9. F_bar enters b_e = F_bar a F_bar' twice (18) and
    the log strains as ln of its eigenvalues (LIBM): a log strain moves by (18 + LIBM) EPS
    absolute, the stress by (3 lambda + 2 mu) that (K = lambda + 2/3 mu on the trace, 2 mu on
    each principal value), plus the stress's own roundings on its scale (24, as in
    tests/test_hencky_split.py). The return only shrinks a difference of trial stresses
    (the factor 1 - 3 mu dgamma / q <= 1, dgamma moves by dq / (3 mu + H)). The force
    P : Grad N_a sums 4 points of w (tau F^-T) per cell and at most 4 cells per node: P's
    factor w / det of the block takes 3 roundings where it took 1, the hoop term's
    w tau_tt / (F_tt R) 6 (with F_tt's own 2) where it took 3, and the products and sums
    16 more, on the node's scale sum |w| |F^-1| |Grad N| (|tau| + the stress bound).

    The new pass's F differs by n_F = :func:`gradient_roundings` (EPS on F ~ 1; F's entries
    <= 1.1 and its stretches >= 0.9 in these cases): J_q = det F by 3 x 1.1^2 n_F <= 4 n_F,
    the F-bar factor (J_bar / J_q)^(1/3) by 1/3 of two such on J ~ 0.9^3, <= 4 n_F, F_bar by
    n_F / 0.9 + 4 n_F <= 6 n_F relative on top of the 9: 12 n_F more in b_e. In the force
    F^-1 = adj F / det and 1 / F_tt move by 4 n_F relative (on |tau|), and the reference
    gradients add 12 roundings: P J^-T (3), its sums over a row or column of points (1),
    their values at the nodes (4), the hoop sum (2) and the node's sum (2), on the node's
    scale taken with sum_b |dN_a/dxi_b| |J^-1_b.| (>= |Grad N_a|)."""
    lam, mu = material.lmbda, material.mu
    n_f = gradient_roundings(g, u)
    n_eps = 18 + 12 * n_f + LIBM
    tau_scale = float(np.abs(tau).max())
    d_tau = rounding(n_eps, 3.0 * lam + 2.0 * mu) + rounding(24 + LIBM, tau_scale + 2.0 * mu)
    node_scale = np.zeros(u.size // 2)
    dN = np.abs(shape_functions(GAUSS)[1])  # (q, a, b)
    inv = np.abs(g.dxi.reshape(-1, 4, 2, 2)).sum(axis=3)  # (c, q, b)
    for c in range(g.dofs.shape[0]):
        for q in range(4):
            grad = dN[q] @ inv[c, q] + np.abs(g.N[q]) / g.R[c, q]
            node_scale[g.dofs[c]] += g.w[c, q] * grad * 1.1  # |F^-1| <= 1.1 in these cases
    d_f = (rounding(16 + 6 + 12, float(node_scale.max()) * (tau_scale + d_tau))
           + float(node_scale.max()) * d_tau + rounding(4 * n_f, float(node_scale.max())
                                                        * tau_scale))
    d_b = rounding(2 * n_eps + 2 * LIBM + 2 * 16, 1.0)  # b_e = F a F' ~ 1: as in bounds of
    # tests/test_hencky_split.py, the exp of the returned strains on top of the trial's error
    d_eps = d_tau / (3.0 * mu)
    return d_f, d_tau, d_b, d_eps, rounding(4 * n_f, 1.0)


@pytest.mark.parametrize("plane", [False, True], ids=["axisymmetric", "plane_strain"])
@pytest.mark.parametrize("name", list(MATERIALS))
def test_force_pass_matches_the_previous_one(name, plane):
    material = MATERIALS[name]
    cells, xy = mesh(plane)
    geometry = Geometry(kind=PLANE_STRAIN) if plane else Geometry()
    g = QuadGeometry(cells, xy, np.arange(cells.shape[0]), geometry)
    n_state = max(material.n_state, 1)
    state0 = np.empty((cells.shape[0], 4, n_state))
    state0[:] = material.initial_state()
    point_copy = getattr(material, "point_copy", False)
    new = kernels(material.update, material.energy, material.n_state, point_copy, plane)[0]
    old = previous_kernel(material.update, n_state, point_copy, plane)
    yielded = {}
    for case, u in displacements(xy).items():
        f_new, s_new, t_new, wp_new, j_new = run_pass(new, material, g, u, state0, True)
        f_old, s_old, t_old, wp_old, j_old = run_pass(old, material, g, u, state0, False)
        d_f, d_tau, d_b, d_eps, d_j = bounds(material, g, u, t_old)
        if name == "johnson_cook":  # two returns stopping by one rule: see test_hencky_split
            q_max = float(np.abs(t_old).max()) * 3.0
            dx = root_tolerance(q_max, material.mu)
            d_tau += 3.0 * material.mu * dx
            d_b += 3.0 * dx
            d_eps += dx
        assert abs(j_new - j_old) <= d_j, case  # J_q of F's two roundings (bounds)
        assert np.abs(f_new - f_old).max() <= d_f, case
        assert np.abs(t_new - t_old).max() <= d_tau, case
        if material.n_state:
            assert np.abs(s_new[..., 1:5] - s_old[..., 1:5]).max() <= d_b, case
            assert np.abs(s_new[..., 0] - s_old[..., 0]).max() <= d_eps, case
            yielded[case] = float((s_old[..., 0] > 0.0).mean())
    if material.n_state:  # the cases cover both branches of the return
        assert yielded["identity"] == 0.0 and yielded["elastic"] == 0.0
        assert yielded["yielding"] > 0.3
