"""Cell fields of the path-dependent bodies, from the state at their three points.

Per cell: the plastic strain and the equivalent plastic strain ``eps_p_eq``
averaged over the cell's points, and ``yielded`` = 1 if any of its points has
yielded (eps_bar_p > 0), else 0. Cells of linear bodies hold 0. The mean
plastic strain gives the cell's stress for output, C : (eps(u) - eps_p) at the
cell midpoint: in the elastic range exactly the linear material's value.
"""
from __future__ import annotations

import numpy as np
from dolfinx import fem

from .. import compat
from ..bodies import DeformableModel
from .quadrature import N_COMP, QuadratureForce


class PlasticCellFields:
    """DG0 Functions ``eps_p`` (4 components), ``eps_p_eq`` (-) and ``yielded`` (0/1)."""

    def __init__(self, model: DeformableModel, forces: list[QuadratureForce]):
        mesh = model.mesh
        self.forces = forces
        self.n_cells = mesh.topology.index_map(2).size_local
        V4 = compat.vector_space(mesh, "DG", 0, dim=N_COMP)
        self.eps_p = fem.Function(V4, name="eps_p")
        Q0 = compat.scalar_space(mesh, "DG", 0)
        self.eps_p_eq = fem.Function(Q0, name="eps_p_eq")
        self.yielded = fem.Function(Q0, name="yielded")
        dof = compat.cell_dofs(Q0).ravel()  # one dof per cell
        self._dofs = [dof[f.cells].astype(np.intp) for f in forces]
        self._dof_vec = [compat.cell_dofs(self.eps_p.function_space).ravel()[f.cells].astype(np.intp)
                         for f in forces]
        self._owned_dofs = dof[: self.n_cells].astype(np.intp)

    def refresh(self) -> None:
        """Copy the current cell means into the Functions (owned cells)."""
        eps_p = self.eps_p.x.array.reshape(-1, N_COMP)
        for force, dofs, dofs_vec in zip(self.forces, self._dofs, self._dof_vec):
            mean_eps_p, eps_bar, yielded = force.cell_values()
            eps_p[dofs_vec] = mean_eps_p
            self.eps_p_eq.x.array[dofs] = eps_bar
            self.yielded.x.array[dofs] = yielded

    def arrays(self) -> dict[str, np.ndarray]:
        """{name: values over this rank's owned cells} of eps_p_eq and yielded, current."""
        self.refresh()
        return {"eps_p_eq": self.eps_p_eq.x.array[self._owned_dofs],
                "yielded": self.yielded.x.array[self._owned_dofs]}
