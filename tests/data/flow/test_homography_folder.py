"""Homography folders (Oxford and HPatches layouts): frames in index order, homographies from the first frame that
map its content where it is (checked by resampling the frames and against OpenCV), frames of different sizes padded
with their own bounds kept, bad folders refused by name."""

import cv2
import numpy as np
import pytest

from core.errors import InputError
from data.flow import read_homography, read_homography_folder


def _texture(h: int = 90, w: int = 120) -> np.ndarray:
    rng = np.random.default_rng(0)
    texture = cv2.GaussianBlur(rng.normal(0, 1, (h, w)), (0, 0), 2.0)
    return np.clip(128 + 40 * texture / texture.std(), 0, 255).astype(np.float32)


def _homographies(count: int) -> np.ndarray:
    """``(count, 3, 3)`` homographies from frame 1: a small rotation, scale, shift and tilt growing per frame."""
    out = []
    for k in range(count):
        angle, scale = np.deg2rad(1.5 * k), 1 + 0.02 * k
        c, s = scale * np.cos(angle), scale * np.sin(angle)
        out.append(np.array([[c, -s, 2.5 * k], [s, c, -1.5 * k], [1e-5 * k, -2e-5 * k, 1.0]]))
    return np.stack(out)


def _write(folder, names: list[str], h_names: list[str], scale: float = 1.0, color: bool = False) -> np.ndarray:
    """Frames of the texture seen through :func:`_homographies` as ``names`` and the homographies from the first
    (times ``scale``, which must not matter) as ``h_names``; the frames as uint8 ``(T, H, W)``."""
    folder.mkdir(exist_ok=True)
    image, chain = _texture(), _homographies(len(names))
    frames = np.stack([cv2.warpPerspective(image, h, image.shape[::-1], flags=cv2.INTER_LINEAR,
                                           borderMode=cv2.BORDER_REFLECT) for h in chain]).round().astype(np.uint8)
    for name, frame in zip(names, frames, strict=True):
        cv2.imwrite(str(folder / name), cv2.cvtColor(frame, cv2.COLOR_GRAY2BGR) if color else frame)
    for name, h in zip(h_names, chain[1:], strict=True):
        np.savetxt(folder / name, scale * h)
    return frames


def test_oxford_layout_frames_and_truth(tmp_path):
    names = [f"img{k}.ppm" for k in range(1, 5)]
    frames = _write(tmp_path / "bikes", names, [f"H1to{k}p" for k in range(2, 5)], scale=3.0, color=True)
    seq = read_homography_folder(tmp_path / "bikes")
    np.testing.assert_array_equal(seq.frames, frames)
    assert seq.frames.dtype == np.float32
    np.testing.assert_allclose(seq.homographies, _homographies(4), rtol=1e-9, atol=1e-12)
    points = np.random.default_rng(1).uniform([25, 25], [95, 65], (200, 2))
    tracks, valid = seq.track(points)
    for t in range(1, 4):
        expected = cv2.perspectiveTransform(points[None], _homographies(4)[t])[0]
        np.testing.assert_allclose(tracks[t], expected, atol=1e-9)
        ok = valid[t]
        assert ok.mean() > 0.5
        # the content of frame 1 at the points is where the homography puts it in frame t
        maps = tracks[t][ok].astype(np.float32)[None]
        moved = cv2.remap(seq.frames[t], maps[..., 0], maps[..., 1], cv2.INTER_LINEAR)[0]
        start = cv2.remap(seq.frames[0], *points[ok].astype(np.float32)[None].transpose(2, 0, 1), cv2.INTER_LINEAR)[0]
        assert np.median(np.abs(moved - start)) < 2.0


