"""bench/point_tracking.py: one JSON object with every method's metrics, a plot, and the importable demo."""

import json
import re

import cv2
import numpy as np
import pytest

from bench import point_tracking
from core.errors import InputError


def test_json_schema_and_plot(tmp_path, capsys):
    png = tmp_path / "plot.png"
    assert (
        point_tracking.main(["--synthetic", "--frames", "5", "--points", "60", "--json", "--plot", str(png)])
        == 0
    )
    result = json.loads(capsys.readouterr().out)
    methods = result["datasets"]["synthetic"]["methods"]
    assert set(methods) == {"ccot", "ccot_ff", "mosse", "klt"}
    for m in methods.values():
        assert set(m) >= {"epe_median", "epe_mean", "inlier_frac", "inlier_epe_mean", "point_frames_per_s"}
        assert set(m["precision_at"]) == {"1", "2", "3"}
        assert 0 <= m["precision_at"]["1"] <= m["precision_at"]["3"] == m["inlier_frac"] <= 1
        assert m["speed_vs_klt"] == m["point_frames_per_s"] / methods["klt"]["point_frames_per_s"]
    assert png.stat().st_size > 10_000
    assert result["summary"]["synthetic"]["rows"] == 1 and list(result["summary"]) == ["synthetic", "all"]
    assert result["summary"]["all"]["methods"]["ccot"]["rows_beating_klt"] in (0, 1)


def test_metrics_against_hand_computed_values():
    data = point_tracking.Dataset(
        frames=np.zeros((3, 8, 8), np.uint8),
        points=np.zeros((4, 2)),
        truth=np.array([[0.0, 0.0], [1.0, 0.0], [5.0, 0.0], [9.0, 9.0]]),
        valid=np.array([True, True, True, False]),
    )
    pred = np.array([[0.5, 0.0], [1.0, 2.5], [5.0, 0.0], [0.0, 0.0]])
    lost = np.array([False, False, True, False])
    m = point_tracking.metrics(pred, lost, data, seconds=2.0)
    assert m["epe_median"] == 0.5 and m["epe_mean"] == 1.0  # EPEs 0.5, 2.5, 0 (lost: kept position)
    assert m["inlier_frac"] == 2 / 3 and m["inlier_epe_mean"] == 1.5
    assert m["precision_at"] == {"1": 1 / 3, "2": 1 / 3, "3": 2 / 3}
    assert m["point_frames_per_s"] == 4 * 2 / 2.0


def test_summary_counts_the_rows_beating_klt():
    """Hand-made rows: a win, a loss on inliers, a loss on precision, a KLT row without inliers (won on precision
    by any row) and a row without inliers of its own (loses to a KLT with inliers); counts, names and means per
    group and over all, against values worked out by hand."""
    nan = float("nan")

    def row(ccot, klt):
        return {"methods": {name: {"inlier_frac": f, "inlier_epe_mean": e, "lost_frac": lost}
                            for name, (f, e, lost) in (("ccot", ccot), ("klt", klt))}}

    result = {
        "a": row((0.9, 0.5, 0.1), (0.8, 0.6, 0.0)),  # won
        "b": row((0.7, 0.5, 0.3), (0.8, 0.6, 0.0)),  # fewer inliers
        "c": row((0.9, 0.7, 0.1), (0.8, 0.6, 0.0)),  # less precise
        "d": row((0.5, 0.9, 0.5), (0.0, nan, 1.0)),  # KLT without inliers: won
        "e": row((0.0, nan, 1.0), (0.2, 1.0, 0.4)),  # no inliers of its own: lost in both
    }
    groups = {"a": "g1", "b": "g1", "c": "g2", "d": "g2", "e": "g2"}
    summary = point_tracking.summary(result, groups)
    assert list(summary) == ["g1", "g2", "all"]
    expected = {"g1": (2, 1, 1, 2, ["b"]), "g2": (3, 1, 2, 1, ["c", "e"]), "all": (5, 2, 3, 3, ["b", "c", "e"])}
    for group, (rows, both, inliers, precision, losing) in expected.items():
        ccot = summary[group]["methods"]["ccot"]
        assert summary[group]["rows"] == rows and ccot["rows_losing"] == losing
        assert (ccot["rows_beating_klt"], ccot["rows_beating_klt_inliers"], ccot["rows_beating_klt_precision"]) == (
            both, inliers, precision)
    ccot, klt = summary["all"]["methods"]["ccot"], summary["all"]["methods"]["klt"]
    assert ccot["inlier_frac_mean"] == pytest.approx(3.0 / 5) and klt["inlier_frac_mean"] == pytest.approx(2.6 / 5)
    assert ccot["inlier_epe_mean"] == pytest.approx(2.6 / 4) and klt["inlier_epe_mean"] == pytest.approx(2.8 / 4)
    assert ccot["lost_frac_mean"] == pytest.approx(2.0 / 5) and "rows_beating_klt" not in klt
    lines = point_tracking.summary_lines(summary)
    assert "ccot >= klt in both on 2 of 5 rows (inliers 3, precision 3); loses: b, c, e" in lines[-1]


