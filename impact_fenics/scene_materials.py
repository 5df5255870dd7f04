"""The [materials.NAME] tables of a scene file: a model by name, or a class of one's own.

A model by name (``impact_fenics.materials.MODELS``) takes ``E`` (Pa), ``nu`` and
``density`` (kg/m^3) and the parameters its class states (names, units, ranges:
:mod:`impact_fenics.materials.parameters`); a value out of range is refused in one
line naming the table and the key. A class of one's own, ``model =
"package.module:Class"``, is imported (from the installed packages, then from the
scene file's directory), and every key of its table but ``model`` goes to its
constructor as a keyword argument (``E``, ``nu``, ``density`` too: the scene's
plausibility checks and estimates read them), which checks them; its ``strain``
attribute ("small" or "finite") is its kinematics.

:func:`check_kinematics` builds each material at the kinematics of the bodies that
use it, once the bodies are read: a model without that kinematics, a key its form
at that kinematics does not take, and whatever the class refuses are one line
naming the table. Building a material is cheap (no mesh, no compilation).
"""
from __future__ import annotations

import importlib
import re
import sys
from dataclasses import dataclass, field
from typing import Any

from .errors import InputError
from .materials import KINEMATICS, MODELS, missing_attributes
from .materials.parameters import CLASS_DEFAULT, REQUIRED
from .scene_keys import STRAIN_WORDS
from .scene_table import Table, is_number, toml_text

COMMON = ("model", "E", "nu", "density")  # the keys every material table holds
_PATH = re.compile(r"^[A-Za-z_][\w]*(\.[A-Za-z_][\w]*)*:[A-Za-z_][\w]*$")


@dataclass
class MaterialSpec:
    """A [materials.NAME] table, read and checked; ``classes`` its class per kinematics,
    ``params`` the keys given beyond E, nu and density (as written)."""

    name: str
    E: float        # Pa
    nu: float
    density: float  # kg/m^3
    model: str = "elastic"  # a name of MODELS, or "package.module:Class"
    params: dict[str, Any] = field(default_factory=dict)
    classes: dict[str, Any] = field(default_factory=dict)
    built: dict[str, Any] = field(default_factory=dict)  # kinematics -> the material

    @property
    def where(self) -> str:
        return f"[materials.{self.name}]"

    @property
    def custom(self) -> bool:
        return self.model not in MODELS

    @property
    def plastic(self) -> bool:
        """A path-dependent material (quadrature-point state; eps_p_eq outputs)."""
        return any(not getattr(m, "linear", False) for m in self.built.values())

    # the parameters of J2 by name (scripts that read a j2 table)
    @property
    def yield_stress(self) -> float:
        return self.params.get("yield_stress", 0.0)

    @property
    def hardening(self) -> float:
        return self.params.get("hardening", 0.0)

    @property
    def viscosity(self) -> float:
        return self.params.get("viscosity", 0.0)

    def material(self, strain: str):
        """The material for a body of kinematics ``strain`` (built by check_kinematics)."""
        if strain not in self.built:
            self.built[strain] = _build(self, strain)
        return self.built[strain]


def read_material(name: str, data: Any, base: str) -> MaterialSpec:
    """One [materials.NAME] table; ``base`` the scene file's directory (for an import path)."""
    where = f"[materials.{name}]"
    if not isinstance(data, dict):
        raise InputError(f"{where} must be a table, not {toml_text(data)}")
    model = data.get("model", "elastic")
    if not isinstance(model, str) or not model:
        raise InputError(f"{where} model = {toml_text(model)}: must be a non-empty string (the "
                         "constitutive model)")
    if model in MODELS:
        t = Table(data, where, "materials", tuple(MODELS))
    elif ":" in model:
        t = Table({k: v for k, v in data.items() if k in COMMON}, where, "materials")
    else:
        raise InputError(f"{where} model = {toml_text(model)}: use one of {', '.join(MODELS)}, "
                         'or a class of your own as "package.module:Class"')
    E, density = t.value("E"), t.value("density")
    nu = t.value("nu")
    if not -1.0 < nu < 0.5:
        raise t.error("nu", "Poisson's ratio must lie in (-1, 0.5); nu >= 0.5 is "
                            "incompressible and has no explicit stable time step")
    spec = MaterialSpec(name, E, nu, density, model)
    if spec.custom:
        spec.params = {k: v for k, v in data.items() if k not in COMMON}
        cls = import_class(where, model, base)
        spec.classes = {cls.strain: cls}
        return spec
    spec.classes = dict(MODELS[model])
    own = {p.name: p for cls in spec.classes.values() for p in cls.parameters}
    for key in data:
        if key in COMMON:
            continue
        if key not in own:
            users = [f'"{m}"' for m, classes in MODELS.items()
                     if any(key in (p.name for p in c.parameters) for c in classes.values())]
            raise t.error(key, f"only for model = {' or '.join(users)}")
        p = own[key]
        v = t.data[key]
        what = p.what if p.unit in ("", "-") else f"{p.what} ({p.unit})"
        if p.choices:
            if not p.admits(v):
                raise t.error(key, f"must be {p.range_text} ({what})")
            spec.params[key] = v
            continue
        if not is_number(v):
            raise t.error(key, f"must be a finite number ({what})")
        if not p.admits(float(v)):
            raise t.error(key, f"must be {p.range_text} ({what})")
        spec.params[key] = float(v)
    return spec


