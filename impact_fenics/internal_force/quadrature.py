"""Internal force of a path-dependent body: state at the quadrature points, f_int(u, state).

On triangles (P1) the state lives at the points of the stiffness rule
(forms.STIFFNESS_DEGREE = 2: three points per triangle); on quadrilaterals (Q1) at
the 2x2 Gauss points, with mean dilatation (:mod:`.bbar`; only the fused path below
runs there). One array per variable over (owned cells x points), shown here for
triangles:
the plastic strain ``eps_p`` (n, 3, 4) in the (rr, tt, zz, rz) notation of
:mod:`..materials.axisym`, the material's other variables ``state`` (n, 3,
n_state; ``state[..., 0]`` the equivalent plastic strain) and the stress
``sigma`` (n, 3, 4) in Pa. Each step, from u^n (m):

    eps_q = B_q u_e  (eps_tt = u_r / r at the point),   point update -> sigma_q,
    f_int = sum over cells and points of  w_q |J| 2 pi r_q  B_q' sigma_q   (N),

the assembled vector of  int sigma : eps(w) 2 pi r dx  with the same rule.

In plane strain (the model's geometry, :mod:`..geometry`) a P1 cell has one point, its
centroid: its strain is constant and eps_out = 0, so three points would carry one state
three times. There w = t |J| / 2 (m^3) and the point update sees (eps_xx, 0, eps_yy,
eps_xy) and returns the full stress, sigma_out included (:func:`plane_kernel`); on Q1
the B-bar kernel runs unchanged on the plane-strain geometry (inv_r = 0, w = t |J| / 4).

Two implementations give the same f_int to round-off:

* ``"fast"``: one fused compiled pass over the cells (strain at the three
  points from the cell's dofs, the point update, the element force, a
  scatter-add into the local owned + ghost array), then one reverse scatter;
  the geometry (dofs, P1 gradients, point radii and weights) is precomputed;
* ``"generic"``: dolfinx does the finite-element work: the strain by a
  ``fem.Expression`` at the points, the point update, the stress into a
  quadrature-element Function and ``assemble_vector`` of the residual form.

Under MPI each rank updates the points of the cells it owns (dolfinx
integrates owned cells only), so every point belongs to exactly one rank; the
ghost entries of f_int are summed into their owners by the reverse scatter.
The displacement's ghost entries must be current on entry.

The kernels are specialised on the material's compiled ``update`` and its number
of state variables, and built once per process and material (numba cannot cache a function that calls
another compiled function given at run time).
"""
from __future__ import annotations

import math

import basix
import numpy as np
import ufl
from dolfinx import fem
from numba import njit
from petsc4py import PETSc

from .. import forms
from .. import compat
from .. import q1
from ..bodies import DeformableModel
from ..errors import InputError
from ..operators import compile_form
from ..stability import parts_stable_dt
from . import bbar
from .base import Booking

N_POINTS = 3  # points of the degree-2 triangle rule
N_COMP = 4    # (rr, tt, zz, rz)


def reference_rule(degree: int = forms.STIFFNESS_DEGREE) -> tuple[np.ndarray, np.ndarray]:
    """Points (reference triangle) and weights of the rule dolfinx uses for ``degree``."""
    points, weights = basix.make_quadrature(basix.CellType.triangle, degree)
    return np.asarray(points, dtype=np.float64), np.asarray(weights, dtype=np.float64)


def owned_cells(model: DeformableModel, body: str) -> np.ndarray:
    """Local indices of the cells of ``body`` owned by this rank (sorted)."""
    n_owned = model.mesh.topology.index_map(2).size_local
    cells = model.tmesh.cells(body)
    return np.sort(cells[cells < n_owned]).astype(np.int32)


class CellGeometry:
    """Fixed (small strain) geometry of P1 triangles at the rule's points.

    ``dofs`` (n, 3) node (block) indices; ``dNdr``, ``dNdz`` (n, 3) P1 gradients
    (1/m); ``N`` (3 points, 3 nodes) shape values; ``r`` (n, 3) point radii (m) and
    ``inv_r`` their inverses (1/m);
    ``w`` (n, 3) weights w_q |J| 2 pi r_q (m^3).

    In plane strain (the model's geometry) one point per cell, the centroid (the strain
    of a P1 cell is constant and eps_out = 0): ``N`` (1, 3) = 1/3, ``r`` (n, 1) the
    centroid's x, ``inv_r`` (n, 1) = 0 (the out-of-plane strain's factor) and ``w``
    (n, 1) = t |J| / 2 = t A (m^3)."""

    def __init__(self, model: DeformableModel, cells: np.ndarray):
        plane = model.geometry.plane
        if plane:  # the one-point rule: the centroid, weight 1/2
            ref_points, ref_weights = np.full((1, 2), 1.0 / 3.0), np.array([0.5])
        else:
            ref_points, ref_weights = reference_rule()
            assert ref_points.shape[0] == N_POINTS
        self.cells = cells
        self.dofs = model.cell_dofs[cells].astype(np.int32)
        xy = model.node_xy[self.dofs]  # (n, 3, 2)
        xi, eta = ref_points[:, 0], ref_points[:, 1]
        self.N = np.ascontiguousarray(np.stack([1.0 - xi - eta, xi, eta], axis=1))
        d = xy[:, 1:, :] - xy[:, :1, :]  # J = [[r1-r0, r2-r0], [z1-z0, z2-z0]]
        det = d[:, 0, 0] * d[:, 1, 1] - d[:, 1, 0] * d[:, 0, 1]
        # reference gradients (-1,-1), (1,0), (0,1) mapped by J^-T
        g_ref = np.array([[-1.0, -1.0], [1.0, 0.0], [0.0, 1.0]])
        inv = np.empty((cells.size, 2, 2))  # J^-1
        inv[:, 0, 0], inv[:, 0, 1] = d[:, 1, 1] / det, -d[:, 1, 0] / det
        inv[:, 1, 0], inv[:, 1, 1] = -d[:, 0, 1] / det, d[:, 0, 0] / det
        grad = np.einsum("ia,nab->nib", g_ref, inv)  # dN_i/dx_b = dN_i/dX_a (J^-1)_ab
        self.dNdr = np.ascontiguousarray(grad[:, :, 0])
        self.dNdz = np.ascontiguousarray(grad[:, :, 1])
        self.r = np.ascontiguousarray(np.einsum("qi,ni->nq", self.N, xy[:, :, 0]))
        if plane:
            self.inv_r = np.zeros_like(self.r)  # eps_out = 0
            self.w = np.ascontiguousarray(ref_weights[None, :] * np.abs(det)[:, None]
                                          * model.geometry.thickness)
        else:
            self.inv_r = 1.0 / self.r  # the kernel multiplies (a division per point costs more)
            self.w = np.ascontiguousarray(ref_weights[None, :] * np.abs(det)[:, None]
                                          * 2.0 * math.pi * self.r)


