"""SettingsMixin: mappings in and out, unknown keys named, checks on replace."""

from dataclasses import dataclass

import pytest

from core.errors import InputError
from core.settings import SettingsMixin


@dataclass(frozen=True)
class Knobs(SettingsMixin):
    size: int = 3
    steps: tuple[int, ...] = (1, 2)

    KIND = "test"

    def __post_init__(self) -> None:
        object.__setattr__(self, "steps", tuple(self.steps))
        if self.size < 1:
            raise InputError(f"size must be >= 1, got {self.size}")


def test_round_trip_replace_and_errors() -> None:
    k = Knobs.from_dict({"size": 5, "steps": [3]})
    assert k == Knobs(5, (3,)) and k.to_dict() == {"size": 5, "steps": [3]}
    assert Knobs.from_dict(k.to_dict()) == k and k.replace(size=2) == Knobs(2, (3,))
    with pytest.raises(InputError, match=r"unknown test settings \['sise'\]; known: size, steps"):
        Knobs.from_dict({"sise": 1})
    with pytest.raises(InputError, match="size must be"):
        k.replace(size=0)
