"""The finite-strain stored energy and cell means against the passes they replaced: F formed
once, to round-off.

F is formed in one place, :func:`impact_fenics.internal_force.finite.cell_deformation`,
through the reference cell (Grad u = (du/dxi, du/deta) J^-1 from the node differences),
for the force, the stored energy and the cell means alike; the stored energy takes the
F-bar factors of the force (:func:`~impact_fenics.internal_force.finite.fbar_factors`, the
ratio as J_bar (1 / J_q)). The passes before summed u_a Grad N_a at each point
(``deformation_gradient``, kept below verbatim with the two passes that called it, as the
oracle) and took the quotient J_bar / J_q: the same quantities, other roundings (class (b)
of tests/roundoff.py).

Cases: those of tests/test_finite_force_pass.py (a distorted Q1 mesh touching the axis,
every finite material, both geometries, F = I, a dilatation, random elastic and yielding
fields), with the point state and stress of one force pass at the same displacement (so
the stored energy sees yielded points' plastic state).
"""
import math

import numpy as np
import pytest
from numba import njit

from impact_fenics.geometry import Geometry, PLANE_STRAIN
from impact_fenics.internal_force.finite import WORK, cell_means, cube_root, kernels
from impact_fenics.q1 import QuadGeometry
from roundoff import EPS, LIBM, rounding
from test_finite_force_pass import MATERIALS, displacements, gradient_roundings, mesh, run_pass

_PREVIOUS: dict = {}


@njit(cache=True, inline="always")
def previous_deformation_gradient(c, q, dNdR, dNdZ, N, R, dofs, u, F, plane) -> float:
    """F at point q of cell c into F = (F_rr, F_rz, F_zr, F_zz, F_tt); returns J (verbatim)."""
    frr = frz = fzr = fzz = ur = 0.0
    for a in range(4):
        k = 2 * dofs[c, a]
        gr, gz = dNdR[c, q, a], dNdZ[c, q, a]
        frr += gr * u[k]
        frz += gz * u[k]
        fzr += gr * u[k + 1]
        fzz += gz * u[k + 1]
        ur += N[q, a] * u[k]
    if plane:
        F[0], F[1], F[2], F[3], F[4] = 1.0 + frr, frz, fzr, 1.0 + fzz, 1.0
        return F[0] * F[3] - F[1] * F[2]
    F[0], F[1], F[2], F[3], F[4] = 1.0 + frr, frz, fzr, 1.0 + fzz, 1.0 + ur / R[c, q]
    return (F[0] * F[3] - F[1] * F[2]) * F[4]


def previous_stored(energy, plane: bool):
    """The stored-energy pass before F was formed once (verbatim)."""
    key = (energy, plane)
    if key in _PREVIOUS:
        return _PREVIOUS[key]

    @njit(fastmath=False)
    def stored(params, dofs, dNdR, dNdZ, N, R, w, volume, u, state, Fq, Jq, fbar, work):
        total = 0.0
        for c in range(dofs.shape[0]):
            jbar = 0.0
            for q in range(4):
                Jq[q] = previous_deformation_gradient(c, q, dNdR, dNdZ, N, R, dofs, u, Fq[q],
                                                      plane)
                jbar += w[c, q] * Jq[q]
            jbar /= volume[c]
            for q in range(4):
                if plane:
                    alpha = math.sqrt(jbar / Jq[q])
                    for i in range(4):
                        fbar[i] = alpha * Fq[q, i]
                    fbar[4] = 1.0
                else:
                    alpha = cube_root(jbar / Jq[q])
                    for i in range(5):
                        fbar[i] = alpha * Fq[q, i]
                total += w[c, q] * energy(fbar, state[c, q], params, work)
        return total

    _PREVIOUS[key] = stored
    return stored