class QuadPointGeometry:
    """Fixed geometry of Q1 cells at the 2x2 Gauss points (:class:`..q1.QuadGeometry`,
    the one the finite-strain force reads) under the names of :class:`CellGeometry`:
    at small strain the reference and the current coordinates are one.

    ``dofs`` (n, 4); ``dNdr``, ``dNdz`` (n, 4 points, 4 nodes) (1/m); ``N`` (4, 4);
    ``r``, ``inv_r`` (n, 4) (m, 1/m); ``w`` (n, 4) (m^3); ``quad`` the Q1 geometry."""

    def __init__(self, model: DeformableModel, cells: np.ndarray):
        g = q1.QuadGeometry(model.cell_dofs, model.node_xy, cells, model.geometry)
        self.quad = g
        self.cells, self.dofs, self.N, self.w = cells, g.dofs, g.N, g.w
        self.dNdr, self.dNdz, self.r, self.inv_r = g.dNdR, g.dNdZ, g.R, g.inv_R


class QuadratureState:
    """Internal variables at the points of owned cells: eps_p, state, sigma (see module).

    ``by_component``: eps_p and sigma are stored one array per component, ``eps_p_c`` and
    ``sigma_c`` (4, cells x points), and ``eps_p``, ``sigma`` (cells, points, 4) are views
    of them (the layout of the axisymmetric triangles' cell kernel, :func:`kernels`, whose
    loads of a component at a cell's three points are then contiguous); otherwise they
    are stored as shown. ``kernel_arrays`` is what the cell kernel takes: (eps_p_c,
    state, sigma_c) or (eps_p, state, sigma)."""

    def __init__(self, n_cells: int, n_state: int, n_points: int = N_POINTS,
                 by_component: bool = False):
        self.by_component = by_component
        self.state = np.zeros((n_cells, n_points, max(n_state, 1)))
        if by_component:
            self.eps_p_c = np.zeros((N_COMP, n_cells * n_points))
            self.sigma_c = np.zeros((N_COMP, n_cells * n_points))
            self.eps_p = self.eps_p_c.reshape(N_COMP, n_cells, n_points).transpose(1, 2, 0)
            self.sigma = self.sigma_c.reshape(N_COMP, n_cells, n_points).transpose(1, 2, 0)
            self.kernel_arrays = (self.eps_p_c, self.state, self.sigma_c)
        else:
            self.eps_p = np.zeros((n_cells, n_points, N_COMP))
            self.sigma = np.zeros((n_cells, n_points, N_COMP))
            self.kernel_arrays = (self.eps_p, self.state, self.sigma)

    def copy_from(self, other: "QuadratureState") -> None:
        """This state := ``other``'s (the same layout), in place."""
        for mine, theirs in zip(self.kernel_arrays, other.kernel_arrays):
            np.copyto(mine, theirs)


# ---------------------------------------------------------------- compiled kernels
_KERNELS: dict = {}


