"""Peak-to-sidelobe ratio against a direct loop over the sidelobe values."""

import numpy as np
import pytest
import torch

from models.dcf import peak_to_sidelobe_ratio


def _psr_direct(r: np.ndarray, exclude: int) -> float:
    peak = np.unravel_index(np.argmax(r), r.shape)
    half = exclude // 2
    side = []
    for index in np.ndindex(*r.shape):
        inside = True
        for i, p, n in zip(index, peak, r.shape, strict=True):
            d = abs(i - p)
            inside &= min(d, n - d) <= half
        if not inside:
            side.append(r[index])
    side = np.array(side)
    return (r[peak] - side.mean()) / side.std()


@pytest.mark.parametrize("size", [(40,), (25, 25), (17, 31)])
@pytest.mark.parametrize("exclude", [5, 11])
def test_psr_equals_direct(size, exclude):
    gen = torch.Generator().manual_seed(3)
    r = torch.randn(6, *size, generator=gen, dtype=torch.float64)
    # peaks in the corner (the window wraps) and in the middle
    r.view(6, -1)[0, 0] = 9.0
    r.view(6, -1)[1, -1] = 9.0
    r.view(6, -1)[2, r[0].numel() // 2] = 9.0
    got = peak_to_sidelobe_ratio(r, len(size), exclude)
    ref = np.array([_psr_direct(ri, exclude) for ri in r.numpy()])
    np.testing.assert_allclose(got.numpy(), ref, rtol=1e-10)
    got32 = peak_to_sidelobe_ratio(r.float(), len(size), exclude)
    np.testing.assert_allclose(got32.numpy(), ref, rtol=1e-4)


def test_psr_rejects_bad_window():
    with pytest.raises(ValueError, match="odd"):
        peak_to_sidelobe_ratio(torch.rand(2, 9, 9), 2, exclude=4)
    with pytest.raises(ValueError, match="sidelobe"):
        peak_to_sidelobe_ratio(torch.rand(2, 5, 5), 2, exclude=11)
