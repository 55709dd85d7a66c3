"""The runtime's point tracker: its command, run without torch, against the PyTorch tracker on the same frames
and start points (tracks within 0.01 px, the same lost flags), through blur and motion-blur changes too, OpenCV's
start points, a lone point, a point that an occluder hides and uncovers, frames compressed into flat blocks, a
noisy sequence on the low-SNR graphs, a fast-turning camera, frames that do not fit the bundle."""

import cv2
import numpy as np
import pytest
import torch

from core.errors import InputError
from core.frames import read_frames
from core.good_features import good_features
from core.streak import streak_blur
from data.flow import homography_sequence, synthetic_sequence
from models.tracking import PointTracker
from models.tracking.blur import radial_power_profile, relative_blur
from models.tracking.compression import block_grid_ratio
from models.tracking.motion_blur import motion_blur_streak
from runtime.tracking import OnnxPointTracker
from tests.models.tracking.test_blur import textured
from tests.models.tracking.test_point_tracker import (
    _fine_texture_pair,
    _noisy_sequence,
    _smooth_image,
    _translate,
    weakening_streak_frames,
)

pytestmark = pytest.mark.slow  # uses an exported bundle


@pytest.fixture(scope="module")
def frames(tmp_path_factory):
    folder = tmp_path_factory.mktemp("frames")
    seq = synthetic_sequence(frames=6, size=(96, 128), max_motion=4.0, seed=2)
    for t, frame in enumerate(seq.frames):
        cv2.imwrite(str(folder / f"f_{t:03d}.png"), frame.round().astype(np.uint8))
    return folder


def _pytorch_tracks(folder, points: np.ndarray):
    images, _ = read_frames(folder)
    tracks, lost, psr = PointTracker("ccot").track([torch.from_numpy(f) for f in images],
                                                   torch.from_numpy(points).float())
    return tracks.numpy(), lost.numpy(), psr.numpy()


def _assert_tracks_as_pytorch(bundle, images: list[np.ndarray], start: np.ndarray,
                              tracker: PointTracker | None = None) -> None:
    """The runtime's lost flags equal PyTorch's (``tracker``, default ``PointTracker("ccot")``) and its positions
    lie within 0.01 px of them."""
    tracks, lost, _ = OnnxPointTracker(bundle, threads=1).track(images, start)
    tracker = PointTracker("ccot") if tracker is None else tracker
    ref_tracks, ref_lost, _ = tracker.track([torch.from_numpy(f) for f in images], torch.from_numpy(start).float())
    np.testing.assert_array_equal(lost, ref_lost.numpy())
    assert np.abs(tracks - ref_tracks.numpy()).max() < 0.01


def test_command_without_torch_matches_pytorch(torch_free, tracking_bundle, frames, tmp_path) -> None:
    points = np.random.default_rng(0).uniform([4, 4], [124, 92], (60, 2))
    points[0] = (-5, 10)  # outside: lost from the start
    np.save(tmp_path / "points.npy", points)
    torch_free("runtime.tracking", "--bundle", tracking_bundle, "--frames", frames, "--points",
               tmp_path / "points.npy", "--out", tmp_path / "tracks.npz")
    data = np.load(tmp_path / "tracks.npz")
    tracks, lost, psr = _pytorch_tracks(frames, points)
    assert str(data["method"]) == "ccot" and data["tracks"].shape == (6, 60, 2)
    np.testing.assert_array_equal(data["lost"], lost)
    assert np.abs(data["tracks"] - tracks).max() < 0.01
    assert data["lost"][0, 0] and not data["lost"][-1, 1:].all()
    np.testing.assert_allclose(data["psr"][1:], psr[1:], rtol=1e-3)


def test_detected_points_are_opencvs_good_features(torch_free, tracking_bundle, frames, tmp_path) -> None:
    proc = torch_free("runtime.tracking", "--bundle", tracking_bundle, "--frames", frames, "--detect", "25", "--out",
                      tmp_path / "tracks.npz")
    data = np.load(tmp_path / "tracks.npz")
    assert f"{len(data['lost'])}/{len(data['lost'])} frames" in proc.stderr  # the progress line
    first = read_frames(frames)[0][0]
    np.testing.assert_array_equal(data["points"], good_features(first, 25))
    expected = cv2.goodFeaturesToTrack(first.astype(np.uint8), 25, 0.01, 5).reshape(-1, 2)
    np.testing.assert_allclose(data["points"], expected)