def kernels(update, n_state: int = 1, point=None, screen=None, ahead: bool = False):
    """The fused cell kernel and the point loop of the generic path for ``update``, whose
    points carry ``n_state`` variables (the last axis of the state array, at least 1).
    With ``point``, the same update on scalars (:mod:`..materials.axisym`), the fused
    kernel calls that instead, on the point's values where they are. With ``screen``
    too, the kernel runs that test first, inlined: where it finds the trial stress
    elastic the trial stress is the result and ``point`` is not called. With ``ahead``
    it runs the screen at a cell's three points before it updates any (three
    independent chains of arithmetic the core overlaps: J2's step, whose ``point`` is
    inlined, is faster so; a material whose ``point`` is a call would keep the three
    trial stresses across it), and a cell whose three points it finds elastic takes a
    straight-line block without the point loop. The kernel reads eps_p and sigma by
    component (``QuadratureState(by_component=True).kernel_arrays``)."""
    if screen is not None and point is None:
        raise ValueError("a screen needs the scalar point it screens for")
    ahead = bool(ahead) and screen is not None
    key = (update, max(int(n_state), 1), point, screen, ahead)
    if key in _KERNELS:
        return _KERNELS[key]
    ns = key[1]
    scalar = point is not None  # a constant of the compiled kernel: one branch is compiled
    screened = screen is not None
    point = bbar.no_point if point is None else point
    screen = bbar.no_screen if screen is None else screen

    @njit
    def fused(params, dt, dofs, dNdr, dNdz, N, inv_r, w, u, f, eps_p, state, sigma, work):
        """f += sum_q w_q B_q' sigma_q over the cells; returns the plastic work increment
        sum_q w_q 1/2 (sigma_n + sigma_{n+1}) : (eps_p,{n+1} - eps_p,n) (J).

        ``eps_p`` and ``sigma`` (4, cells x points): one array per component, so that
        a component's loads at a cell's three points are contiguous (with the elastic
        cells' straight-line block, the step of a J2 body is faster so). Every array is
        C-contiguous (the force's are). The arrays are read through flat
        views with the cell and point offsets computed once (a 2- or 3-d index multiplies
        by run-time strides at every access) and the rule's shape values are hoisted out
        of the cell loop (they are the same for every cell). A material's scalar
        ``point`` takes the strain and plastic strain as numbers and its state where it
        lies; otherwise its ``update`` sees them through small scratch arrays (a view
        into the big arrays per point would cost two reference-count updates each),
        copied in and out (unrolled: ``ns`` is fixed when the kernel is built). A
        material's ``screen`` runs before its ``point``, which only the points it leaves
        undecided call (with ``ahead``, at the cell's three points before the first
        update). A point the screen decides keeps its plastic strain and books no work:
        the update it stands for changes neither (d eps_p = eps_p - eps_p = 0)."""
        # (The generic path's loop below repeats the point block: a compiled helper for
        # it, called or inlined by numba, made this kernel 2-5x slower.)
        if state.shape[2] != ns:
            raise ValueError("state array: its last axis is not the kernel's n_state")
        eps, ep, s = work[0], work[1], work[2]
        st = work[3, :ns]
        dof, g_r, g_z = dofs.reshape(-1), dNdr.reshape(-1), dNdz.reshape(-1)
        ir_q, w_q = inv_r.reshape(-1), w.reshape(-1)
        st_q = state.reshape(-1)
        ep0, ep1, ep2, ep3 = eps_p[0], eps_p[1], eps_p[2], eps_p[3]  # by component
        sg0, sg1, sg2, sg3 = sigma[0], sigma[1], sigma[2], sigma[3]
        n00, n01, n02 = N[0, 0], N[0, 1], N[0, 2]
        n10, n11, n12 = N[1, 0], N[1, 1], N[1, 2]
        n20, n21, n22 = N[2, 0], N[2, 1], N[2, 2]
        wp = 0.0
        for c in range(dofs.shape[0]):
            c3 = 3 * c  # the cell's first node, and its first point
            a0, a1, a2 = 2 * dof[c3], 2 * dof[c3 + 1], 2 * dof[c3 + 2]
            ur0, ur1, ur2 = u[a0], u[a1], u[a2]
            uz0, uz1, uz2 = u[a0 + 1], u[a1 + 1], u[a2 + 1]
            gr0, gr1, gr2 = g_r[c3], g_r[c3 + 1], g_r[c3 + 2]
            gz0, gz1, gz2 = g_z[c3], g_z[c3 + 1], g_z[c3 + 2]
            e_rr = gr0 * ur0 + gr1 * ur1 + gr2 * ur2
            e_zz = gz0 * uz0 + gz1 * uz1 + gz2 * uz2
            e_rz = 0.5 * ((gz0 * ur0 + gz1 * ur1 + gz2 * ur2) + (gr0 * uz0 + gr1 * uz1 + gr2 * uz2))
            # P1 gradients are constant in the cell: f_i = B_i' sum_q w_q sigma_q needs the
            # weighted sums of sigma_rr, sigma_zz, sigma_rz and, for the hoop term, of
            # w_q sigma_tt,q / r_q N_i(x_q)
            S_rr = S_zz = S_rz = h0 = h1 = h2 = 0.0
            if ahead:
                # the material's elastic test at the cell's three points before any update:
                # straight-line code whose three chains the core runs side by side
                e_tt0 = (n00 * ur0 + n01 * ur1 + n02 * ur2) * ir_q[c3]
                e_tt1 = (n10 * ur0 + n11 * ur1 + n12 * ur2) * ir_q[c3 + 1]
                e_tt2 = (n20 * ur0 + n21 * ur1 + n22 * ur2) * ir_q[c3 + 2]
                tr0 = screen(e_rr, e_tt0, e_zz, e_rz, ep0[c3], ep1[c3], ep2[c3],
                             ep3[c3], st_q, ns * c3, params)
                tr1 = screen(e_rr, e_tt1, e_zz, e_rz, ep0[c3 + 1], ep1[c3 + 1],
                             ep2[c3 + 1], ep3[c3 + 1], st_q, ns * (c3 + 1), params)
                tr2 = screen(e_rr, e_tt2, e_zz, e_rz, ep0[c3 + 2], ep1[c3 + 2],
                             ep2[c3 + 2], ep3[c3 + 2], st_q, ns * (c3 + 2), params)
                if tr0[0] and tr1[0] and tr2[0]:
                    # the cell is elastic (most cells, most steps): its three trial stresses
                    # are the result, and this straight-line block does what the point loop
                    # below does for them, in its order (the same sums, bit for bit), without
                    # the loop's selections and branches and the inlined return beside them
                    _, s0, s1, s2, s3 = tr0
                    i = c3 + 0
                    wq = w_q[i]
                    sg0[i], sg1[i], sg2[i], sg3[i] = s0, s1, s2, s3
                    S_rr += wq * s0
                    S_zz += wq * s2
                    S_rz += wq * s3
                    t = wq * s1 * ir_q[i]
                    h0 += t * n00
                    h1 += t * n01
                    h2 += t * n02
                    _, s0, s1, s2, s3 = tr1
                    i = c3 + 1
                    wq = w_q[i]
                    sg0[i], sg1[i], sg2[i], sg3[i] = s0, s1, s2, s3
                    S_rr += wq * s0
                    S_zz += wq * s2
                    S_rz += wq * s3
                    t = wq * s1 * ir_q[i]
                    h0 += t * n10
                    h1 += t * n11
                    h2 += t * n12
                    _, s0, s1, s2, s3 = tr2
                    i = c3 + 2
                    wq = w_q[i]
                    sg0[i], sg1[i], sg2[i], sg3[i] = s0, s1, s2, s3
                    S_rr += wq * s0
                    S_zz += wq * s2
                    S_rz += wq * s3
                    t = wq * s1 * ir_q[i]
                    h0 += t * n20
                    h1 += t * n21
                    h2 += t * n22
                    f[a0] += gr0 * S_rr + gz0 * S_rz + h0
                    f[a1] += gr1 * S_rr + gz1 * S_rz + h1
                    f[a2] += gr2 * S_rr + gz2 * S_rz + h2
                    f[a0 + 1] += gz0 * S_zz + gr0 * S_rz
                    f[a1 + 1] += gz1 * S_zz + gr1 * S_rz
                    f[a2 + 1] += gz2 * S_zz + gr2 * S_rz
                    continue
            else:
                e_tt0 = e_tt1 = e_tt2 = 0.0
                tr0 = tr1 = tr2 = (False, 0.0, 0.0, 0.0, 0.0)
            for q in range(3):
                if q == 0:
                    n0, n1, n2 = n00, n01, n02
                    e_tt, trial = e_tt0, tr0
                elif q == 1:
                    n0, n1, n2 = n10, n11, n12
                    e_tt, trial = e_tt1, tr1
                else:
                    n0, n1, n2 = n20, n21, n22
                    e_tt, trial = e_tt2, tr2
                i = c3 + q  # the point
                k0 = ns * i  # its first state variable
                ir = ir_q[i]
                if not ahead:
                    e_tt = (n0 * ur0 + n1 * ur1 + n2 * ur2) * ir
                wq = w_q[i]
                elastic, s0, s1, s2, s3 = trial  # ahead: the trial stress if elastic
                if screened and not ahead:  # the material's elastic test: no call
                    elastic, s0, s1, s2, s3 = screen(e_rr, e_tt, e_zz, e_rz, ep0[i],
                                                     ep1[i], ep2[i], ep3[i],
                                                     st_q, k0, params)
                if not elastic:
                    p0, p1, p2, p3 = ep0[i], ep1[i], ep2[i], ep3[i]
                    if scalar:
                        s0, s1, s2, s3, q0, q1, q2, q3 = point(e_rr, e_tt, e_zz, e_rz, p0, p1,
                                                               p2, p3, st_q, k0, params, dt)
                    else:
                        eps[0], eps[1], eps[2], eps[3] = e_rr, e_tt, e_zz, e_rz
                        ep[0], ep[1], ep[2], ep[3] = p0, p1, p2, p3
                        for k in range(ns):
                            st[k] = st_q[k0 + k]
                        update(eps, ep, st, params, dt, s)
                        for k in range(ns):
                            st_q[k0 + k] = st[k]
                        s0, s1, s2, s3 = s[0], s[1], s[2], s[3]
                        q0, q1, q2, q3 = ep[0], ep[1], ep[2], ep[3]
                    d0, d1, d2, d3 = q0 - p0, q1 - p1, q2 - p2, q3 - p3
                    if d0 != 0.0 or d1 != 0.0 or d2 != 0.0 or d3 != 0.0:  # plastic: its work
                        o0, o1, o2, o3 = sg0[i], sg1[i], sg2[i], sg3[i]
                        wp += 0.5 * wq * ((o0 + s0) * d0 + (o1 + s1) * d1 + (o2 + s2) * d2
                                          + 2.0 * (o3 + s3) * d3)
                        ep0[i], ep1[i], ep2[i], ep3[i] = q0, q1, q2, q3
                sg0[i], sg1[i], sg2[i], sg3[i] = s0, s1, s2, s3
                S_rr += wq * s0
                S_zz += wq * s2
                S_rz += wq * s3
                t = wq * s1 * ir
                h0 += t * n0
                h1 += t * n1
                h2 += t * n2
            f[a0] += gr0 * S_rr + gz0 * S_rz + h0
            f[a1] += gr1 * S_rr + gz1 * S_rz + h1
            f[a2] += gr2 * S_rr + gz2 * S_rz + h2
            f[a0 + 1] += gz0 * S_zz + gr0 * S_rz
            f[a1 + 1] += gz1 * S_zz + gr1 * S_rz
            f[a2 + 1] += gz2 * S_zz + gr2 * S_rz
        return wp

    @njit
    def points(params, dt, eps_all, w, eps_p, state, sigma, qdofs, sigma_q, work):
        """Point updates from the strains ``eps_all`` (n, 3 * 4) evaluated by dolfinx;
        the stresses also go to ``sigma_q`` (the quadrature Function's array) at
        ``qdofs`` (n, 3). Returns the plastic work increment (J), as :func:`fused`."""
        eps, ep, s = work[0], work[1], work[2]
        st = work[3, :ns]
        wp = 0.0
        for c in range(eps_all.shape[0]):
            for q in range(3):
                for i in range(4):
                    eps[i] = eps_all[c, 4 * q + i]
                p0, p1, p2, p3 = eps_p[c, q, 0], eps_p[c, q, 1], eps_p[c, q, 2], eps_p[c, q, 3]
                o0, o1, o2, o3 = sigma[c, q, 0], sigma[c, q, 1], sigma[c, q, 2], sigma[c, q, 3]
                ep[0], ep[1], ep[2], ep[3] = p0, p1, p2, p3
                for k in range(ns):
                    st[k] = state[c, q, k]
                update(eps, ep, st, params, dt, s)
                for k in range(ns):
                    state[c, q, k] = st[k]
                k4 = 4 * qdofs[c, q]
                for i in range(4):
                    sigma[c, q, i] = s[i]
                    eps_p[c, q, i] = ep[i]
                    sigma_q[k4 + i] = s[i]
                wp += 0.5 * w[c, q] * ((o0 + s[0]) * (ep[0] - p0) + (o1 + s[1]) * (ep[1] - p1)
                                       + (o2 + s[2]) * (ep[2] - p2)
                                       + 2.0 * (o3 + s[3]) * (ep[3] - p3))
        return wp

    _KERNELS[key] = (fused, points)
    return fused, points


