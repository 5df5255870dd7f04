"""The J2 thick-walled cylinder on Q1 (B-bar) against its limit pressure (Hill).

An elastic-perfectly plastic (J2, no hardening) cylinder, inner radius a, outer b, in
plane strain (a slice of height b - a with u_z = 0 on its top and bottom, as the Lame
test of tests/test_small_strain_q1.py), driven quasi-statically by the radial
displacement U of its inner wall; the reaction pressure p = sum of the inner wall's
radial forces / (2 pi a H). Each increment is solved by the elastic-stiffness
(Newton-free) iteration  K du = -R(u),  R the B-bar kernel's internal force at the
free dofs (the points' update from the state of the last converged increment: one
backward-Euler return per increment), K the assembled B-bar elastic stiffness with
the constrained rows and columns replaced by the identity, factored once (MUMPS, on
COMM_WORLD: the mesh and the solve are distributed under mpirun).

Closed forms (Hill, The Mathematical Theory of Plasticity, ch. V; k = sigma_y / sqrt 3,
G the shear modulus), for an incompressible material, where u_r = U a / r exactly and
the strain path at every point is radial:

* elastic: p = 2 G U (b^2 - a^2) / (a b^2); first yield at the inner wall at
  p_Y = sigma_y (b^2 - a^2) / (sqrt 3 b^2), U_Y = k a / (2 G);
* elastic-plastic, plastic zone a <= r <= c, c^2 = 2 G a U / k:
  p = 2 k (ln(c / a) + (1 - c^2 / b^2) / 2);
* collapse at c = b, U_L = k b^2 / (2 G a): p_L = (2 / sqrt 3) sigma_y ln(b / a).

The limit pressure holds for every nu: at collapse the stresses are stationary, the
strain rate is plastic, deviatoric and has eps_zz = 0, so s_zz = 0 and sigma_zz is the
mean of sigma_rr and sigma_tt as in the incompressible case. Below collapse a
compressible material's sigma_zz lags: the curve is Hill's to O(1 - 2 nu) and the
plateau is approached only asymptotically. The main case takes nu = 0.4999.

The mesh's own figures, from a series of the element in h (the nodal interpolant of
1/r, the only radial field whose cell-mean dilatation vanishes in every cell, at the
2x2 Gauss points; see discrete_limit and the constants below):

* the discrete limit pressure p_h (the kinematic theorem of the discrete problem with
  that mechanism; the static theorem then bounds every equilibrated state by it:
  p <= p_h at every increment, for any nu, up to the iteration's residual) exceeds p_L
  by eps_1 = 13/144 h^2 (1/a^2 - 1/b^2) / ln(b/a) (1.5e-3 at 8 cells through the wall);
* the elastic reaction exceeds Hill's by eps_2 = h^2 / 18 (1/a^2 + 1/b^2);
* the cell that holds the plastic front c integrates a kinked integrand by 2-point
  Gauss: at most x_1^2 / 2 h^2 times the jump of its slope 4 k / c^2 (x_1 = 1/2 -
  1/(2 sqrt 3)), relative to p >= p_Y;
* the point strains are first-order off, |d_q| = |d(r_q)| (1 -+ h / (2 sqrt 3 r)) at
  the lower and upper point, which cancels in a cell whose points are on one branch
  (both elastic: 2 delta each way; both plastic: delta) but not in the front cell
  (one of each): at most its weight h / 2 times the integrand 2 k / c times delta,
  (h / a)^2 / (2 sqrt 3 (1 - a^2 / b^2)) relative to p >= p_Y;
* the first point to yield is the innermost Gauss point, whose strain (a series of
  the element) puts the onset at p_Y (1 + c1 h/a + c2 (h/a)^2 + O(h^3)).
"""
import math

import numpy as np
import pytest
from dolfinx import fem
from mpi4py import MPI
from petsc4py import PETSc

from roundoff import rounding

from impact_fenics.bodies import Body, DeformableModel
from impact_fenics.internal_force.quadrature import QuadratureForce
from impact_fenics.materials.j2 import J2
from impact_fenics.operators import assemble_stiffness
from impact_fenics.quad_meshes import quad_rectangle

