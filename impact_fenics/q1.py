"""Bilinear quadrilaterals (Q1) in axisymmetry and plane strain: the 2x2 Gauss geometry,
the lumped mass and the mean-dilatation (B-bar) elastic element.

One geometry serves every Q1 force: the finite-strain one (F-bar, total Lagrangian,
:mod:`.internal_force.finite`) reads it in the reference coordinates (R, Z), the
small-strain ones (B-bar: the path-dependent force of :mod:`.internal_force.bbar` and
the stiffness K of the linear bodies, :func:`bbar_element_matrices`) in the same
coordinates, which small strain does not tell apart from the current ones.

**Reference cell.** The unit square [0, 1]^2 with dolfinx's vertex order (0, 0),
(1, 0), (0, 1), (1, 1); N_a the bilinear shape functions; the 2x2 Gauss points
1/2 -+ 1/(2 sqrt 3) with the weight 1/4 each. At point q of a cell:
dN_a/dx = J^-T dN_a/dxi with J = dx/dxi (1/m), r_q = sum_a N_a(xi_q) r_a (m, > 0
at every Gauss point, also in a cell that touches the axis) and the weight
w_q = 1/4 |det J| 2 pi r_q (m^3), so that sum_q w_q g(x_q) is the ring integral of g.
In plane strain (:mod:`.geometry`) w_q = 1/4 |det J| t (m^3, t the slab's thickness) and
the factor of the out-of-plane row, inv_R, is 0 (eps_out = 0): every kernel below serves
both geometries unchanged.

**Lumped mass.** m_a = rho sum_q w_q N_a(x_q) (kg), the row sums of the consistent
mass: positive at every node (N_a >= 0), axis nodes included. 2x2 Gauss integrates
rho N_a 2 pi r |det J| (degree 2 in each reference variable) exactly.

**Mean dilatation at small strain (B-bar).** The strain at point q in the
four-component notation of :mod:`.materials.axisym` (rr, tt, zz, rz; tensor shear),
eps_q = B_q u_e with eps_tt = u_r(x_q) / r_q, has its volumetric part
theta_q = eps_rr + eps_tt + eps_zz (the hoop strain included) replaced by the cell's
ring-weighted mean theta_bar = sum_q w_q theta_q / V (V = sum_q w_q, m^3):

    eps_bar_q = eps_q + (theta_bar - theta_q) / 3 (1, 1, 1, 0) = B_bar_q u_e,

the Q1/P0 element of Nagtegaal, Parks & Rice (1974) in the B-bar form of Hughes
(1980): one volume constraint per cell, so a nearly incompressible or plastically
flowing body does not lock (a fully integrated Q1 does, in axisymmetry as in plane
strain). The internal force is f_e = sum_q w_q B_bar_q' G sigma_q with G =
diag(1, 1, 1, 2) (the tensor shear counts twice in sigma : eps); with
sigma_q = D eps_bar_q it is K_e u_e, K_e = sum_q w_q B_bar_q' G D B_bar_q (N/m),
symmetric for a symmetric G D. Since B_bar_q differs from B_q only in its
volumetric rows, f_e = sum_q w_q B_q' G (dev sigma_q + p_bar (1, 1, 1, 0)) with
p_bar = sum_q w_q tr(sigma_q) / (3 V): the form the path-dependent kernel uses.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from .geometry import Geometry


N_POINTS = 4
N_NODES = 4
_G = 0.5 / math.sqrt(3.0)
# 2x2 Gauss points on the reference square [0, 1]^2, and dolfinx's vertex order of a
# quadrilateral: (0, 0), (1, 0), (0, 1), (1, 1)
GAUSS = np.array([[0.5 - _G, 0.5 - _G], [0.5 + _G, 0.5 - _G],
                  [0.5 - _G, 0.5 + _G], [0.5 + _G, 0.5 + _G]])
GAUSS_WEIGHT = 0.25
VERTICES = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0]])


def shape_functions(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Q1 values (p, 4) and reference gradients (p, 4, 2) at reference points (p, 2)."""
    x, y = points[:, 0:1], points[:, 1:2]
    vx, vy = VERTICES[:, 0], VERTICES[:, 1]
    fx = np.where(vx == 1.0, x, 1.0 - x)
    fy = np.where(vy == 1.0, y, 1.0 - y)
    sx = np.where(vx == 1.0, 1.0, -1.0)
    sy = np.where(vy == 1.0, 1.0, -1.0)
    return fx * fy, np.stack([sx * fy, fx * sy], axis=-1)