def plane_kernel(update, n_state: int = 1, point=None, screen=None):
    """The fused cell kernel of P1 triangles in plane strain, one point per cell: the
    strain of a P1 cell is constant and eps_out = 0, so its three points would carry the
    same strain and state (docs/plane_strain.md). Same signature and results as
    :func:`kernels`' ``fused`` with the one-point geometry of :class:`CellGeometry`
    (``w`` (n, 1) = t |J| / 2, ``inv_r`` unread): the strain (eps_xx, 0, eps_yy,
    eps_xy), the point update (behind the material's ``screen`` if it has one) and
    f_i = w B_i' sigma (N); returns the plastic work increment (J)."""
    if screen is not None and point is None:
        raise ValueError("a screen needs the scalar point it screens for")
    key = ("plane", update, max(int(n_state), 1), point, screen)
    if key in _KERNELS:
        return _KERNELS[key]
    ns = key[2]
    scalar, screened = point is not None, screen is not None  # constants of the kernel
    point = bbar.no_point if point is None else point
    screen = bbar.no_screen if screen is None else screen

    @njit
    def fused(params, dt, dofs, dNdr, dNdz, N, inv_r, w, u, f, eps_p, state, sigma, work):
        """f += sum over cells of w_c B' sigma_c; returns the plastic work increment
        sum_c w_c 1/2 (sigma_n + sigma_{n+1}) : (eps_p,{n+1} - eps_p,n) (J)."""
        if state.shape[2] != ns or eps_p.shape[1] != 1:
            raise ValueError("state arrays: not one point per cell with the kernel's n_state")
        eps, ep, s = work[0], work[1], work[2]
        st = work[3, :ns]
        dof, g_r, g_z = dofs.reshape(-1), dNdr.reshape(-1), dNdz.reshape(-1)
        w_q, ep_q, st_q, sg_q = w.reshape(-1), eps_p.reshape(-1), state.reshape(-1), \
            sigma.reshape(-1)
        wp = 0.0
        for c in range(dofs.shape[0]):
            c3 = 3 * c  # the cell's first node
            a0, a1, a2 = 2 * dof[c3], 2 * dof[c3 + 1], 2 * dof[c3 + 2]
            ux0, ux1, ux2 = u[a0], u[a1], u[a2]
            uy0, uy1, uy2 = u[a0 + 1], u[a1 + 1], u[a2 + 1]
            gx0, gx1, gx2 = g_r[c3], g_r[c3 + 1], g_r[c3 + 2]
            gy0, gy1, gy2 = g_z[c3], g_z[c3 + 1], g_z[c3 + 2]
            e_xx = gx0 * ux0 + gx1 * ux1 + gx2 * ux2
            e_yy = gy0 * uy0 + gy1 * uy1 + gy2 * uy2
            e_xy = 0.5 * ((gy0 * ux0 + gy1 * ux1 + gy2 * ux2) + (gx0 * uy0 + gx1 * uy1 + gx2 * uy2))
            j = 4 * c   # the point's first tensor component
            k0 = ns * c  # its first state variable
            p0, p1, p2, p3 = ep_q[j], ep_q[j + 1], ep_q[j + 2], ep_q[j + 3]
            elastic = False
            s0 = s1 = s2 = s3 = 0.0
            if screened:  # the material's elastic test: the trial stress, no call
                elastic, s0, s1, s2, s3 = screen(e_xx, 0.0, e_yy, e_xy, p0, p1, p2, p3, st_q,
                                                 k0, params)
            wq = w_q[c]
            if not elastic:
                if scalar:
                    s0, s1, s2, s3, q0, q1, q2, q3 = point(e_xx, 0.0, e_yy, e_xy, p0, p1, p2,
                                                           p3, st_q, k0, params, dt)
                else:
                    eps[0], eps[1], eps[2], eps[3] = e_xx, 0.0, e_yy, e_xy
                    ep[0], ep[1], ep[2], ep[3] = p0, p1, p2, p3
                    for k in range(ns):
                        st[k] = st_q[k0 + k]
                    update(eps, ep, st, params, dt, s)
                    for k in range(ns):
                        st_q[k0 + k] = st[k]
                    s0, s1, s2, s3 = s[0], s[1], s[2], s[3]
                    q0, q1, q2, q3 = ep[0], ep[1], ep[2], ep[3]
                d0, d1, d2, d3 = q0 - p0, q1 - p1, q2 - p2, q3 - p3
                if d0 != 0.0 or d1 != 0.0 or d2 != 0.0 or d3 != 0.0:  # plastic: its work
                    o0, o1, o2, o3 = sg_q[j], sg_q[j + 1], sg_q[j + 2], sg_q[j + 3]
                    wp += 0.5 * wq * ((o0 + s0) * d0 + (o1 + s1) * d1 + (o2 + s2) * d2
                                      + 2.0 * (o3 + s3) * d3)
                    ep_q[j], ep_q[j + 1], ep_q[j + 2], ep_q[j + 3] = q0, q1, q2, q3
            sg_q[j], sg_q[j + 1], sg_q[j + 2], sg_q[j + 3] = s0, s1, s2, s3
            S_xx, S_yy, S_xy = wq * s0, wq * s2, wq * s3
            f[a0] += gx0 * S_xx + gy0 * S_xy
            f[a1] += gx1 * S_xx + gy1 * S_xy
            f[a2] += gx2 * S_xx + gy2 * S_xy
            f[a0 + 1] += gy0 * S_yy + gx0 * S_xy
            f[a1 + 1] += gy1 * S_yy + gx1 * S_xy
            f[a2 + 1] += gy2 * S_yy + gx2 * S_xy
        return wp

    _KERNELS[key] = fused
    return fused


