"""The internal force f_int(u) of the deformable bodies, behind one seam.

The integrator asks each force for one thing, "add -dt M^-1 f_int(u^n) into v":

* :class:`.linear.LinearForce` for the linear bodies: K assembled once, one
  MatMultAdd per step;
* :class:`.quadrature.QuadratureForce` for each path-dependent body: the state
  at the stiffness rule's points, f_int(u, state) assembled every step by a
  fused compiled cell kernel (``"fast"``) or by dolfinx (``"generic"``).

Bodies of both kinds share one run: the forces act on disjoint cells and add
into the same velocity.
"""
from .linear import LinearForce
from .quadrature import QuadratureForce

__all__ = ["LinearForce", "QuadratureForce"]
