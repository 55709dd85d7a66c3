"""Label encoder: output strides, the initial weights W(y) = 1, E(y) >= 0, gradients, input checks; the area
resize against brute-force bin means."""

import pytest
import torch

from core.errors import InputError
from models.vos.label_encoder import LabelEncoder, area_resize


@pytest.mark.parametrize(("stride", "size", "out"), [(8, (240, 427), (30, 54)), (16, (240, 427), (15, 27)),
                                                     (8, (64, 96), (8, 12))])
def test_shapes_initial_weights_and_gradients(stride: int, size: tuple, out: tuple) -> None:
    torch.manual_seed(0)
    enc = LabelEncoder(2, 16, stride)
    labels = (torch.rand(3, 2, *size) > 0.5).float()
    e, w = enc(labels, out)
    assert e.shape == w.shape == (3, 16, *out)
    assert (e >= 0).all() and torch.equal(w, torch.ones_like(w))  # W(y) starts at 1 everywhere
    (e.sum() + w.sum()).backward()
    assert all(p.grad is not None for p in enc.parameters())


def test_output_follows_the_features_size() -> None:
    e, w = LabelEncoder(1, 4, 8)(torch.rand(1, 1, 60, 90), (7, 11))  # backbones that round differently
    assert e.shape == (1, 4, 7, 11)


def test_bad_input() -> None:
    with pytest.raises(InputError, match="stride"):
        LabelEncoder(2, 16, 4)
    with pytest.raises(InputError, match=r"\(N, 2, H, W\)"):
        LabelEncoder(2, 16, 8)(torch.rand(1, 1, 32, 32), (4, 4))


@pytest.mark.parametrize(("size", "out"), [((240, 427), (30, 54)), ((9, 13), (2, 3)), ((64, 96), (8, 12)),
                                           ((5, 7), (5, 7))])
def test_area_resize_is_the_mean_over_adaptive_pooling_bins(size: tuple, out: tuple) -> None:
    x = torch.rand(2, 3, *size, dtype=torch.float64, generator=torch.Generator().manual_seed(0))
    ref = torch.empty(2, 3, *out, dtype=torch.float64)
    for i in range(out[0]):
        r0, r1 = (i * size[0]) // out[0], -(-((i + 1) * size[0]) // out[0])
        for j in range(out[1]):
            c0, c1 = (j * size[1]) // out[1], -(-((j + 1) * size[1]) // out[1])
            ref[..., i, j] = x[..., r0:r1, c0:c1].mean((-2, -1))
    torch.testing.assert_close(area_resize(x, out), ref, rtol=1e-12, atol=1e-12)
    torch.testing.assert_close(area_resize(x.float(), out), ref.float(), rtol=1e-5, atol=1e-6)
