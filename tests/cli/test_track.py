"""``infer.py track`` end to end on small synthetic frames, and its one-line errors for bad input."""

import subprocess
import sys

import cv2
import numpy as np
import pytest

import infer
from data.flow import synthetic_sequence
from tests.cli.conftest import ROOT


@pytest.fixture(scope="module")
def frame_dir(tmp_path_factory):
    folder = tmp_path_factory.mktemp("frames")
    seq = synthetic_sequence(frames=4, size=(96, 128), max_motion=4.0, seed=2)
    for t, frame in enumerate(seq.frames):
        cv2.imwrite(str(folder / f"f_{t:03d}.png"), frame.round().astype(np.uint8))
    return folder, seq


@pytest.mark.parametrize("method", ["ccot", "klt"])
def test_track_detect_and_points(frame_dir, tmp_path, method, capsys):
    folder, seq = frame_dir
    out = tmp_path / "tracks.npz"
    assert (
        infer.main(
            ["track", "--frames", str(folder), "--detect", "30", "--method", method, "--out", str(out)]
        )
        == 0
    )
    printed = capsys.readouterr().out
    assert ("first frame pair" in printed) == (method == "ccot")  # first-call latency and steady speed
    data = np.load(out)
    assert "frame_seconds" not in data  # timings are printed, the tracks file stays deterministic
    assert data["tracks"].shape[:2] == (4, len(data["points"])) and 10 <= len(data["points"]) <= 30
    truth, valid = seq.track(data["points"])
    ok = valid[-1] & ~data["lost"][-1]
    assert ok.mean() > 0.5
    assert np.median(np.linalg.norm(data["tracks"][-1] - truth[-1], axis=1)[ok]) < 1.5
    np.savetxt(tmp_path / "p.txt", [[40.0, 50.0], [-10.0, 5.0]])
    video = tmp_path / "o.mp4"
    args = [
        "track",
        "--frames",
        str(folder / "*.png"),
        "--points",
        str(tmp_path / "p.txt"),
        "--method",
        method,
    ]
    assert infer.main([*args, "--out", str(out), "--video", str(video)]) == 0
    assert np.load(out)["lost"][:, 1].all()  # outside the image: lost, not silently kept
    assert video.stat().st_size > 0


def test_track_reads_a_video_file(frame_dir, tmp_path, capsys):
    # the frames as an MPEG-4 video (lossy), tracked against the synthetic sequence's ground truth
    folder, seq = frame_dir
    video = tmp_path / "clip.mp4"
    writer = cv2.VideoWriter(str(video), cv2.VideoWriter_fourcc(*"mp4v"), 10.0, (128, 96))
    for frame in seq.frames:
        writer.write(cv2.cvtColor(frame.round().astype(np.uint8), cv2.COLOR_GRAY2BGR))
    writer.release()
    out = tmp_path / "tracks.npz"
    assert infer.main(["track", "--frames", str(video), "--detect", "30", "--out", str(out)]) == 0
    data = np.load(out)
    assert list(data["frames"]) == [f"{video}#{t}" for t in range(4)]
    truth, valid = seq.track(data["points"])
    ok = valid[-1] & ~data["lost"][-1]
    assert ok.mean() > 0.5
    assert np.median(np.linalg.norm(data["tracks"][-1] - truth[-1], axis=1)[ok]) < 1.5
    capsys.readouterr()
    (tmp_path / "broken.mp4").write_bytes(b"not a video at all")
    assert infer.main(["track", "--frames", str(tmp_path / "broken.mp4"), "--detect", "5", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "broken.mp4: not a readable video" in err and err.count("\n") == 1, err


def test_a_broken_video_ends_in_one_stderr_line(tmp_path):
    # FFmpeg's own log lines go to the process's stderr, which only a subprocess shows
    (tmp_path / "broken.mp4").write_bytes(b"not a video at all")
    argv = ["track", "--frames", str(tmp_path / "broken.mp4"), "--detect", "5", "--out", str(tmp_path / "t.npz")]
    proc = subprocess.run([sys.executable, str(ROOT / "infer.py"), *argv], cwd=ROOT, capture_output=True, text=True)
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1, proc.stderr
    assert not (tmp_path / "t.npz").exists()


def test_track_errors(frame_dir, tmp_path, capsys):
    folder, _ = frame_dir
    out = str(tmp_path / "t.npz")
    (tmp_path / "empty.txt").write_text("# nothing\n")
    (tmp_path / "bad.txt").write_text("1 2\n3\n")
    odd = tmp_path / "odd"
    odd.mkdir()
    cv2.imwrite(str(odd / "a.png"), np.zeros((40, 50), np.uint8))
    cv2.imwrite(str(odd / "b.png"), np.zeros((41, 50), np.uint8))
    cases = [
        (["--frames", str(tmp_path / "none"), "--detect", "5"], "no image frames"),
        (["--frames", str(folder), "--points", str(tmp_path / "empty.txt")], "empty"),
        (["--frames", str(folder), "--points", str(tmp_path / "bad.txt")], "cannot read points"),
        (["--frames", str(odd), "--detect", "5"], "has size"),
        (["--frames", str(folder), "--points", str(tmp_path / "missing.npy")], "not found"),
    ]
    for args, message in cases:
        assert infer.main(["track", *args, "--out", out]) == 2
        err = capsys.readouterr().err
        assert message in err and err.count("\n") == 1, err


@pytest.mark.slow  # uses an exported bundle
def test_track_with_a_bundle_runs_the_runtime(frame_dir, tracking_bundle, tmp_path, capsys):
    from runtime.tracking import track_files

    folder, _ = frame_dir
    assert infer.main(["track", "--frames", str(folder), "--detect", "20", "--onnx", str(tracking_bundle), "--out",
                       str(tmp_path / "cli.npz")]) == 0
    assert "onnxruntime" in capsys.readouterr().out
    track_files(tracking_bundle, folder, tmp_path / "runtime.npz", detect=20)
    assert (tmp_path / "cli.npz").read_bytes() == (tmp_path / "runtime.npz").read_bytes()
    # PyTorch starts from the runtime's points, so the two paths' tracks can be compared point by point
    assert infer.main(["track", "--frames", str(folder), "--detect", "20", "--out", str(tmp_path / "torch.npz")]) == 0
    np.testing.assert_array_equal(np.load(tmp_path / "torch.npz")["points"], np.load(tmp_path / "cli.npz")["points"])