COMM = MPI.COMM_WORLD
A_IN, B_OUT = 0.1, 0.2  # m
E, SY = 1e9, 1e6  # Pa
H = B_OUT - A_IN  # m, the slice's height
K_SHEAR = SY / math.sqrt(3.0)  # k, the yield stress in shear (Pa)
P_LIMIT = 2.0 / math.sqrt(3.0) * SY * math.log(B_OUT / A_IN)
P_YIELD = SY * (B_OUT ** 2 - A_IN ** 2) / (math.sqrt(3.0) * B_OUT ** 2)
NU = 0.4999  # the main case: Hill's incompressible curve to O(1 - 2 nu) = 2e-4
GAUSS_X1 = 0.5 - 0.5 / math.sqrt(3.0)  # the lower 2-point Gauss abscissa on [0, 1]
# p_onset / p_Y = 1 + C1 h/a + C2 (h/a)^2: the innermost point's |d(a)| / |d_1| (a series
# of the B-bar strain of the interpolant of 1/r: 1 + (1 - sqrt3/6) h/a - (sqrt3/12 +
# 1/72) (h/a)^2) times the elastic reaction's 1 + eps_2
C1 = 1.0 - math.sqrt(3.0) / 6.0
C2 = -(math.sqrt(3.0) / 12.0 + 1.0 / 72.0) + (1.0 + (A_IN / B_OUT) ** 2) / 18.0
# the iteration stops when |R|_2 |v*|_2 <= RES |F|: the residual's share of p relative
RES = 1e-10
MAX_ITERATIONS = 100


def hill_pressure(U: float, G: float) -> float:
    """Hill's p(U) (Pa) of the incompressible cylinder at the inner displacement U (m)."""
    c2 = 2.0 * G * A_IN * U / K_SHEAR
    if c2 <= A_IN ** 2:
        return 2.0 * G * U * (B_OUT ** 2 - A_IN ** 2) / (A_IN * B_OUT ** 2)
    if c2 >= B_OUT ** 2:
        return P_LIMIT
    return 2.0 * K_SHEAR * (0.5 * math.log(c2 / A_IN ** 2) + 0.5 * (1.0 - c2 / B_OUT ** 2))


def discrete_limit(n: int) -> float:
    """p_h (Pa): the plastic dissipation of the mechanism v_r = a / r_i at the n + 1 node
    columns (z-independent, v_z = 0; each cell's ring-weighted dilatation vanishes, so
    the B-bar strain is deviatoric at every point) over the work rate of p on v_r(a) = 1.
    Per unit 2 pi H a point of a cell of width h has the weight h / 2 r_q; at the point
    d = eps - tr(eps) / 3 (1, 1, 1) with eps = (v', v / r_q, 0) and the dissipation
    sigma_y sqrt(2/3 d : d). Computed here from the nodes, not by the code under test."""
    r = np.linspace(A_IN, B_OUT, n + 1)
    v = A_IN / r
    total = 0.0
    for i in range(n):
        h = r[i + 1] - r[i]
        slope = (v[i + 1] - v[i]) / h
        for x in (GAUSS_X1, 1.0 - GAUSS_X1):
            rq = r[i] + x * h
            e = np.array([slope, (v[i] + x * (v[i + 1] - v[i])) / rq, 0.0])
            d = e - e.sum() / 3.0
            total += 0.5 * h * rq * SY * math.sqrt(2.0 / 3.0 * float(d @ d))
    return total / A_IN


def mesh_errors(n: int) -> dict:
    """The mesh's relative errors at n cells through the wall (see the module)."""
    h = H / n
    eps_1 = 13.0 / 144.0 * h ** 2 * (1 / A_IN ** 2 - 1 / B_OUT ** 2) / math.log(B_OUT / A_IN)
    eps_2 = h ** 2 / 18.0 * (1 / A_IN ** 2 + 1 / B_OUT ** 2)
    kink = GAUSS_X1 ** 2 / 2.0 * 4.0 * (h / A_IN) ** 2 / (1.0 - (A_IN / B_OUT) ** 2)
    front = (h / A_IN) ** 2 / (2.0 * math.sqrt(3.0) * (1.0 - (A_IN / B_OUT) ** 2))
    return {"h_a": h / A_IN, "eps_1": eps_1, "eps_2": eps_2, "kink": kink, "front": front}


