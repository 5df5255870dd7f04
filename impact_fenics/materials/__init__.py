"""Materials: one module each, holding its parameters and its stress update and nothing else.

A linear material (``linear = True``, :mod:`.elastic`) gives the stress as a UFL
function of the strain, and the stiffness is assembled once. A path-dependent
material (``linear = False``) gives a compiled point update in the
four-component notation of :mod:`.axisym`; the internal force evaluates it at
the quadrature points of the stiffness rule every step. A finite-strain material
gives the Kirchhoff stress of the deformation gradient at a point (:mod:`.hencky`
states the signature).

:data:`MODELS` names every material a scene file may use, with its class for
each kinematics it has (``"small"``, ``"finite"``, the ``strain`` of a body);
each class states its kinematics (``strain``) and its parameters
(``parameters``, :mod:`.parameters`). :data:`INTERFACE` lists what the drivers
read of a material of each kinematics: a class of one's own provides that.
"""
from .elastic import STEEL, IsotropicConstants, LinearElastic
from .drucker_prager import DruckerPrager
from .finite_j2 import FiniteJ2
from .j2 import J2
from .johnson_cook import JohnsonCook
from .neo_hookean import NeoHookean
from .parameters import Parameter

KINEMATICS = ("small", "finite")

# name -> {kinematics: class}
MODELS: dict[str, dict[str, type]] = {
    "elastic": {"small": LinearElastic},
    "j2": {"small": J2, "finite": FiniteJ2},
    "johnson_cook": {"finite": JohnsonCook},
    "drucker_prager": {"small": DruckerPrager},
    "neo_hookean": {"finite": NeoHookean},
}

# What the drivers read of a material, per kinematics (attributes and methods). Small
# strain, linear: the stress as a UFL expression, K assembled once; small strain,
# path-dependent: the compiled point update of .axisym at the quadrature points
# (internal_force/quadrature.py); finite strain: the compiled point update of .hencky
# (internal_force/finite.py), ``temperature_index`` optional.
INTERFACE: dict[str, tuple[str, ...]] = {
    "small linear": ("density", "wave_speed", "linear", "stress"),
    "small": ("density", "wave_speed", "linear", "lmbda", "mu", "n_state", "params", "update"),
    "finite": ("density", "wave_speed", "n_state", "params", "initial_state", "update",
               "energy"),
}


def is_finite(material) -> bool:
    """Whether ``material`` (an instance) is a finite-strain one (its ``strain``)."""
    return getattr(material, "strain", "small") == "finite"


def interface_of(material) -> str:
    """The key of :data:`INTERFACE` a material (an instance) must satisfy."""
    if is_finite(material):
        return "finite"
    return "small linear" if getattr(material, "linear", False) else "small"


def missing_attributes(material) -> list[str]:
    """What a material lacks of the interface of its kinematics (empty if nothing)."""
    return [a for a in INTERFACE[interface_of(material)] if not hasattr(material, a)]


__all__ = ["DruckerPrager", "FiniteJ2", "INTERFACE", "IsotropicConstants", "J2", "JohnsonCook",
           "KINEMATICS", "LinearElastic", "MODELS", "NeoHookean", "Parameter", "STEEL",
           "interface_of", "is_finite", "missing_attributes"]
