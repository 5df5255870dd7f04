"""A matrix-free internal force for axisymmetric P1 triangles (CST), compiled with cffi.

It computes f = K u element by element from the node coordinates, the cell
connectivity and u, with the same 3-point quadrature (degree 2) as the
assembled stiffness of impact_fenics.forms, so that it matches K u to round-off:

    f_i = sum_cells sum_q w_q |det J| 2 pi r_q  B_i(r_q)' D B(r_q) u

The in-plane gradients of a linear triangle are constant; only the hoop strain
u_r / r and the ring weight 2 pi r vary between the quadrature points. Reads per
cell: 3 block indices (12 B), and through them 3 coordinates and 3 displacements
(gathered, cache friendly in dolfinx's cell order), against ~12 nnz/row * 12 B
of the AIJ matrix: ~5x less memory traffic for ~200 flops per cell.

Serial only (the scatter of f has no owner/ghost logic); a prototype that the
benchmark harness compares with MatMult (impact_fenics.bench, part "matfree").
"""
from __future__ import annotations

import tempfile

import numpy as np

CDEF = """
void cst_axi_force(int n_cells, const int32_t *cells, const double *xy, const double *u,
                   double *f, double lam, double mu, const double *qN, const double *qw);
void cst_axi_force_batched(int n_cells, const int32_t *cells, const double *xy, const double *u,
                           double *f, double lam, double mu, const double *qN, const double *qw);
"""

