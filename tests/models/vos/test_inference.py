"""models/vos/inference.py: synthetic test-video settings read from a checkpoint's datamodule."""

import torch

from models.vos.inference import synthetic_test_settings


def test_synthetic_settings_follow_the_checkpoint_data(tmp_path) -> None:
    ckpt = tmp_path / "fake.ckpt"
    data = {"height": 64, "width": 96, "eval_objects": 3, "n_distractors": 0, "object_scale": [0.25, 0.45]}
    torch.save({"state_dict": {}, "datamodule_hyper_parameters": data}, ckpt)
    got = synthetic_test_settings(ckpt, width=112, height=None)
    assert got == {"height": 64, "width": 112, "n_objects": 3, "n_distractors": 0, "object_scale": (0.25, 0.45)}
    default = synthetic_test_settings(None)
    assert default == {"height": 96, "width": 160, "n_objects": 2, "n_distractors": 1, "object_scale": (0.15, 0.3)}