def import_class(where: str, path: str, base: str):
    """The class of ``"package.module:Class"``, imported from the installed packages or
    from ``base``; its ``strain`` must name a kinematics."""
    head = f"{where} model = {toml_text(path)}:"
    if not _PATH.match(path):
        raise InputError(f'{head} not an import path "package.module:Class"')
    module_name, attr = path.split(":")
    added = base not in sys.path
    if added:
        sys.path.append(base)
    try:
        module = importlib.import_module(module_name)
    except Exception as exc:  # noqa: BLE001  (the user's module: any failure is one line)
        reason = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise InputError(f"{head} cannot import {module_name} ({type(exc).__name__}: "
                         f"{reason})") from None
    finally:
        if added:
            sys.path.remove(base)
    if not hasattr(module, attr):
        raise InputError(f"{head} the module {module_name} ({getattr(module, '__file__', '?')}) "
                         f"has no attribute {attr}")
    cls = getattr(module, attr)
    strain = getattr(cls, "strain", None)
    if strain not in KINEMATICS:
        raise InputError(f"{head} {attr} states no kinematics: give the class strain = "
                         '"small" or strain = "finite"')
    return cls


def check_kinematics(materials: dict[str, MaterialSpec], bodies) -> None:
    """Build each material at the kinematics of its bodies (an unused one at its first):
    a model without that kinematics, a key that form does not take, and what the class
    refuses are one line naming the table."""
    for spec in materials.values():
        strains = [b.strain for b in bodies if b.material == spec.name] or [next(iter(spec.classes))]
        for strain in dict.fromkeys(strains):
            spec.material(strain)


def _build(spec: MaterialSpec, strain: str):
    """The material of ``spec`` at ``strain`` (checked: kinematics, keys, the class's checks,
    the interface of its kinematics)."""
    where = spec.where
    if strain not in spec.classes:
        has = next(iter(spec.classes))
        other = (' (at finite strain an elastic solid is model = "neo_hookean")'
                 if spec.model == "elastic" else "")
        raise InputError(f"{where} model = {toml_text(spec.model)} has a "
                         f"{_adjective(has)} form only: its body needs "
                         f'strain = "{has}"{other}')
    cls = spec.classes[strain]
    kwargs: dict[str, Any] = {"E": spec.E, "nu": spec.nu, "density": spec.density}
    if spec.custom:
        kwargs.update(spec.params)
        try:
            material = cls(**kwargs)
        except (TypeError, ValueError) as exc:
            raise InputError(f"{where} {spec.model}({', '.join(kwargs)}): "
                             f"{str(exc).splitlines()[0] if str(exc) else type(exc).__name__}"
                             ) from None
        missing = missing_attributes(material)
        if missing:
            raise InputError(f"{where} model = {toml_text(spec.model)}: the material has no "
                             f"attribute '{missing[0]}' (a {_adjective(strain)} material "
                             f"needs {', '.join(_needs(material))})")
        return material
    own = {p.name: p for p in cls.parameters}
    for key, value in spec.params.items():
        if key not in own:
            takes = ", ".join(("E", "nu", "density") + tuple(own))
            raise InputError(f"{where} {key} = {toml_text(value)}: the "
                             f"{_adjective(strain)} form of model = {toml_text(spec.model)} "
                             f"({cls.__name__}) has no such parameter (it takes {takes})")
    missing = [p for p in cls.parameters
               if p.name not in spec.params and p.scene_default == REQUIRED]
    if len(missing) == 1:
        raise InputError(f"{where} {missing[0].name} is missing: {missing[0].described}")
    if missing:  # every one in the one line, so that one edit mends the table
        raise InputError(f"{where} {len(missing)} parameters are missing: "
                         + "; ".join(f"{p.name} ({p.described})" for p in missing))
    for p in cls.parameters:
        if p.name in spec.params:
            kwargs[p.name] = spec.params[p.name]
        elif p.scene_default not in (REQUIRED, CLASS_DEFAULT):
            kwargs[p.name] = p.scene_default
    try:
        return cls(**kwargs)
    except InputError as exc:  # the class's own checks: "material.KEY = ...: ..."
        text = str(exc)
        raise InputError(f"{where} {text.removeprefix('material.')}") from None


def _adjective(strain: str) -> str:
    """'small-strain' or 'finite-strain'."""
    return STRAIN_WORDS[strain].replace(" ", "-")


def _needs(material) -> tuple[str, ...]:
    from .materials import INTERFACE, interface_of

    return INTERFACE[interface_of(material)]