SOURCE = r"""
#include <stdint.h>
#include <math.h>

/* f += K u over the cells; cells: 3 node (block) indices per cell; xy: (r, z) per node;
   u, f: (u_r, u_z) per node; qN: 3 quadrature points x 3 shape values; qw: 3 weights
   on the reference triangle (area 1/2). */
void cst_axi_force(int n_cells, const int32_t *cells, const double *xy, const double *u,
                   double *f, double lam, double mu, const double *qN, const double *qw)
{
    const double two_pi = 6.283185307179586;
    for (int c = 0; c < n_cells; ++c) {
        const int32_t i0 = cells[3 * c], i1 = cells[3 * c + 1], i2 = cells[3 * c + 2];
        const double r0 = xy[2 * i0], z0 = xy[2 * i0 + 1];
        const double r1 = xy[2 * i1], z1 = xy[2 * i1 + 1];
        const double r2 = xy[2 * i2], z2 = xy[2 * i2 + 1];
        const double det = (r1 - r0) * (z2 - z0) - (r2 - r0) * (z1 - z0);
        const double inv = 1.0 / det;
        const double br[3] = {(z1 - z2) * inv, (z2 - z0) * inv, (z0 - z1) * inv};
        const double bz[3] = {(r2 - r1) * inv, (r0 - r2) * inv, (r1 - r0) * inv};
        const double ur[3] = {u[2 * i0], u[2 * i1], u[2 * i2]};
        const double uz[3] = {u[2 * i0 + 1], u[2 * i1 + 1], u[2 * i2 + 1]};
        const double err = br[0] * ur[0] + br[1] * ur[1] + br[2] * ur[2];
        const double ezz = bz[0] * uz[0] + bz[1] * uz[1] + bz[2] * uz[2];
        const double grz = bz[0] * ur[0] + bz[1] * ur[1] + bz[2] * ur[2]
                         + br[0] * uz[0] + br[1] * uz[1] + br[2] * uz[2];
        const double scale = two_pi * fabs(det);
        double a_rr = 0.0, a_zz = 0.0, a_w = 0.0, h[3] = {0.0, 0.0, 0.0};
        for (int q = 0; q < 3; ++q) {
            const double *N = qN + 3 * q;
            const double rq = N[0] * r0 + N[1] * r1 + N[2] * r2;
            const double irq = 1.0 / rq;
            const double ett = (N[0] * ur[0] + N[1] * ur[1] + N[2] * ur[2]) * irq;
            const double W = qw[q] * scale * rq;
            const double ltr = lam * (err + ett + ezz);
            a_rr += W * (ltr + 2.0 * mu * err);
            a_zz += W * (ltr + 2.0 * mu * ezz);
            a_w += W;
            const double st = W * (ltr + 2.0 * mu * ett) * irq;
            h[0] += st * N[0]; h[1] += st * N[1]; h[2] += st * N[2];
        }
        const double a_rz = a_w * mu * grz;
        f[2 * i0]     += br[0] * a_rr + bz[0] * a_rz + h[0];
        f[2 * i0 + 1] += bz[0] * a_zz + br[0] * a_rz;
        f[2 * i1]     += br[1] * a_rr + bz[1] * a_rz + h[1];
        f[2 * i1 + 1] += bz[1] * a_zz + br[1] * a_rz;
        f[2 * i2]     += br[2] * a_rr + bz[2] * a_rz + h[2];
        f[2 * i2 + 1] += bz[2] * a_zz + br[2] * a_rz;
    }
}

/* The same in blocks of BLK cells: the element forces of a block first, in a loop with
   no scatter that gcc vectorizes (gathers of xy and u), then the scatter, scalar. */
#define BLK 256
void cst_axi_force_batched(int n_cells, const int32_t *restrict cells, const double *restrict xy,
                           const double *restrict u, double *restrict f, double lam, double mu,
                           const double *restrict qN, const double *restrict qw)
{
    const double two_pi = 6.283185307179586;
    double fe[6][BLK];
    const double N00 = qN[0], N01 = qN[1], N02 = qN[2], N10 = qN[3], N11 = qN[4], N12 = qN[5],
                 N20 = qN[6], N21 = qN[7], N22 = qN[8], w0 = qw[0], w1 = qw[1], w2 = qw[2];
    for (int c0 = 0; c0 < n_cells; c0 += BLK) {
        const int nb = (n_cells - c0 < BLK) ? n_cells - c0 : BLK;
        const int32_t *cc = cells + 3 * c0;
#pragma GCC ivdep
        for (int k = 0; k < nb; ++k) {
            const int32_t i0 = cc[3 * k], i1 = cc[3 * k + 1], i2 = cc[3 * k + 2];
            const double r0 = xy[2 * i0], z0 = xy[2 * i0 + 1];
            const double r1 = xy[2 * i1], z1 = xy[2 * i1 + 1];
            const double r2 = xy[2 * i2], z2 = xy[2 * i2 + 1];
            const double det = (r1 - r0) * (z2 - z0) - (r2 - r0) * (z1 - z0);
            const double inv = 1.0 / det;
            const double br0 = (z1 - z2) * inv, br1 = (z2 - z0) * inv, br2 = (z0 - z1) * inv;
            const double bz0 = (r2 - r1) * inv, bz1 = (r0 - r2) * inv, bz2 = (r1 - r0) * inv;
            const double ur0 = u[2 * i0], ur1 = u[2 * i1], ur2 = u[2 * i2];
            const double uz0 = u[2 * i0 + 1], uz1 = u[2 * i1 + 1], uz2 = u[2 * i2 + 1];
            const double err = br0 * ur0 + br1 * ur1 + br2 * ur2;
            const double ezz = bz0 * uz0 + bz1 * uz1 + bz2 * uz2;
            const double grz = bz0 * ur0 + bz1 * ur1 + bz2 * ur2 + br0 * uz0 + br1 * uz1 + br2 * uz2;
            const double scale = two_pi * fabs(det);
            const double rq0 = N00 * r0 + N01 * r1 + N02 * r2;
            const double rq1 = N10 * r0 + N11 * r1 + N12 * r2;
            const double rq2 = N20 * r0 + N21 * r1 + N22 * r2;
            const double i0q = 1.0 / rq0, i1q = 1.0 / rq1, i2q = 1.0 / rq2;
            const double e0 = (N00 * ur0 + N01 * ur1 + N02 * ur2) * i0q;
            const double e1 = (N10 * ur0 + N11 * ur1 + N12 * ur2) * i1q;
            const double e2 = (N20 * ur0 + N21 * ur1 + N22 * ur2) * i2q;
            const double W0 = w0 * scale * rq0, W1 = w1 * scale * rq1, W2 = w2 * scale * rq2;
            const double l0 = lam * (err + e0 + ezz), l1 = lam * (err + e1 + ezz), l2 = lam * (err + e2 + ezz);
            const double a_rr = W0 * (l0 + 2.0 * mu * err) + W1 * (l1 + 2.0 * mu * err) + W2 * (l2 + 2.0 * mu * err);
            const double a_zz = W0 * (l0 + 2.0 * mu * ezz) + W1 * (l1 + 2.0 * mu * ezz) + W2 * (l2 + 2.0 * mu * ezz);
            const double a_rz = (W0 + W1 + W2) * mu * grz;
            const double s0 = W0 * (l0 + 2.0 * mu * e0) * i0q, s1 = W1 * (l1 + 2.0 * mu * e1) * i1q,
                         s2 = W2 * (l2 + 2.0 * mu * e2) * i2q;
            const double h0 = s0 * N00 + s1 * N10 + s2 * N20;
            const double h1 = s0 * N01 + s1 * N11 + s2 * N21;
            const double h2 = s0 * N02 + s1 * N12 + s2 * N22;
            fe[0][k] = br0 * a_rr + bz0 * a_rz + h0;
            fe[1][k] = bz0 * a_zz + br0 * a_rz;
            fe[2][k] = br1 * a_rr + bz1 * a_rz + h1;
            fe[3][k] = bz1 * a_zz + br1 * a_rz;
            fe[4][k] = br2 * a_rr + bz2 * a_rz + h2;
            fe[5][k] = bz2 * a_zz + br2 * a_rz;
        }
        for (int k = 0; k < nb; ++k) {
            const int32_t i0 = cc[3 * k], i1 = cc[3 * k + 1], i2 = cc[3 * k + 2];
            f[2 * i0] += fe[0][k]; f[2 * i0 + 1] += fe[1][k];
            f[2 * i1] += fe[2][k]; f[2 * i1 + 1] += fe[3][k];
            f[2 * i2] += fe[4][k]; f[2 * i2 + 1] += fe[5][k];
        }
    }
}
"""

