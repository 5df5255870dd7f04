"""Contact: pairing (node pairs, rigid faces, node to segment), the one front-end
(ContactSet) and one family of three methods side by side."""
from .dme import DME
from .film import FILM
from .interface import ContactSet, RigidBody
from .pairing import Constraints, pair_surfaces, rigid_face, spherical_button
from .penalty import Penalty

METHODS = {"penalty": Penalty, "film": FILM, "dme": DME}

__all__ = ["DME", "FILM", "Penalty", "ContactSet", "RigidBody", "Constraints",
           "pair_surfaces", "rigid_face", "spherical_button", "METHODS"]
