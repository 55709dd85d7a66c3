"""Tukey window: a plain loop over its definition, the Hann window at a full taper, separable, bad taper refused."""

import math

import pytest
import torch

from core.errors import InputError
from models.dcf import cosine_window, tukey_window


def _loop_tukey(n: int, taper: float) -> list[float]:
    """The window in natural order, sample by sample from the definition (samples at k / (n + 1), k = 1..n)."""
    values = []
    for k in range(1, n + 1):
        x = k / (n + 1)
        if x < taper / 2:
            values.append(0.5 * (1 - math.cos(2 * math.pi * x / taper)))
        elif x > 1 - taper / 2:
            values.append(0.5 * (1 - math.cos(2 * math.pi * (1 - x) / taper)))
        else:
            values.append(1.0)
    return values


@pytest.mark.parametrize(("n", "taper"), [(31, 0.5), (21, 0.3), (8, 0.75)])
def test_equals_the_definition(n, taper):
    got = tukey_window((n,), taper, dtype=torch.float64)
    want = torch.tensor(_loop_tukey(n, taper), dtype=torch.float64).roll(-(n // 2))  # FFT order
    torch.testing.assert_close(got, want, rtol=0, atol=1e-12)
    assert got[0] == 1 and got.min() > 0


def test_full_taper_is_the_hann_window_and_2d_is_separable():
    torch.testing.assert_close(tukey_window((9, 12), 1.0), cosine_window((9, 12)))
    two = tukey_window((11, 15), 0.5, dtype=torch.float64)
    torch.testing.assert_close(two, tukey_window((11,), 0.5, dtype=torch.float64)[:, None]
                               * tukey_window((15,), 0.5, dtype=torch.float64))


def test_bad_taper():
    for taper in (0.0, 1.5):
        with pytest.raises(InputError, match="taper"):
            tukey_window((9,), taper)
