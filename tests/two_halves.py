"""A rectangle of triangles or quadrilaterals in two cell groups, and the round-off of an
element eigenvalue: what the tests of the stable steps share."""
from __future__ import annotations

import numpy as np
from dolfinx import mesh as dmesh

from impact_fenics import compat
from impact_fenics.meshing import TaggedMesh

# A largest element eigenvalue w^2 of S = M^-1/2 K M^-1/2 (6 x 6 or 8 x 8). LAPACK's
# symmetric eigensolver is backward stable: |dw^2| <= c n EPS ||S||, and ||S|| = w^2 for
# a positive semi-definite S. Take c n = 8 x 8. The element matrices' entries are
# quadrature sums of products, each within 32 roundings. They enter w^2 by at most
# sqrt(8) x their relative error (|dS| <= d |S| entrywise, so ||dS|| <= d sqrt(n) ||S||).
# On quadrilaterals, a Jacobian entry sums 4 products of a coordinate with a weight.
# Each product rounds on |x| <= x_max, and the sum is about h / 2: a relative error of
# 8 EPS x_max / h, which enters K_e (1/J^2) and M_e (J) about 3 times.
EIG = 64 + 3 * 32


def two_halves(comm, lo: tuple[float, float], hi: tuple[float, float], n_r: int, n_z: int,
               quadrilateral: bool, names: tuple[str, str], split: int = 1) -> TaggedMesh:
    """The rectangle lo..hi (m, (r, z)) of n_r x n_z cells (triangles or quadrilaterals):
    the cell group names[0] below the middle of coordinate ``split`` (1: the height; 0:
    the radius, an inner core and an outer ring), names[1] beyond; no facet groups."""
    cell = dmesh.CellType.quadrilateral if quadrilateral else dmesh.CellType.triangle
    mesh = dmesh.create_rectangle(comm, [np.array(lo, dtype=float), np.array(hi, dtype=float)],
                                  [n_r, n_z], cell_type=cell)
    cmap = mesh.topology.index_map(2)
    cells = np.arange(cmap.size_local + cmap.num_ghosts, dtype=np.int32)
    centre = mesh.geometry.x[compat.geometry_dofs(mesh)[cells], split].mean(axis=1)
    middle = 0.5 * (lo[split] + hi[split])
    cell_tags = dmesh.meshtags(mesh, 2, cells, np.where(centre < middle, 1, 2).astype(np.int32))
    facet_tags = dmesh.meshtags(mesh, 1, np.zeros(0, dtype=np.int32), np.zeros(0, dtype=np.int32))
    return TaggedMesh(mesh, cell_tags, facet_tags, {names[0]: 1, names[1]: 2}, {})