def test_a_lone_point_and_bad_frames(tracking_bundle, frames) -> None:
    images, _ = read_frames(frames)
    tracker = OnnxPointTracker(tracking_bundle, threads=1)
    start = np.array([[60.0, 40.0]])
    tracks, lost, _ = tracker.track(images, start)
    ref_tracks, ref_lost, _ = _pytorch_tracks(frames, start)
    assert tracks.shape == (6, 1, 2) and np.abs(tracks - ref_tracks).max() < 0.01
    np.testing.assert_array_equal(lost, ref_lost)
    with pytest.raises(InputError, match=r"frame 0 is \(40, 64\)"):
        tracker.track([np.zeros((40, 64))], start)
    with pytest.raises(InputError, match="frame 1 has size"):
        tracker.track([images[0], images[0][:, :100]], start)
    with pytest.raises(InputError, match="no good features"):
        good_features(np.zeros((96, 128)), 10)


def test_blur_matching_branches_match_pytorch(tracking_bundle) -> None:
    """A defocus that sets in and wears off again: the runtime takes the same retrain and blurred-search branches
    as PyTorch (checked to happen) and gives the same tracks."""
    seq = synthetic_sequence(frames=4, size=(96, 128), max_motion=3.0, blur=0.0, seed=4)
    sigmas = (0.0, 2.5, 2.5, 0.0)  # blur variance changes of +6.25 and -6.25 px^2, beyond the 2 px^2 threshold
    images = [cv2.GaussianBlur(f, (0, 0), s) if s else f for f, s in zip(seq.frames.astype(np.float32), sigmas,
                                                                          strict=True)]
    profiles = radial_power_profile(torch.from_numpy(np.stack(images))[:, None])
    blurrier, sharper = relative_blur(profiles[[0, 2]], profiles[[1, 3]])
    assert blurrier > 2 and sharper < -2
    start = np.random.default_rng(1).uniform([10, 10], [118, 86], (40, 2))
    _assert_tracks_as_pytorch(tracking_bundle, images, start)


@pytest.mark.parametrize("size", [(96, 128), (144, 160)])
def test_streak_matching_branches_match_pytorch(tracking_bundle, size) -> None:
    """A motion blur that sets in, grows, turns and stops: the runtime finds the same streaks (its ``streak`` graph
    against PyTorch's), takes the same cross-blurred steps and gives the same tracks; at 144 x 160 the quarters
    are large enough to find the streaks uniform (matched beyond ``blur_match``), in both alike."""
    seq = synthetic_sequence(frames=5, size=size, max_motion=3.0, blur=0.0, seed=5)
    streaks = (None, (8.0, 0.4), (11.0, 0.5), (9.0, 2.0), None)  # changes beyond the 4 px^2 threshold
    images = [f if s is None else streak_blur(f, *s) for f, s in zip(seq.frames.astype(np.float32), streaks,
                                                                      strict=True)]
    tracker = OnnxPointTracker(tracking_bundle, threads=1)
    found = [tracker._streak(f[None, None]) for f in images]
    assert [s is None for s in found] == [s is None for s in streaks]
    reference = torch.stack([torch.from_numpy(f) for f in images])[:, None]
    readings = np.stack([tracker.streak_graph(f[None, None])[0] for f in images])
    np.testing.assert_allclose(readings[:, :4], motion_blur_streak(reference).numpy(), rtol=1e-3, atol=1e-3)
    np.testing.assert_allclose(readings[:, 4], block_grid_ratio(reference).numpy(), rtol=1e-4)
    uniform = [tracker._uniform(f[None, None], s) for f, s in zip(images, found, strict=True)]
    assert uniform == [PointTracker("ccot")._uniform(torch.from_numpy(f)[None, None], s)
                       for f, s in zip(images, found, strict=True)]
    assert any(uniform) == (size == (144, 160))
    start = np.random.default_rng(2).uniform([10, 10], [size[1] - 10, size[0] - 10], (40, 2))
    tracks, lost, _ = tracker.track(images, start)
    ref_tracks, ref_lost, _ = PointTracker("ccot").track([torch.from_numpy(f) for f in images],
                                                         torch.from_numpy(start).float())
    np.testing.assert_array_equal(lost, ref_lost.numpy())
    assert np.abs(tracks - ref_tracks.numpy()).max() < 0.01


def test_a_blocked_frame_as_in_pytorch(tracking_bundle) -> None:
    """Frames compressed until their 8 px blocks are nearly flat (JPEG quality 2) between clean ones: the step
    graph drops the two finest levels' corrections where PyTorch does (checked to happen) and tracks alike."""
    seq = synthetic_sequence(frames=4, size=(96, 128), max_motion=3.0, seed=6)
    images = [f.round().astype(np.uint8) for f in seq.frames]
    images[1:3] = [cv2.imdecode(cv2.imencode(".jpg", f, [cv2.IMWRITE_JPEG_QUALITY, 2])[1], cv2.IMREAD_GRAYSCALE)
                   for f in images[1:3]]
    images = [f.astype(np.float32) for f in images]
    tracker = PointTracker("ccot")
    blocked = [float(block_grid_ratio(torch.from_numpy(f)[None, None])) > tracker.block_limit for f in images]
    assert blocked == [False, True, True, False]
    start = np.random.default_rng(3).uniform([10, 10], [118, 86], (40, 2))
    _assert_tracks_as_pytorch(tracking_bundle, images, start, tracker)