def test_repeats_must_be_positive(capsys):
    with pytest.raises(SystemExit) as err:
        point_tracking.main(["--synthetic", "--repeats", "0"])
    assert err.value.code == 2 and "--repeats must be at least 1" in capsys.readouterr().err


def test_every_sintel_folder_counts():
    """``--sintel A --sintel B C`` keeps all three folders (argparse ``extend``, not the last option only)."""
    args = point_tracking.build_parser().parse_args(["--sintel", "A", "--sintel", "B", "C"])
    assert args.sintel == ["A", "B", "C"]
    assert point_tracking.build_parser().parse_args([]).sintel == []


def test_stress_conditions_are_rows_with_occlusion_recall(capsys):
    argv = ["--stress", "occlusion", "jpeg", "--frames", "4", "--points", "150", "--methods", "ccot", "klt",
            "--repeats", "1", "--json"]
    assert point_tracking.main(argv) == 0
    result = json.loads(capsys.readouterr().out)["datasets"]
    assert set(result) == {"stress_occlusion", "stress_jpeg"}
    occlusion = result["stress_occlusion"]["methods"]
    assert 0 <= occlusion["ccot"]["occluded_lost_frac"] <= 1 and "occluded_lost_frac" in occlusion["klt"]
    assert "occluded_lost_frac" not in result["stress_jpeg"]["methods"]["ccot"]
    for m in (*occlusion.values(), *result["stress_jpeg"]["methods"].values()):
        assert m["first_call_s"] > 0


def test_homography_rows_per_image_and_condition(tmp_path, capsys):
    """``--homography A B`` with two conditions gives four rows named by condition, folder and file;
    ``--homography-cameras moving fixed`` adds the four fixed-camera rows; a missing image is refused with its
    name."""
    import cv2

    rng = np.random.default_rng(0)
    for name in ("a", "b"):
        (tmp_path / name).mkdir()
        texture = cv2.GaussianBlur(rng.normal(128, 40, (96, 128)), (0, 0), 1.5).clip(0, 255).astype(np.uint8)
        cv2.imwrite(str(tmp_path / name / "img.png"), texture)
    argv = ["--homography", str(tmp_path / "a" / "img.png"), "--homography", str(tmp_path / "b" / "img.png"),
            "--homography-conditions", "blur", "none", "--points", "40", "--methods", "ccot", "klt",
            "--repeats", "1", "--json"]
    assert point_tracking.main(argv) == 0
    result = json.loads(capsys.readouterr().out)["datasets"]
    assert set(result) == {f"homography_{c}_{f}_img" for c in ("blur", "none") for f in ("a", "b")}
    for row in result.values():
        assert row["frames"] == 6 and 0 < row["evaluated_points"] <= row["points"] <= 40
    argv = [*argv[:4], "--homography-cameras", "moving", "fixed", *argv[4:]]
    assert point_tracking.main(argv) == 0
    both = json.loads(capsys.readouterr().out)["datasets"]
    fixed = {f"homography_fixed_{c}_{f}_img" for c in ("blur", "none") for f in ("a", "b")}
    assert set(both) == set(result) | fixed
    for name in fixed:  # nothing moves: KLT stays within a pixel of the start points on these textures
        assert both[name]["methods"]["klt"]["epe_median"] < 1.0
    assert point_tracking.main(["--homography", str(tmp_path / "missing.png"), "--json"]) == 2
    assert "missing.png" in capsys.readouterr().err  # a clear error, no traceback


