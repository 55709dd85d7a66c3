"""Real-image homography sequences: seeded, ground truth that holds (frame t sampled at the tracks equals frame 0
at the points), the degradation growing frame by frame, bad input refused."""

import cv2
import numpy as np
import pytest

from core.errors import InputError
from data.flow import HOMOGRAPHY_CONDITIONS, degrade, homography_sequence


def _image(h: int = 120, w: int = 160) -> np.ndarray:
    rng = np.random.default_rng(0)
    texture = cv2.GaussianBlur(rng.normal(0, 1, (h, w)), (0, 0), 2.0)
    return np.clip(128 + 40 * texture / texture.std(), 0, 255)


def _sample(frame: np.ndarray, xy: np.ndarray) -> np.ndarray:
    maps = xy.astype(np.float32)[None]
    return cv2.remap(frame, maps[..., 0], maps[..., 1], cv2.INTER_LINEAR)[0]


@pytest.mark.parametrize("condition", HOMOGRAPHY_CONDITIONS)
def test_seeded_frames_in_range(condition):
    a = homography_sequence(_image(), condition, frames=4, seed=3)
    b = homography_sequence(_image(), condition, frames=4, seed=3)
    np.testing.assert_array_equal(a.frames, b.frames)
    assert a.frames.shape == (4, 120, 160) and a.frames.dtype == np.float32
    assert a.frames.min() >= 0 and a.frames.max() <= 255
    np.testing.assert_array_equal(a.homographies[0], np.eye(3))


def test_ground_truth_follows_the_content():
    seq = homography_sequence(_image(), "none", frames=5, seed=1)
    gen = np.random.default_rng(1)
    points = gen.uniform([20, 20], [140, 100], (300, 2))
    tracks, valid = seq.track(points)
    for t in range(1, 5):
        ok = valid[t]
        assert ok.mean() > 0.5
        np.testing.assert_allclose(tracks[t], cv2.perspectiveTransform(points[None], seq.homographies[t])[0])
        moved = np.abs(_sample(seq.frames[t], tracks[t][ok]) - _sample(seq.frames[0], points[ok])).mean()
        wrong = np.abs(_sample(seq.frames[t], tracks[t][ok] + 2.0) - _sample(seq.frames[0], points[ok])).mean()
        assert moved < 2.5 and wrong > 3 * moved, (t, moved, wrong)  # the noise (std 1 per frame) is what is left


def test_fixed_camera_keeps_the_content_in_place():
    """``moving=False``: every homography the identity, the truth the start points, and each frame the moving
    sequence's degradation of the unwarped image (same seed: frame 0 equal; later frames match a direct degradation
    with the same random stream)."""
    image = _image()
    fixed = homography_sequence(image, "jpeg", frames=5, seed=4, moving=False)
    np.testing.assert_array_equal(fixed.homographies, np.broadcast_to(np.eye(3), (5, 3, 3)))
    points = np.array([[20.0, 30.0], [100.5, 60.25]])
    tracks, valid = fixed.track(points)
    np.testing.assert_allclose(tracks, np.broadcast_to(points, (5, 2, 2)))
    assert valid.all()
    moving = homography_sequence(image, "jpeg", frames=5, seed=4)
    np.testing.assert_array_equal(fixed.frames[0], moving.frames[0])
    rng = np.random.default_rng([4, HOMOGRAPHY_CONDITIONS.index("jpeg")])
    expected = [degrade(image.astype(np.float32), "jpeg", t / 4, rng) for t in range(5)]
    np.testing.assert_array_equal(fixed.frames, np.stack(expected))


def test_valid_points_stay_inside_every_frame():
    seq = homography_sequence(_image(), "none", frames=6, seed=2, step=15.0)
    points = np.array([[3.0, 60.0], [80.0, 60.0], [159.0, 119.0]])
    tracks, valid = seq.track(points)
    assert not valid[:, [0, 2]].any() and valid[0, 1]
    assert (valid[1:] <= valid[:-1]).all()  # once out, never valid again


def test_degradation_grows_over_the_frames():
    image = _image()
    blur = homography_sequence(image, "blur", frames=6).frames
    sharpness = [np.abs(cv2.Laplacian(f, cv2.CV_32F)).mean() for f in blur]
    assert all(a > b for a, b in zip(sharpness, sharpness[1:], strict=False))
    light = homography_sequence(image, "light", frames=6).frames
    assert all(a > b for a, b in zip(light.mean((1, 2)), light.mean((1, 2))[1:], strict=False))
    jpeg = homography_sequence(image, "jpeg", frames=6).frames
    none = homography_sequence(image, "none", frames=6).frames
    assert np.abs(jpeg[-1] - none[-1]).mean() > 2 * np.abs(jpeg[0] - none[0]).mean()


