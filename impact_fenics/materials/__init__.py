"""Materials: one module each, holding its parameters and its stress update and nothing else.

A linear material (``linear = True``, :mod:`.elastic`) gives the stress as a UFL
function of the strain, and the stiffness is assembled once. A path-dependent
material (``linear = False``) gives a compiled point update in the
four-component notation of :mod:`.axisym`; the internal force evaluates it at
the quadrature points of the stiffness rule every step.
"""
from .elastic import STEEL, IsotropicConstants, LinearElastic
from .drucker_prager import DruckerPrager
from .j2 import J2

__all__ = ["DruckerPrager", "IsotropicConstants", "J2", "LinearElastic", "STEEL"]