@pytest.mark.parametrize("blur", [0.0, 2.0])
def test_a_lost_point_comes_back_as_in_pytorch(tracking_bundle, blur) -> None:
    """A disc hides one point in frames 2-3 and is gone from frame 4: the runtime loses it and brings it back in
    the same frames as PyTorch, with the same tracks and PSRs; with the frames from 4 on blurred, both retrain the
    tracked points' filters while the hidden point keeps the ones it was lost with (its PSR tells)."""
    img = _smooth_image(160, 160, 8)
    ys, xs = np.mgrid[:160, :160]
    disc = torch.from_numpy((xs - 46.0) ** 2 + (ys - 44.0) ** 2 <= 24.0**2)
    frames = [_translate(img, 3.0 * t, 2.0 * t) for t in range(7)]
    frames[2:4] = [torch.where(disc, _smooth_image(160, 160, 9), f) for f in frames[2:4]]
    images = [f.float().numpy() for f in frames]
    images[4:] = [cv2.GaussianBlur(f, (0, 0), blur) if blur else f for f in images[4:]]
    start = np.array([[40.0, 40.0], [100.0, 60.0], [120.0, 120.0], [60.0, 110.0], [110.0, 30.0]])
    tracks, lost, psr = OnnxPointTracker(tracking_bundle, threads=1).track(images, start)
    ref = PointTracker("ccot").track([torch.from_numpy(f) for f in images], torch.from_numpy(start).float())
    np.testing.assert_array_equal(lost, ref[1].numpy())
    assert np.abs(tracks - ref[0].numpy()).max() < 0.01
    np.testing.assert_allclose(psr[1:], ref[2][1:].numpy(), rtol=1e-3)
    assert lost[2:4, 0].all() and lost[-1, 0] == bool(blur)  # back unless the blur hides it from its old filters


def test_a_noisy_sequence_runs_on_the_low_snr_graphs_as_in_pytorch(tracking_bundle) -> None:
    """Noise of std 20 on a moving texture: the ``snr`` graph sends the sequence to the low-SNR pair of graphs, as
    PyTorch hands it to its twin (checked), and both track alike; a clean first frame stays on the usual pair."""
    frames, points, _ = _noisy_sequence(20.0)
    images, start = [f.float().numpy() for f in frames], points.float().numpy()
    reference = PointTracker("ccot")
    assert reference.init(torch.from_numpy(images[0]), torch.from_numpy(start)).low_snr
    tracker = OnnxPointTracker(tracking_bundle, threads=1)
    tracks, lost, _ = tracker.track(images, start)
    assert tracker.on_low_snr_graphs
    ref_tracks, ref_lost, _ = reference.track([torch.from_numpy(f) for f in images], torch.from_numpy(start))
    np.testing.assert_array_equal(lost, ref_lost.numpy())
    assert np.abs(tracks - ref_tracks.numpy()).max() < 0.01
    clean, _, _ = _noisy_sequence(0.0)
    tracker.track([f.float().numpy() for f in clean[:2]], start)
    assert not tracker.on_low_snr_graphs and tracker.step_graph is tracker._graphs(False)[1]


@pytest.mark.parametrize("degrees", [0.0, 6.0])
def test_a_first_step_in_under_read_noise_runs_again_on_the_low_snr_graphs_as_in_pytorch(tracking_bundle,
                                                                                        degrees) -> None:
    """Dark frames stored as JPEG at quality 90 (``_fine_texture_pair``): the ``snr`` graph keeps the usual pair,
    the first step's PSRs and the ``first_step_noise`` graph send the sequence to the low-SNR graphs, as PyTorch
    retries its first step with the twin (checked), and both track alike, over a third frame (the first again) too,
    on the noise floor that step measured. With the second frame turned by 6 degrees the retried step is turn
    matched on the low-SNR graphs, tracked again on the usual pair from the turn it gave and retried again there
    (the runtime crashed here on the two pairs' filter shapes), and the third frame turns back."""
    frames, points, _ = _fine_texture_pair("dark_jpeg", degrees)
    images, start = [f.float().numpy() for f in (*frames, frames[0])], points.float().numpy()
    reference = PointTracker("ccot")
    tensors = [torch.from_numpy(f) for f in images]
    state = reference.init(tensors[0], torch.from_numpy(start))
    assert not state.low_snr
    state = reference.step(tensors[1], state)
    assert state.low_snr
    tracker = OnnxPointTracker(tracking_bundle, threads=1)
    tracks, lost, _ = tracker.track(images, start)
    assert tracker.on_low_snr_graphs
    ref_tracks, ref_lost, _ = reference.track(tensors, torch.from_numpy(start))
    np.testing.assert_array_equal(lost, ref_lost.numpy())
    assert np.abs(tracks - ref_tracks.numpy()).max() < 0.01