def test_bad_input():
    with pytest.raises(InputError, match="unknown homography condition"):
        homography_sequence(_image(), "rain")
    with pytest.raises(InputError, match="gray"):
        homography_sequence(np.zeros((40, 40, 3)), "blur")
    with pytest.raises(InputError, match="2 frames"):
        homography_sequence(_image(), "blur", frames=1)
    with pytest.raises(InputError, match=r"\(P, 2\)"):
        homography_sequence(_image(), "none", frames=2).track(np.zeros((3, 3)))


def test_motion_blur_smears_one_direction_only():
    image = _image()
    last = {}
    for name, angle in (("along x", 0.0), ("along y", np.pi / 2)):
        frames = homography_sequence(image, "motion", frames=6, seed=5, motion_angle=angle).frames
        last[name] = [np.abs(cv2.Sobel(frames[-1], cv2.CV_32F, dx, 1 - dx)).mean() for dx in (1, 0)]  # |d/dx|, |d/dy|
    assert last["along x"][0] < 0.6 * last["along y"][0]  # the x-derivative suffers from a streak along x
    assert last["along y"][1] < 0.6 * last["along x"][1]


def test_degrade_refuses_unknown_conditions_and_strengths():
    rng = np.random.default_rng(0)
    with pytest.raises(InputError, match="fog"):
        degrade(_image(), "fog", 0.5, rng)
    for strength in (-0.1, 1.2, float("nan")):
        with pytest.raises(InputError, match="strength"):
            degrade(_image(), "blur", strength, rng)


def _step_rotation_and_scale(chain: np.ndarray, width: int, height: int) -> np.ndarray:
    """Per step ``(T - 1, 2)``: rotation (rad) and log scale of the step's affine part about the image centre."""
    centre = np.array([[1.0, 0.0, -width / 2], [0.0, 1.0, -height / 2], [0.0, 0.0, 1.0]])
    out = []
    for before, after in zip(chain[:-1], chain[1:], strict=True):
        move = centre @ after @ np.linalg.inv(before) @ np.linalg.inv(centre)
        move = move / move[2, 2]
        out.append([np.arctan2(move[1, 0], move[0, 0]), np.log(np.hypot(move[0, 0], move[1, 0]))])
    return np.array(out)


def test_geometry_multiplies_each_steps_rotation_and_scale():
    """The same seed's steps turn and zoom ``geometry`` times as far, read back from the chained homographies;
    ``geometry`` 0 without translation keeps the camera still."""
    image = _image()
    base = homography_sequence(image, "none", frames=5, seed=6).homographies
    fast = homography_sequence(image, "none", frames=5, seed=6, geometry=3.0).homographies
    still = homography_sequence(image, "none", frames=5, seed=6, geometry=0.0, step=0.0).homographies
    a, b = _step_rotation_and_scale(base, 160, 120), _step_rotation_and_scale(fast, 160, 120)
    assert np.abs(a[:, 0]).max() > np.deg2rad(0.5)  # the steps do turn
    np.testing.assert_allclose(b, 3 * a, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(still, np.broadcast_to(np.eye(3), still.shape), atol=1e-12)


@pytest.mark.parametrize("geometry", [-1.0, float("nan"), float("inf")])
def test_bad_geometry_refused(geometry):
    with pytest.raises(InputError, match="geometry multiplier"):
        homography_sequence(_image(), "none", frames=3, geometry=geometry)


def test_step_scales_each_steps_translation():
    """The same seed's chain with ``step`` 5 times larger and no turn (``geometry`` 0) moves 5 times as far in
    every step: pure translations, read back from the chained homographies."""
    image = _image()
    slow = homography_sequence(image, "none", frames=5, seed=2, geometry=0.0, step=2.0).homographies
    fast = homography_sequence(image, "none", frames=5, seed=2, geometry=0.0, step=10.0).homographies
    moves = [np.diff(h[:, :2, 2], axis=0) for h in (slow, fast)]
    assert np.abs(moves[0]).max() > 0.5 and np.abs(moves[0]).max() <= 2.0  # within +-step per axis
    np.testing.assert_allclose(moves[1], 5 * moves[0], rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(fast[:, :2, :2], np.broadcast_to(np.eye(2), (5, 2, 2)), atol=1e-12)


@pytest.mark.parametrize("step", [-1.0, float("nan"), float("inf")])
def test_bad_step_refused(step):
    with pytest.raises(InputError, match="translation step"):
        homography_sequence(_image(), "none", frames=3, step=step)
