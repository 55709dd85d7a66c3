"""bench/vos.py: the first-frame-copy baseline and the JSON layout on a tiny synthetic video set, the DAVOS family
side by side with FRTM, tracker overrides, method checks and the speed table."""

import pytest

from bench.vos import load_videos, parse_args, run, run_method
from core.errors import InputError
from data.vos.datamodule import synthetic_videos
from models.builders import davos_system, frtm_system
from models.vos.metrics import evaluate_sequence
from tests.models.test_checkpoint import save_checkpoint

TINY_DAVOS = {"backbone": "resnet18", "weights": None, "projection_channels": 8, "encoding_channels": 4, "mdim": 8,
              "encoder_dims": (4, 8, 8), "tracker": {"init_iters": 2, "update_iters": 1, "memory_size": 4}}


def test_first_frame_copy_and_target_model_only() -> None:
    videos = synthetic_videos("test", 1, n_frames=5, height=48, width=64, n_objects=2)
    _, _, labels = videos[0]
    copy = run_method(None, videos)
    ref = evaluate_sequence(labels[:1].expand_as(labels), labels)
    assert abs(copy["jf"] - sum(o["J&F-Mean"] for o in ref.values()) / len(ref)) < 1e-12
    model = frtm_system(mdim=8, tracker={"channels": 8, "num_aug": 2, "memory_size": 6, "init_schedule": [2],
                                              "update_schedule": [2]})
    tm = run_method(lambda: model.make_tracker(use_decoder=False), videos)
    assert set(tm) == {"jf", "j", "f", "fps", "ms_per_frame", "per_sequence"} and tm["fps"] > 0
    assert 0 <= tm["jf"] <= 1 and set(tm["per_sequence"][videos[0][0]]) == {"1", "2"}
    obj = tm["per_sequence"][videos[0][0]]["1"]
    assert set(obj) == {"jf", "j", "f"} and abs(obj["jf"] - (obj["j"] + obj["f"]) / 2) < 1e-12
    assert parse_args(["--davis", "x", "--split", "val"]).resolution == "480p"


def test_davos_family_runs_beside_frtm_on_lookalike_videos(tmp_path) -> None:
    davos = save_checkpoint(davos_system(**TINY_DAVOS), tmp_path / "davos.ckpt")
    lwl = save_checkpoint(davos_system(**TINY_DAVOS, distractors=False), tmp_path / "lwl.ckpt")
    args = ["--davos-ckpt", str(davos), "--lwl-ckpt", str(lwl), "--extra", f"davos_again={davos}", "--lookalike",
            "--videos", "1", "--max-frames", "4", "--height", "48", "--width", "64", "--objects", "2",
            "--tracker", "channels=8", "num_aug=2", "memory_size=4", "init_schedule=[2]", "update_schedule=[2]"]
    out = run(parse_args([*args, "--methods", "davos,davos_no_wta,lwl,davos_again,first_frame_copy"]))
    assert list(out["methods"]) == ["davos", "davos_no_wta", "lwl", "davos_again", "first_frame_copy"]
    assert out["dataset"].startswith("lookalike:1x48x64") and out["checkpoints"]["lwl"] == str(lwl)
    for m in ("davos", "lwl"):
        assert set(out["methods"][m]["per_sequence"]["synthetic-2000000"]) == {"1", "2"}
        assert set(out["methods"][m]["ms_per_frame"]) >= {"backbone", "decoder", "update", "init"}
    # the same network twice gives the same masks; the ablation switch changes the tracker only
    assert out["methods"]["davos_again"]["jf"] == out["methods"]["davos"]["jf"]
    # without --methods: every method the checkpoints allow
    assert list(run(parse_args([*args, "--max-frames", "3"]))["methods"]) == [
        "davos", "davos_no_wta", "lwl", "davos_again", "frtm", "target_model_only", "first_frame_copy"]