def von_mises(sigma: np.ndarray) -> np.ndarray:
    """sigma_eq (Pa) of stresses (..., 4) in (rr, tt, zz, rz), tensor shear."""
    dev = sigma[..., :3] - sigma[..., :3].mean(axis=-1, keepdims=True)
    return np.sqrt(1.5 * ((dev ** 2).sum(axis=-1) + 2.0 * sigma[..., 3] ** 2))


def ramp(n: int, nu: float, u_end: float, n_increments: int) -> dict:
    """The displacement-controlled ramp U_k = u_end U_L k / n_increments on n x n cells:
    per increment the reaction pressure p (Pa) and the iterations; the onset pressure
    (the last elastic increment's p scaled to sigma_eq,max = sigma_y: the response is
    linear until a point yields)."""
    tm = quad_rectangle(COMM, A_IN, 0.0, B_OUT, H, n, n, "wall")
    material = J2(E=E, nu=nu, density=1e3, yield_stress=SY)
    model = DeformableModel(tm, [Body("wall", material)])
    u = fem.Function(model.V)
    n_owned = model.n_owned
    force = QuadratureForce(model, "wall", u, 1.0, np.zeros(n_owned))
    qs = force.qs
    inner = model.facet_dofs("inner", 0)
    constrained = np.unique(np.concatenate(
        [inner, model.facet_dofs("bottom", 1), model.facet_dofs("top", 1)]))
    K = assemble_stiffness(model)
    K.zeroRowsColumns(model.to_global(constrained).astype(PETSc.IntType), 1.0)
    ksp = PETSc.KSP().create(COMM)
    ksp.setOperators(K)
    ksp.setType("preonly")
    ksp.getPC().setType("lu")
    ksp.getPC().setFactorSolverType("mumps")
    rhs, du = K.createVecLeft(), K.createVecRight()
    # |v*|_2 over the free radial dofs, v* = a / r <= 1: at most sqrt(their number)
    free_r = np.setdiff1d(np.arange(0, n_owned, 2), constrained)
    v_norm = math.sqrt(COMM.allreduce(free_r.size))
    U_L = K_SHEAR * B_OUT ** 2 / (2.0 * material.mu * A_IN)
    committed = [a.copy() for a in (qs.eps_p, qs.state, qs.sigma)]
    pressures, iterations, onset = [], [], None
    for k in range(1, n_increments + 1):
        u.x.array[inner] = u_end * U_L * k / n_increments
        for it in range(MAX_ITERATIONS):
            u.x.scatter_forward()
            for a, c in zip((qs.eps_p, qs.state, qs.sigma), committed):
                a[:] = c  # every iterate returns from the last converged state
            f = force.compute()
            reaction = COMM.allreduce(float(f[inner].sum()))
            R = f.copy()
            R[constrained] = 0.0
            if math.sqrt(COMM.allreduce(float(R @ R))) * v_norm <= RES * abs(reaction):
                break
            rhs.array[:] = -R
            ksp.solve(rhs, du)
            u.x.array[:n_owned] += du.array
        iterations.append(it)
        for a, c in zip((qs.eps_p, qs.state, qs.sigma), committed):
            c[:] = a
        p = reaction / (2.0 * math.pi * A_IN * H)
        pressures.append(p)
        if COMM.allreduce(float(qs.state[..., 0].max(initial=0.0)), op=MPI.MAX) == 0.0:
            onset = p * SY / COMM.allreduce(float(von_mises(qs.sigma).max(initial=0.0)),
                                            op=MPI.MAX)
    for obj in (ksp, K, rhs, du):
        obj.destroy()
    U = u_end * U_L * np.arange(1, n_increments + 1) / n_increments
    return {"U": U, "U_L": U_L, "p": np.array(pressures), "iterations": np.array(iterations),
            "onset": onset, "G": material.mu, "n_cells": COMM.allreduce(force.cells.size)}


@pytest.fixture(scope="module")
def ramps():
    # 40 increments to 2 U_L: 4 in the elastic range (U_Y / U_L = a^2 / b^2 = 1/4), then
    # the plastic front crosses the wall in 15, the rest on the plateau
    return {n: ramp(n, NU, 2.0, 40) for n in (4, 8)}


def static_bound(run: dict, n: int) -> float:
    """p_h (1 + RES) plus the roundings of the reaction's sum and of p_h's own (about 20
    operations per point of every cell)."""
    return discrete_limit(n) * (1.0 + RES + rounding(20 * 4 * run["n_cells"]))


