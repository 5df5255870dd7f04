"""Reading one TOML table of a scene file by its section of the key table (scene_keys).

:class:`Table` checks a table's keys (unknown, missing) and values (kind, sign,
range, choices); every error is an :class:`~impact_fenics.errors.InputError`
naming the table and the key. :func:`within` prefixes the errors the library
raises while a table is being built with that table's name.
"""
from __future__ import annotations

import math
from contextlib import contextmanager
from typing import Any, Iterator

from .errors import InputError
from .scene_keys import REQUIRED, SECTIONS

MISSING = object()
_TABLE = object()  # "the default of the key table"


def toml_text(value: Any) -> str:
    """A value as TOML spells it."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return f'"{value}"'
    if isinstance(value, list):
        return "[" + ", ".join(toml_text(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{" + ", ".join(f"{k} = {toml_text(v)}" for k, v in value.items()) + "}"
    return repr(value)


def is_number(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


class Table:
    """One TOML table being read by its section of the key table (scene_keys): unknown
    keys, missing keys and bad values name the table and the key. ``groups``: the
    variant of the entry (the keys of other variants are unknown here)."""

    def __init__(self, data: Any, where: str, section: str, groups: tuple[str, ...] = ()):
        if not isinstance(data, dict):
            raise InputError(f"{where} must be a table, not {toml_text(data)}")
        self.data, self.where, self.groups = data, where, groups
        self.section = SECTIONS[section]
        allowed = self.section.allowed(groups)
        for key in data:
            if key not in allowed:
                raise InputError(f"{where} unknown key '{key}' (allowed here: "
                                 f"{', '.join(allowed)})")

    def __contains__(self, key: str) -> bool:
        return key in self.data

    def error(self, key: str, problem: str) -> InputError:
        return InputError(f"{self.where} {key} = {toml_text(self.data[key])}: {problem}")

    def value(self, key: str, default: Any = _TABLE) -> Any:
        """The value of ``key`` checked by its kind in the key table; if absent, the
        table's default (or ``default``, for a default the reader computes); a
        required key that is absent is an error."""
        spec = self.section.key(key, self.groups)  # (two variants may name a key alike)
        if default is _TABLE:
            default = spec.default
            if isinstance(default, list):
                default = tuple(default)
        if default == REQUIRED:
            default = MISSING
        what, kind = spec.described, spec.kind
        if kind == "number":
            return self.number(key, what, default)
        if kind == "positive":
            return self.positive(key, what, default)
        if kind == "count":
            return self.count(key, what, default)
        if kind == "flag":
            return self.flag(key, what, default)
        if kind == "text":
            return self.text(key, what, default, choices=spec.choices or None)
        if kind == "pair":
            return self.pair(key, what, default)
        if kind == "stiffness":  # a penalty: N/m > 0, or one of the key's words
            v = self.data.get(key)
            if isinstance(v, str):
                if v not in spec.choices:
                    words = [f'"{w}"' for w in spec.choices]
                    raise self.error(key, "give a stiffness in N/m"
                                     + "".join(f", {w}" for w in words[:-1]) + f" or {words[-1]}")
                return v
            return self.positive(key, what, default)
        raise ValueError(f"{self.section.toml} {key}: kind {kind} is read by its own code")

    def _get(self, key: str, what: str, default: Any) -> Any:
        if key in self.data:
            return self.data[key]
        if default is MISSING:
            raise InputError(f"{self.where} {key} is missing: {what}")
        return default

    def number(self, key: str, what: str, default: Any = MISSING) -> float:
        """A finite number (int or float)."""
        v = self._get(key, what, default)
        if key not in self.data:
            return v
        if not is_number(v):
            raise self.error(key, f"must be a finite number ({what})")
        return float(v)

    def positive(self, key: str, what: str, default: Any = MISSING) -> float:
        v = self.number(key, what, default)
        if key in self.data and not v > 0:
            raise self.error(key, f"must be > 0 ({what})")
        return v

    def count(self, key: str, what: str, default: Any = MISSING) -> int:
        """An integer >= 1."""
        v = self._get(key, what, default)
        if key not in self.data:
            return v
        if not isinstance(v, int) or isinstance(v, bool) or v < 1:
            raise self.error(key, f"must be an integer >= 1 ({what})")
        return v

    def flag(self, key: str, what: str, default: bool) -> bool:
        v = self._get(key, what, default)
        if not isinstance(v, bool):
            raise self.error(key, f"must be true or false ({what})")
        return v

    def text(self, key: str, what: str, default: Any = MISSING,
             choices: tuple[str, ...] | None = None) -> str:
        v = self._get(key, what, default)
        if key not in self.data:
            return v
        if not isinstance(v, str) or not v:
            raise self.error(key, f"must be a non-empty string ({what})")
        if choices is not None and v not in choices:
            raise self.error(key, f"use one of {', '.join(choices)}")
        return v

    def pair(self, key: str, what: str, default: Any = MISSING) -> tuple[float, float]:
        v = self._get(key, what, default)
        if key not in self.data:
            return v
        if not isinstance(v, list) or len(v) != 2 or not all(is_number(x) for x in v):
            raise self.error(key, f"must be two finite numbers [a, b] ({what})")
        return float(v[0]), float(v[1])


def tables_of(parent: Table, key: str, what: str) -> list[tuple[str, Any]]:
    """The named sub-tables [key.NAME] of a table (name, data)."""
    data = parent.data.get(key, {})
    if not isinstance(data, dict):
        raise InputError(f"{parent.where} {key} must be a table of [{key}.NAME] tables ({what})")
    for name, value in data.items():
        if not isinstance(value, dict):
            raise InputError(f"[{key}] {name} = {toml_text(value)}: must be a table [{key}.{name}] "
                             f"({what})")
    return list(data.items())


def array_of(parent: Table, key: str) -> list[tuple[str, Any]]:
    """The entries of an array of tables [[key]], each with its label '[key #k]'."""
    data = parent.data.get(key, [])
    if not isinstance(data, list) or not all(isinstance(d, dict) for d in data):
        raise InputError(f"[{key}] must be an array of tables: write [[{key}]] above each entry")
    return [(f"[{key} #{k + 1}]", d) for k, d in enumerate(data)]


@contextmanager
def within(where: str) -> Iterator[None]:
    """Prefix the InputErrors of the library with the table they come from."""
    try:
        yield
    except InputError as exc:
        raise InputError(f"{where} {exc}") from None
