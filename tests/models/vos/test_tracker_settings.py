"""FRTMSettings: the paper's defaults, JSON round trip, checked values and unknown keys named."""

import json

import pytest

from core.errors import InputError
from models.vos.tracker_settings import FRTMSettings


def test_defaults_are_the_papers_inference_settings() -> None:
    s = FRTMSettings()
    assert (s.channels, s.num_aug, s.memory_size, s.update_every, s.learning_rate) == (96, 5, 80, 8, 0.1)
    assert s.init_schedule == (5, 10, 10, 10, 10) and s.update_schedule == (10,) and s.reg == (1e-4, 1e-2)


def test_json_round_trip_and_lists_become_tuples() -> None:
    s = FRTMSettings.from_dict({"channels": 32, "update_schedule": [5, 5], "reg": [1e-3, 1e-2]})
    assert s.update_schedule == (5, 5) and s.reg == (1e-3, 1e-2)
    assert FRTMSettings.from_dict(json.loads(json.dumps(s.to_dict()))) == s
    assert s.replace(label_stride=2) == FRTMSettings(channels=32, update_schedule=(5, 5), reg=(1e-3, 1e-2),
                                                     label_stride=2)


@pytest.mark.parametrize(("change", "message"), [
    ({"chanels": 8}, r"unknown tracker settings \['chanels'\]"),
    ({"optimizer": "adam"}, "optimizer must be one of"),
    ({"optimizer_dtype": "float16"}, "optimizer_dtype"),
    ({"kernel_size": 4}, "kernel_size must be odd"),
    ({"memory_size": 0}, "memory_size must be at least 1"),
    ({"update_schedule": []}, "non-empty"),
    ({"reg": [1e-4]}, "two non-negative"),
    ({"feature_norm": "batch"}, "feature_norm must be one of"),
    ({"flip_test": "false"}, "flip_test must be true or false"),
    ({"use_decoder": 1}, "use_decoder must be true or false"),
    ({"keep_first": 1.0}, "keep_first must lie in"),
    ({"keep_first": -0.1}, "keep_first must lie in"),
    ({"keep_first": "0.25"}, "keep_first must lie in"),
    ({"keep_first": True}, "keep_first must lie in"),
    ({"keep_first": float("nan")}, "keep_first must lie in"),
    ({"keep_first": 0.25, "memory_size": 1}, "keep_first needs memory_size >= 2"),
])
def test_bad_settings_are_named(change, message) -> None:
    with pytest.raises(InputError, match=message):
        FRTMSettings().replace(**change)