@pytest.mark.parametrize("n", [4, 8])
def test_limit_pressure(ramps, n):
    """nu = 0.4999, n cells through the wall: p <= p_h at every increment (the discrete
    static theorem); the plateau (every increment with U >= U_L) equals p_h to the
    compressibility's O(1 - 2 nu), hence p_L to eps_1 (1 + h/a) + (1 - 2 nu) (0.19 %
    at 8 cells); p_h itself is p_L (1 + eps_1) to the series' next order."""
    run, m = ramps[n], mesh_errors(n)
    p, U = run["p"], run["U"]
    p_h = discrete_limit(n)
    if COMM.rank == 0:
        print(f"n = {n}: p_h / p_L - 1 = {p_h / P_LIMIT - 1:.4g} (eps_1 {m['eps_1']:.4g}), "
              f"plateau / p_L - 1 = {p[-1] / P_LIMIT - 1:.4g}, plateau / p_h - 1 = "
              f"{p[-1] / p_h - 1:.3g}, max p / p_h - 1 = {p.max() / p_h - 1:.3g}, iterations "
              f"per increment <= {run['iterations'].max()}")
    assert run["iterations"].max() < MAX_ITERATIONS - 1
    assert abs(p_h / P_LIMIT - 1.0 - m["eps_1"]) <= m["eps_1"] * m["h_a"]
    assert np.all(p <= static_bound(run, n))
    plateau = p[U >= run["U_L"]]
    assert plateau.size >= 10
    assert np.all(plateau >= p_h * (1.0 - (1.0 - 2 * NU)))
    assert np.all(np.abs(plateau / P_LIMIT - 1.0) <= m["eps_1"] * (1 + m["h_a"]) + (1 - 2 * NU))


@pytest.mark.parametrize("n", [4, 8])
def test_pressure_follows_hill_and_yields_at_p_y(ramps, n):
    """Every increment against Hill's p(U), within the mesh's error: the larger of the
    smooth parts' eps_1, eps_2 plus the front cell's two terms, times 1 + h/a for the
    next order, plus O(1 - 2 nu) for the compressibility (1.1 % at 8 cells). The onset
    (the first point yields) at p_Y (1 + C1 h/a + C2 (h/a)^2), to (h/a)^3 + (1 - 2 nu):
    it tends to p_Y as h -> 0, from above (the innermost Gauss point lies inside the
    wall)."""
    run, m = ramps[n], mesh_errors(n)
    hill = np.array([hill_pressure(U, run["G"]) for U in run["U"]])
    err = np.abs(run["p"] / hill - 1.0)
    tol = ((max(m["eps_1"], m["eps_2"]) + m["kink"] + m["front"]) * (1 + m["h_a"])
           + (1 - 2 * NU))
    expected_onset = P_YIELD * (1 + C1 * m["h_a"] + C2 * m["h_a"] ** 2)
    if COMM.rank == 0:
        print(f"n = {n}: p / Hill - 1 at most {err.max():.4g} (tolerance {tol:.4g}); onset "
              f"p / p_Y - 1 = {run['onset'] / P_YIELD - 1:.4g}, expected "
              f"{expected_onset / P_YIELD - 1:.4g}")
    assert np.all(err <= tol)
    assert run["onset"] is not None and run["onset"] > P_YIELD
    assert abs(run["onset"] / expected_onset - 1.0) <= m["h_a"] ** 3 + (1 - 2 * NU)


def test_compressible_cylinder_stays_below_the_discrete_limit():
    """nu = 0.3 on 8 cells, to 3 U_L: the static theorem holds for any nu (p <= p_h at
    every increment); the reaction rises towards the plateau at every increment."""
    run = ramp(8, 0.3, 3.0, 30)
    p = run["p"]
    p_h = discrete_limit(8)
    if COMM.rank == 0:
        print(f"nu = 0.3, n = 8: p / p_h - 1 at U = 3 U_L: {p[-1] / p_h - 1:.3g}; "
              f"p / p_L - 1: {p[-1] / P_LIMIT - 1:.3g}; iterations <= {run['iterations'].max()}")
    assert run["iterations"].max() < MAX_ITERATIONS - 1
    assert np.all(p <= static_bound(run, 8))
    assert np.all(np.diff(p) > 0.0)