@njit(cache=True)
def velocity_update(coef, f, u, v, f_prev, u_prev) -> float:
    """v += coef * f (coef = -dt / m, 0 on fixed dofs) on the owned dofs; returns the
    deformation work 1/2 (f_prev + f) . (u - u_prev) (J) and stores f, u as the previous."""
    work = 0.0
    for i in range(coef.size):
        fi = f[i]
        ui = u[i]
        v[i] += coef[i] * fi
        work += 0.5 * (f_prev[i] + fi) * (ui - u_prev[i])
        f_prev[i] = fi
        u_prev[i] = ui
    return work


@njit(cache=True)
def elastic_energy(lmbda, mu, sigma, w) -> float:
    """psi_e = sum_q w_q 1/2 sigma : C^-1 : sigma (J) over the points."""
    total = 0.0
    c = lmbda / (3.0 * lmbda + 2.0 * mu)
    for k in range(sigma.shape[0]):
        for q in range(sigma.shape[1]):
            s = sigma[k, q]
            tr = s[0] + s[1] + s[2]
            ss = s[0] * s[0] + s[1] * s[1] + s[2] * s[2] + 2.0 * s[3] * s[3]
            total += w[k, q] * (ss - c * tr * tr) / (4.0 * mu)
    return total


@njit(cache=True)
def cell_means(which, eps_p, state, out_eps_p, out_eps_bar, out_yielded) -> None:
    """Per cell in ``which`` (positions): the mean plastic strain and equivalent plastic
    strain of its points, and 1 if any point has yielded (eps_bar_p > 0), else 0."""
    n_points = eps_p.shape[1]
    for c in which:
        for i in range(4):
            total = eps_p[c, 0, i]
            for q in range(1, n_points):
                total += eps_p[c, q, i]
            out_eps_p[c, i] = total / n_points
        total = state[c, 0, 0]
        yielded = state[c, 0, 0] > 0.0
        for q in range(1, n_points):
            total += state[c, q, 0]
            yielded = yielded or state[c, q, 0] > 0.0
        out_eps_bar[c] = total / n_points
        out_yielded[c] = 1.0 if yielded else 0.0