_LIB = None


def build(tmpdir: str | None = None, flags: tuple[str, ...] = ("-O3", "-march=native")):
    """Compile the kernel (gcc -O3 -march=native) once per process; returns (ffi, lib)."""
    global _LIB
    if _LIB is not None:
        return _LIB
    import cffi

    ffi = cffi.FFI()
    ffi.cdef(CDEF)
    name = "_impact_matfree_cst"
    ffi.set_source(name, SOURCE, extra_compile_args=list(flags))
    tmpdir = tmpdir or tempfile.mkdtemp(prefix="impact_matfree_")
    path = ffi.compile(tmpdir=tmpdir, verbose=False)
    import importlib.util

    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    _LIB = (module.ffi, module.lib)
    return _LIB


class MatrixFreeCST:
    """f = K u for one body of a serial :class:`impact_fenics.bodies.DeformableModel`."""

    def __init__(self, model):
        import basix

        from impact_fenics.compat import cell_dofs

        if model.comm.size != 1:
            raise RuntimeError("the matrix-free prototype is serial")
        if len(model.parts) != 1:
            raise RuntimeError("the matrix-free prototype takes one material")
        material = model.parts[0][0]
        self.lam, self.mu = float(material.lmbda), float(material.mu)
        self.ffi, self.lib = build()
        n_cells = model.mesh.topology.index_map(2).size_local
        self.cells = np.ascontiguousarray(
            cell_dofs(model.V)[:n_cells], dtype=np.int32)
        self.xy = np.ascontiguousarray(model.node_xy, dtype=np.float64)
        pts, wts = basix.make_quadrature(basix.CellType.triangle, 2)
        self.qN = np.ascontiguousarray(
            np.column_stack([1.0 - pts[:, 0] - pts[:, 1], pts[:, 0], pts[:, 1]]))
        self.qw = np.ascontiguousarray(wts, dtype=np.float64)
        if self.qw.size != 3:
            raise RuntimeError("the kernel is written for the 3-point rule")
        self.n_cells = n_cells
        p = self.ffi.cast
        self._cells_p = p("int32_t *", self.cells.ctypes.data)
        self._xy_p = p("double *", self.xy.ctypes.data)
        self._qN_p = p("double *", self.qN.ctypes.data)
        self._qw_p = p("double *", self.qw.ctypes.data)

    def force(self, u: np.ndarray, f: np.ndarray, batched: bool = True) -> np.ndarray:
        """f = K u (N) for the local unrolled arrays u (m) and f (contiguous float64);
        ``batched`` picks the vectorized kernel, else the plain cell loop."""
        f.fill(0.0)
        p = self.ffi.cast
        kernel = self.lib.cst_axi_force_batched if batched else self.lib.cst_axi_force
        kernel(self.n_cells, self._cells_p, self._xy_p,
                               p("double *", u.ctypes.data), p("double *", f.ctypes.data),
                               self.lam, self.mu, self._qN_p, self._qw_p)
        return f


def matfree_bytes_per_dof(n_cells: int, n_dofs: int) -> float:
    """Bytes per dof the kernel moves at least: 12 B of connectivity per cell, u and the
    coordinates (8 B per dof each), f zeroed, read and written (24 B per dof)."""
    return 12.0 * n_cells / n_dofs + 8.0 + 8.0 + 24.0


if __name__ == "__main__":  # a check by hand: python benchmarks/matfree_cst.py
    from impact_fenics import meshing
    from impact_fenics.bodies import Body, DeformableModel
    from impact_fenics.materials import LinearElastic
    from impact_fenics.operators import assemble_stiffness

    tm = meshing.bar(radius=0.5, length=1.0, h=0.01)
    model = DeformableModel(tm, [Body("bar", LinearElastic())])
    K = assemble_stiffness(model)
    x, y = K.createVecRight(), K.createVecLeft()
    x.array[:] = np.random.default_rng(1).standard_normal(x.array.size)
    K.mult(x, y)
    mf = MatrixFreeCST(model)
    for batched in (False, True):
        f = mf.force(x.array.copy(), np.empty_like(x.array), batched)
        print("batched" if batched else "plain", "relative difference",
              np.abs(f - y.array).max() / np.abs(y.array).max())
