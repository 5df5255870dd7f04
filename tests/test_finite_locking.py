"""Volumetric locking: a thick-walled cylinder of a nearly incompressible solid (nu = 0.499).

Plane strain (u_z = 0 at every node), inner radius a, outer b, internal pressure p.
Closed form (Lame): u_r(r) = (1 + nu) p a^2 / (E (b^2 - a^2)) ((1 - 2 nu) r + b^2 / r).
The quasi-static state, to which a damped run settles, is the solution of the
stiffness of the undeformed body, K u = f; K of the Q1 mean-dilatation element
comes from central differences of its f_int at u = 0 (exact for the linear part,
O(h^2) = 1e-18 relative for the rest), K of the CST from the project's
small-strain form (forms.stiffness_form). Each process solves on its own
(COMM_SELF): the numbers are the same under mpirun.
"""
import math

import numpy as np
from dolfinx import fem, mesh as dmesh
from mpi4py import MPI

from impact_fenics import forms
from impact_fenics.geometry import AXISYMMETRIC_GEOMETRY
from impact_fenics.compat import vector_space
from impact_fenics.bodies import Body, DeformableModel
from impact_fenics.integrator import Integrator
from impact_fenics.materials import LinearElastic
from impact_fenics.materials.neo_hookean import NeoHookean
from impact_fenics.operators import compile_form
from impact_fenics.quad_meshes import one_body
from impact_fenics.stepping import FollowingStep

A, B, P, E, NU = 0.1, 0.2, 1e6, 1e9, 0.499


def exact(r):
    return (1 + NU) * P * A * A / (E * (B * B - A * A)) * ((1 - 2 * NU) * r + B * B / r)


def inner_loads(xy, n_dofs):
    """Nodal forces of the pressure on r = a: p 2 pi a l / 2 to each end of each edge (N)."""
    f = np.zeros(n_dofs)
    inner = np.flatnonzero(np.abs(xy[:, 0] - A) < 1e-12)  # m: far above round-off, below h
    z = xy[inner, 1]
    order = np.argsort(z)
    for i, j in zip(inner[order][:-1], inner[order][1:]):
        half = P * 2 * math.pi * A * abs(xy[j, 1] - xy[i, 1]) / 2
        f[2 * i] += half
        f[2 * j] += half
    return f, inner


def solve(K, f, xy):
    """u_r with u_z = 0 everywhere (plane strain); returns u_r at the inner nodes' mean."""
    free = np.arange(0, K.shape[0], 2)
    u = np.linalg.solve(K[np.ix_(free, free)], f[free])
    return u


def q1_inner_displacement(n):
    comm = MPI.COMM_SELF
    mesh = dmesh.create_rectangle(comm, [np.array([A, 0.0]), np.array([B, (B - A) / n])], [n, 1],
                                  cell_type=dmesh.CellType.quadrilateral)
    model = DeformableModel(one_body(mesh), [Body("body", NeoHookean(E=E, nu=NU, density=1000.0))])
    integ = Integrator(model, None, np.zeros(0, dtype=np.int32),
                       policy=FollowingStep(None, 1.0, None, 0.5, 10))
    force, u_fn, u_owned = integ.finite[0], integ.u_function, integ.u_owned
    N = model.n_owned
    K = np.zeros((N, N))
    h = 1e-9
    for j in range(0, N, 2):  # u_r columns only (u_z = 0)
        e = np.zeros(N)
        e[j] = h
        u_owned[:] = e
        u_fn.x.scatter_forward()
        fp = force.compute(1.0).copy()
        u_owned[:] = -e
        u_fn.x.scatter_forward()
        fm = force.compute(1.0).copy()
        K[:, j] = (fp - fm) / (2 * h)
    xy = model.node_xy
    f, inner = inner_loads(xy, N)
    u = solve(K, f, xy)
    return float(u[inner].mean())


def cst_inner_displacement(n):
    comm = MPI.COMM_SELF
    mesh = dmesh.create_rectangle(comm, [np.array([A, 0.0]), np.array([B, (B - A) / n])], [n, 1],
                                  cell_type=dmesh.CellType.triangle,
                                  diagonal=dmesh.DiagonalType.right)
    V = vector_space(mesh, "Lagrange", 1)
    parts = [(LinearElastic(E=E, nu=NU, density=1000.0),
              forms.cell_measure(mesh, None, None, forms.STIFFNESS_DEGREE))]
    Kp = fem.petsc.assemble_matrix(compile_form(forms.stiffness_form(V, parts, AXISYMMETRIC_GEOMETRY)))
    Kp.assemble()
    dense = Kp.convert("dense")  # held: getDenseArray is a view of this Mat's storage
    K = dense.getDenseArray().copy()
    dense.destroy()
    Kp.destroy()
    xy = V.tabulate_dof_coordinates()[:, :2]
    f, inner = inner_loads(xy, K.shape[0])
    u = solve(K, f, xy)
    return float(u[inner].mean())


def test_q1_mean_dilatation_converges_cst_locks():
    """Relative error of u_r(a) at nu = 0.499 on n = 4, 8, 16 cells through the wall:
    Q1 with mean dilatation converges (error below 2 %, 1 %, 0.5 % and falling, about
    as h^2), the CST on the same nodes locks: its error constant carries
    lambda / mu = 499, so on every mesh its error is more than ten times Q1's (the
    factor ten is a margin on the ratio, not a fit: measured 115-240)."""
    u_ex = exact(A)
    q1 = [abs(q1_inner_displacement(n) / u_ex - 1) for n in (4, 8, 16)]
    cst = [abs(cst_inner_displacement(n) / u_ex - 1) for n in (4, 8, 16)]
    print("Q1 F-bar relative errors", q1, "CST relative errors", cst)
    assert q1[0] < 2e-2 and q1[1] < 1e-2 and q1[2] < 5e-3
    assert q1[2] < q1[1] / 3 < q1[0] / 9  # about h^2
    assert np.all(np.isfinite(cst))
    assert all(c > 10 * q for c, q in zip(cst, q1))