def test_hpatches_layout_and_index_order(tmp_path):
    """``1.png ... N.png`` with ``H_1_k`` reads as the Oxford layout does; frames are ordered by index (10 after 2,
    not by name)."""
    oxford = _write(tmp_path / "a", ["img1.png", "img2.png", "img10.png"], ["H1to2p", "H1to10p"])
    _write(tmp_path / "b", ["1.png", "2.png", "10.png"], ["H_1_2", "H_1_10.txt"])
    a, b = read_homography_folder(tmp_path / "a"), read_homography_folder(tmp_path / "b")
    np.testing.assert_array_equal(a.frames, oxford)
    np.testing.assert_array_equal(b.frames, oxford)
    np.testing.assert_allclose(a.homographies, b.homographies)
    np.testing.assert_allclose(a.homographies, _homographies(3), rtol=1e-9, atol=1e-12)


def test_read_homography_scales_and_refuses(tmp_path):
    good = tmp_path / "H"
    np.savetxt(good, 2.0 * _homographies(3)[2])
    np.testing.assert_allclose(read_homography(good), _homographies(3)[2], rtol=1e-12)
    cases = {"short": "1 0 0\n0 1 0\n", "text": "1 0 0\n0 one 0\n0 0 1\n", "nan": "1 0 0\n0 nan 0\n0 0 1\n",
             "singular": "1 2 3\n2 4 6\n0 0 1\n"}
    for name, text in cases.items():
        (tmp_path / name).write_text(text)
        with pytest.raises(InputError, match=name):
            read_homography(tmp_path / name)


def test_frames_of_different_sizes_are_padded_and_keep_their_own_bounds(tmp_path):
    """A smaller frame is padded at the bottom and right (its border repeated) to the largest size; a point is
    valid only 6 px inside its own frame, not in the padding."""
    frames = _write(tmp_path / "v", ["1.png", "2.png", "3.png"], ["H_1_2", "H_1_3"])
    small = frames[2, :70, :100]
    cv2.imwrite(str(tmp_path / "v" / "3.png"), small)
    seq = read_homography_folder(tmp_path / "v")
    assert seq.frames.shape == (3, 90, 120)
    np.testing.assert_array_equal(seq.frames[2, :70, :100], small)
    np.testing.assert_array_equal(seq.frames[2, 70:, :100], np.broadcast_to(small[-1], (20, 100)))
    np.testing.assert_array_equal(seq.frames[2, :, 100:], np.broadcast_to(seq.frames[2, :, 99:100], (90, 20)))
    np.testing.assert_array_equal(seq.sizes, [[90, 120], [90, 120], [70, 100]])
    points = np.random.default_rng(2).uniform([8, 8], [112, 82], (400, 2))
    tracks, valid = seq.track(points)
    x, y = tracks[2, :, 0], tracks[2, :, 1]
    inside_small = (x >= 6) & (x <= 99 - 6) & (y >= 6) & (y <= 69 - 6)
    np.testing.assert_array_equal(valid[2], valid[1] & inside_small)
    assert valid[1].sum() > valid[2].sum() > 0


@pytest.mark.parametrize("case", ["missing", "one_frame", "no_homography", "bad_homography", "twice", "no_index"])
def test_bad_folders_are_refused_by_name(tmp_path, case):
    folder = tmp_path / case
    if case != "missing":
        names = ["img1.png"] if case == "one_frame" else ["img1.png", "img2.png", "img3.png"]
        _write(folder, names, [] if case == "one_frame" else ["H1to2p", "H1to3p"])
    expected = {"missing": "not found", "one_frame": "at least 2 frames", "no_homography": "H1to3p, H1to3p.txt",
                "bad_homography": "H1to2p", "twice": "share an index", "no_index": "first.png"}
    if case == "no_homography":
        (folder / "H1to3p").unlink()
    elif case == "bad_homography":
        (folder / "H1to2p").write_text("1 0 0\n0 1 0\n")
    elif case == "twice":
        cv2.imwrite(str(folder / "1.png"), np.zeros((90, 120), np.uint8))
    elif case == "no_index":
        cv2.imwrite(str(folder / "first.png"), np.zeros((90, 120), np.uint8))
    with pytest.raises(InputError, match=expected[case]) as err:
        read_homography_folder(folder)
    assert case in str(err.value)  # the folder (or a file in it) is named