def reference_point(X: np.ndarray, point: np.ndarray) -> np.ndarray:
    """The reference coordinates xi (2,) of the physical point ``point`` (r, z) (m) in the
    cell of vertices X (4, 2) (m, dolfinx's order): the root of sum_a N_a(xi) X_a = x by
    Newton's method from the cell's centre (the bilinear map is invertible on a cell that
    is not twisted; a point inside converges quadratically, in a few iterations). A
    coordinate within a few round-offs of 0 or 1 is put there: a point on a node or an
    edge reads those nodes alone."""
    xi = np.array([0.5, 0.5])
    scale = float(np.max(np.abs(X - X.mean(axis=0)))) or 1.0
    for _ in range(50):
        N, dN = shape_functions(xi[None, :])
        residual = N[0] @ X - point
        if np.max(np.abs(residual)) <= 4.0 * np.finfo(float).eps * max(scale, np.max(np.abs(X))):
            break
        xi = xi - np.linalg.solve(X.T @ dN[0], residual)
    tol = 16.0 * np.finfo(float).eps
    for k in range(2):
        for edge in (0.0, 1.0):
            if abs(xi[k] - edge) <= tol:
                xi[k] = edge
    return xi


class QuadGeometry:
    """Geometry of Q1 cells at the 2x2 Gauss points (see the module).

    ``dofs`` (n, 4) node (block) indices; ``dNdR``, ``dNdZ`` (n, 4 points, 4 nodes)
    (1/m); ``dxi`` (n, 4 points, 4) the inverse Jacobian J^-1 = dxi/dX at the points,
    (dxi/dR, dxi/dZ, deta/dR, deta/dZ) (1/m); ``N`` (4 points, 4 nodes); ``R`` (n, 4)
    point radii (m) and ``inv_R`` their inverses (1/m); ``w`` (n, 4) weights
    1/4 |det J| 2 pi R_q (m^3); ``volume`` (n,) the cells' ring volumes V (m^3). In plane
    strain ``w`` = 1/4 |det J| t, ``inv_R`` = 0 (the out-of-plane strain's factor) and
    ``volume`` the slab's t A."""

    def __init__(self, cell_nodes: np.ndarray, node_xy: np.ndarray, cells: np.ndarray,
                 geometry: Geometry):
        """``cell_nodes``: the dofmap (local cells, 4) in the block indices of ``node_xy``;
        ``geometry`` the section's (required: a site that forgot it would weigh a plane-
        strain slab with rings)."""
        self.cells = cells
        self.dofs = np.ascontiguousarray(cell_nodes[cells].astype(np.int32))
        X = node_xy[self.dofs]  # (n, 4, 2)
        N, dN = shape_functions(GAUSS)  # (4, 4), (4, 4, 2)
        self.N = np.ascontiguousarray(N)
        jac = np.einsum("nia,qib->nqab", X, dN)  # dX_a / dxi_b
        det = jac[..., 0, 0] * jac[..., 1, 1] - jac[..., 0, 1] * jac[..., 1, 0]
        # a cell may be numbered clockwise (dolfinx's rectangles are): the sign of det is
        # the orientation, one per cell; a sign change inside a cell is a twisted cell
        if np.any(det[:, :1] * det <= 0.0):
            raise ValueError("a quadrilateral of the reference mesh is twisted (det changes sign)")
        inv = np.empty_like(jac)
        inv[..., 0, 0], inv[..., 0, 1] = jac[..., 1, 1] / det, -jac[..., 0, 1] / det
        inv[..., 1, 0], inv[..., 1, 1] = -jac[..., 1, 0] / det, jac[..., 0, 0] / det
        grad = np.einsum("qib,nqba->nqia", dN, inv)  # dN_i / dX_a
        self.dNdR = np.ascontiguousarray(grad[..., 0])
        self.dNdZ = np.ascontiguousarray(grad[..., 1])
        self.dxi = np.ascontiguousarray(inv.reshape(inv.shape[0], N_POINTS, 4))
        self.R = np.ascontiguousarray(np.einsum("qi,ni->nq", N, X[:, :, 0]))
        if geometry.plane:
            self.inv_R = np.zeros_like(self.R)  # eps_out = 0
            self.w = np.ascontiguousarray(GAUSS_WEIGHT * np.abs(det) * geometry.thickness)
        else:
            self.inv_R = 1.0 / self.R  # kernels multiply (a division per point costs more)
            self.w = np.ascontiguousarray(GAUSS_WEIGHT * np.abs(det) * 2.0 * math.pi * self.R)
        self.volume = self.w.sum(axis=1)

    def node_masses(self, density: float) -> np.ndarray:
        """(n, 4) the cells' lumped masses rho sum_q w_q N_a(x_q) (kg) per node."""
        return density * self.w @ self.N

    def lumped_mass(self, density: float, n_local_nodes: int) -> np.ndarray:
        """Row sums of the consistent mass, rho int N_a 2 pi R dX (kg), per local node
        (these cells only: sum ghosts with a reverse scatter)."""
        m = np.zeros(n_local_nodes)
        np.add.at(m, self.dofs.ravel(), self.node_masses(density).ravel())
        return m