def test_tracker_overrides_and_method_checks() -> None:
    from bench.vos import parse_extra, parse_tracker

    assert parse_tracker(["channels=32", "update_schedule=[5, 5]", "label_stride=2"]) == {
        "channels": 32, "update_schedule": [5, 5], "label_stride": 2}
    for bad in (["channels"], ["channels=thirty"]):
        with pytest.raises(InputError, match="KEY=JSON"):
            parse_tracker(bad)
    with pytest.raises(InputError, match="frtm2"):
        run(parse_args(["--methods", "frtm,frtm2"]))
    with pytest.raises(InputError, match="needs a checkpoint"):
        run(parse_args(["--methods", "davos"]))
    with pytest.raises(InputError, match="NAME=CKPT"):
        parse_extra(["frtm=x.ckpt"])
    with pytest.raises(InputError, match="give --davis"):
        run(parse_args(["--composites", "twins", "--methods", "first_frame_copy"]))


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
    davos = davos_system(**TINY_DAVOS)
    out = speed({"lite0": model.make_tracker, "r18": frtm_system(config=config).make_tracker,
                 "davos": davos.make_tracker}, n_frames=3, repeats=1)
    assert set(out) == {"lite0", "r18", "davos"} and set(out["lite0"]) == {"240p", "480p"}
    assert all(out[m][r]["fps"] > 0 and out[m][r]["cpu_s_per_frame"] > 0 for m in out for r in out[m])


@pytest.mark.slow  # uses an exported bundle
def test_a_bundle_runs_as_a_method(vos_setup) -> None:
    args = parse_args(["--synthetic", "--videos", "1", "--max-frames", "4", "--height", "64", "--width", "96",
                       "--methods", "first_frame_copy", "--onnx", str(vos_setup["bundle"]), "--threads", "1"])
    result = run(args)
    row = result["methods"][f"onnx:{vos_setup['bundle'].name}"]
    assert set(result["methods"]) == {"first_frame_copy", f"onnx:{vos_setup['bundle'].name}"}
    assert 0 <= row["jf"] <= 1 and row["fps"] > 0 and row["ms_per_frame"]["frame"] > 0


def test_per_frame_curves_match_a_per_frame_count() -> None:
    videos = synthetic_videos("test", 1, n_frames=5, height=48, width=64, n_objects=2)
    name, _, labels = videos[0]
    labels = labels.clone()
    labels[2, :3] = 255  # void rows, left out of J
    out = run_method(None, [(name, videos[0][1], labels)], per_frame=True)
    copy = labels[0].numpy()
    for obj in ("1", "2"):
        curve = out["per_sequence"][name][obj]["frames"]
        assert set(out["per_sequence"][name][obj]) == {"jf", "j", "f", "frames"}
        for t, truth in enumerate(labels.numpy()):
            keep = truth != 255
            p, g = (copy == int(obj)) & keep, (truth == int(obj)) & keep
            union = (p | g).sum()
            assert curve["j"][t] == pytest.approx((p & g).sum() / union if union else 1.0, abs=1e-12)
            assert curve["area"][t] == pytest.approx((copy == int(obj)).mean(), abs=1e-12)
            assert curve["gt_area"][t] == pytest.approx((truth == int(obj)).mean(), abs=1e-12)
    assert "frames" not in run_method(None, videos)["per_sequence"][name]["1"]


def test_plot_frames_writes_the_curves_and_implies_per_frame(tmp_path, capsys) -> None:
    import json

    from bench.vos import main

    png = tmp_path / "frames.png"
    small = ["--videos", "1", "--max-frames", "4", "--height", "48", "--width", "64", "--methods", "first_frame_copy"]
    assert main([*small, "--plot-frames", str(png), "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    obj = next(iter(result["methods"]["first_frame_copy"]["per_sequence"].values()))["1"]
    assert len(obj["frames"]["j"]) == 4 and png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert main(["--speed", "--methods", "first_frame_copy", "--plot-frames", str(tmp_path / "none.png")]) == 2
    assert "needs videos" in capsys.readouterr().err and not (tmp_path / "none.png").exists()


@pytest.mark.slow  # uses an exported bundle
def test_a_davos_bundle_runs_as_a_method_like_its_pytorch_tracker(davos_setup) -> None:
    args = parse_args(["--lookalike", "--videos", "1", "--objects", "2", "--max-frames", "6", "--height", "64",
                       "--width", "96", "--methods", "first_frame_copy", "--onnx", str(davos_setup["bundle"]),
                       "--threads", "1"])
    result = run(args)
    row = result["methods"][f"onnx:{davos_setup['bundle'].name}"]
    assert row["fps"] > 0 and row["ms_per_frame"]["frame"] > 0
    _, videos = load_videos(args)
    reference = run_method(lambda: davos_setup["tracker"], videos, "davos", False)
    assert row["jf"] == pytest.approx(reference["jf"], abs=0.01)
    assert row["jf"] != pytest.approx(result["methods"]["first_frame_copy"]["jf"], abs=0.01)
