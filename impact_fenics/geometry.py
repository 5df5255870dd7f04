"""The geometry of a scene's section: axisymmetric (a body of revolution) or plane strain
(a long body of thickness t, nothing moving out of the plane).

Both write a point's tensors in the order (first, out-of-plane, second, shear) and
differ in two numbers per point (docs/plane_strain.md):

    axisymmetric  (r, z):  w_q = 2 pi r_q |J_q| W_q  (m^3),  eps_tt = u_r / r
    plane strain  (x, y):  w_q = t |J_q| W_q         (m^3),  eps_out = 0

so every mass (kg), force (N) and energy (J) of a plane-strain scene is that of a slab of
thickness t (m). The internal names of the stress slots stay the axisymmetric ones
(sigma_rr, sigma_tt, sigma_zz, sigma_rz); what a user reads and writes (fields, probe
quantities, plot labels) is named by :meth:`Geometry.public`, one name per slot.
Pure data: no dolfinx.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from .errors import InputError

AXISYMMETRIC = "axisymmetric"
PLANE_STRAIN = "plane_strain"
KINDS = (AXISYMMETRIC, PLANE_STRAIN)
SYMMETRY_PLANES = ("x=0",)

# the user's name of each internal slot and coordinate in plane strain
_PLANE_NAMES = {"sigma_rr": "sigma_xx", "sigma_tt": "sigma_out", "sigma_zz": "sigma_yy",
                "sigma_rz": "sigma_xy", "u_r": "u_x", "u_z": "u_y", "r": "x", "z": "y"}


@dataclass(frozen=True)
class Geometry:
    """``kind``: AXISYMMETRIC or PLANE_STRAIN; ``thickness`` t (m) of a plane-strain slab
    (1: per metre); ``symmetry``: a plane-strain half model's symmetry plane ("x=0": u_x = 0
    on the nodes of x = 0) or None. Axisymmetry has its axis r = 0 and no thickness."""

    kind: str = AXISYMMETRIC
    thickness: float = 1.0
    symmetry: str | None = None

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise InputError(f"geometry = {self.kind!r}: use one of {', '.join(KINDS)}")
        if not (self.thickness > 0.0 and math.isfinite(self.thickness)):
            raise InputError(f"thickness = {self.thickness!r}: must be finite and > 0 (m)")
        if self.kind == AXISYMMETRIC and (self.thickness != 1.0 or self.symmetry is not None):
            raise InputError("an axisymmetric geometry has no thickness and no symmetry "
                             "plane (its axis r = 0 is one)")
        if self.symmetry is not None and self.symmetry not in SYMMETRY_PLANES:
            raise InputError(f"symmetry = {self.symmetry!r}: use one of "
                             f"{', '.join(SYMMETRY_PLANES)}")

    @property
    def plane(self) -> bool:
        """True in plane strain."""
        return self.kind == PLANE_STRAIN

    @property
    def held_first(self) -> bool:
        """Whether the nodes on the first coordinate's zero (r = 0, or x = 0 in a half
        model) have u_1 = 0: the axis of axisymmetry, a declared symmetry plane."""
        return not self.plane or self.symmetry == "x=0"

    def public(self, name: str) -> str:
        """The user's name of an internal slot, displacement or coordinate name."""
        return _PLANE_NAMES.get(name, name) if self.plane else name

    def internal(self, name: str) -> str:
        """The internal name of a user's name (:meth:`public`'s inverse; others unchanged)."""
        if self.plane:
            for k, v in _PLANE_NAMES.items():
                if v == name:
                    return k
        return name

    @property
    def axes(self) -> tuple[str, str]:
        """The coordinates' names: (r, z) or (x, y)."""
        return ("x", "y") if self.plane else ("r", "z")


AXISYMMETRIC_GEOMETRY = Geometry()
