"""bench/point_tracking_scaling.py: the line fit against closed forms, the JSON of a small run, the plot and bad
input."""

import json

import cv2
import numpy as np
import pytest

from bench import point_tracking_scaling as scaling
from core.errors import InputError


def test_fit_line_recovers_an_exact_line():
    counts = np.array([10, 100, 1000, 5000])
    line = scaling.fit_line(counts, 4.0 + 0.025 * counts)  # 4 ms per frame, 25 µs per point
    assert line["per_frame_ms"] == pytest.approx(4.0, abs=1e-9)
    assert line["per_point_us"] == pytest.approx(25.0, abs=1e-9)
    assert line["r2"] == pytest.approx(1.0, abs=1e-12)


def test_fit_line_r2_of_scattered_times_against_its_definition():
    counts = np.array([1.0, 2.0, 3.0, 4.0])
    ms = np.array([1.0, 3.0, 2.0, 5.0])
    line = scaling.fit_line(counts, ms)
    # the least-squares line through these four points by hand: slope 1.1, intercept 0.0
    assert line["per_point_us"] == pytest.approx(1100.0)
    assert line["per_frame_ms"] == pytest.approx(0.0, abs=1e-12)
    residual = ms - 1.1 * counts
    assert line["r2"] == pytest.approx(1 - (residual**2).sum() / ((ms - ms.mean()) ** 2).sum())
    assert 0 < line["r2"] < 1


def test_fit_line_needs_two_distinct_counts():
    with pytest.raises(InputError, match="two or more distinct point counts"):
        scaling.fit_line(np.array([50, 50]), np.array([1.0, 1.1]))


def test_scaling_limits_and_fixed_share_follow_from_the_lines():
    rows = [{"points": n, "methods": {"ccot": {"ms_per_frame": 10 + 0.05 * n}, "klt": {"ms_per_frame": 0.01 * n}}}
            for n in (100, 1000, 4000)]
    fits = scaling.scaling(rows, ["ccot", "klt"])
    assert fits["ccot"]["asymptotic_speed_vs_klt"] == pytest.approx(0.2)  # 10 µs against 50 µs per point
    assert fits["klt"]["asymptotic_speed_vs_klt"] == pytest.approx(1.0)
    assert fits["ccot"]["fixed_share"]["1000"] == pytest.approx(10 / 60)


def test_json_of_a_small_run_and_its_plot(tmp_path, capsys):
    png = tmp_path / "scaling.png"
    argv = ["--synthetic", "--length", "3", "--points", "5", "40", "--repeats", "1", "--json", "--plot", str(png)]
    assert scaling.main(argv) == 0
    result = json.loads(capsys.readouterr().out)
    assert [row["points"] for row in result["counts"]] == [5, 40] and result["frames"] == 3
    for row in result["counts"]:
        ccot, klt = row["methods"]["ccot"], row["methods"]["klt"]
        assert ccot["speed_vs_klt"] == ccot["point_frames_per_s"] / klt["point_frames_per_s"]
        # 2 steps of ms_per_frame each track the row's points
        assert ccot["point_frames_per_s"] == pytest.approx(row["points"] * 2 / (2 * ccot["ms_per_frame"] / 1e3))
    assert set(result["fits"]) == {"ccot", "klt"} and result["fits"]["klt"]["asymptotic_speed_vs_klt"] == 1.0
    assert png.stat().st_size > 10_000


def test_counts_above_the_detected_points_become_the_detected_count(tmp_path, capsys):
    frame = np.zeros((64, 64), np.uint8)
    frame[20:40, 20:40] = 200  # four corners
    for i in range(2):
        cv2.imwrite(str(tmp_path / f"{i:02d}.png"), frame)
    assert scaling.main(["--frames-dir", str(tmp_path), "--points", "2", "50", "--repeats", "1", "--json"]) == 0
    counts = [row["points"] for row in json.loads(capsys.readouterr().out)["counts"]]
    assert counts[0] == 2 and 2 < counts[1] < 50


def test_bad_input_is_refused_with_the_input_named(tmp_path, capsys):
    missing = tmp_path / "nowhere"
    assert scaling.main(["--frames-dir", str(missing), "--points", "5", "10"]) == 2
    assert f"no image frames found at {missing}" in capsys.readouterr().err
    for argv in (["--points", "5"], ["--points", "0", "5"], ["--length", "1"]):
        with pytest.raises(SystemExit) as exit_info:
            scaling.main(argv)
        assert exit_info.value.code == 2


def test_grid_points_are_every_step_px_in_a_seeded_order():
    points = scaling.grid_points((10, 13), 3, seed=5)
    expected = {(x, y) for y in range(1, 10, 3) for x in range(1, 13, 3)}  # from step // 2 = 1 px on
    assert len(points) == len(expected) and set(map(tuple, points.astype(int).tolist())) == expected
    np.testing.assert_array_equal(points, scaling.grid_points((10, 13), 3, seed=5))
    assert not np.array_equal(points, scaling.grid_points((10, 13), 3, seed=6))
    every = scaling.grid_points((200, 300), 1)
    assert len(every) == 200 * 300
    first = every[:400]  # a prefix covers the frame: each quarter holds about a quarter of it
    quarters = np.histogram2d(first[:, 0], first[:, 1], bins=2, range=[[0, 300], [0, 200]])[0]
    assert quarters.min() >= 70
    with pytest.raises(InputError, match="grid step"):
        scaling.grid_points((10, 10), 0)


def test_a_run_from_a_grid_names_its_start_points_and_clock(capsys):
    argv = ["--synthetic", "--length", "2", "--grid", "8", "--points", "10", "100000", "--methods", "klt",
            "--repeats", "1", "--json"]
    assert scaling.main(argv) == 0
    result = json.loads(capsys.readouterr().out)
    # the grid of a 384 x 512 frame every 8 px holds 48 * 64 points, fewer than the largest count asked
    assert [row["points"] for row in result["counts"]] == [10, 48 * 64]
    assert result["start_points"] == {"grid": 8, "seed": 0}
    assert result["device"] == "cpu" and result["clock"] == "process_cpu_time"


def test_a_device_that_is_not_there_is_refused(capsys):
    assert scaling.main(["--synthetic", "--points", "5", "10", "--device", "gpu0"]) == 2
    assert "--device 'gpu0' is not a torch device" in capsys.readouterr().err
