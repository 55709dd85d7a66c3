"""DAVOS tracker settings: paper defaults, checks, JSON round trip."""

import pytest

from core.errors import InputError
from models.vos.davos_settings import DAVOSSettings


def test_defaults_are_the_papers_inference_settings_and_round_trip() -> None:
    s = DAVOSSettings()
    assert (s.init_iters, s.update_iters, s.update_every, s.memory_size, s.learning_rate) == (20, 5, 1, 32, 0.1)
    assert DAVOSSettings.from_dict(s.to_dict()) == s and s.replace(update_iters=3).update_iters == 3


@pytest.mark.parametrize(("change", "message"), [
    ({"update_every": 0}, "update_every"), ({"init_iters": -1}, "init_iters"), ({"learning_rate": 1.0}, "lr|learning"),
    ({"keep_first": 1.0}, "keep_first"), ({"memory_size": 1}, "keep_first"), ({"iters": 3}, "unknown DAVOS tracker"),
])
def test_bad_settings_are_named(change: dict, message: str) -> None:
    with pytest.raises(InputError, match=message):
        DAVOSSettings.from_dict(change)
