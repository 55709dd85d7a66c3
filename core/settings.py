"""Frozen dataclasses of settings that read and write plain mappings (config sections, JSON settings files)."""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Mapping
from typing import TypeVar

from core.errors import InputError

S = TypeVar("S", bound="SettingsMixin")


class SettingsMixin:
    """``from_dict`` / ``replace`` / ``to_dict`` for a frozen dataclass whose ``__post_init__`` checks its values.

    ``KIND`` names the settings in the error for an unknown key (``unknown tracker settings [...]``).
    """

    KIND = "tracker"

    @classmethod
    def from_dict(cls: type[S], values: Mapping[str, object]) -> S:
        """Settings from a mapping; an unknown key is an ``InputError`` that lists the known ones."""
        names = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(values) - names)
        if unknown:
            raise InputError(f"unknown {cls.KIND} settings {unknown}; known: {', '.join(sorted(names))}")
        return cls(**values)

    def replace(self: S, **changes: object) -> S:
        """A copy with ``changes`` applied (checked like ``from_dict``)."""
        return type(self).from_dict({**self.to_dict(), **changes})

    def to_dict(self) -> dict[str, object]:
        """JSON-ready mapping (tuples become lists)."""
        return {k: list(v) if isinstance(v, tuple) else v for k, v in dataclasses.asdict(self).items()}


def parse_tracker(items: list[str] | None, option: str = "--tracker") -> dict:
    """Settings given on a command line as ``KEY=JSON`` items (``option`` names the flag in errors):
    ``["channels=32", "update_schedule=[5]"]`` -> ``{"channels": 32, "update_schedule": [5]}``."""
    out = {}
    for item in items or []:
        key, sep, value = item.partition("=")
        try:
            if not sep:
                raise ValueError("no '='")
            out[key] = json.loads(value)
        except ValueError as err:  # JSONDecodeError is a ValueError
            raise InputError(f"{option} item {item!r} is not KEY=JSON ({err})") from err
    return out
