"""zoom_on_object: a window of 1/zoom of the frame around the object's centroid, resized back (against OpenCV's
bilinear resize of the same window, and OpenCV's black border below zoom 1); SequenceTrainingSamples' zoomed test
frames."""

import cv2
import numpy as np
import pytest
import torch

from core.errors import InputError
from data.vos.datamodule import SequenceTrainingSamples
from data.vos.zoom import zoom_on_object, zoom_window
from tests.data.vos.test_datamodule import FakeSequence


def _block(h: int, w: int, top: int, left: int, size: int) -> torch.Tensor:
    mask = torch.zeros(h, w)
    mask[top : top + size, left : left + size] = 1
    return mask


def test_window_is_centred_on_the_object_and_kept_inside_the_frame() -> None:
    assert zoom_window(_block(24, 32, 10, 14, 4), 2.0) == (0 + 12 - 6, 16 - 8, 12, 16)  # centroid (11.5, 15.5)
    assert zoom_window(_block(24, 32, 0, 0, 2), 2.0) == (0, 0, 12, 16)  # pushed inside at the corner
    assert zoom_window(_block(24, 32, 20, 28, 4), 1.5) == (8, 11, 16, 21)
    assert zoom_window(torch.zeros(24, 32), 2.0) is None
    # zoom < 1: the window holds the whole frame, centred on the object where it can be
    assert zoom_window(_block(24, 32, 10, 14, 4), 0.5) == (12 - 24, 16 - 32, 48, 64)
    assert zoom_window(_block(24, 32, 0, 0, 2), 0.75) == (-8, -11, 32, 43)  # pushed to hold the frame


def test_zoom_out_shrinks_the_frame_onto_a_black_canvas_as_opencv_does() -> None:
    gen = torch.Generator().manual_seed(1)
    images = torch.rand(1, 3, 24, 32, generator=gen)
    masks = _block(24, 32, 2, 3, 8)[None]
    out, out_masks, zoomed = zoom_on_object(images, masks, 0.75)
    assert zoomed == [True]
    top, left, ch, cw = zoom_window(masks[0], 0.75)
    stacked = torch.cat([images[0], masks]).permute(1, 2, 0).numpy()
    canvas = cv2.copyMakeBorder(stacked, -top, top + ch - 24, -left, left + cw - 32, cv2.BORDER_CONSTANT, value=0)
    expected = cv2.resize(canvas, (32, 24), interpolation=cv2.INTER_LINEAR)
    np.testing.assert_allclose(out[0].permute(1, 2, 0).numpy(), expected[..., :3], atol=1e-5)
    np.testing.assert_array_equal(out_masks[0].numpy(), (expected[..., 3] > 0.5).astype(np.float32))
    assert out_masks[0].sum() == pytest.approx(64 * 0.75**2, abs=8)  # area x zoom^2, give or take the edge


def test_zoom_matches_opencv_on_the_window_and_magnifies_the_object() -> None:
    gen = torch.Generator().manual_seed(0)
    images = torch.rand(2, 3, 24, 32, generator=gen)
    masks = torch.stack([_block(24, 32, 8, 10, 6), torch.zeros(24, 32)])
    out, out_masks, zoomed = zoom_on_object(images, masks, 2.0)
    assert zoomed == [True, False]
    top, left, ch, cw = zoom_window(masks[0], 2.0)
    crop = images[0, :, top : top + ch, left : left + cw].permute(1, 2, 0).numpy()
    expected = cv2.resize(crop, (32, 24), interpolation=cv2.INTER_LINEAR)
    np.testing.assert_allclose(out[0].permute(1, 2, 0).numpy(), expected, atol=1e-5)
    assert out_masks[0].sum() == pytest.approx(4 * 36, abs=12)  # area x zoom^2, give or take the edge
    torch.testing.assert_close(out[1], images[1], rtol=0, atol=0)  # empty mask: left as it is
    torch.testing.assert_close(out_masks[1], masks[1], rtol=0, atol=0)


def test_zoom_refuses_bad_input() -> None:
    with pytest.raises(InputError, match="positive"):
        zoom_on_object(torch.rand(1, 3, 8, 8), torch.ones(1, 8, 8), 0.0)
    with pytest.raises(InputError, match="masks"):
        zoom_on_object(torch.rand(1, 3, 8, 8), torch.ones(1, 8, 9), 2.0)
    with pytest.raises(InputError, match="zoom_prob"):
        SequenceTrainingSamples([FakeSequence()], 1, zoom_prob=0.5)  # no zooms
    with pytest.raises(InputError, match="zoom_prob"):
        SequenceTrainingSamples([FakeSequence()], 1, zooms=[-0.5], zoom_prob=0.5)


def test_zoomed_samples_keep_the_reference_and_magnify_the_test_frames() -> None:
    args = dict(n_test_frames=2, max_gap=3, min_pixels=10, seed=1)
    plain = SequenceTrainingSamples([FakeSequence()], 4, **args)[0]
    zoomed = SequenceTrainingSamples([FakeSequence()], 4, zooms=[2.0], zoom_prob=1.0, **args)[0]
    torch.testing.assert_close(plain["test_zoom"], torch.ones(2), rtol=0, atol=0)
    torch.testing.assert_close(zoomed["test_zoom"], torch.full((2,), 2.0), rtol=0, atol=0)
    torch.testing.assert_close(zoomed["ref_image"], plain["ref_image"], rtol=0, atol=0)
    images, masks, _ = zoom_on_object(plain["test_images"], plain["test_masks"], 2.0)
    torch.testing.assert_close(zoomed["test_images"], images, rtol=0, atol=0)
    torch.testing.assert_close(zoomed["test_masks"], masks, rtol=0, atol=0)
    assert (zoomed["test_masks"].sum((1, 2)) > 3 * plain["test_masks"].sum((1, 2))).all()