def test_a_turning_first_step_retried_without_noise_returns_to_the_usual_graphs_as_in_pytorch(tracking_bundle):
    """The low-contrast pair turned by 8 degrees: the first step runs again on the low-SNR graphs, its turn sends it
    back to the usual pair, where the retry no longer fires (PyTorch keeps its tracker, checked), and the runtime
    ends on the usual pair with PyTorch's tracks, over a third frame (the first again) too."""
    frames, points, _ = _fine_texture_pair("low_contrast", 8.0)
    images, start = [f.float().numpy() for f in (*frames, frames[0])], points.float().numpy()
    reference = PointTracker("ccot")
    tensors = [torch.from_numpy(f) for f in images]
    assert not reference.step(tensors[1], reference.init(tensors[0], torch.from_numpy(start))).low_snr
    tracker = OnnxPointTracker(tracking_bundle, threads=1)
    tracks, lost, _ = tracker.track(images, start)
    assert not tracker.on_low_snr_graphs
    ref_tracks, ref_lost, _ = reference.track(tensors, torch.from_numpy(start))
    np.testing.assert_array_equal(lost, ref_lost.numpy())
    assert np.abs(tracks - ref_tracks.numpy()).max() < 0.01


def test_a_weakening_streak_continues_as_in_pytorch(tracking_bundle) -> None:
    """Frame 5's weak streak reading (``weakening_streak_frames``) continues frame 4's streak in the runtime too:
    the same lost flags and positions within 0.01 px as PyTorch's, whose step matches that streak."""
    images = weakening_streak_frames()
    start = np.random.default_rng(4).uniform([30, 30], [290, 210], (40, 2))
    _assert_tracks_as_pytorch(tracking_bundle, images, start)


def test_a_fast_turning_camera_is_turn_matched_as_in_pytorch(tracking_bundle) -> None:
    """A texture through homographies that turn by up to 10 degrees and zoom by up to 15 % a frame: the runtime
    tracks the steps again from the turned previous frame where PyTorch does (``cv2.warpAffine`` for kornia's
    warp: positions within 0.01 px, the same lost flags), and the turn matching does move the tracks (by more than
    a pixel against PyTorch without it)."""
    seq = homography_sequence(textured(192, 256, 0), "none", frames=6, seed=21, geometry=5.0)
    images = [f.astype(np.float32) for f in seq.frames]
    xs, ys = np.arange(40.0, 217.0, 12.0), np.arange(40.0, 153.0, 12.0)
    start = np.stack(np.meshgrid(xs, ys), -1).reshape(-1, 2).astype(np.float32)
    _assert_tracks_as_pytorch(tracking_bundle, images, start)
    tracks, _, _ = OnnxPointTracker(tracking_bundle, threads=1).track(images, start)
    unmatched, _, _ = PointTracker("ccot", turn_match=None).track([torch.from_numpy(f) for f in images],
                                                                   torch.from_numpy(start))
    assert np.abs(tracks - unmatched.numpy()).max() > 1.0


def test_a_large_frame_searches_the_fifth_level_as_in_pytorch(tracking_bundle) -> None:
    """A 704 px frame moved by (50, -45) px: the runtime takes the ``*_large`` graphs, whose fifth level searches
    where PyTorch's does (its image is large enough, checked), and tracks alike, every point home; a smaller frame
    takes the 4-level graphs."""
    image = _smooth_image(704, 704, 3)
    images = [image.float().numpy(), _translate(image, 50.0, -45.0).float().numpy()]
    tracker = PointTracker("ccot")
    assert tracker._level_gate(torch.zeros(1, 1, 44, 44), 4) is True  # the fifth-level image of a 704 px frame
    start = np.random.default_rng(5).uniform([200, 200], [500, 500], (20, 2))
    _assert_tracks_as_pytorch(tracking_bundle, images, start, tracker)
    runtime = OnnxPointTracker(tracking_bundle, threads=1)
    tracks, lost, _ = runtime.track(images, start)
    assert runtime.large and not lost[-1].any() and np.abs(tracks[-1] - (start + [50.0, -45.0])).max() < 0.1
    runtime.track([image[:656].float().numpy() for image in (image, _translate(image, 2.0, 1.0))], start - 100)
    assert not runtime.large  # 656 px: one short of the bundle's large_min_side
