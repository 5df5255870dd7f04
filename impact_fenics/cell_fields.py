"""Cell values of the P1 displacement: strain and stress at the DG0 point (the centroid).

On a linear (P1) triangle the gradient of u is constant, and at the centroid
u_r = (u_r1 + u_r2 + u_r3) / 3 and r = (r1 + r2 + r3) / 3, so the axisymmetric
strain of a cell in the point notation of :mod:`.materials.axisym`,

    eps = (du_r/dr, u_r/r, du_z/dz, (du_r/dz + du_z/dr) / 2)    (rr, tt, zz, rz),

is a few flops from the cell's three nodes: the value a UFL Expression of
``forms.strain`` gives at the DG0 interpolation point, to round-off. A linear
material maps it to the stress by a constant 4x4 matrix D (Pa), read once
from the material's UFL ``stress`` applied to the four unit strains; a material
whose stress cannot be read that way (one that depends on position, say) is
evaluated with a compiled UFL Expression per body instead (slower, the same values).

Output components (Pa): sigma_rr, sigma_zz, sigma_tt, sigma_rz and von Mises,
sqrt(3/2 dev(sigma) : dev(sigma)).
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from .compat import cell_dofs, eval_expression

STRESS_NAMES = ("sigma_rr", "sigma_zz", "sigma_tt", "sigma_rz", "von_mises")
# the output components in the point notation (rr, tt, zz, rz)
_COMPONENT = {"sigma_rr": 0, "sigma_tt": 1, "sigma_zz": 2, "sigma_rz": 3}
_TENSOR = ((0, 0), (1, 1), (2, 2), (0, 2))  # (r, theta, z) tensor entries of the notation


def stiffness_matrix(material) -> np.ndarray | None:
    """D (Pa, 4x4) with sigma = D eps in the notation (rr, tt, zz, rz), tensor shear; None
    if the material is not linear or its stress is not a constant map of the strain."""
    import ufl

    if not getattr(material, "linear", False):
        return None
    D = np.empty((4, 4))
    try:
        for j, (a, b) in enumerate(_TENSOR):
            unit = [[0.0] * 3 for _ in range(3)]
            unit[a][b] = unit[b][a] = 1.0
            s = material.stress(ufl.as_tensor(unit))
            for i, (p, q) in enumerate(_TENSOR):
                D[i, j] = float(s[p, q])
    except Exception:  # the stress needs a mesh (position, a Function): not a constant map
        return None
    return D


def isotropic_stiffness(lmbda: float, mu: float) -> np.ndarray:
    """D (Pa, 4x4) of isotropic elasticity in the notation (rr, tt, zz, rz), tensor shear:
    sigma = lambda tr(eps) I + 2 mu eps."""
    D = np.full((4, 4), 0.0)
    D[:3, :3] = lmbda
    D[[0, 1, 2], [0, 1, 2]] = lmbda + 2.0 * mu
    D[3, 3] = 2.0 * mu
    return D


@njit(cache=True)
def triangle_strain(r1, z1, r2, z2, r3, z3, ur1, uz1, ur2, uz2, ur3, uz3):
    """Strain (rr, tt, zz, rz; tensor shear) at the centroid of a P1 triangle with nodes
    (r_k, z_k) in m and displacements (ur_k, uz_k) in m."""
    r21, z21, r31, z31 = r2 - r1, z2 - z1, r3 - r1, z3 - z1
    det = r21 * z31 - r31 * z21
    dur2, duz2, dur3, duz3 = ur2 - ur1, uz2 - uz1, ur3 - ur1, uz3 - uz1
    # grad u = [du/dxi] J^-1 with J = [[r21, r31], [z21, z31]]
    dur_dr = (dur2 * z31 - dur3 * z21) / det
    dur_dz = (dur3 * r21 - dur2 * r31) / det
    duz_dr = (duz2 * z31 - duz3 * z21) / det
    duz_dz = (duz3 * r21 - duz2 * r31) / det
    hoop = ((ur1 + ur2 + ur3) / 3.0) / ((r1 + r2 + r3) / 3.0)
    return dur_dr, hoop, duz_dz, 0.5 * (dur_dz + duz_dr)


@njit(cache=True)
def cell_strain(cell_dofs, xy, u, cells, out) -> None:
    """Strain (rr, tt, zz, rz) at the centroid of each of ``cells`` into ``out`` (n, 4).

    ``cell_dofs`` (n_cells, 3) node (block) indices; ``xy`` (n_nodes, 2) their (r, z) in m;
    ``u`` the unrolled displacement (m) of the nodes (2 per node)."""
    for k in range(cells.size):
        c = cells[k]
        a, b, d = cell_dofs[c, 0], cell_dofs[c, 1], cell_dofs[c, 2]
        e = triangle_strain(xy[a, 0], xy[a, 1], xy[b, 0], xy[b, 1], xy[d, 0], xy[d, 1],
                            u[2 * a], u[2 * a + 1], u[2 * b], u[2 * b + 1], u[2 * d], u[2 * d + 1])
        out[k, 0], out[k, 1], out[k, 2], out[k, 3] = e[0], e[1], e[2], e[3]


@njit(cache=True)
def stress_outputs(D, e0, e1, e2, e3):
    """(sigma_rr, sigma_zz, sigma_tt, sigma_rz, von Mises) in Pa of sigma = D eps, for the
    strain (e0, e1, e2, e3) = (rr, tt, zz, rz) with tensor shear."""
    s0 = D[0, 0] * e0 + D[0, 1] * e1 + D[0, 2] * e2 + D[0, 3] * e3
    s1 = D[1, 0] * e0 + D[1, 1] * e1 + D[1, 2] * e2 + D[1, 3] * e3
    s2 = D[2, 0] * e0 + D[2, 1] * e1 + D[2, 2] * e2 + D[2, 3] * e3
    s3 = D[3, 0] * e0 + D[3, 1] * e1 + D[3, 2] * e2 + D[3, 3] * e3
    m = (s0 + s1 + s2) / 3.0
    d0, d1, d2 = s0 - m, s1 - m, s2 - m
    return s0, s2, s1, s3, math.sqrt(1.5 * (d0 * d0 + d1 * d1 + d2 * d2 + 2.0 * s3 * s3))


@njit(cache=True)
def linear_stress(D, eps, out, columns) -> None:
    """The five stress outputs of strains ``eps`` (n, 4) into out[:, columns[k]]."""
    for k in range(eps.shape[0]):
        s = stress_outputs(D, eps[k, 0], eps[k, 1], eps[k, 2], eps[k, 3])
        j = columns[k]
        for i in range(5):
            out[i, j] = s[i]


class CellStress:
    """The five stress outputs (Pa) of every owned cell, body by body.

    ``evaluate(u)`` takes the unrolled displacement of the local nodes (owned and
    ghosts, m) and returns a (5, n_owned_cells) array in STRESS_NAMES order."""

    def __init__(self, model, plastic_forces=()):
        V = model.V
        mesh = model.mesh
        self.model = model
        self.n_cells = mesh.topology.index_map(2).size_local
        self.cell_dofs = cell_dofs(V).astype(np.int64)
        self.xy = np.ascontiguousarray(model.node_xy)
        self.values = np.zeros((len(STRESS_NAMES), self.n_cells))
        self._linear = []  # (owned cells, D, strain buffer)
        self._ufl = []  # (owned cells, [compiled Expression per output])
        # path-dependent bodies: C : (eps - mean eps_p of the cell's points)
        self._plastic = [(f.cells.astype(np.int64), isotropic_stiffness(f.material.lmbda,
                                                                         f.material.mu),
                          np.empty((f.cells.size, 4)), f) for f in plastic_forces]
        plastic = {f.body for f in plastic_forces}
        for body in model.bodies.values():
            if body.name in plastic:
                continue
            cells = model.tmesh.cells(body.name)
            cells = np.sort(cells[cells < self.n_cells]).astype(np.int64)
            D = stiffness_matrix(body.material)
            if D is not None:
                self._linear.append((cells, D, np.empty((cells.size, 4))))
            else:
                self._ufl.append((cells.astype(np.int32), self._expressions(body.material)))
        self._u_fn = None

    def _expressions(self, material):
        from dolfinx import fem

        from .forms import stress_components

        if self._u_fn is None:
            self._u_fn = fem.Function(self.model.V)
        comps = stress_components(self._u_fn, material)
        points = np.array([[1.0 / 3.0, 1.0 / 3.0]])
        return [fem.Expression(comps[name], points) for name in STRESS_NAMES]

    def evaluate(self, u: np.ndarray) -> np.ndarray:
        """Stresses (Pa) of the owned cells for the local displacement ``u`` (ghosts current)."""
        for cells, D, eps in self._linear:
            cell_strain(self.cell_dofs, self.xy, u, cells, eps)
            linear_stress(D, eps, self.values, cells)
        for cells, D, eps, force in self._plastic:
            cell_strain(self.cell_dofs, self.xy, u, cells, eps)
            eps -= force.cell_values()[0]
            linear_stress(D, eps, self.values, cells)
        if self._ufl:
            self._u_fn.x.array[:] = u
            for cells, exprs in self._ufl:
                for k, expr in enumerate(exprs):
                    self.values[k, cells] = eval_expression(expr, self.model.mesh, cells)[:, 0]
        return self.values
