"""The internal force f_int(u) of the deformable bodies, behind one protocol.

Every force follows :class:`.base.Force` (``set_step``, ``velocity_increment``,
``stable_dt``, ``book``): "add -h_n M^-1 f_int(u^n) into v" on its own cells.

* :class:`.linear.LinearForce` for the linear bodies: K assembled once, one
  MatMultAdd per step;
* :class:`.quadrature.QuadratureForce` for each small-strain path-dependent body: the
  state at the stiffness rule's points, f_int(u, state) assembled every step by a
  fused compiled cell kernel (``"fast"``; triangles, or B-bar Q1 from :mod:`.bbar`)
  or by dolfinx (``"generic"``);
* :class:`.finite.FiniteStrainForce` for a finite-strain body: F-bar Q1, total
  Lagrangian, its stable step from the current cells.

Bodies of several kinds share one run: the forces act on disjoint cells and add
into the same velocity.
"""
from .base import Booking, Force
from .finite import FiniteStrainForce
from .linear import LinearForce
from .quadrature import QuadratureForce

__all__ = ["Booking", "FiniteStrainForce", "Force", "LinearForce", "QuadratureForce"]
