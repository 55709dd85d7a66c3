"""Peak and PSR of point-interleaved response maps against brute-force loops over the (P, N, N) maps."""

import pytest
import torch

from models.dcf import response_peak
from models.tracking.interleaved import _halving_max, interleaved_argmax, interleaved_peak, interleaved_psr


def _maps(p: int, n: int, m: int, seed: int) -> torch.Tensor:
    """Random maps (P, N, M) with a clear maximum somewhere, float64."""
    gen = torch.Generator().manual_seed(seed)
    maps = torch.randn(p, n, m, generator=gen, dtype=torch.float64)
    rows = torch.randint(n, (p,), generator=gen)
    cols = torch.randint(m, (p,), generator=gen)
    maps[torch.arange(p), rows, cols] += 6.0
    return maps


def _psr_loop(response: torch.Tensor, exclude: int) -> float:
    """PSR of one periodic map by the definition: peak, then mean and std of every value outside the window."""
    n, m = response.shape
    flat = int(response.argmax())
    r0, c0 = divmod(flat, m)
    side = []
    for r in range(n):
        for c in range(m):
            dr = min((r - r0) % n, (r0 - r) % n)
            dc = min((c - c0) % m, (c0 - c) % m)
            if dr > exclude // 2 or dc > exclude // 2:
                side.append(float(response[r, c]))
    side = torch.tensor(side, dtype=torch.float64)
    return float((response.max() - side.mean()) / side.std(unbiased=False))


@pytest.mark.parametrize("exporting", [False, True])
@pytest.mark.parametrize(("n", "m"), [(21, 21), (15, 15), (9, 11), (32, 31)])
def test_argmax_and_peak_equal_the_per_map_results(n, m, exporting, monkeypatch):
    monkeypatch.setattr(torch.compiler, "is_exporting", lambda: exporting)  # the exported forms: gathers, halving max
    maps = _maps(40, n, m, seed=n + m)
    interleaved = maps.permute(1, 0, 2).contiguous()
    value, row, column = interleaved_argmax(interleaved)
    flat = maps.flatten(1).argmax(1)
    assert torch.equal(row, flat // m) and torch.equal(column, flat % m)
    torch.testing.assert_close(value, maps.flatten(1).amax(1))
    shift, peak = interleaved_peak(interleaved)
    expected_shift, expected_peak = response_peak(maps, 2)
    torch.testing.assert_close(shift, expected_shift, rtol=0, atol=1e-12)
    torch.testing.assert_close(peak, expected_peak)
    integer, _ = interleaved_peak(interleaved, subpixel=False)
    torch.testing.assert_close(integer, response_peak(maps, 2, subpixel=False)[0])


def test_halving_max_equals_the_maximum_over_the_outer_axis():
    gen = torch.Generator().manual_seed(5)
    for n in range(1, 34):
        score = torch.randn(n, 7, 5, generator=gen, dtype=torch.float64)
        assert torch.equal(_halving_max(score), score.amax(0)), n


def test_weighted_argmax_is_the_maximum_of_the_weighted_maps_with_the_maps_value():
    maps = _maps(30, 15, 15, seed=3)
    weight = torch.rand(15, 1, 15, generator=torch.Generator().manual_seed(4), dtype=torch.float64)
    value, row, column = interleaved_argmax(maps.permute(1, 0, 2).contiguous(), weight)
    flat = (maps * weight[:, 0]).flatten(1).argmax(1)  # one map at a time: (P, N, M) times (N, M)
    assert torch.equal(row, flat // 15) and torch.equal(column, flat % 15)
    torch.testing.assert_close(value, maps.flatten(1)[torch.arange(30), flat])


@pytest.mark.parametrize(("n", "m", "exclude"), [(21, 21, 7), (15, 15, 11), (9, 11, 3)])
def test_psr_equals_a_loop_over_the_sidelobe(n, m, exclude):
    maps = _maps(12, n, m, seed=exclude)
    maps[0] = torch.roll(maps[0], (n // 2, m // 2), (0, 1))  # a peak near the wrap-around
    psr = interleaved_psr(maps.permute(1, 0, 2).contiguous(), exclude)
    expected = torch.tensor([_psr_loop(r, exclude) for r in maps], dtype=torch.float64)
    torch.testing.assert_close(psr, expected, rtol=1e-10, atol=1e-10)


def test_psr_window_is_checked():
    maps = torch.zeros(9, 3, 9)
    with pytest.raises(ValueError, match="odd"):
        interleaved_psr(maps, 4)
    with pytest.raises(ValueError, match="odd"):
        interleaved_psr(maps, 11)
