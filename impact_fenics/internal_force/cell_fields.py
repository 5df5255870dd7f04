"""Cell fields of the path-dependent bodies, from the state at their three points.

Per cell: ``eps_p_eq``, the equivalent plastic strain averaged over the cell's
points, and ``yielded`` = 1 if any of its points has yielded (eps_bar_p > 0),
else 0. Cells of linear bodies hold 0. A frame's values come from the state its
stresses came from (:meth:`.quadrature.QuadratureForce.point_stresses`, the
points' update at the displacement written); the cell stress itself is the
weighted mean of the point stresses (:mod:`...cell_fields`).
"""
from __future__ import annotations

import numpy as np

from ..bodies import DeformableModel
from .quadrature import QuadratureForce

NAMES = ("eps_p_eq", "yielded")


class PlasticCellFields:
    """``eps_p_eq`` (-) and ``yielded`` (0/1) over this rank's owned cells."""

    def __init__(self, model: DeformableModel, forces: list[QuadratureForce]):
        self.forces = forces
        self.n_cells = model.mesh.topology.index_map(2).size_local
        self._values = {name: np.zeros(self.n_cells) for name in NAMES}

    def arrays(self, frame: bool = False) -> dict[str, np.ndarray]:
        """{name: values over this rank's owned cells} of eps_p_eq and yielded: of the
        committed state (the points' last update), or with ``frame`` of the state of the
        frame's stresses (the forces' :attr:`~.quadrature.QuadratureForce.frame`, which
        the frame's stress evaluation has just filled). The arrays are reused by the next
        call."""
        eps_p_eq, yielded = self._values["eps_p_eq"], self._values["yielded"]
        for force in self.forces:
            _, eps_bar, flag = force.cell_values(qs=force.frame if frame else None)
            eps_p_eq[force.cells] = eps_bar
            yielded[force.cells] = flag
        return self._values

    def frame_arrays(self) -> dict[str, np.ndarray]:
        """:meth:`arrays` of a frame (a field writer's cell-field provider)."""
        return self.arrays(frame=True)