@njit(cache=True)
def previous_cell_means(tau, state, w, volume, dofs, dNdR, dNdZ, N, R, u, Fq, Jq, out_sigma,
                        out_eps, out_t, i_temp, plane) -> None:
    """The cell means before F was formed once (verbatim)."""
    for c in range(dofs.shape[0]):
        jbar = 0.0
        for q in range(4):
            jbar += w[c, q] * previous_deformation_gradient(c, q, dNdR, dNdZ, N, R, dofs, u,
                                                            Fq[q], plane)
        jbar /= volume[c]
        for i in range(4):
            s = 0.0
            for q in range(4):
                s += w[c, q] * tau[c, q, i]
            out_sigma[c, i] = s / (volume[c] * jbar)
        e = 0.0
        t = 0.0
        for q in range(4):
            e += w[c, q] * state[c, q, 0]
            if i_temp >= 0:
                t += w[c, q] * state[c, q, i_temp]
        out_eps[c] = e / volume[c]
        out_t[c] = t / volume[c] if i_temp >= 0 else 0.0


def stretch_roundings(g, u, plane: bool) -> float:
    """Roundings (in EPS, on F ~ 1) between the two passes' F at a point: the in-plane
    entries' (:func:`test_finite_force_pass.gradient_roundings`) and, in axisymmetry, the
    hoop stretch's: 1 + (sum_a N_a u_r,a) x, both the same sum, with x = 1 / R (its
    reciprocal made at set-up, then a product: 2 roundings) where the previous divided by
    R (1): 3 on the scale sum_a N_a |u_r,a| / R, the largest over the points."""
    n_f = gradient_roundings(g, u)
    if plane:
        return n_f
    ur = np.abs(u.reshape(-1, 2)[:, 0])[g.dofs]  # (c, a)
    hoop = float((np.einsum("qa,ca->cq", g.N, ur) * g.inv_R).max())
    return n_f + 3.0 * hoop


def pass_state(material, g, u, plane):
    """(state, tau, J_min) of one force pass at ``u`` from the initial state."""
    n_state = max(material.n_state, 1)
    state0 = np.empty((g.dofs.shape[0], 4, n_state))
    state0[:] = material.initial_state()
    force = kernels(material.update, material.energy, material.n_state,
                    getattr(material, "point_copy", False), plane)[0]
    _, state, tau, _, j_min = run_pass(force, material, g, u, state0, True)
    return state, tau, j_min


def geometry_of(plane: bool):
    cells, xy = mesh(plane)
    geometry = Geometry(kind=PLANE_STRAIN) if plane else Geometry()
    return QuadGeometry(cells, xy, np.arange(cells.shape[0]), geometry), xy


def scratch():
    """The kernels' scratch arrays: Fq, Jq, F_bar, work."""
    return np.zeros((4, 8)), np.zeros(4), np.zeros(5), np.zeros(WORK)


# the roundings of one evaluation of a point's log strains from F_bar and a (b_e = F a F',
# its mean, half difference and determinant, the logarithms; the count of the stress's own
# roundings in tests/test_hencky_split.py), absolute on strains ~ 0
N_EPS_OWN = 24 + LIBM
# the roundings of one evaluation of psi on its scale S (the sum of the |terms| it adds):
# Hencky's 2 mu (3 a^2 + g^2 d^2) + K/2 tr^2 takes 12 and S = psi (all terms >= 0);
# neo-Hookean's mu/2 (tr b - 3 - 2 ln J) + lambda/2 (ln J)^2 takes 14 (tr b: 9 on 5 F^2,
# ln J: 3 + LIBM on mu) on S = mu/2 (5 x 1.1^2 + 3 + 2 |ln J|) <= 5 mu
N_PSI_OWN = 16


def stored_bound(material, g, u, tau, psi_total, plane) -> float:
    """|stored_new - stored_previous| (J) at most: per point w_q (T_q dpsi/deps-part +
    own roundings), summed, plus the two sums' own roundings.

    dpsi = sum_i tau_i d eps_i (the principal Kirchhoff stress is the derivative of psi in
    the principal log strains, for every isotropic material here); T_q = 5 max_k |tau_k|
    bounds sum_i |tau_i| (each in-plane principal value by |tau_rr| or |tau_zz| plus
    |tau_rz|, and |tau_tt|). The log strains move with F_bar: F_bar differs by
    n_Fbar = 9 + 6 n_F relative (tests/test_finite_force_pass.py, ``bounds``: the ratio's 2
    roundings against 1 and the roots within 3 ulp each, 9; F by n_F and the factor by
    4 n_F, 6 n_F), b_e = F_bar a F_bar' by twice that, a log strain by 2 n_Fbar EPS; each
    evaluation adds its own N_EPS_OWN on the strains and N_PSI_OWN on psi's scale S. The sum
    over the points runs in the same order in both, n_points roundings each on the sum of
    the terms (w_q psi_q >= 0: the total)."""
    n_fbar = 9.0 + 6.0 * stretch_roundings(g, u, plane)
    t_q = 5.0 * np.abs(tau).max(axis=2)  # (c, q)
    strain_part = EPS * (2.0 * n_fbar + 2.0 * N_EPS_OWN) * float((g.w * t_q).sum())
    s_total = psi_total if material.n_state else 5.0 * material.mu * float(g.w.sum())
    n_points = g.w.size
    return strain_part + rounding(2 * N_PSI_OWN, s_total) + rounding(2 * n_points, psi_total)