@pytest.mark.parametrize(("option", "value", "moved", "error"), [
    ("--homography-geometry", 3.0, 1.0, "geometry multiplier"),  # 3 times the rotation, scale change and tilt
    ("--homography-step", 20.0, 5.0, "translation step"),  # steps of up to 20 px per axis
])
def test_homography_motion_options_reach_the_sequences(tmp_path, capsys, option, value, moved, error):
    """``--homography-geometry`` and ``--homography-step``: the rows' truth is that of the generator's sequence
    with that argument (built here independently), which moves it by more than ``moved`` px from the default
    sequence's; the JSON records the value, and a negative one is refused naming the image."""
    from core.frames import read_frame_gray
    from data.flow import homography_sequence

    rng = np.random.default_rng(3)
    texture = cv2.GaussianBlur(rng.normal(128, 40, (160, 200)), (0, 0), 1.5).clip(0, 255).astype(np.uint8)
    image = tmp_path / "img.png"
    cv2.imwrite(str(image), texture)
    argv = ["--homography", str(image), "--homography-conditions", "none", "--points", "30", "--seed", "2"]
    datasets, _ = point_tracking.build_datasets(point_tracking.build_parser().parse_args([*argv, option, str(value)]))
    data = datasets[f"homography_none_{tmp_path.name}_img"]
    keyword = option.removeprefix("--homography-")
    tracks, valid = homography_sequence(read_frame_gray(image), "none", 6, 2, **{keyword: value}).track(data.points)
    np.testing.assert_array_equal(data.truth, tracks[-1])
    np.testing.assert_array_equal(data.valid, valid[-1])
    plain = homography_sequence(read_frame_gray(image), "none", 6, 2).track(data.points)[0][-1]
    assert np.abs(plain - tracks[-1]).max() > moved
    assert point_tracking.main([*argv, option, str(value), "--methods", "klt", "--repeats", "1", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)[f"homography_{keyword}"] == value
    assert point_tracking.main([*argv, option, "-1", "--json"]) == 2
    err = capsys.readouterr().err
    assert "img.png" in err and error in err


def test_homography_folder_rows_match_the_generated_sequence(tmp_path, capsys):
    """``--homography-folder DIR``: a generated homography sequence written in the Oxford layout (frames and
    ``H1tokp`` files) gives the dataset that :func:`homography_dataset` builds from the image itself (frames, start
    points, truth, valid), one row ``homography_folder_<parent>_<folder>`` in the group ``homography_folder``; a
    missing folder is refused with its name."""
    import cv2

    from data.flow import homography_sequence

    rng = np.random.default_rng(4)
    texture = cv2.GaussianBlur(rng.normal(128, 40, (96, 128)), (0, 0), 1.5).clip(0, 255).astype(np.uint8)
    cv2.imwrite(str(tmp_path / "img.png"), texture)
    seq = homography_sequence(texture.astype(np.float32), "jpeg", 6, 1)
    folder = tmp_path / "oxford" / "ubc"
    folder.mkdir(parents=True)
    for k, (frame, h) in enumerate(zip(seq.frames, seq.homographies, strict=True), start=1):
        cv2.imwrite(str(folder / f"img{k}.png"), frame.astype(np.uint8))
        if k > 1:
            np.savetxt(folder / f"H1to{k}p", h)
    expected = point_tracking.homography_dataset(tmp_path / "img.png", "jpeg", 40, seed=1)
    read = point_tracking.homography_folder_dataset(folder, 40)
    np.testing.assert_array_equal(read.frames, expected.frames)
    np.testing.assert_array_equal(read.points, expected.points)
    np.testing.assert_allclose(read.truth, expected.truth, atol=1e-9)
    np.testing.assert_array_equal(read.valid, expected.valid)
    argv = ["--homography-folder", str(folder), "--points", "40", "--methods", "ccot", "klt", "--repeats", "1",
            "--json"]
    assert point_tracking.main(argv) == 0
    out = json.loads(capsys.readouterr().out)
    assert set(out["datasets"]) == {"homography_folder_oxford_ubc"}
    assert out["summary"]["homography_folder"]["rows"] == 1
    assert out["datasets"]["homography_folder_oxford_ubc"]["frames"] == 6
    assert point_tracking.main(["--homography-folder", str(tmp_path / "nowhere"), "--json"]) == 2
    assert "nowhere" in capsys.readouterr().err


def test_roundtrip_plays_the_frames_forward_and_back(tmp_path, capsys):
    """``--roundtrip DIR``: ``--roundtrip-frames`` frames (from ``start``, every ``stride``-th), then back to the
    first; the truth at the last frame is the start; too short a video, too few frames, a negative start or a
    stride below 1 is refused with the folder's name."""
    import cv2

    rng = np.random.default_rng(1)
    texture = cv2.GaussianBlur(rng.normal(128, 40, (120, 160)), (0, 0), 1.5).clip(0, 255)
    for t in range(5):  # content moving 2 px right per frame
        cv2.imwrite(str(tmp_path / f"{t:05d}.png"), np.roll(texture, 2 * t, axis=1)[:, 10:-10].astype(np.uint8))
    data = point_tracking.roundtrip_dataset(tmp_path, 4, 50)
    order = [0, 1, 2, 3, 2, 1, 0]
    assert len(data.frames) == 7
    for frame, t in zip(data.frames, order, strict=True):
        np.testing.assert_array_equal(frame, cv2.imread(str(tmp_path / f"{t:05d}.png"), cv2.IMREAD_GRAYSCALE))
    np.testing.assert_array_equal(data.truth, data.points)
    assert data.valid.all() and 0 < len(data.points) <= 50
    argv = ["--roundtrip", str(tmp_path), "--roundtrip-frames", "3", "--points", "40", "--methods", "ccot", "klt",
            "--repeats", "1", "--json"]
    assert point_tracking.main(argv) == 0
    row = json.loads(capsys.readouterr().out)["datasets"][f"roundtrip_{tmp_path.name}"]
    assert row["frames"] == 5 and row["methods"]["klt"]["inlier_frac"] > 0.8  # a pure translation comes back
    dark = point_tracking.roundtrip_dataset(tmp_path, 4, 50, condition="light", strength=1.0, seed=2)
    again = point_tracking.roundtrip_dataset(tmp_path, 4, 50, condition="light", strength=1.0, seed=2)
    np.testing.assert_array_equal(dark.frames, again.frames)  # seeded
    np.testing.assert_array_equal(dark.frames[2], dark.frames[4])  # the way back shows the same degraded frames
    ratio = dark.frames.mean() / data.frames.mean()
    assert 0.05 < ratio < 0.15  # exposure 0.15 and gamma 1.3 of the homography sets' darkest frame
    argv += ["--roundtrip-conditions", "none", "light"]
    assert point_tracking.main(argv) == 0
    names = set(json.loads(capsys.readouterr().out)["datasets"])
    assert names == {f"roundtrip_{tmp_path.name}", f"roundtrip_light_{tmp_path.name}"}
    with pytest.raises(InputError, match="strength"):
        point_tracking.roundtrip_dataset(tmp_path, 4, 50, condition="light", strength=1.5)
    with pytest.raises(InputError, match=f"{tmp_path.name}.*asks for 6"):
        point_tracking.roundtrip_dataset(tmp_path, 6, 50)
    with pytest.raises(InputError, match=f"{tmp_path.name}.*asks for 4 from frame 2"):
        point_tracking.roundtrip_dataset(tmp_path, 4, 50, start=2)
    with pytest.raises(InputError, match="at least 2 frames"):
        point_tracking.roundtrip_dataset(tmp_path, 1, 50)
    with pytest.raises(InputError, match="start >= 0"):
        point_tracking.roundtrip_dataset(tmp_path, 3, 50, start=-1)
    later = point_tracking.roundtrip_dataset(tmp_path, 3, 50, start=2)  # frames 2, 3, 4, 3, 2
    for frame, t in zip(later.frames, [2, 3, 4, 3, 2], strict=True):
        np.testing.assert_array_equal(frame, cv2.imread(str(tmp_path / f"{t:05d}.png"), cv2.IMREAD_GRAYSCALE))
    large = point_tracking.roundtrip_dataset(tmp_path, 3, 50, scale=2.5)  # frames 0, 1, 2, 1, 0 enlarged
    for frame, t in zip(large.frames, [0, 1, 2, 1, 0], strict=True):
        stored = cv2.imread(str(tmp_path / f"{t:05d}.png"), cv2.IMREAD_GRAYSCALE).astype(np.float32)
        enlarged = cv2.resize(stored, (350, 300), interpolation=cv2.INTER_CUBIC).round().clip(0, 255)
        np.testing.assert_array_equal(frame, enlarged.astype(np.uint8))
    for scale in (0.5, 9.0, float("nan")):
        with pytest.raises(InputError, match="scale"):
            point_tracking.roundtrip_dataset(tmp_path, 3, 50, scale=scale)
    assert point_tracking.main([*argv, "--roundtrip-scale", "2"]) == 0
    assert json.loads(capsys.readouterr().out)["roundtrip_scale"] == 2.0
    faster = point_tracking.roundtrip_dataset(tmp_path, 3, 50, stride=2)  # frames 0, 2, 4, 2, 0
    for frame, t in zip(faster.frames, [0, 2, 4, 2, 0], strict=True):
        np.testing.assert_array_equal(frame, cv2.imread(str(tmp_path / f"{t:05d}.png"), cv2.IMREAD_GRAYSCALE))
    with pytest.raises(InputError, match=f"{tmp_path.name}.*asks for 3 from frame 1 with stride 2"):
        point_tracking.roundtrip_dataset(tmp_path, 3, 50, start=1, stride=2)  # frame 5 does not exist
    with pytest.raises(InputError, match="stride >= 1"):
        point_tracking.roundtrip_dataset(tmp_path, 3, 50, stride=0)


def test_a_homography_image_too_small_is_refused_naming_the_file(tmp_path):
    cv2.imwrite(str(tmp_path / "small.png"), np.full((20, 40), 128, np.uint8))
    with pytest.raises(InputError, match=re.escape(f"{tmp_path / 'small.png'}: the image must be")):
        point_tracking.homography_dataset(tmp_path / "small.png", "jpeg", 10)


def test_tracker_settings_reach_the_dcf_trackers(capsys):
    """``--tracker`` sets PointTracker arguments (here one that changes the tracks); an unknown one is refused."""
    base = ["--synthetic", "--frames", "4", "--points", "80", "--methods", "ccot", "--repeats", "1", "--json"]
    runs = []
    for extra in ([], ["--tracker", "patch_size=[31,15,15,15,15]", "noise_reg=0"]):
        assert point_tracking.main(base + extra) == 0
        runs.append(json.loads(capsys.readouterr().out))
    assert runs[0]["tracker"] == {} and runs[1]["tracker"] == {"patch_size": [31, 15, 15, 15, 15], "noise_reg": 0}
    epe = [r["datasets"]["synthetic"]["methods"]["ccot"]["epe_mean"] for r in runs]
    assert epe[0] != epe[1]
    assert point_tracking.main(base + ["--tracker", "colour=1"]) == 2
    assert "colour" in capsys.readouterr().err


@pytest.mark.slow  # uses an exported bundle
def test_runtime_tracker_is_a_method(tracking_bundle, capsys):
    assert point_tracking.main(["--synthetic", "--frames", "4", "--points", "40", "--repeats", "1", "--methods",
                                "ccot", "ccot_ort", "klt", "--bundle", str(tracking_bundle), "--json"]) == 0
    methods = json.loads(capsys.readouterr().out)["datasets"]["synthetic"]["methods"]
    assert methods["ccot_ort"]["speed_vs_klt"] > 0
    for key in ("epe_median", "inlier_frac", "lost_frac"):
        assert methods["ccot_ort"][key] == pytest.approx(methods["ccot"][key], abs=1e-3)


def test_sintel_conditions_add_degraded_rows_with_the_same_truth(tmp_path, capsys):
    """``--sintel DIR --sintel-conditions dark jpeg``: the plain row plus one row per condition, the frames those
    of :func:`data.flow.stress_frames`, the ground truth the flow's (a pure 2 px shift, so every evaluated point's
    truth is its start plus (2, 0))."""
    import cv2

    from data.flow import stress_frames, write_flo

    folder = tmp_path / "scene" / "clean"
    (folder / "gt").mkdir(parents=True)
    rng = np.random.default_rng(3)
    texture = cv2.GaussianBlur(rng.normal(128, 40, (100, 140)), (0, 0), 1.5).clip(0, 255)
    frames = [texture[:, 10:-10], np.roll(texture, 2, axis=1)[:, 10:-10]]  # content moves 2 px right
    for t, frame in enumerate(frames, 1):
        cv2.imwrite(str(folder / f"frame_{t:04d}.png"), frame.astype(np.uint8))
    flow = np.zeros((100, 120, 2), np.float32)
    flow[..., 0] = 2
    write_flo(folder / "gt" / "frame_0001.flo", flow)
    dark = point_tracking.sintel_dataset(folder, 60, condition="dark", seed=5)
    plain = np.stack([cv2.imread(str(folder / f"frame_{t:04d}.png"), cv2.IMREAD_GRAYSCALE) for t in (1, 2)])
    np.testing.assert_array_equal(dark.frames, stress_frames(plain, "dark", 5).round().clip(0, 255).astype(np.uint8))
    np.testing.assert_allclose(dark.truth[dark.valid], dark.points[dark.valid] + [2, 0])
    argv = ["--sintel", str(folder), "--sintel-conditions", "dark", "jpeg", "--points", "40", "--methods", "ccot",
            "klt", "--repeats", "1", "--json"]
    assert point_tracking.main(argv) == 0
    out = json.loads(capsys.readouterr().out)
    assert set(out["datasets"]) == {"scene_clean", "scene_clean_dark", "scene_clean_jpeg"}
    assert {"pairs", "pairs_dark", "pairs_jpeg"} <= set(out["summary"])
    with pytest.raises(SystemExit):  # a condition that changes the motion is not a photometric one
        point_tracking.build_parser().parse_args(["--sintel", str(folder), "--sintel-conditions", "fast_motion"])


def test_roundtrip_under_a_stress_condition(tmp_path, capsys):
    """``--roundtrip-conditions stress_dark``: the forward frames are those of :func:`data.flow.stress_frames`
    (seeded), the way back replays them, the rows are named ``roundtrip_stress_dark_<folder>``."""
    import cv2

    from data.flow import stress_frames

    rng = np.random.default_rng(2)
    texture = cv2.GaussianBlur(rng.normal(128, 40, (120, 160)), (0, 0), 1.5).clip(0, 255)
    for t in range(3):
        cv2.imwrite(str(tmp_path / f"{t:05d}.png"), np.roll(texture, 2 * t, axis=1)[:, 10:-10].astype(np.uint8))
    plain = np.stack([cv2.imread(str(tmp_path / f"{t:05d}.png"), cv2.IMREAD_GRAYSCALE) for t in range(3)])
    dark = point_tracking.roundtrip_dataset(tmp_path, 3, 40, condition="stress_dark", seed=4)
    expected = stress_frames(plain, "dark", 4).round().clip(0, 255).astype(np.uint8)
    np.testing.assert_array_equal(dark.frames, np.concatenate([expected, expected[-2::-1]]))
    argv = ["--roundtrip", str(tmp_path), "--roundtrip-frames", "3", "--roundtrip-conditions", "stress_dark",
            "--points", "30", "--methods", "ccot", "klt", "--repeats", "1", "--json"]
    assert point_tracking.main(argv) == 0
    out = json.loads(capsys.readouterr().out)
    assert set(out["datasets"]) == {f"roundtrip_stress_dark_{tmp_path.name}"}
    assert "roundtrip_stress_dark" in out["summary"]


def test_homography_under_a_stress_condition(tmp_path, capsys):
    """``--homography-conditions stress_jpeg``: the frames are the undegraded homography views under
    :func:`data.flow.stress_frames` (seeded), the truth is the homographies', the rows are named
    ``homography_stress_jpeg_<folder>_<stem>``."""
    import cv2

    from data.flow import homography_sequence, stress_frames

    rng = np.random.default_rng(3)
    texture = cv2.GaussianBlur(rng.normal(128, 40, (96, 128)), (0, 0), 1.5).clip(0, 255).astype(np.uint8)
    cv2.imwrite(str(tmp_path / "img.png"), texture)
    stressed = point_tracking.homography_dataset(tmp_path / "img.png", "stress_jpeg", 40, seed=2)
    plain = point_tracking.homography_dataset(tmp_path / "img.png", "none", 40, seed=2)
    views = homography_sequence(texture.astype(np.float32), "none", 6, 2)
    expected = stress_frames(views.frames, "jpeg", 2).round().clip(0, 255).astype(np.uint8)
    np.testing.assert_array_equal(stressed.frames, expected)
    truth, valid = views.track(stressed.points)
    np.testing.assert_allclose(stressed.truth, truth[-1])
    np.testing.assert_array_equal(stressed.valid, valid[-1])
    assert not np.array_equal(stressed.frames, plain.frames)
    argv = ["--homography", str(tmp_path / "img.png"), "--homography-conditions", "stress_jpeg", "--points", "30",
            "--methods", "ccot", "klt", "--repeats", "1", "--json"]
    assert point_tracking.main(argv) == 0
    out = json.loads(capsys.readouterr().out)
    assert set(out["datasets"]) == {f"homography_stress_jpeg_{tmp_path.name}_img"}
    assert "homography_stress_jpeg" in out["summary"]


@pytest.mark.parametrize(("name", "lines"), [
    ("homography_bear_fixed_stress_low_contrast", ["homography_bear_", "fixed_stress_low_", "contrast"]),
    ("roundtrip_dog-agility", ["roundtrip_dog-agility"]),
    ("sintel_alley_1_final_stress_dark", ["sintel_alley_1_", "final_stress_dark"]),
])
def test_plot_titles_wrap_long_names_after_underscores(name: str, lines: list[str]) -> None:
    assert point_tracking._wrapped(name, 22).split("\n") == lines


def test_detector_quality_and_spacing_set_the_start_points():
    """A lower ``quality`` admits weaker corners (a superset of the stronger ones here), every pair of points keeps
    the ``spacing`` (Chebyshev distance, brute force over all pairs) and ``--quality`` reaches the detector."""
    frame = np.random.default_rng(0).uniform(0, 255, (96, 128)).astype(np.uint8)
    frame = cv2.GaussianBlur(frame, (0, 0), 2.0)
    strong = point_tracking.Detector(spacing=2, quality=0.3)(frame, 5000)
    weak = point_tracking.Detector(spacing=2, quality=0.01)(frame, 5000)
    assert 0 < len(strong) < len(weak)
    assert {tuple(p) for p in strong} <= {tuple(p) for p in weak}
    gaps = np.abs(weak[:, None] - weak[None]).max(-1) + np.eye(len(weak)) * 1e9
    assert gaps.min() > 2
    args = point_tracking.build_parser().parse_args(["--quality", "0.3", "--spacing", "2"])
    assert (args.quality, args.spacing) == (0.3, 2)


@pytest.mark.parametrize("flags, setting", [(["--quality", "0"], {"quality": 0.0}),
                                            (["--quality", "1.5"], {"quality": 1.5}),
                                            (["--spacing", "0"], {"spacing": 0})])
def test_bad_detector_settings_are_refused(flags, setting, capsys):
    message = "spacing (--spacing) must be at least 1 px and its quality (--quality) in (0, 1)"
    assert point_tracking.main(["--synthetic", "--frames", "3", "--points", "20", *flags]) == 2
    assert message in capsys.readouterr().err
    with pytest.raises(InputError, match=re.escape(message)):  # a Detector built in code is refused as well
        point_tracking.Detector(**setting)


def test_every_method_of_a_run_is_timed_by_the_clock_of_its_device(monkeypatch):
    """Off the CPU the DCF trackers are timed by the wall clock, and so are KLT and the runtime, which stay on the
    CPU: a run's speed ratios compare one clock. A stand-in runtime tracker (no bundle export) takes 2 clock ticks."""

    class Runtime:
        def track(self, images, points):
            n = len(points)
            return np.zeros((len(images), n, 2)), np.zeros((len(images), n), bool), None

    ticks = iter(range(100))
    asked = []

    def clock(device):
        asked.append(device)
        return lambda: 2.0 * next(ticks)

    monkeypatch.setattr(point_tracking, "clock", clock)
    monkeypatch.setitem(point_tracking._ORT_TRACKERS, ("stand-in", 1), Runtime())
    frames, points = np.zeros((3, 8, 8), np.uint8), np.zeros((4, 2))
    assert point_tracking.run_ort(frames, points, "stand-in", 1, "cuda")[-1] == 2.0
    assert point_tracking.run_klt(frames, points, "cuda")[-1] == 2.0
    assert asked == ["cuda", "cuda"]