# ---------------------------------------------------------------- the force
class QuadratureForce:
    """f_int of one path-dependent body (cells of group ``body``) and its energy terms.

    ``u`` is the displacement Function (m) whose array the integrator steps (ghosts
    forward-scattered before :meth:`velocity_increment`); ``coef`` the owned
    -h_n / m (s/kg), 0 on fixed dofs; ``path`` 'fast' or 'generic' ('fast' only on a
    quadrilateral mesh: B-bar, :mod:`.bbar`); ``mass`` the owned lumped masses (kg),
    needed by :meth:`set_step` only. ``dt`` (s) is the step the point updates see (a
    rate-dependent model reads it): the step just taken, h_{n-1/2}."""

    def __init__(self, model: DeformableModel, body: str, u: fem.Function, dt: float,
                 coef: np.ndarray, path: str = "fast", mass: np.ndarray | None = None):
        if path not in ("fast", "generic"):
            raise ValueError(f"path = '{path}': use 'fast' or 'generic'")
        self.model, self.body, self.u, self.dt, self.path = model, body, u, float(dt), path
        self.mass, self.h = mass, float(dt)
        self._stable_dt = None
        self.material = model.bodies[body].material
        self.params = self.material.params()
        self.cells = owned_cells(model, body)
        quad = getattr(model, "quadrilateral", False)
        if quad and path != "fast":
            raise InputError(f"f_int path '{path}' runs on triangles only: a body on "
                             "quadrilaterals takes the fused B-bar kernel (path 'fast')")
        if model.geometry.plane and path != "fast":
            raise InputError(f"f_int path '{path}' runs axisymmetric triangles only: a "
                             "plane-strain body takes the fused kernel (path 'fast')")
        self.geometry = (QuadPointGeometry if quad else CellGeometry)(model, self.cells)
        n_points = self.geometry.w.shape[1]
        # the axisymmetric triangles' kernel reads eps_p and sigma by component
        self._by_component = not quad and not model.geometry.plane
        self.qs = QuadratureState(self.cells.size, self.material.n_state, n_points,
                                  self._by_component)
        self.coef = coef
        self.f = fem.Function(model.V)  # f_int (N), owned + ghost entries
        n = model.n_owned
        self.f_owned = self.f.x.array[:n]
        self._f_prev = np.zeros(n)
        self._u_prev = np.zeros(n)
        self._work = np.zeros((bbar.WORK_ROWS if quad else 4, max(N_COMP, self.material.n_state)))
        self.deformation_work_local = 0.0  # sum 1/2 (f^{n-1} + f^n) . (u^n - u^{n-1}) (J)
        self.plastic_work_local = 0.0      # sum over points of 1/2 (s^{n-1} + s^n) : d eps_p (J)
        self._started = False
        point, screen = (getattr(self.material, name, None) for name in ("point", "screen"))
        ahead = getattr(self.material, "screen_ahead", False)
        if quad:
            self._fused, self._points = bbar.kernel(self.material.update, point, screen), None
        elif model.geometry.plane:
            self._fused = plane_kernel(self.material.update, self.material.n_state, point,
                                       screen)
            self._points = None
        else:
            self._fused, self._points = kernels(self.material.update, self.material.n_state,
                                                point, screen, ahead)
        if path == "generic":
            self._setup_generic()
        self._setup_cell_fields()
        # the points at an output's displacement (point_stresses): their own state and a
        # force array that is written, never read
        self.frame = QuadratureState(self.cells.size, self.material.n_state, n_points,
                                     self._by_component)
        self._frame_f = np.zeros_like(self.f.x.array)
        self._load_kernels()

    def _load_kernels(self) -> None:
        """Compile (or load from the cache) every kernel of a step and of an output for the
        types of this body's arrays, now at set-up, without running them: the fused cell
        kernel is specialised on the material's update (a closure, compiled once per
        process, ~1 s), which would otherwise compile inside the first timed step."""
        from ..jit_watch import load

        g, qs, n = self.geometry, self.qs, self.model.n_owned
        # the fused kernel on either path: point_stresses runs it
        load(self._fused, self.params, self.dt, g.dofs, g.dNdr, g.dNdz, g.N, g.inv_r, g.w,
             self.u.x.array, self.f.x.array, *qs.kernel_arrays, self._work)
        if self.path == "generic":
            load(self._points, self.params, self.dt, self._eps_buf, g.w, qs.eps_p, qs.state,
                 qs.sigma, self._qdofs, self._sigma_q.x.array, self._work)
        owned = self.u.x.array[:n]
        load(velocity_update, self.coef, self.f_owned, owned, owned, self._f_prev, self._u_prev)
        load(elastic_energy, self.material.lmbda, self.material.mu, qs.sigma, g.w)
        load(cell_means, self._all, qs.eps_p, qs.state, self._cell_eps_p, self._cell_eps_bar,
             self._cell_yielded)

    # ------------------------------------------------------------ generic path
    def _setup_generic(self) -> None:
        model = self.model
        mesh = model.mesh
        points, _ = reference_rule()
        r = forms.radius(mesh)
        e = forms.strain(self.u, r)
        self._eps_expr = fem.Expression(ufl.as_vector([e[0, 0], e[1, 1], e[2, 2], e[0, 2]]), points)
        self._eps_buf = np.zeros((self.cells.size, N_POINTS * N_COMP))
        Q = compat.quadrature_vector_space(mesh, forms.STIFFNESS_DEGREE, N_COMP)
        self._sigma_q = fem.Function(Q)
        qdofs = compat.cell_dofs(Q)[self.cells]
        self._qdofs = np.ascontiguousarray(qdofs.astype(np.int32))
        s = self._sigma_q
        sigma = ufl.as_tensor([[s[0], 0, s[3]], [0, s[1], 0], [s[3], 0, s[2]]])
        w = ufl.TestFunction(model.V)
        dx = forms.cell_measure(mesh, model.tmesh.cell_tags, model.tmesh.cell_tag(self.body),
                                forms.STIFFNESS_DEGREE)
        self._form = compile_form(ufl.inner(sigma, forms.strain(w, r)) * 2 * math.pi * r * dx)

    # ------------------------------------------------------------ the step
    def compute(self) -> np.ndarray:
        """f_int(u) (N) into ``self.f`` (owned entries summed over ranks): the point
        updates bring the state to the time of u and book their plastic work. Returns
        the owned view."""
        g, qs = self.geometry, self.qs
        if self.path == "fast":
            arr = self.f.x.array
            arr[:] = 0.0
            wp = self._fused(self.params, self.dt, g.dofs, g.dNdr, g.dNdz, g.N, g.inv_r, g.w,
                             self.u.x.array, arr, *qs.kernel_arrays, self._work)
            compat.scatter_add(self.f.x)
        else:
            compat.eval_expression_into(self._eps_expr, self.model.mesh, self.cells, self._eps_buf)
            wp = self._points(self.params, self.dt, self._eps_buf, g.w, qs.eps_p, qs.state,
                              qs.sigma, self._qdofs, self._sigma_q.x.array, self._work)
            vec = compat.petsc_vec(self.f)
            with vec.localForm() as local:
                local.set(0.0)
            fem.petsc.assemble_vector(vec, self._form)
            vec.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        self.plastic_work_local += wp
        return self.f_owned

    def set_step(self, h: float, h_avg: float) -> None:
        """coef = -h_avg / m on the free dofs (written in place; the set-up's arithmetic);
        the point updates take the step just taken (the previous h)."""
        if self.mass is None:
            raise ValueError("set_step needs the lumped masses: give mass to the force")
        np.divide(-h_avg, self.mass, out=self.coef, where=self.coef != 0.0)
        self.dt, self.h = self.h, float(h)

    def velocity_increment(self, u: np.ndarray, v: np.ndarray, h_avg: float) -> None:
        """v += coef f_int(u^n) (coef = -h_avg / m from :meth:`set_step`) on the free owned
        dofs, and book the deformation work."""
        self.add_velocity_increment(u, v)

    def stable_dt(self) -> float:
        """2 / omega of the element bound over the body's cells (s), the elastic element
        matrices, the dofs where coef = 0 (the fixed ones) removed; computed once (small
        strain: the cells do not move). Collective."""
        if self._stable_dt is None:
            fixed = np.flatnonzero(self.coef == 0.0).astype(np.int32)
            self._stable_dt = parts_stable_dt(self.model, fixed, [self.body])
        return self._stable_dt

    def book(self) -> Booking:
        """work: the deformation work; stored: psi_e of the current stresses; dissipated:
        the plastic work (J, this rank)."""
        return Booking(work=self.deformation_work_local, stored=self.elastic_energy_local(),
                       dissipated=self.plastic_work_local)

    def add_velocity_increment(self, u_owned: np.ndarray, v_owned: np.ndarray) -> None:
        """v += -dt M^-1 f_int(u^n) on the free owned dofs, and book the deformation work."""
        self.compute()
        if not self._started:  # step 0: f^{-1} := f^0, u^{-1} := u^0 (no work yet)
            self._f_prev[:] = self.f_owned
            self._u_prev[:] = u_owned
            self._started = True
        self.deformation_work_local += velocity_update(self.coef, self.f_owned, u_owned, v_owned,
                                                       self._f_prev, self._u_prev)

    # ------------------------------------------------------------ energy (J), local to this rank
    def elastic_energy_local(self) -> float:
        """psi_e of the current stresses: sum over points of 1/2 sigma : C^-1 : sigma w (J)."""
        return elastic_energy(self.material.lmbda, self.material.mu, self.qs.sigma, self.geometry.w)

    # ------------------------------------------------------------ cell fields
    def _setup_cell_fields(self) -> None:
        n = self.cells.size
        self._all = np.arange(n, dtype=np.intp)
        self._cell_eps_p = np.zeros((n, N_COMP))
        self._cell_eps_bar = np.zeros(n)
        self._cell_yielded = np.zeros(n)

    def cell_values(self, which: np.ndarray | None = None, qs: QuadratureState | None = None
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Per owned cell of the body: mean eps_p (n, 4), mean eps_bar_p (n,) and the
        yielded flag (n,) (1 if any point has eps_bar_p > 0) of the state ``qs`` (default:
        the committed one, :attr:`qs`; :attr:`frame` for an output's); only the positions
        ``which`` (into ``cells``) are brought up to date when given."""
        qs = self.qs if qs is None else qs
        cell_means(self._all if which is None else which, qs.eps_p, qs.state,
                   self._cell_eps_p, self._cell_eps_bar, self._cell_yielded)
        return self._cell_eps_p, self._cell_eps_bar, self._cell_yielded

    @property
    def cell_kernel(self):
        """The material's fused cell kernel (:func:`kernels`): called with the arguments of
        :meth:`compute`'s call (for any cells: their geometry, a displacement, a force
        array and the points' state), it updates the points and adds the force."""
        return self._fused

    @property
    def work(self) -> np.ndarray:
        """The cell kernel's scratch array (its shape is what the kernel needs)."""
        return self._work

    def point_stresses(self, u: np.ndarray) -> QuadratureState:
        """The points' update at the displacement ``u`` (m; the local array, owned and ghost
        entries current, laid out as the Function's) from the committed state, into
        :attr:`frame`, which it returns; the committed state is left as it is.

        An output comes after the step that moved u^n to u^{n+1}, while the points hold
        the update at u^n. This is the update the next step makes at u^{n+1}, by the same
        kernel (the fused one, on either path) from the same state, over the step that
        reached u^{n+1} (:attr:`h`, h_{n+1/2}; the points' :attr:`dt` is still h_{n-1/2}, which
        a rate-dependent material would read when the step varies): its stresses are what
        the material computes for the displacement written with them, and satisfy its
        yield condition. One pass over the body's cells."""
        qs, fr, g = self.qs, self.frame, self.geometry
        fr.copy_from(qs)
        self._frame_f.fill(0.0)
        self._fused(self.params, self.h, g.dofs, g.dNdr, g.dNdz, g.N, g.inv_r, g.w, u,
                    self._frame_f, *fr.kernel_arrays, self._work)
        return fr