# ---------------------------------------------------------------- small strain, B-bar
@njit(cache=True)
def strain_rows(c, q, dNdR, dNdZ, N, inv_R, B) -> None:
    """B_q (4 x 8, (rr, tt, zz, rz) x (u_r, u_z) of the four nodes) at point q of cell c."""
    for a in range(4):
        gr, gz = dNdR[c, q, a], dNdZ[c, q, a]
        B[0, 2 * a], B[0, 2 * a + 1] = gr, 0.0
        B[1, 2 * a], B[1, 2 * a + 1] = N[q, a] * inv_R[c, q], 0.0
        B[2, 2 * a], B[2, 2 * a + 1] = 0.0, gz
        B[3, 2 * a], B[3, 2 * a + 1] = 0.5 * gz, 0.5 * gr


@njit(cache=True)
def bbar_element_matrices(dNdR, dNdZ, N, inv_R, w, D, Ke) -> None:
    """K_e = sum_q w_q B_bar_q' G D B_bar_q (N/m) of every cell into ``Ke`` (n, 8, 8), in
    the cell's dof order 2 a + component; D (4 x 4, Pa) the elastic stiffness in the
    notation (rr, tt, zz, rz) with tensor shear, G = diag(1, 1, 1, 2)."""
    B = np.empty((N_POINTS, 4, 8))
    bbar = np.empty(8)
    S = np.empty((4, 8))
    for c in range(Ke.shape[0]):
        vol = 0.0
        for j in range(8):
            bbar[j] = 0.0
        for q in range(N_POINTS):
            strain_rows(c, q, dNdR, dNdZ, N, inv_R, B[q])
            vol += w[c, q]
            for j in range(8):
                bbar[j] += w[c, q] * (B[q, 0, j] + B[q, 1, j] + B[q, 2, j])
        for j in range(8):
            bbar[j] /= vol
        for i in range(8):
            for j in range(8):
                Ke[c, i, j] = 0.0
        for q in range(N_POINTS):
            Bq = B[q]
            for j in range(8):  # B_bar_q = B_q + (b_bar - b_q) / 3 on the normal rows
                d = (bbar[j] - (Bq[0, j] + Bq[1, j] + Bq[2, j])) / 3.0
                Bq[0, j] += d
                Bq[1, j] += d
                Bq[2, j] += d
            for k in range(4):  # S = G D B_bar_q
                g = 2.0 if k == 3 else 1.0
                for j in range(8):
                    S[k, j] = g * (D[k, 0] * Bq[0, j] + D[k, 1] * Bq[1, j] + D[k, 2] * Bq[2, j]
                                   + D[k, 3] * Bq[3, j])
            wq = w[c, q]
            for i in range(8):
                for j in range(8):
                    Ke[c, i, j] += wq * (Bq[0, i] * S[0, j] + Bq[1, i] * S[1, j]
                                         + Bq[2, i] * S[2, j] + Bq[3, i] * S[3, j])


@njit(cache=True)
def mean_strain(dofs, dNdR, dNdZ, N, inv_R, w, u, out) -> None:
    """Per cell the ring-weighted mean strain sum_q w_q eps_bar_q / V = sum_q w_q eps_q / V
    (rr, tt, zz, rz; -) of the local displacement ``u`` (m, unrolled): B-bar keeps the
    mean. A linear body's cell stress is D times it (Pa), the weighted mean of its point
    stresses."""
    for c in range(dofs.shape[0]):
        e0 = e1 = e2 = e3 = vol = 0.0
        for q in range(N_POINTS):
            rr = tt = zz = rz = 0.0
            for a in range(4):
                k = 2 * dofs[c, a]
                gr, gz = dNdR[c, q, a], dNdZ[c, q, a]
                rr += gr * u[k]
                tt += N[q, a] * u[k]
                zz += gz * u[k + 1]
                rz += 0.5 * (gz * u[k] + gr * u[k + 1])
            wq = w[c, q]
            e0 += wq * rr
            e1 += wq * tt * inv_R[c, q]
            e2 += wq * zz
            e3 += wq * rz
            vol += wq
        out[c, 0], out[c, 1], out[c, 2], out[c, 3] = e0 / vol, e1 / vol, e2 / vol, e3 / vol
