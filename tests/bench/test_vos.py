"""bench/vos.py: the first-frame-copy baseline and the JSON layout on a tiny synthetic video set, tracker
overrides and the speed table."""

import pytest

from bench.vos import parse_args, run_method
from data.vos.datamodule import synthetic_videos
from models.builders import frtm_system
from models.vos.metrics import evaluate_sequence


def test_first_frame_copy_and_target_model_only() -> None:
    videos = synthetic_videos("test", 1, n_frames=5, height=48, width=64, n_objects=2)
    _, _, labels = videos[0]
    copy = run_method(None, "first_frame_copy", videos)
    ref = evaluate_sequence(labels[:1].expand_as(labels), labels)
    assert abs(copy["jf"] - sum(o["J&F-Mean"] for o in ref.values()) / len(ref)) < 1e-12
    model = frtm_system(mdim=8, tracker={"channels": 8, "num_aug": 2, "memory_size": 6, "init_schedule": [2],
                                              "update_schedule": [2]})
    tm = run_method(model, "target_model_only", videos)
    assert set(tm) == {"jf", "j", "f", "fps", "ms_per_frame", "per_sequence"} and tm["fps"] > 0
    assert 0 <= tm["jf"] <= 1 and set(tm["per_sequence"][videos[0][0]]) == {"1", "2"}
    obj = tm["per_sequence"][videos[0][0]]["1"]
    assert set(obj) == {"jf", "j", "f"} and abs(obj["jf"] - (obj["j"] + obj["f"]) / 2) < 1e-12
    assert parse_args(["--davis", "x", "--split", "val"]).resolution == "480p"


def test_tracker_overrides_and_method_checks() -> None:
    from bench.vos import parse_tracker, run
    from core.errors import InputError

    assert parse_tracker(["channels=32", "update_schedule=[5, 5]", "label_stride=2"]) == {
        "channels": 32, "update_schedule": [5, 5], "label_stride": 2}
    for bad in (["channels"], ["channels=thirty"]):
        with pytest.raises(InputError, match="KEY=JSON"):
            parse_tracker(bad)
    with pytest.raises(InputError, match="frtm2"):
        run(parse_args(["--methods", "frtm,frtm2"]))


@pytest.mark.slow
def test_untrained_pretrained_system_and_speed_side_by_side(tmp_path) -> None:
    from bench.vos import speed

    model = frtm_system(backbone="efficientnet_lite0", weights="imagenet", feature_layer="layer2",
                       feature_norm="instance_l2", mdim=8, tracker={"channels": 8, "num_aug": 2, "memory_size": 4,
                                                                    "init_schedule": [2], "update_schedule": [2]})
    assert model.backbone.channels["layer2"] == 40 and model.make_tracker().settings.feature_norm == "instance_l2"
    config = tmp_path / "tiny.yaml"
    config.write_text("model:\n  class_path: models.vos.lit.FRTMSegmentation\n  init_args:\n    mdim: 8\n    tracker:"
                      " {channels: 8, num_aug: 2, memory_size: 4, init_schedule: [2], update_schedule: [2]}\n")
    out = speed({"lite0": model, "r18": frtm_system(config=config)}, n_frames=3, repeats=1)
    assert set(out) == {"lite0", "r18"} and set(out["lite0"]) == {"240p", "480p"}
    assert all(out[m][r]["fps"] > 0 and out[m][r]["cpu_s_per_frame"] > 0 for m in out for r in out[m])
