"""Block-grid ratio of compressed frames: equal to a loop over the pixel pairs, about 1 without compression,
growing as the JPEG quality falls, batched, bad input refused. Compression error variance: the variance of known
per-block errors, close to JPEG's true error, none without a grid."""

import cv2
import numpy as np
import pytest
import torch

from core.errors import InputError
from models.tracking.compression import BlockGridRatio, block_grid_ratio, compression_error_variance
from tests.models.tracking.test_blur import textured


def _jpeg(image: np.ndarray, quality: int) -> np.ndarray:
    data = cv2.imencode(".jpg", image.clip(0, 255).round().astype(np.uint8), [cv2.IMWRITE_JPEG_QUALITY, quality])[1]
    return cv2.imdecode(data, cv2.IMREAD_GRAYSCALE).astype(np.float64)


def _loop_ratio(image: np.ndarray, block: int) -> float:
    """The ratio by a plain loop over every pair of neighbouring pixels along each axis."""
    ratios = []
    for plane in (image, image.T):  # steps along x, then along y
        border, inside = [], []
        for row in plane:
            for i in range(len(row) - 1):
                (border if (i + 1) % block == 0 else inside).append(abs(row[i + 1] - row[i]))
        ratios.append((np.mean(border) + 1e-6) / (np.mean(inside) + 1e-6))
    return float(np.mean(ratios))


@pytest.mark.parametrize("block", [8, 4])
def test_ratio_equals_a_loop_over_the_pixel_pairs(block):
    image = _jpeg(textured(40, 56, 1), 10)
    got = block_grid_ratio(torch.from_numpy(image)[None, None], block)
    assert got.shape == (1,)
    assert got.item() == pytest.approx(_loop_ratio(image, block), rel=1e-9)


def test_ratio_grows_as_the_quality_falls():
    image = textured(160, 200, 3)
    raw = block_grid_ratio(torch.from_numpy(image)[None, None]).item()
    ratios = [block_grid_ratio(torch.from_numpy(_jpeg(image, q))[None, None]).item() for q in (95, 60, 15, 2)]
    assert 0.95 < raw < 1.05 and 0.95 < ratios[0] < 1.1
    assert all(a < b for a, b in zip(ratios, ratios[1:], strict=False)), ratios
    assert ratios[-1] > 5  # quality 2: nearly flat blocks


def test_flat_blocks_and_batches():
    rng = np.random.default_rng(0)
    blocks = np.kron(rng.uniform(0, 255, (6, 8)), np.ones((8, 8)))  # 48 x 64 px of flat 8 x 8 blocks
    smooth = textured(48, 64, 2)
    batch = torch.from_numpy(np.stack([blocks + rng.normal(0, 0.5, blocks.shape), smooth]))[:, None]
    ratios = block_grid_ratio(batch)
    assert ratios[0] > 20 and 0.8 < ratios[1] < 1.2
    torch.testing.assert_close(BlockGridRatio()(batch), ratios)
    torch.testing.assert_close(block_grid_ratio(batch[1:].float()), ratios[1:].float())


def test_bad_input():
    with pytest.raises(InputError, match="gray"):
        block_grid_ratio(torch.zeros(1, 3, 32, 32))
    with pytest.raises(InputError, match="2 blocks"):
        block_grid_ratio(torch.zeros(1, 1, 12, 32))


@pytest.mark.parametrize("error_std", [2.0, 5.0, 10.0])
def test_error_variance_of_known_block_errors(error_std):
    """A smooth scene plus an independent Gaussian offset per 8 x 8 block: the variance of the offsets."""
    rng = np.random.default_rng(int(error_std))
    scene = 128 + 0.1 * (textured(240, 320, 3) - 128)
    image = scene + np.kron(rng.normal(0, error_std, (30, 40)), np.ones((8, 8)))
    got = compression_error_variance(torch.from_numpy(image)[None, None])
    assert got.shape == (1,)
    assert got.item() ** 0.5 == pytest.approx(error_std, rel=0.1)


def test_error_variance_follows_the_jpeg_error():
    image = textured(240, 320, 4)
    for quality in (15, 5):
        compressed = _jpeg(image, quality)
        true_std = (compressed - image.clip(0, 255).round()).std()
        got = compression_error_variance(torch.from_numpy(compressed)[None, None]).item() ** 0.5
        assert 0.5 * true_std < got < 1.5 * true_std, (quality, got, true_std)
    # no grid, or one of chance strength (quality 95): nothing
    for frame in (image, _jpeg(image, 95)):
        assert compression_error_variance(torch.from_numpy(frame)[None, None]).item() == 0


def test_error_variance_bad_input():
    with pytest.raises(InputError, match="compression_error_variance expects"):
        compression_error_variance(torch.zeros(1, 3, 32, 32))
    with pytest.raises(InputError, match="2 blocks"):
        compression_error_variance(torch.zeros(1, 1, 32, 12))