@pytest.mark.parametrize("plane", [False, True], ids=["axisymmetric", "plane_strain"])
@pytest.mark.parametrize("name", list(MATERIALS))
def test_stored_energy_matches_the_previous_one(name, plane):
    material = MATERIALS[name]
    g, xy = geometry_of(plane)
    new = kernels(material.update, material.energy, material.n_state,
                  getattr(material, "point_copy", False), plane)[1]
    old = previous_stored(material.energy, plane)
    params = material.params()
    for case, u in displacements(xy).items():
        state, tau, _ = pass_state(material, g, u, plane)
        e_new = new(params, g.dofs, g.dxi, g.N, g.inv_R, g.w, g.volume, u, state, *scratch())
        e_old = old(params, g.dofs, g.dNdR, g.dNdZ, g.N, g.R, g.w, g.volume, u, state,
                    *scratch())
        bound = stored_bound(material, g, u, tau, e_old, plane)
        if case == "identity":  # F = I exactly in both, so J_q = 1 and the same J_bar, root
            assert e_new == e_old  # and F_bar (J_bar within an ulp of 1: psi ~ 0, not 0)
        else:
            assert e_old > 0.0, case
        assert abs(e_new - e_old) <= bound, (case, e_new - e_old, bound)


@pytest.mark.parametrize("plane", [False, True], ids=["axisymmetric", "plane_strain"])
@pytest.mark.parametrize("name", list(MATERIALS))
def test_cell_means_match_the_previous_ones(name, plane):
    """sigma = sum_q w_q tau_q / (V J_bar): the sum is the same computation on the same tau
    in both; J_bar = sum_q w_q J_q / V moves by the J_q's 4 n_F EPS (absolute, J ~ 1: the
    bound of tests/test_finite_force_pass.py) over J_bar >= J_min, plus the 9 roundings of
    each of the two means (18), and V J_bar and the quotient round twice in each (4): sigma
    within (4 n_F / J_min + 22) EPS |sigma|. eps_bar_p and the temperature do not read F:
    equal bit for bit."""
    material = MATERIALS[name]
    g, xy = geometry_of(plane)
    n = g.dofs.shape[0]
    i_temp = getattr(material, "temperature_index", -1)
    for case, u in displacements(xy).items():
        state, tau, j_min = pass_state(material, g, u, plane)
        new = np.zeros((n, 4)), np.zeros(n), np.zeros(n)
        old = np.zeros((n, 4)), np.zeros(n), np.zeros(n)
        Fq, Jq, _, _ = scratch()
        cell_means(tau, state, g.w, g.volume, g.dofs, g.dxi, g.N, g.inv_R, u, Fq, Jq, *new,
                   i_temp, plane)
        previous_cell_means(tau, state, g.w, g.volume, g.dofs, g.dNdR, g.dNdZ, g.N, g.R, u,
                            Fq, Jq, *old, i_temp, plane)
        n_f = stretch_roundings(g, u, plane)
        bound = EPS * (4.0 * n_f / j_min + 22.0) * np.abs(old[0])
        assert np.all(np.abs(new[0] - old[0]) <= bound), case
        assert np.array_equal(new[1], old[1]) and np.array_equal(new[2], old[2]), case
        if i_temp >= 0:
            assert old[2].min() > 0.0  # the temperature mean is there to compare
