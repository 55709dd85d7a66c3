"""DCF point tracker: patches, exact and sub-pixel translations through the pyramid, lost flags, bad input."""

import math

import cv2
import numpy as np
import pytest
import torch
from kornia.geometry.transform import pyrdown

from core.errors import InputError
from core.streak import streak_blur
from data.flow import homography_sequence, stress_frames, synthetic_sequence
from models.dcf import cosine_window, cubic_spline_fourier
from models.dcf.dft import band_index
from models.tracking import PointTracker, extract_patches, good_features_to_track
from models.tracking.compression import block_grid_ratio
from models.tracking.motion_blur import motion_blur_streak
from models.tracking.point_tracker import displacement_prior, image_pyramid, pyramid_min_size
from tests.models.tracking.test_blur import textured


def _smooth_image(h: int, w: int, seed: int) -> torch.Tensor:
    """Periodic band-limited random image (float64, about 0..255), cheap to translate exactly by a
    Fourier shift."""
    gen = torch.Generator().manual_seed(seed)
    ky = torch.fft.fftfreq(h, dtype=torch.float64).reshape(-1, 1)
    kx = torch.fft.rfftfreq(w, dtype=torch.float64).reshape(1, -1)
    radius = torch.sqrt(ky**2 + kx**2)
    spec = torch.complex(torch.randn(h, w // 2 + 1, generator=gen), torch.randn(h, w // 2 + 1, generator=gen))
    spec = spec.to(torch.complex128) * (radius < 0.2) / (radius + 0.02)
    img = torch.fft.irfft2(spec, s=(h, w))
    return 128 + 40 * img / img.std()


def _translate(img: torch.Tensor, dx: float, dy: float) -> torch.Tensor:
    """Content moved by (+dx, +dy): out(x) = img(x - d), exact for the band-limited periodic image."""
    h, w = img.shape
    ky = torch.fft.fftfreq(h, dtype=torch.float64).reshape(-1, 1)
    kx = torch.fft.rfftfreq(w, dtype=torch.float64).reshape(1, -1)
    phase = torch.exp(-2j * math.pi * (kx * dx + ky * dy))
    return torch.fft.irfft2(torch.fft.rfft2(img) * phase, s=(h, w))


def test_extract_patches_equals_direct_crop():
    img = torch.arange(20 * 30, dtype=torch.float64).reshape(20, 30)
    centres = torch.tensor([[10.0, 8.0], [15.0, 12.0]], dtype=torch.float64)
    patches = extract_patches(img[None, None], centres, 5).permute(1, 0, 2)  # (P, 5, 5)
    for patch, (x, y) in zip(patches, centres.long().tolist(), strict=True):
        crop = img[y - 2 : y + 3, x - 2 : x + 3]
        torch.testing.assert_close(patch, crop)  # natural order: centre at index size // 2
    half = extract_patches(img[None, None], torch.tensor([[10.5, 8.25]], dtype=torch.float64), 3)
    assert half[1, 0, 1].item() == pytest.approx(
        img[8, 10] * 0.375 + img[8, 11] * 0.375 + img[9, 10] * 0.125 + img[9, 11] * 0.125
    )


def test_extract_patches_equals_grid_sample_with_border_padding(monkeypatch):
    gen = torch.Generator().manual_seed(2)
    img = torch.rand(1, 1, 23, 31, generator=gen, dtype=torch.float64)
    centres = torch.rand(50, 2, generator=gen, dtype=torch.float64) * torch.tensor([30.0, 22.0])
    centres[:4] = torch.tensor([[0.0, 0.0], [30.0, 22.0], [0.25, 21.5], [29.75, 0.5]], dtype=torch.float64)
    size = 7
    off = torch.arange(size, dtype=torch.float64) - size // 2
    xy = torch.stack(torch.meshgrid(off, off, indexing="xy"), -1) + centres[:, None, None, :]
    grid = (xy + 0.5) / torch.tensor([31.0, 23.0], dtype=torch.float64) * 2 - 1
    expected = torch.nn.functional.grid_sample(img, grid.reshape(1, -1, size, 2), mode="bilinear",
                                               padding_mode="border", align_corners=False).reshape(-1, size, size)
    expected = expected.permute(1, 0, 2)  # point-interleaved: (rows, P, columns)
    torch.testing.assert_close(extract_patches(img, centres, size), expected)
    monkeypatch.setattr(torch.compiler, "is_exporting", lambda: True)  # the flat-index gather used for ONNX
    torch.testing.assert_close(extract_patches(img, centres, size), expected)


@pytest.mark.parametrize("method", ["ccot", "ccot_ff", "mosse"])
def test_large_integer_translation_is_recovered(method):
    img = _smooth_image(160, 192, 0)
    moved = _translate(img, 23.0, -17.0)
    points = torch.tensor([[60.0, 70.0], [100.0, 90.0], [130.0, 60.0], [80.0, 110.0]], dtype=torch.float64)
    tracker = PointTracker(method).double()
    tracks, lost, _ = tracker.track([img, moved], points)
    assert not lost.any()
    err = (tracks[1] - points - torch.tensor([23.0, -17.0], dtype=torch.float64)).abs().max().item()
    # the residual comes from bilinear sampling of the patch at the fractional search centre left by the
    # coarser levels (its phase response is not linear); it shrinks with the patch size
    assert err < 0.075, err


def test_subpixel_translation_ccot():
    img = _smooth_image(128, 128, 1)
    d = torch.tensor([3.37, -1.71], dtype=torch.float64)
    moved = _translate(img, *d.tolist())
    points = torch.tensor([[40.0, 50.0], [64.0, 64.0], [90.0, 80.0]], dtype=torch.float64)
    tracks, lost, psr = PointTracker("ccot").double().track([img, moved], points)
    assert not lost.any() and (psr[1] > 10).all()
    assert (tracks[1] - points - d).abs().max().item() < 0.1


def test_lost_flags_for_flat_regions_and_leaving_points():
    img = _smooth_image(128, 128, 2)
    img[:, :48] = 100.0  # flat: no structure, so the PSR collapses
    moved = _translate(img, 0.0, 0.0)
    moved[:, :48] = 100.0
    points = torch.tensor([[20.0, 60.0], [90.0, 60.0], [-5.0, 10.0]], dtype=torch.float64)
    tracks, lost, _ = PointTracker("ccot").double().track([img, moved], points)
    assert lost[0].tolist() == [False, False, True]  # outside the image from the start
    assert lost[1].tolist() == [True, False, True]
    torch.testing.assert_close(tracks[1, 0], points[0])  # lost points stay where they were last trusted
    shifted = _translate(_smooth_image(128, 128, 3), 30.0, 0.0)
    points = torch.tensor([[110.0, 64.0], [40.0, 64.0], [60.0, 30.0]])  # the first one leaves the image
    t2, l2, _ = PointTracker("ccot").double().track([_smooth_image(128, 128, 3), shifted], points)
    # its content is gone: whatever it matches is weak against the other points' peaks and does not track back
    assert l2[1].tolist() == [True, False, False]


@pytest.mark.parametrize("miss", [(0.0, 0.0), (2.0, 0.0), (-1.5, 2.5), (3.0, -3.0)])
def test_backward_error_is_the_distance_of_a_wrong_match(miss):
    """A sample taken at a wrong position ``true + miss`` in the new frame tracks back to ``start + miss`` in the
    previous frame (pure translation): the forward-backward error is ``|miss|``, measured by one search whose
    cosine window pulls the peak towards the patch centre (at most about 20 % short)."""
    img = _smooth_image(128, 128, 7)
    d = torch.tensor([5.3, -2.4], dtype=torch.float64)
    moved = _translate(img, *d.tolist())
    tracker = PointTracker("ccot").double()
    start = torch.tensor([[50.0, 60.0], [70.0, 64.0], [64.0, 80.0]], dtype=torch.float64)
    wrong = start + d + torch.tensor(miss, dtype=torch.float64)
    sample = tracker._sample(moved[None, None], wrong, 0)[:2]
    error = tracker._backward_error(img[None, None], start, *sample)
    expected = math.hypot(*miss)
    assert (error >= 0.75 * expected - 0.02).all() and (error <= 1.02 * expected + 0.02).all(), (error, expected)


def test_backward_test_on_the_weak_points_only_equals_the_test_on_all(monkeypatch):
    """Eager runs and exported graphs search back only for the weak points (and one spare search); a compiled step
    searches back for every point and and-s: the flags of the test on every point, also with no weak point at all
    and with the last point (the spare search's) weak or not."""
    tracker = PointTracker("ccot")
    gen = torch.Generator().manual_seed(0)
    previous = torch.rand(1, 1, 96, 128, generator=gen) * 255
    start = torch.rand(40, 2, generator=gen) * torch.tensor([127.0, 95.0])
    zr, zi, _ = tracker._sample(previous, start, 0)  # samples at the start: they track back home
    wrong = torch.arange(40) % 3 == 0  # these samples are noise: they track back elsewhere
    noise_shape = zr[:, wrong].shape
    zr[:, wrong], zi[:, wrong] = torch.randn(noise_shape, generator=gen), torch.randn(noise_shape, generator=gen)
    misses = ~(tracker._backward_error(previous, start, zr, zi) <= tracker.fb_threshold)  # every point, one batch
    assert 0 < misses.sum() < 40
    some = torch.rand(40, generator=gen) < 0.3
    for weak in (some, some | misses, torch.zeros(40, dtype=torch.bool), torch.ones(40, dtype=torch.bool)):
        for mode in ("eager", "exporting", "compiling"):
            if mode != "eager":
                monkeypatch.setattr(torch.compiler, "is_compiling", lambda: True)
                monkeypatch.setattr(torch.compiler, "is_exporting", lambda m=mode: m == "exporting")
            assert torch.equal(tracker._fails_backward(weak, previous, start, zr, zi), weak & misses), (mode, weak)
            monkeypatch.undo()


def test_an_eager_backward_test_without_weak_points_searches_nothing(monkeypatch):
    tracker = PointTracker("ccot")
    previous = torch.rand(1, 1, 64, 80, generator=torch.Generator().manual_seed(1)) * 255
    start = torch.tensor([[20.0, 30.0], [50.0, 40.0]])
    zr, zi, _ = tracker._sample(previous, start, 0)

    def no_search(*args, **kwargs):
        raise AssertionError("searched back without a weak point")

    monkeypatch.setattr(tracker, "_backward_error", no_search)
    none = torch.zeros(2, dtype=torch.bool)
    assert torch.equal(tracker._fails_backward(none, previous, start, zr, zi), none)
    with pytest.raises(AssertionError, match="searched back"):  # a weak point is searched
        tracker._fails_backward(torch.tensor([True, False]), previous, start, zr, zi)


def test_weak_peak_threshold_is_relative_to_the_geometric_mean_psr():
    tracker = PointTracker("ccot", psr_relative=0.3)
    psr = torch.tensor([4.0, 16.0, 9.0, 1.0, float("nan"), 100.0])
    lost = torch.tensor([False, False, False, False, False, True])
    tracked = [4.0, 16.0, 9.0, 1.0]  # the lost point and the non-finite PSR do not count
    expected = 0.3 * math.exp(sum(math.log(v) for v in tracked) / len(tracked))
    assert tracker._lost_threshold(psr, lost).item() == pytest.approx(expected, rel=1e-6)


def test_psr_mean_is_a_running_geometric_mean():
    """Against a loop over the frames: a point's first finite PSR starts its mean, each later one enters the log
    mean with weight ``psr_rate``, and a frame in which the point is lost or has no finite PSR leaves it alone."""
    rate = 0.25
    tracker = PointTracker("ccot", psr_rate=rate)
    nan = float("nan")
    psr = torch.tensor([[12.0, 5.0, nan], [8.0, 9.0, 2.0], [20.0, nan, 6.0], [4.0, 16.0, 3.0]], dtype=torch.float64)
    lost = torch.tensor([[False, False, False], [False, False, True], [False, False, False], [True, False, False]])
    mean = torch.full((3,), float("inf"), dtype=torch.float64)
    expected = [float("inf")] * 3
    for t in range(4):
        mean = tracker._psr_mean(mean, psr[t], lost[t])
        for p in range(3):
            value = psr[t, p].item()
            if lost[t, p] or not math.isfinite(value):
                continue
            old = expected[p]
            expected[p] = value if math.isinf(old) else math.exp((1 - rate) * math.log(old) + rate * math.log(value))
        torch.testing.assert_close(mean, torch.tensor(expected, dtype=torch.float64))
    off = PointTracker("ccot", psr_rate=None)._psr_mean(mean, psr[0], lost[0])
    assert torch.equal(off, mean)  # without the history test the means are never touched
    for value in (0.0, -0.1, 1.5, float("nan")):
        with pytest.raises(InputError, match="psr_rate"):
            PointTracker("ccot", psr_rate=value)


def test_weak_points_are_tested_only_below_their_own_psr_history(monkeypatch):
    """A point weak against the frame's other points takes the forward-backward test (here made to fail always)
    only while its PSR is also below ``psr_relative`` times its own running mean: with no history yet (inf) every
    frame-weak point is tested, with a history equal to its present PSR none, with one ten times higher all
    again; ``psr_rate=None`` tests them whatever the history."""
    gen = torch.Generator().manual_seed(4)
    img = _smooth_image(160, 160, 11)
    moved = _translate(img, 2.0, 1.0)
    moved[:, :60] += 25 * torch.randn(160, 60, generator=gen, dtype=torch.float64)  # noisy left: weak peaks there
    grid = torch.arange(20.0, 141.0, 15.0, dtype=torch.float64)
    points = torch.stack(torch.meshgrid(grid, grid, indexing="xy"), -1).reshape(-1, 2)
    results = {}
    for rate in (0.3, None):
        tracker = PointTracker("ccot", psr_rate=rate).double()
        monkeypatch.setattr(tracker, "_fails_backward", lambda weak, *args: weak)
        state = tracker.init(img, points)
        _, _, psr, *_ = tracker(moved[None, None], img[None, None], state.positions, state.lost, state.psr_mean,
                                *state.filters)
        frame_weak = psr < tracker._lost_threshold(psr, state.lost)
        floor = ~(psr >= tracker.psr_threshold)
        for name, history in (("none", state.psr_mean), ("same", psr), ("higher", 10 * psr)):
            lost = tracker(moved[None, None], img[None, None], state.positions, state.lost, history,
                           *state.filters)[1]
            results[rate, name] = lost
        assert 0 < frame_weak.sum() < len(points) // 2 and not (floor & ~frame_weak).any()
    assert torch.equal(results[0.3, "none"], frame_weak) and torch.equal(results[0.3, "higher"], frame_weak)
    assert not results[0.3, "same"].any()
    assert all(torch.equal(results[None, name], frame_weak) for name in ("none", "same", "higher"))


def test_occluded_point_is_lost_while_the_others_are_kept():
    """An opaque patch of other texture slides over one point between two frames: its peak collapses and it does
    not track back home, so it is flagged lost; the visible points, some in a darker and blurred copy of the
    frame, are kept."""
    img = _smooth_image(160, 160, 8)
    d = (3.0, 2.0)
    moved = _translate(img, *d)
    ys, xs = torch.meshgrid(torch.arange(160.0), torch.arange(160.0), indexing="ij")
    disc = (xs - 43.0) ** 2 + (ys - 42.0) ** 2 <= 22.0**2
    moved = torch.where(disc, _smooth_image(160, 160, 9), moved)
    points = torch.tensor([[40.0, 40.0], [100.0, 60.0], [120.0, 120.0], [60.0, 110.0], [110.0, 30.0]])
    for frames in ([img, moved], [0.3 * img, 0.3 * moved]):  # a darker copy keeps the decision
        tracks, lost, _ = PointTracker("ccot").double().track([f.double() for f in frames], points.double())
        assert lost[1].tolist() == [True, False, False, False, False]
        np.testing.assert_allclose(tracks[1, 1:] - points[1:].double(), np.tile(d, (4, 1)), atol=0.05)


def test_occluded_point_comes_back_where_it_is_once_uncovered():
    """An opaque disc covers one point in frames 2-3 of a steady translation and is gone from frame 4: the point is
    lost while covered and back from frame 5 (frame 4's forward-backward test still meets the disc in frame 3)
    at its true position, the exact translation, although it moved 12 x 8 px while frozen (its level-0 search
    window, 31 px, sees it there: the backward test starts where the other points' step puts it); with
    ``psr_recover=None`` it stays lost, and a point outside the image from the start (no PSR history) never
    comes back."""
    img = _smooth_image(160, 160, 8)
    d = torch.tensor([3.0, 2.0], dtype=torch.float64)
    ys, xs = torch.meshgrid(torch.arange(160.0), torch.arange(160.0), indexing="ij")
    disc = (xs - 46.0) ** 2 + (ys - 44.0) ** 2 <= 24.0**2
    cover = _smooth_image(160, 160, 9)
    frames = [_translate(img, *(t * d).tolist()) for t in range(7)]
    frames[2:4] = [torch.where(disc, cover, f) for f in frames[2:4]]
    points = torch.tensor([[40.0, 40.0], [100.0, 60.0], [120.0, 120.0], [60.0, 110.0], [110.0, 30.0],
                           [-3.0, 80.0]], dtype=torch.float64)
    tracks, lost, _ = PointTracker("ccot").double().track(frames, points)
    assert lost[:, 0].tolist() == [False, False, True, True, True, False, False]
    assert not lost[:, 1:5].any() and lost[:, 5].all()
    assert (tracks[6, :5] - (points[:5] + 6 * d)).norm(dim=-1).max() < 0.05
    _, final, _ = PointTracker("ccot", psr_recover=None).double().track(frames, points)
    assert final[2:, 0].all() and not final[:, 1:5].any()
    with pytest.raises(InputError, match="psr_recover"):
        PointTracker(psr_recover=0.0)


def test_origin_of_the_backward_test():
    """A tracked point is tested back to its start; a point coming back to where the mean step of the points
    tracked into the frame (hand-computed; the lost ones do not count) puts it in the previous frame."""
    start = torch.tensor([[10.0, 10.0], [20.0, 5.0], [50.0, 50.0], [0.0, 0.0]])
    moved = torch.tensor([[13.0, 12.0], [24.0, 9.0], [70.0, 10.0], [31.0, 42.0]])
    lost = torch.tensor([False, False, True, True])
    back = torch.tensor([False, False, False, True])
    origin = PointTracker._origin(start, moved, lost, back)
    mean_step = torch.tensor([(3.0 + 4.0) / 2, (2.0 + 4.0) / 2])
    torch.testing.assert_close(origin[:3], start[:3])
    torch.testing.assert_close(origin[3], moved[3] - mean_step)


def test_retraining_keeps_the_filters_of_lost_points():
    """Blur matching retrains the filters on another view; a lost point keeps the ones it was lost with (so that it
    can come back), the tracked points get exactly those of a fresh start on that view."""
    tracker = PointTracker("ccot").double()
    points = torch.tensor([[40.0, 40.0], [100.0, 60.0], [70.0, 90.0]], dtype=torch.float64)
    state = tracker.init(_smooth_image(128, 128, 4), points)
    state.lost[1] = True
    other = _smooth_image(128, 128, 5)[None, None]
    retrained, fresh = tracker._retrained(other, state), tracker._train(other, points)
    assert retrained.lost.tolist() == [False, True, False]
    for kept, old, new in zip(retrained.filters, state.filters, fresh.filters, strict=True):
        torch.testing.assert_close(kept[:, :, 1], old[:, :, 1], rtol=0, atol=0)
        torch.testing.assert_close(kept[:, :, [0, 2]], new[:, :, [0, 2]], rtol=0, atol=0)
        assert not torch.allclose(old[:, :, 1], new[:, :, 1])


def test_bad_input():
    img = torch.rand(64, 64) * 255
    with pytest.raises(InputError, match="size"):
        PointTracker("mosse").track([img, torch.rand(64, 65)], torch.tensor([[30.0, 30.0]]))
    with pytest.raises(InputError, match="empty"):
        PointTracker("mosse").track([img, img], torch.zeros(0, 2))
    with pytest.raises(InputError, match="unknown tracking method"):
        PointTracker("klt")
    with pytest.raises(InputError, match=r"\(P, 2\)"):
        PointTracker("mosse").track([img], torch.zeros(4, 3))


def test_pyramid_equals_kornia_pyrdown_away_from_the_border():
    img = _smooth_image(64, 96, 4)[None, None]
    pyramid = image_pyramid(img, 3)
    expected = [img, pyrdown(img)]
    expected.append(pyrdown(expected[1]))
    for level, (ours, ref) in enumerate(zip(pyramid, expected, strict=True)):
        assert ours.shape == ref.shape
        torch.testing.assert_close(ours[..., 4:-4, 4:-4], ref[..., 4:-4, 4:-4], rtol=1e-9, atol=1e-9 * 2**level)


def test_pyramid_min_size_against_a_search_with_torch_padding_rule():
    # the reference: the least frame side for which torch's reflect padding (3 px) accepts every level the pyramid
    # blurs, each level (n + 1) // 2 px of the one below (checked on an odd and an even frame first)
    assert [p.shape[-2:] for p in image_pyramid(torch.zeros(1, 1, 45, 46), 4)] == [(45, 46), (23, 23), (12, 12),
                                                                                   (6, 6)]

    def pads(n: int, levels: int) -> bool:
        for _ in range(levels - 1):
            try:
                torch.nn.functional.pad(torch.zeros(1, 1, n, n), (2, 3, 2, 3), mode="reflect")
            except RuntimeError:
                return False
            n = (n + 1) // 2
        return True

    for levels in range(1, 7):
        least = next(n for n in range(1, 200) if pads(n, levels))
        assert pyramid_min_size(levels) == least
        assert len(image_pyramid(torch.zeros(1, 1, least, 3 * least), levels)) == levels
        if least > 1:
            with pytest.raises(InputError, match=f"needs at least {least} px"):
                image_pyramid(torch.zeros(1, 1, 3 * least, least - 1), levels)


def test_tracker_refuses_frames_below_its_minimum_and_tracks_at_it():
    # the 5-level pyramid's: its fourth blurred level must be 4 px; 4 levels need the blur profile's 8 px a side
    # after halving
    assert PointTracker("ccot").min_frame_size == pyramid_min_size(5) == 25
    assert PointTracker("ccot", levels=4).min_frame_size == 16
    assert PointTracker("ccot", levels=4, blur_match=None).min_frame_size == pyramid_min_size(4) == 13
    img = _smooth_image(64, 64, 3)
    moved = _translate(img, 1.0, 0.0)
    tracker = PointTracker("ccot")
    tracks, lost, _ = tracker.track([img[:25, :25], moved[:25, :25]], torch.tensor([[12.0, 12.0]], dtype=torch.float64))
    assert tracks.shape == (2, 1, 2) and lost.shape == (2, 1)
    with pytest.raises(InputError, match=r"\(24, 25\) px is too small"):
        tracker.track([img[:24, :25], moved[:24, :25]], torch.tensor([[8.0, 8.0]], dtype=torch.float64))


@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
def test_exported_pyramid_form_equals_the_eager_one(monkeypatch, dtype):
    # the strided convolutions of an export against the strided slices of eager mode, on odd and even sizes
    from models.tracking import point_tracker

    img = (torch.rand(1, 1, 67, 90, generator=torch.Generator().manual_seed(0)) * 255).to(dtype)
    eager = image_pyramid(img, 4)
    monkeypatch.setattr(point_tracker, "exporting", lambda: True)
    exported = image_pyramid(img, 4)
    for ours, ref in zip(exported, eager, strict=True):
        assert ours.shape == ref.shape and ours.dtype == dtype
        torch.testing.assert_close(ours, ref, rtol=1e-6, atol=1e-4)


def test_per_level_settings_are_checked():
    # the default band keeps round(0.5 * 15) = 8 frequencies of the 31 px level 0, round(0.7 * 10) = 7 of the 21 px
    assert PointTracker("ccot").sizes == (31, 21, 21, 21, 21) and PointTracker("ccot").bands == (8, 7, 7, 7, 7)
    assert PointTracker("ccot", levels=2, newton_iterations=2).bands == (8, 7)
    # the default Newton steps follow the number of levels: 2 at level 0, none at the coarser levels
    assert PointTracker("ccot").newton == (2, 0, 0, 0, 0) and PointTracker("ccot", levels=4).newton == (2, 0, 0, 0)
    assert PointTracker("ccot", levels=1).newton == (2,) and PointTracker("mosse", levels=5).newton == (0,) * 5
    assert PointTracker("ccot", levels=3, patch_size=(21, 15, 25), newton_iterations=2).sizes == (21, 15, 25)
    with pytest.raises(InputError, match="one value per pyramid level"):
        PointTracker("ccot", patch_size=(21, 15))
    with pytest.raises(InputError, match="odd"):
        PointTracker("ccot", levels=3, patch_size=(21, 16, 25))
    tracker = PointTracker("ccot", levels=3, patch_size=(21, 15, 25), band=(1.0, 0.7, 0.5), newton_iterations=2)
    assert tracker.bands == (10, 5, 6)  # highest kept frequency per level
    assert tuple(tracker.label_2.shape) == (13, 1, 7)
    with pytest.raises(InputError, match="band"):
        PointTracker("ccot", band=1.5)


@pytest.mark.parametrize("band", [1.0, 0.5])
def test_subpixel_translation_with_and_without_band_limit(band):
    img = _smooth_image(128, 128, 5)
    d = torch.tensor([-2.63, 1.18], dtype=torch.float64)
    points = torch.tensor([[40.0, 50.0], [64.0, 64.0], [90.0, 80.0]], dtype=torch.float64)
    tracks, lost, _ = PointTracker("ccot", band=band).double().track([img, _translate(img, *d.tolist())], points)
    assert not lost.any()
    assert (tracks[1] - points - d).abs().max() < 0.05


def test_good_features_find_rectangle_corners():
    img = torch.zeros(80, 100)
    img[20:50, 30:70] = 200.0
    pts = good_features_to_track(img, 10, 0.05, 5)
    corners = torch.tensor([[30.0, 20.0], [69.0, 20.0], [30.0, 49.0], [69.0, 49.0]])
    dist = torch.cdist(corners, pts).min(1).values
    assert (dist <= 2.0).all()
    assert len(good_features_to_track(img, 2, 0.05, 5)) == 2
    d = torch.cdist(pts, pts) + 1e3 * torch.eye(len(pts))
    assert (d.min() > 5).item()
    rng = np.random.default_rng(0)
    many = good_features_to_track(torch.from_numpy(rng.uniform(0, 255, (64, 64))), 20, 0.01, 3)
    assert len(many) == 20


@pytest.mark.slow
def test_compiled_step_equals_eager():
    img = _smooth_image(96, 128, 6).float()
    frames = [img, _translate(img.double(), 4.3, -2.6).float(), _translate(img.double(), 7.9, -4.1).float()]
    points = torch.tensor([[40.0, 50.0], [64.0, 40.0], [90.0, 60.0], [70.0, 30.0]])
    tracker = PointTracker("ccot")
    eager = tracker.track(frames, points)
    compiled = tracker.track(frames, points, compile=True)
    for got, want in zip(compiled, eager, strict=True):
        torch.testing.assert_close(got, want, rtol=1e-4, atol=1e-4)
    assert not eager[1].any()


@pytest.mark.parametrize("method", ["ccot", "mosse"])
def test_noise_spectrum_is_the_expected_power_of_white_noise(method):
    """Closed form: unit white noise ``n`` gives ``E |DFT(w n)(k)|^2 = s_y(k_y)^2 s_x(k_x)^2 sum w^2`` in every
    frequency of the sample transform (window ``w``, per-axis scales ``s`` of the continuous filter), here
    against a Monte Carlo mean as well."""
    tracker = PointTracker(method).double()
    for level, (n, m) in enumerate(zip(tracker.sizes, tracker.bands, strict=True)):
        window = cosine_window((n,), dtype=torch.float64)
        scale = torch.ones(n, dtype=torch.float64)
        if method != "mosse":
            scale = cubic_spline_fourier(torch.fft.fftfreq(n, dtype=torch.float64)) / n
        rows = scale[band_index(n, m)]
        power = rows[:, None] ** 2 * rows[None, : m + 1] ** 2 * window.square().sum() ** 2
        got = getattr(tracker, f"noise_spectrum_{level}")[:, 0]
        torch.testing.assert_close(got, power, rtol=1e-6, atol=0)  # built in float32
    gen = torch.Generator().manual_seed(0)
    n = tracker.sizes[1]
    noise = torch.randn(n, 20000, n, generator=gen, dtype=torch.float64)
    zr, zi = tracker.dfts[1](noise)
    monte_carlo = (zr.square() + zi.square()).mean(1)
    torch.testing.assert_close(monte_carlo, tracker.noise_spectrum_1[:, 0], rtol=0.05, atol=0)


def _blur(img: torch.Tensor, sigma: float) -> torch.Tensor:
    """Gaussian blur of a periodic image through its spectrum."""
    h, w = img.shape
    ky = torch.fft.fftfreq(h, dtype=torch.float64).reshape(-1, 1)
    kx = torch.fft.rfftfreq(w, dtype=torch.float64).reshape(1, -1)
    gain = torch.exp(-2 * math.pi**2 * sigma**2 * (ky**2 + kx**2))
    return torch.fft.irfft2(torch.fft.rfft2(img) * gain, s=(h, w))


def test_noise_regulariser_makes_blurred_noisy_tracks_more_precise():
    """On a strongly blurred texture with sensor noise (the low-signal case: most of the band holds only noise),
    the noise-adaptive regulariser keeps the noise-only frequencies from steering the peak."""
    gen = torch.Generator().manual_seed(6)
    img = _blur(_smooth_image(160, 160, 6), 3.0)
    d = (2.4, -1.3)
    frames = [img, _translate(img, *d)]
    frames = [(f + torch.randn(f.shape, generator=gen, dtype=torch.float64)).round() for f in frames]
    grid = torch.arange(30.0, 131.0, 10.0, dtype=torch.float64)
    points = torch.stack(torch.meshgrid(grid, grid, indexing="xy"), -1).reshape(-1, 2)
    errors = {}
    for noise_reg in (0.0, 30.0):
        tracks, _, _ = PointTracker("ccot", noise_reg=noise_reg).double().track(frames, points)
        errors[noise_reg] = (tracks[1] - points - torch.tensor(d, dtype=torch.float64)).norm(dim=-1).median().item()
    assert errors[30.0] < 0.7 * errors[0.0], errors


def test_noise_reg_is_checked():
    for value in (-1.0, float("nan")):
        with pytest.raises(InputError, match="noise_reg"):
            PointTracker("ccot", noise_reg=value)


def _blur_sequence(blurs: tuple[float, ...], seed: int) -> tuple[list[torch.Tensor], torch.Tensor, torch.Tensor]:
    """A periodic texture moved by (3, -2) px per frame and blurred by ``blurs`` (Gaussian stds), with sensor noise
    of std 1, rounded: frames, start points on a grid, their true last positions."""
    img = _smooth_image(192, 192, seed)
    gen = torch.Generator().manual_seed(seed)
    frames = [_blur(torch.roll(img, (-2 * t, 3 * t), (0, 1)), s) for t, s in enumerate(blurs)]
    frames = [(f + torch.randn(f.shape, generator=gen, dtype=torch.float64)).round() for f in frames]
    grid = torch.arange(40.0, 153.0, 8.0, dtype=torch.float64)
    points = torch.stack(torch.meshgrid(grid, grid, indexing="xy"), -1).reshape(-1, 2)
    return frames, points, points + torch.tensor([3.0, -2.0], dtype=torch.float64) * (len(blurs) - 1)


@pytest.mark.parametrize("blurs", [(0.5, 1.5, 2.3, 3.0, 3.6), (3.6, 3.6, 0.5, 0.5, 0.5)])
def test_blur_matching_removes_the_drift_of_a_changing_blur(blurs):
    """Growing defocus (the filters are sharper than each new frame) and defocus wearing off (the frame is
    sharper than the filters): matching the blur before the search is several times more precise than not."""
    frames, points, truth = _blur_sequence(blurs, seed=8)
    errors = {}
    for blur_match in (None, 2.0):
        tracks, lost, _ = PointTracker("ccot", blur_match=blur_match).double().track(frames, points)
        errors[blur_match] = (tracks[-1] - truth).norm(dim=-1).median().item()
    assert not lost[-1].any()  # the matched tracker's
    assert errors[2.0] < 0.3 and errors[2.0] < 0.5 * errors[None], errors


def test_blur_matching_leaves_a_steady_blur_alone():
    frames, points, _ = _blur_sequence((1.0, 1.3, 0.8, 1.2), seed=9)  # changes below 2 px^2
    plain = PointTracker("ccot", blur_match=None).double().track(frames, points)
    matched = PointTracker("ccot").double().track(frames, points)
    for a, b in zip(plain, matched, strict=True):
        torch.testing.assert_close(a, b)


def _streak_sequence(lengths: tuple[float, ...], angle: float, seed: int):
    """Crops of a broadband random texture (detail at several scales, sharp-edged rectangles) moving by (3, -2) px
    per frame, blurred by straight streaks of ``lengths`` px at ``angle`` (a panning camera), with sensor noise
    of std 1, rounded: frames, start points on a grid, their true last positions."""
    big = textured(260, 260, seed, rectangles=60)
    rng = np.random.default_rng(seed + 1)
    frames = []
    for t, length in enumerate(lengths):  # content moves right and up: the crop window moves left and down
        crop = np.ascontiguousarray(big[30 + 2 * t : 222 + 2 * t, 30 - 3 * t : 222 - 3 * t], np.float32)
        noisy = streak_blur(crop, length, angle) + rng.normal(0, 1, crop.shape)
        frames.append(torch.from_numpy(noisy.clip(0, 255).round()))
    grid = torch.arange(40.0, 153.0, 8.0, dtype=torch.float64)
    points = torch.stack(torch.meshgrid(grid, grid, indexing="xy"), -1).reshape(-1, 2)
    return frames, points, points + torch.tensor([3.0, -2.0], dtype=torch.float64) * (len(lengths) - 1)


def test_streak_matching_removes_the_scatter_of_a_growing_motion_blur():
    """A motion blur growing from 2 to 14 px: the streaks are found (cepstral scores below the default -10 from 5
    px on) and matched exactly, several times more precise than the Gaussian stand-in of the plain blur
    matching (0.33 against 1.00 px when written)."""
    frames, points, truth = _streak_sequence((2.0, 5.0, 8.0, 11.0, 14.0), 0.6, seed=11)
    scores = motion_blur_streak(torch.stack(frames)[:, None].float())[:, 2]
    assert (scores[1:] < -10).all(), scores
    errors = {}
    for streak_score in (None, -10.0):
        tracks, lost, _ = PointTracker("ccot", streak_score=streak_score).double().track(frames, points)
        errors[streak_score] = (tracks[-1] - truth).norm(dim=-1).median().item()
    assert not lost[-1].any()  # the streak-matched tracker's
    assert errors[-10.0] < 0.5 * errors[None], errors


@pytest.mark.parametrize("length", [8.0, 16.0])
def test_a_streak_on_the_block_lattice_counts_where_no_block_grid_shows(length):
    """A vertical streak of 8 or 16 px ends on the 8 px lattice where a JPEG block grid leaves its cepstral
    minima: found (length and angle within 0.3 px and 0.02 rad) in the uncompressed frame, whose block-grid ratio
    is about 1, and not once the frame is JPEG-compressed (quality 50: a block grid shows, and the minimum could be
    the grid's)."""
    frame = _streak_sequence((length,), math.pi / 2, seed=3)[0][0]
    tracker = PointTracker("ccot")
    found = tracker._streak(frame[None, None].float())
    assert found is not None and abs(found[0] - length) < 0.3 and abs(found[1] - math.pi / 2) < 0.02, found
    ok, data = cv2.imencode(".jpg", frame.numpy().astype(np.uint8), [cv2.IMWRITE_JPEG_QUALITY, 50])
    compressed = torch.from_numpy(cv2.imdecode(data, cv2.IMREAD_GRAYSCALE).astype(np.float32))
    assert tracker._streak(compressed[None, None]) is None


def test_a_streak_is_uniform_where_it_blurs_every_quarter():
    """An 8 px streak at 0.6 rad read in each quarter of the frame: a panning camera's blurs all four alike, the
    same streak over the left half only (a pan that follows an object, sharp on the right) is not uniform; no
    streak, quarters too small to read, or a previous frame with the same streak, never are."""
    tracker = PointTracker("ccot")
    streaked = _streak_sequence((8.0,), 0.6, seed=3)[0][0]
    sharp = _streak_sequence((0.0,), 0.6, seed=3)[0][0]  # the same crop and noise, no blur
    partial = torch.cat([streaked[:, :96], sharp[:, 96:]], 1)
    assert tracker._uniform(streaked[None, None].float(), (8.0, 0.6))
    assert not tracker._uniform(partial[None, None].float(), (8.0, 0.6))
    assert not tracker._uniform(streaked[None, None].float(), None)
    assert not tracker._uniform(streaked[None, None, :120].float(), (8.0, 0.6))  # quarters of 60 px
    # a first streak that the previous frame already showed (below the detection tests) is no new blur
    assert tracker._uniform(streaked[None, None].float(), (8.0, 0.6), previous=sharp[None, None].float())
    assert not tracker._uniform(streaked[None, None].float(), (8.0, 0.6), previous=streaked[None, None].float())


def test_streak_score_is_checked():
    with pytest.raises(InputError, match="streak_score"):
        PointTracker("ccot", streak_score=3.0)
    with pytest.raises(InputError, match="streak_match"):
        PointTracker("ccot", streak_match=0.0)


def test_search_prior_does_not_bias_a_clear_peak():
    """The displacement prior chooses the peak; the sub-pixel position still comes from the unweighted map."""
    img = _smooth_image(128, 128, 10)
    frames = [img, _translate(img, 2.7, -1.4)]
    points = torch.tensor([[40.0, 50.0], [64.0, 64.0], [90.0, 70.0]], dtype=torch.float64)
    free = PointTracker("ccot", search_sigma=0.0).double().track(frames, points)[0][1]
    weighted = PointTracker("ccot").double().track(frames, points)[0][1]
    torch.testing.assert_close(weighted, free, atol=0.01, rtol=0)
    torch.testing.assert_close(weighted - points, torch.tensor([[2.7, -1.4]] * 3, dtype=torch.float64), atol=0.05,
                               rtol=0)


def test_label_width_per_method_matches_the_closed_form_gaussian():
    """Each level's label is the Fourier series of a periodic Gaussian, ``prod_axes sqrt(2 pi) sigma / n
    exp(-2 (pi sigma k / n)^2)`` (REFERENCE: the C-COT label) over the level's band, of std 0.7 px for the continuous
    filters and 1 px for MOSSE by default (its label the real DFT of the sampled Gaussian), ``sigma`` overriding
    both; a width that is not positive is refused."""
    def closed_form(n: int, m: int, sigma: float) -> torch.Tensor:
        rows = torch.tensor([*range(m + 1), *range(-m, 0)], dtype=torch.float64)[:, None]
        columns = torch.arange(m + 1, dtype=torch.float64)
        axis = [math.sqrt(2 * math.pi) * sigma / n * torch.exp(-2 * (math.pi * sigma * k / n) ** 2)
                for k in (rows, columns)]
        return (axis[0] * axis[1])[:, None, :]  # (2M + 1, 1, M + 1)

    for method, settings, sigma in (("ccot", {}, 0.7), ("ccot_ff", {}, 0.7), ("ccot", {"sigma": 1.3}, 1.3)):
        tracker = PointTracker(method, **settings)
        for level, (n, m) in enumerate(zip(tracker.sizes, tracker.bands, strict=True)):
            torch.testing.assert_close(getattr(tracker, f"label_{level}").double(), closed_form(n, m, sigma),
                                       rtol=1e-6, atol=1e-9)
    mosse = PointTracker("mosse")
    n, m = mosse.sizes[0], mosse.bands[0]
    offsets = torch.remainder(torch.arange(n) + n // 2, n) - n // 2  # FFT order
    gaussian = torch.exp(-(offsets[:, None] ** 2 + offsets[None, :] ** 2) / 2.0).double()  # std 1 px
    want = torch.fft.rfft2(gaussian / gaussian.max()).real[band_index(n, m), : m + 1, None].transpose(1, 2)
    torch.testing.assert_close(mosse.label_0.double(), want, rtol=1e-5, atol=1e-6)
    for value in (0.0, -0.5, float("nan")):
        with pytest.raises(InputError, match="label sigma"):
            PointTracker("ccot", sigma=value)


@pytest.mark.parametrize("seed", [0, 1])
def test_default_label_tracks_a_rotating_scaling_patch_more_precisely_than_one_px(seed):
    """Real scenes deform in every step: on a texture rotated by 4 degrees and scaled by 1.04 about its centre
    (truth from the affine map) the default 0.7 px label of the continuous filter places the points more precisely
    than a 1 px label (measured 4-6 % lower mean error on this texture; on real frames under such maps 2-5 %), which
    is why it is the default; both keep every point."""
    image = textured(192, 192, seed)
    affine = cv2.getRotationMatrix2D((96.0, 96.0), 4.0, 1.04)
    warped = cv2.warpAffine(image, affine, (192, 192), flags=cv2.INTER_CUBIC, borderMode=cv2.BORDER_REFLECT)
    grid = torch.arange(40.0, 153.0, 8.0, dtype=torch.float64)
    points = torch.stack(torch.meshgrid(grid, grid, indexing="xy"), -1).reshape(-1, 2)
    affine = torch.from_numpy(affine)
    truth = points @ affine[:, :2].T + affine[:, 2]
    frames = [torch.from_numpy(image), torch.from_numpy(warped)]
    errors = {}
    # the whole texture turns alike (a turn of 0.08): turn matching is off, the patches must deform as a scene's do
    trackers = (("default", PointTracker("ccot", turn_match=None)),
                ("1 px", PointTracker("ccot", sigma=1.0, turn_match=None)))
    for name, tracker in trackers:
        tracks, lost, _ = tracker.double().track(frames, points)
        assert not lost[1].any()
        errors[name] = (tracks[1] - truth).norm(dim=-1).mean().item()
    assert errors["default"] < 0.98 * errors["1 px"], errors


def test_search_and_blur_settings_are_checked():
    assert PointTracker("ccot").search_sigmas == (3.0, 3.0, 0.0, 0.0, 0.0)
    assert PointTracker("ccot", levels=2, patch_size=21, newton_iterations=2).search_sigmas == (3.0, 0.0)
    with pytest.raises(InputError, match="search_sigma"):
        PointTracker("ccot", search_sigma=-1.0)
    with pytest.raises(InputError, match="one value per pyramid level"):
        PointTracker("ccot", search_sigma=(3.0, 3.0))
    for value in (0.0, -2.0, float("nan")):
        with pytest.raises(InputError, match="blur_match"):
            PointTracker("ccot", blur_match=value)


def _jpeg(image: np.ndarray, quality: int) -> torch.Tensor:
    data = cv2.imencode(".jpg", image.clip(0, 255).round().astype(np.uint8), [cv2.IMWRITE_JPEG_QUALITY, quality])[1]
    return torch.from_numpy(cv2.imdecode(data, cv2.IMREAD_GRAYSCALE).astype(np.float64))


_SHIFT = (3.4, -2.3)  # px: the motion of the compressed pairs below


def _compressed_pair(quality: int, spacing: float) -> tuple[list[torch.Tensor], torch.Tensor]:
    """A texture at JPEG quality 90 and the same texture shifted by ``_SHIFT`` at ``quality``, and a grid of
    points ``(P, 2)`` ``spacing`` px apart inside both."""
    image = textured(200, 240, 5)
    moved = cv2.warpAffine(image, np.float64([[1, 0, _SHIFT[0]], [0, 1, _SHIFT[1]]]), (240, 200),
                           flags=cv2.INTER_CUBIC, borderMode=cv2.BORDER_REFLECT)
    grid = torch.arange(40.0, 161.0, spacing, dtype=torch.float64)
    points = torch.stack(torch.meshgrid(grid, grid, indexing="xy"), -1).reshape(-1, 2)
    return [_jpeg(image, 90), _jpeg(moved, quality)], points


@pytest.mark.parametrize("quality", [3, 20])
def test_a_blocked_frame_takes_the_estimate_of_the_coarser_levels(quality):
    """A frame compressed until its 8 px blocks are nearly flat (JPEG quality 3 on this texture: block-grid ratio
    above 3) gets no correction from the levels on which a block spans more than 2 px, which is more precise than
    taking theirs; at quality 20 (ratio about 1.6) the blocks still hold the scene and both settings track alike.
    (At quality 5 the 31 px level-0 patch is already slightly more precise than the coarser levels.) Without the
    compression term of the regulariser (``compression_reg`` 0), which at quality 3 makes levels 0 and 1 about as
    precise as the coarser levels (0.53 against 0.52 px here), and without the first-step retry (``low_snr_psr``
    None), which reads the block error as noise and hands the pair to the low-SNR twin."""
    frames, points = _compressed_pair(quality, 10.0)
    tracks = {limit: PointTracker("ccot", block_limit=limit, compression_reg=0, low_snr_psr=None).double()
              .track(frames, points)[0][1] for limit in (None, 3.0)}
    errors = {k: (v - points - torch.tensor(_SHIFT, dtype=torch.float64)).norm(dim=-1).median().item()
              for k, v in tracks.items()}
    if quality == 3:
        assert errors[3.0] < 0.8 * errors[None], errors
    else:
        torch.testing.assert_close(tracks[3.0], tracks[None], rtol=0, atol=0)


@pytest.mark.parametrize("quality", [3, 20])
def test_a_blocked_frame_keeps_the_points_whose_peak_its_blocks_weaken(quality):
    """In a frame blocked as above (quality 3) the absolute PSR floor is ``block_psr_threshold``: the points the
    usual floor would flag and the lower one keeps have a PSR between the two and lie where the known shift puts
    them (within 1.5 px), and no point is flagged that the usual floor keeps; at quality 20 (not blocked) the
    setting changes nothing (a 5 px grid: enough points have a PSR between the floors). Without the compression
    term of the regulariser (``compression_reg`` 0), which raises the level-0 PSR of a blocked frame above both
    floors, and without the first-step retry (``low_snr_psr`` None), which would hand the pair to the twin. With
    the 1 px label of MOSSE (``sigma`` 1): on this texture it leaves three points' PSRs between the two floors,
    where the usual floor flags them (with the continuous default's 0.7 px label neither floor flags a point of this
    pair)."""
    frames, points = _compressed_pair(quality, 5.0)
    runs = {floor: PointTracker("ccot", sigma=1.0, block_psr_threshold=floor, compression_reg=0,
                                low_snr_psr=None).double().track(frames, points) for floor in (2.5, 1.5)}
    (tracks, usual, psr), (_, lower, _) = (tuple(v[1] for v in run) for run in runs.values())
    if quality == 20:
        assert torch.equal(usual, lower) and not usual.all()
        return
    kept = usual & ~lower
    assert kept.sum() >= 3 and not (lower & ~usual).any()
    assert ((psr[kept] >= 1.5) & (psr[kept] < 2.5)).all()
    errors = (runs[1.5][0][1] - points - torch.tensor(_SHIFT, dtype=torch.float64)).norm(dim=-1)
    assert (errors[kept] < 1.5).all(), errors[kept]


@pytest.mark.parametrize("floor_relative", [0.4, None])
@pytest.mark.parametrize("scale", [1.0, 0.2])
@pytest.mark.parametrize("count", [12, 6])
def test_the_psr_floor_is_lowered_in_a_frame_of_low_psrs(monkeypatch, floor_relative, scale, count):
    """With the level-0 PSRs of ``count`` points set (``scale`` times a fixed spread) and the tests against the
    frame and the backward search switched off, a point is lost exactly where its PSR is below ``psr_threshold``
    and, in a frame of at least 10 tracked points, below ``floor_relative`` times their geometric mean PSR (a point
    outside the frame is lost and not counted): in the frame of high PSRs the absolute floor, in the other the
    relative one, which keeps points the absolute floor flags; with 6 points, or without ``floor_relative``, the
    absolute floor."""
    import models.tracking.point_tracker as module

    gen = torch.Generator().manual_seed(2)
    img = _smooth_image(96, 96, 6)
    grid = torch.tensor([20.0, 35.0, 50.0, 65.0], dtype=torch.float64)
    inside = torch.stack(torch.meshgrid(grid, grid[:3], indexing="xy"), -1).reshape(-1, 2)[:count]
    points = torch.cat([inside, torch.tensor([[200.0, 40.0]], dtype=torch.float64)])  # the last one outside
    spread_psr = torch.tensor([40.0, 25.0, 12.0, 10.0, 9.0, 2.0, 30.0, 20.0, 15.0, 8.0, 6.0, 3.0], dtype=torch.float64)
    psr = torch.cat([scale * spread_psr[:count], torch.tensor([0.5], dtype=torch.float64)])
    tracker = PointTracker("ccot", floor_relative=floor_relative, low_snr=None).double()
    monkeypatch.setattr(module, "interleaved_psr", lambda *args: psr.clone())
    monkeypatch.setattr(tracker, "_lost_threshold", lambda psr, lost: torch.zeros_like(psr))
    monkeypatch.setattr(tracker, "_fails_backward", lambda weak, *args: torch.zeros_like(weak))
    moved = _translate(img, 1.0, 0.5) + torch.randn(96, 96, generator=gen, dtype=torch.float64)
    state = tracker.init(img, points)
    lost = tracker(moved[None, None], img[None, None], state.positions, state.lost, state.psr_mean, *state.filters)[1]
    values = psr[:-1].tolist()
    mean = math.exp(sum(math.log(v) for v in values) / len(values))
    relative = floor_relative is not None and count >= 10
    floor = min(2.5, floor_relative * mean) if relative else 2.5
    assert lost.tolist() == [v < floor for v in values] + [True], (floor, lost.tolist())
    below_absolute = sum(v < 2.5 for v in values)
    assert below_absolute >= 1 and (sum(v < floor for v in values) < below_absolute) == (relative and scale < 1)


@pytest.mark.parametrize("quality", [3, 20])
def test_in_a_blocked_frame_only_the_floor_flags_points(monkeypatch, quality):
    """With every point made weak against the frame and a forward-backward test made to fail always, every point
    is lost in a frame that is not blocked (quality 20); in a blocked frame (quality 3) the lost points are exactly
    those whose PSR is below ``block_psr_threshold``, whatever the tests on level 0 say (``compression_reg`` 0, as
    above; the floor not lowered to the frame's PSRs, ``floor_relative`` None; no first-step retry, ``low_snr_psr``
    None)."""
    frames, points = _compressed_pair(quality, 8.0)
    tracker = PointTracker("ccot", block_psr_threshold=3.0, compression_reg=0, floor_relative=None,
                           low_snr_psr=None).double()
    monkeypatch.setattr(tracker, "_lost_threshold", lambda psr, lost: torch.full_like(psr, math.inf))
    monkeypatch.setattr(tracker, "_fails_backward", lambda weak, *args: weak)
    _, lost, psr = (v[1] for v in tracker.track(frames, points))
    if quality == 20:
        assert lost.all()
    else:
        assert 0 < lost.sum() < len(points) and torch.equal(lost, psr < 3.0)


def test_block_limit_is_checked():
    for value in (1.0, 0.5, float("nan")):
        with pytest.raises(InputError, match="block_limit"):
            PointTracker("ccot", block_limit=value)
    for value in (-0.5, float("nan")):
        with pytest.raises(InputError, match="block_psr_threshold"):
            PointTracker("ccot", block_psr_threshold=value)


def test_compression_term_makes_compressed_tracks_more_precise():
    """A texture at JPEG quality 90 and shifted at quality 15: with the compression error in the regulariser
    (``compression_reg`` 3) the tracks are at least 15 % more precise than without (0.085 against 0.115 px)."""
    frames, points = _compressed_pair(15, 10.0)
    errors = {}
    for weight in (0.0, 3.0):
        tracks = PointTracker("ccot", compression_reg=weight, low_snr=None).double().track(frames, points)[0]
        errors[weight] = (tracks[1] - points - torch.tensor(_SHIFT, dtype=torch.float64)).norm(dim=-1).median()
    assert errors[3.0] < 0.85 * errors[0.0], errors


def test_signal_to_noise_is_the_patch_variance_over_the_noise():
    """A smooth texture plus white noise of std 10: the median over the points of the variance of each 31 px crop
    (a loop over the points, integer positions) over the noise variance 100, within 15 %."""
    gen = torch.Generator().manual_seed(5)
    image = _smooth_image(120, 140, 5) + 10 * torch.randn(120, 140, generator=gen, dtype=torch.float64)
    points = torch.tensor([[30.0, 30.0], [70.0, 50.0], [100.0, 80.0], [50.0, 90.0], [110.0, 40.0]],
                          dtype=torch.float64)
    got = PointTracker().double().signal_to_noise(image[None, None], points)
    crops = [image[int(y) - 15 : int(y) + 16, int(x) - 15 : int(x) + 16] for x, y in points.tolist()]
    want = np.median([crop.var(unbiased=False).item() / 100 for crop in crops])
    assert got.shape == (1,) and got.item() == pytest.approx(want, rel=0.15)


def test_signal_to_noise_reads_the_points_inside_only():
    """Points outside the frame or not finite are left out: the lower median over the inside points of each 31 px
    crop's variance (a loop over the points, integer positions) over the tracker's own noise variance, exact to
    rounding for an even and an odd count; inf where no point is inside."""
    gen = torch.Generator().manual_seed(6)
    image = (_smooth_image(120, 140, 5) + 10 * torch.randn(120, 140, generator=gen, dtype=torch.float64))[None, None]
    tracker = PointTracker().double()
    inside = [[30.0, 30.0], [70.0, 50.0], [100.0, 80.0], [50.0, 90.0], [110.0, 40.0], [60.0, 70.0]]
    outside = [[-3.0, 40.0], [150.0, 50.0], [40.0, 125.0], [float("nan"), 60.0], [float("inf"), 1.0]]
    noise = tracker._noise_variance(image).item()
    for count in (6, 5):
        points = torch.tensor(outside[:2] + inside[:count] + outside[2:], dtype=torch.float64)
        ratios = sorted(image[0, 0, int(y) - 15 : int(y) + 16, int(x) - 15 : int(x) + 16].var(unbiased=False).item()
                        / noise for x, y in inside[:count])
        got = tracker.signal_to_noise(image, points)
        assert got.shape == (1,) and got.item() == pytest.approx(ratios[(count - 1) // 2], rel=1e-9)
    assert tracker.signal_to_noise(image, torch.tensor(outside, dtype=torch.float64)).item() == math.inf


def _noisy_sequence(noise: float, step: tuple[float, float] = (2.5, -1.5),
                    frames: int = 4) -> tuple[list[torch.Tensor], torch.Tensor, torch.Tensor]:
    """``frames`` frames of a smooth texture moving by ``step`` px per frame, each with its own white noise of std
    ``noise``, a grid of points and their true positions in the last frame."""
    gen = torch.Generator().manual_seed(0)
    image = _smooth_image(160, 160, 4)
    out = [_translate(image, step[0] * t, step[1] * t) + noise * torch.randn(160, 160, generator=gen,
                                                                             dtype=torch.float64)
           for t in range(frames)]
    grid = torch.arange(30.0, 131.0, 10.0, dtype=torch.float64)
    points = torch.stack(torch.meshgrid(grid, grid, indexing="xy"), -1).reshape(-1, 2)
    return out, points, points + (frames - 1) * torch.tensor(step, dtype=torch.float64)


_TWIN_BAND = (0.7,) * 5  # the default twin's band fractions, finest level first
_TWIN_FIRST = (2.0, 2.0, 0.0, 0.0, 0.0)  # the default twin's first-step prior (px per level, finest first)
_TWIN = dict(window="tukey", patch_size=31, band=_TWIN_BAND, low_snr=None, first_step_sigma=_TWIN_FIRST)


def test_a_noisy_sequence_goes_to_the_low_snr_twin():
    """Noise of std 20 on the texture (median SNR about 4, below ``low_snr``): the sequence is tracked by the twin
    (the state says so frame after frame; the tracks equal those of a Tukey, 31 px tracker keeping 0.7 of level
    0's frequencies), more precisely than the Hann tracker alone; without noise, or with ``low_snr`` None, the
    tracker keeps its own filters."""
    frames, points, truth = _noisy_sequence(20.0)
    tracker = PointTracker().double()
    state = tracker.init(frames[0], points)
    assert state.low_snr and tracker.step(frames[1], state).low_snr
    assert not tracker.init(frames[0], points, switch=False).low_snr
    tracks = tracker.track(frames, points)[0]
    twin = PointTracker(**_TWIN).double().track(frames, points)[0]
    torch.testing.assert_close(tracks, twin, rtol=0, atol=0)
    hann = PointTracker(low_snr=None).double().track(frames, points)[0]
    errors = [(t[-1] - truth).norm(dim=-1).median() for t in (tracks, hann)]
    assert errors[0] < 0.8 * errors[1], errors
    assert not PointTracker(low_snr=None).double().init(frames[0], points).low_snr
    clean, _, _ = _noisy_sequence(0.0)
    assert not tracker.init(clean[0], points).low_snr


@pytest.mark.parametrize("noise", [0.0, 20.0])
def test_init_extracts_the_level_0_patches_once(monkeypatch, noise):
    """The first frame's level-0 patches, read for the SNR test, are the ones the filters learn from, on the
    tracker's own path and on the low-SNR twin's (noise 20): one extraction per level, and filters bit-equal to
    those of a tracker (or a twin) without the SNR test, points outside the frame among them."""
    import models.tracking.point_tracker as module

    frames, points, _ = _noisy_sequence(noise)
    points = torch.cat([points, torch.tensor([[-4.0, 10.0], [200.0, 30.0]], dtype=torch.float64)])
    calls = []
    monkeypatch.setattr(module, "extract_patches", lambda *args: calls.append(args[2]) or extract_patches(*args))
    tracker = PointTracker().double()
    state = tracker.init(frames[0], points)
    assert state.low_snr == (noise > 0)
    assert len(calls) == tracker.levels, calls
    alone = (PointTracker(**_TWIN) if noise
             else PointTracker(low_snr=None))
    for got, want in zip(state.filters, alone.double().init(frames[0], points).filters, strict=True):
        torch.testing.assert_close(got, want, rtol=0, atol=0)


def test_window_and_low_snr_settings_are_checked():
    with pytest.raises(InputError, match="unknown patch window"):
        PointTracker("ccot", window="box")
    for value in (0.0, -1.0, float("nan")):
        with pytest.raises(InputError, match="low_snr"):
            PointTracker("ccot", low_snr=value)
    with pytest.raises(InputError, match="compression_reg"):
        PointTracker("ccot", compression_reg=-1.0)
    for value in (0.0, -0.4, float("nan")):
        with pytest.raises(InputError, match="floor_relative"):
            PointTracker("ccot", floor_relative=value)
        with pytest.raises(InputError, match="low_snr_psr"):
            PointTracker("ccot", low_snr_psr=value)


def test_the_low_snr_twin_keeps_every_other_setting():
    """The twin of a tracker with every setting off its default differs only in window, patch sizes, level 0's
    band (at least 0.7 of its frequencies), the first-step prior (2 px where ``search_sigma`` weights) and
    low_snr: each stored setting, each level's label (sigma) and the
    coarser levels' band fractions are the parent's; a parent's wider level-0 band stays."""
    settings = dict(method="mosse", levels=3, sigma=1.5, eta=0.05, reg_rel=0.02, newton_iterations=(1, 1, 0),
                    search_sigma=(2.0, 0.0, 0.0), psr_threshold=3.0, floor_relative=0.5, psr_relative=0.4,
                    psr_rate=0.5, psr_recover=0.8,
                    fb_threshold=2.0, psr_exclude=5, band=0.6, noise_reg=10.0, blur_match=None, streak_score=-5.0,
                    streak_match=3.0, block_limit=4.0, block_psr_threshold=1.0, compression_reg=1.0)
    tracker = PointTracker(**settings, patch_size=(31, 21, 21), low_snr=50.0)
    twin = tracker.low_snr_tracker
    assert (twin.window, twin.sizes, twin.low_snr, twin.low_snr_tracker) == ("tukey", (31, 31, 31), None, None)
    assert (tracker.low_snr_psr, twin.low_snr_psr) == (16.0, None)
    assert (tracker.first_step_sigmas, twin.first_step_sigmas) == (None, (2.0, 0.0, 0.0))
    names = ("method", "levels", "eta", "reg_rel", "newton", "search_sigmas", "psr_threshold", "floor_relative",
             "psr_relative",
             "psr_rate", "psr_recover", "fb_threshold", "psr_exclude", "noise_reg", "blur_match", "streak_score",
             "streak_match", "block_limit", "block_psr_threshold", "compression_reg")
    assert {n: getattr(twin, n) for n in names} == {n: getattr(tracker, n) for n in names}
    assert twin.bands == (10, 9, 9)  # 0.7 of 15 (10.5, rounded to even) at level 0, 0.6 of 15 at the others
    assert PointTracker(band=(0.9, 0.5, 0.5, 0.5, 0.5)).low_snr_tracker.bands == (14, 8, 8, 8, 8)  # 13.5, 7.5: even
    torch.testing.assert_close(twin.label_1, tracker.label_0, rtol=0, atol=0)  # both 31 px, band 9, sigma 1.5


def test_displacement_prior_is_a_gaussian_of_the_wrapped_shift():
    """Every bin of the prior map against a loop over the bins: shift ``i`` for ``i <= n // 2``, ``i - n`` above
    (FFT order), weight ``exp(-(dy^2 + dx^2) / (2 sigma^2))``; sigma 0 weights nothing."""
    for n, sigma in ((7, 2.0), (31, 3.0), (21, 1.5)):
        want = torch.empty(n, 1, n)
        for i in range(n):
            for j in range(n):
                dy, dx = (i if i <= n // 2 else i - n), (j if j <= n // 2 else j - n)
                want[i, 0, j] = math.exp(-(dy * dy + dx * dx) / (2 * sigma * sigma))
        torch.testing.assert_close(displacement_prior(n, sigma), want, rtol=1e-5, atol=1e-12)
    assert torch.equal(displacement_prior(9, 0.0), torch.ones(9, 1, 9))


def test_the_first_step_prior_weights_new_points_in_frames_without_a_codec_grid():
    """``first_step_sigma``: the points without PSR history (inf) in a frame of block-grid ratio up to 1.5 take the
    first-step prior, every other point the ``search_sigma`` one; a tracker without it, a frame whose grid was not
    measured, or (eager) a frame where no point takes it, weights all alike. The low-SNR twin gets 2 px on the
    levels where ``search_sigma`` weights."""
    tracker = PointTracker(first_step_sigma=(2.0, 1.0, 0.0, 0.0, 0.0))
    psr_mean = torch.tensor([math.inf, 4.0, math.inf])
    assert tracker._first_step(torch.tensor([1.02]), psr_mean).tolist() == [True, False, True]
    assert tracker._first_step(torch.tensor([1.5]), psr_mean).tolist() == [True, False, True]
    assert tracker._first_step(torch.tensor([1.9]), psr_mean) is None  # eager, and no point takes it
    assert tracker._first_step(torch.tensor([1.0]), torch.tensor([4.0, 2.0])) is None
    assert tracker._first_step(None, psr_mean) is None
    assert PointTracker()._first_step(torch.tensor([1.0]), psr_mean) is None
    for level, sigmas in ((0, (2.0, 3.0)), (1, (1.0, 3.0))):
        weight = tracker._search_weight(level, torch.tensor([True, False, False]))
        assert weight.shape == (31 if level == 0 else 21, 3, 31 if level == 0 else 21)
        for point, sigma in zip((0, 1, 2), (sigmas[0], sigmas[1], sigmas[1]), strict=True):
            torch.testing.assert_close(weight[:, point : point + 1], displacement_prior(weight.shape[0], sigma))
    assert PointTracker(search_sigma=(3.0, 0, 0, 0, 0)).low_snr_tracker.first_step_sigmas == (2.0, 0, 0, 0, 0)
    assert PointTracker().first_step_sigmas is None
    for value in (-1.0, (2.0, 2.0)):
        with pytest.raises(InputError, match="first_step_sigma"):
            PointTracker(first_step_sigma=value)


def _dark_texture(frames: int, quality: int | None = None) -> tuple[list[torch.Tensor], torch.Tensor, torch.Tensor]:
    """``frames`` frames of fine texture (Gaussian-blurred noise, std 2 px) whose contrast fades from 6 gray levels
    on the right to 0.06 on the left, on a dark background (30) with white noise of std 3, moving by (2.5, -1.5) px
    per frame (cubic interpolation); JPEG-coded at ``quality`` where given. A grid of points and their true
    positions after one step."""
    rng = np.random.default_rng(0)
    texture = cv2.GaussianBlur(rng.normal(0, 1, (224, 224)), (0, 0), 2.0)
    texture = 6 * np.linspace(0.1, 1.0, 224)[None, :] ** 2 * texture / texture.std()
    out = []
    for t in range(frames):
        shift = np.float32([[1, 0, 2.5 * t], [0, 1, -1.5 * t]])
        frame = 30 + cv2.warpAffine(texture, shift, (224, 224), flags=cv2.INTER_CUBIC, borderMode=cv2.BORDER_REFLECT)
        frame = (frame + rng.normal(0, 3, frame.shape)).round().clip(0, 255).astype(np.uint8)
        if quality is not None:
            frame = cv2.imdecode(cv2.imencode(".jpg", frame, [cv2.IMWRITE_JPEG_QUALITY, quality])[1], 0)
        out.append(torch.from_numpy(frame.astype(np.float64)))
    grid = torch.arange(32.0, 193.0, 8.0, dtype=torch.float64)
    points = torch.stack(torch.meshgrid(grid, grid, indexing="xy"), -1).reshape(-1, 2)
    return out, points, points + torch.tensor([2.5, -1.5], dtype=torch.float64)


def test_the_first_step_prior_holds_dark_points_to_the_coarse_estimate_in_their_first_step_only():
    """Low-contrast texture in noise (median SNR about 1.4), the twin's settings: with the 2 px first-step prior
    fewer points miss by more than 3 px in the first step than with the 3 px one; from the second step on both
    step alike (the same positions and lost flags from the same state), and in frames JPEG-coded at quality 70 (a
    block grid, ratio about 2.3) the tracks are the same, though the prior would change them there."""
    first = PointTracker(**_TWIN).double()
    plain = PointTracker(**{**_TWIN, "first_step_sigma": None}).double()
    frames, points, truth = _dark_texture(3)
    misses = [int(((t.track(frames[:2], points)[0][-1] - truth).norm(dim=-1) > 3).sum()) for t in (first, plain)]
    assert misses[0] <= 0.8 * misses[1] and misses[1] >= 10, misses
    state = first.step(frames[1], first.init(frames[0], points))
    after = [t.step(frames[2], state) for t in (first, plain)]
    torch.testing.assert_close(after[0].positions, after[1].positions, rtol=0, atol=0)
    assert torch.equal(after[0].lost, after[1].lost)
    compressed, points, _ = _dark_texture(2, quality=70)
    assert float(block_grid_ratio(compressed[0][None, None])) > 1.5
    for got, want in zip(first.track(compressed, points), plain.track(compressed, points), strict=True):
        torch.testing.assert_close(got, want, rtol=0, atol=0)


@pytest.mark.parametrize("shift", [(0.0, 0.0), (2.5, -1.5)])
def test_first_step_noise_reads_the_white_noise_of_a_textured_pair(shift):
    """Independent white noise of std 6 on both frames of a textured pair, still or moved by a sub-pixel shift:
    the first step's residual noise reads its variance, 36, within 10 %, and its residual SNR the median over the
    points of each 31 px crop's variance (a loop over the points) over 36, within 15 %; a still pair without noise
    reads no noise."""
    tracker = PointTracker().double()
    for noise in (6.0, 0.0):
        if noise == 0 and shift != (0.0, 0.0):
            continue
        frames, points, _ = _noisy_sequence(noise, shift, frames=2)
        state = tracker.init(frames[0], points, switch=False)
        frame = frames[1][None, None]
        new = tracker._advance(tracker, frame, state)
        snr, got, estimate = tracker.first_step_noise(frame, state.filters[0], new.positions, new.lost)
        torch.testing.assert_close(estimate, tracker._noise_variance(frame), rtol=0, atol=0)
        assert got.shape == snr.shape == (1,) and got.item() == pytest.approx(noise**2, abs=max(0.1 * noise**2, 1e-6))
        if noise:
            crops = [frames[1][round(y + shift[1]) - 15 : round(y + shift[1]) + 16,
                               round(x + shift[0]) - 15 : round(x + shift[0]) + 16] for x, y in points.tolist()]
            want = np.median([crop.var(unbiased=False).item() / noise**2 for crop in crops])
            assert snr.item() == pytest.approx(want, rel=0.15)


def _fine_texture_pair(condition: str | None = None,
                       degrees: float = 0.0) -> tuple[list[torch.Tensor], torch.Tensor, torch.Tensor]:
    """Two frames of fine texture (Gaussian-blurred noise, std 1.5 px) of std 15 around mid-gray, the second turned
    by ``degrees`` about the centre and moved by (2.5, -1.5) px (cubic interpolation), under a stress ``condition``
    (e.g. ``dark_jpeg``: 15 % brightness with shot and read noise, then JPEG at quality 90; None: clean); a grid of
    points and their true positions."""
    rng = np.random.default_rng(0)
    texture = cv2.GaussianBlur(rng.normal(0, 1, (224, 224)), (0, 0), 1.5)
    texture = 128 + 15 * texture / texture.std()
    move = cv2.getRotationMatrix2D((111.5, 111.5), degrees, 1.0) + np.array([[0, 0, 2.5], [0, 0, -1.5]])
    frames = np.stack([texture, cv2.warpAffine(texture, move, (224, 224), flags=cv2.INTER_CUBIC,
                                               borderMode=cv2.BORDER_REFLECT)])
    if condition is not None:
        frames = stress_frames(frames, condition, 0)
    grid = torch.arange(32.0, 193.0, 8.0, dtype=torch.float64)
    points = torch.stack(torch.meshgrid(grid, grid, indexing="xy"), -1).reshape(-1, 2)
    frames = [torch.from_numpy(f.round().clip(0, 255)).double() for f in frames]
    move = torch.from_numpy(move)
    return frames, points, points @ move[:, :2].T + move[:, 2]


def test_a_first_step_in_under_read_noise_is_tracked_again_by_the_twin(monkeypatch):
    """Dark frames stored as JPEG at quality 90: the frame's noise estimate reads the codec-thinned finest
    differences (SNR about 30, above ``low_snr``), so :meth:`init` keeps the Hann tracker; its first step's PSRs
    are low and its residuals show the noise, so the twin tracks the step again with a noise floor of 0.5-1.1 times
    the dark condition's noise variance before the codec (``0.6 s + 1.5^2`` at the mean signal ``s = 0.15 * 128``),
    for that step only: far fewer points miss by more than 1 px than without the retry (``low_snr_psr`` None). The
    clean texture keeps the Hann tracker."""
    frames, points, truth = _fine_texture_pair("dark_jpeg")
    tracker, plain = PointTracker().double(), PointTracker(low_snr_psr=None).double()
    twin, floors = tracker.low_snr_tracker, []
    step = twin.forward
    monkeypatch.setattr(twin, "forward", lambda *args, noise_floor=None: floors.append(noise_floor)
                        or step(*args, noise_floor=noise_floor))
    state = tracker.init(frames[0], points)
    assert not state.low_snr and tracker.signal_to_noise(frames[0][None, None], points).item() > 20
    new = tracker.step(frames[1], state)
    noise = 0.6 * 0.15 * 128 + 1.5**2
    assert new.low_snr and len(floors) == 1 and 0.5 < floors[0].item() / noise < 1.1, floors
    assert tracker.step(frames[0], new).low_snr and floors[1:] == [None]
    old = plain.step(frames[1], plain.init(frames[0], points))
    assert not old.low_snr
    misses = [int(((s.positions - truth).norm(dim=-1) > 1).sum()) for s in (new, old)]
    assert misses[0] <= 0.1 * misses[1] and misses[1] >= 30, misses
    clean, points, _ = _fine_texture_pair()
    state = tracker.step(clean[1], tracker.init(clean[0], points))
    assert not state.low_snr and len(floors) == 2


def _turned_first_step(monkeypatch, condition: str, degrees: float):
    """The first step of the fine-texture pair under ``condition``, its second frame turned by ``degrees``
    (:func:`_fine_texture_pair`; the tracker keeps the sequence at :meth:`init`, checked): the state after it, the
    truth, and the noise floors of the tracker's own steps and of its twin's, recorded as they ran."""
    frames, points, truth = _fine_texture_pair(condition, degrees=degrees)
    tracker = PointTracker().double()
    steps, floors = [], []
    for module, record in ((tracker, steps), (tracker.low_snr_tracker, floors)):
        forward = module.forward
        monkeypatch.setattr(module, "forward", lambda *args, noise_floor=None, record=record, forward=forward:
                            record.append(noise_floor) or forward(*args, noise_floor=noise_floor))
    state = tracker.init(frames[0], points)
    assert not state.low_snr
    return tracker.step(frames[1], state), truth, steps, floors


def test_a_turning_first_step_in_under_read_noise_stays_with_the_twin(monkeypatch):
    """The dark JPEG pair with the second frame also turned by 6 degrees (a turn of 0.105, beyond ``turn_match``):
    the retry hands the first step to the twin, which turn matches it on its floor (two twin steps, one floor);
    the tracker tracks the step again from the previous frame turned by the twin's step (its second own step),
    and there the residuals still show the noise, so the twin tracks it once more, on the floor read there, and
    keeps the sequence. Nearly every point ends within 1 px of the truth (1-2 of 441 miss, measured)."""
    new, truth, steps, floors = _turned_first_step(monkeypatch, "dark_jpeg", 6.0)
    assert new.low_snr and steps == [None, None] and len(floors) == 3, (steps, floors)
    assert floors[0] is not None and floors[1] is floors[0] and floors[2] is not floors[0]
    assert int(((new.positions - truth).norm(dim=-1) > 1).sum()) <= 5


def test_a_turning_first_step_retried_without_noise_returns_to_the_tracker(monkeypatch):
    """The fine-texture pair at a quarter of its contrast (``low_contrast``: its SNR keeps the tracker at
    :meth:`init`) turned by 8 degrees: the turn weakens the first step's matches and deforms its residuals, which
    read as under-read noise, so the twin tracks the step; the tracker tracks it again from the previous frame
    turned by the twin's step, where the residuals no longer read as noise, and keeps the sequence: every point
    within 0.5 px of the truth (at most 0.106 px, measured)."""
    new, truth, steps, floors = _turned_first_step(monkeypatch, "low_contrast", 8.0)
    assert not new.low_snr and len(steps) == 2 and floors and floors[0] is not None, (steps, floors)
    assert (new.positions - truth).norm(dim=-1).max() < 0.5


def weakening_streak_frames() -> list[np.ndarray]:
    """Six frames of fine, low-contrast texture under a streak growing from 1 to 12 px at 0.5 rad, fixed camera
    (:func:`data.flow.homography_sequence`, seeded): frame 4's cepstral score is -10.7, frame 5's -9.4, 5.5 below
    its rival; frames 2 and 3 read -8.9 and -9.9 with no streak before them."""
    rng = np.random.default_rng(0)
    texture = cv2.GaussianBlur(rng.normal(0, 1, (240, 320)), (0, 0), 0.7)
    texture = (128 + 5 * texture / texture.std()).astype(np.float32)
    return list(homography_sequence(texture, "motion", frames=6, moving=False, motion_angle=0.5).frames)


def test_a_weakening_streak_continues_from_the_frame_before():
    """Frame 5's weaker reading is a streak only as the continuation of frame 4's (within 0.3 px of the true 12
    px, along 0.5 rad); frames 2 and 3, as weak, start none; tracking carries frame 4's streak into frame 5."""
    frames = [torch.from_numpy(f)[None, None] for f in weakening_streak_frames()]
    tracker = PointTracker()
    found = [tracker._streak(f) for f in frames]
    assert [s is not None for s in found] == [False, False, False, False, True, False]
    continued = tracker._streak(frames[5], found[4])
    assert continued is not None and abs(continued[0] - 12.0) < 0.3 and abs(continued[1] - 0.5) < 0.02
    state = tracker.init(frames[0][0, 0], torch.tensor([[100.0, 80.0], [200.0, 150.0]]))
    streaks = []
    for frame in frames[1:]:
        state = tracker.step(frame[0, 0], state)
        streaks.append(state.streak)
    assert streaks[-2] == found[4] and streaks[-1] == continued


@pytest.mark.skipif(not torch.cuda.is_available(), reason="needs CUDA")
@pytest.mark.parametrize("condition", [None, "dark", "dark_jpeg"])
def test_tracks_on_cuda_match_the_cpu(condition):
    """The same tracker on a CUDA device: the synthetic sequence (6 frames, moderate motion, plain; dark, which the
    low-SNR twin takes; dark JPEG, whose first step the twin tracks again), 300 detected points, float32. The GPU
    sums in another order (and may round convolutions differently), so the tracks agree to a few hundredths of a
    pixel where both devices track a point, and the lost flags on nearly every point."""
    frames = synthetic_sequence(frames=6, size=(240, 320), max_motion=8.0, seed=3).frames
    if condition is not None:
        frames = stress_frames(frames, condition, 0)
    frames = [torch.from_numpy(f.round().clip(0, 255).astype(np.float32)) for f in frames]
    points = good_features_to_track(frames[0], 300, 0.01, 5).float()
    cpu_tracks, cpu_lost, _ = PointTracker("ccot").track(frames, points)
    gpu_tracks, gpu_lost, _ = PointTracker("ccot").cuda().track([f.cuda() for f in frames], points.cuda())
    gpu_tracks, gpu_lost = gpu_tracks.cpu(), gpu_lost.cpu()
    assert (cpu_lost == gpu_lost).float().mean() >= 0.98
    both = ~cpu_lost[-1] & ~gpu_lost[-1]
    assert both.sum() >= 0.5 * len(points)
    gap = (cpu_tracks[-1, both] - gpu_tracks[-1, both]).norm(dim=-1)
    assert gap.median() <= 0.01 and torch.quantile(gap, 0.95) <= 0.05


def test_memory_rate_rises_with_the_frames_turn():
    """The learning rate of a frame whose tracked points rotate by an angle about their centre (a closed-form
    turn: the angle in rad, the fit explaining every step): eta below ``turn_limit``, eta + ``turn_gain`` times the
    excess above it, at most ``eta_max``; eta with fewer than 10 tracked points or ``turn_limit`` None."""
    grid = torch.arange(0.0, 100.0, 20.0, dtype=torch.float64)
    start = torch.stack(torch.meshgrid(grid, grid, indexing="xy"), -1).reshape(-1, 2) + 50
    centre = start.mean(0)

    def turned(degrees: float) -> torch.Tensor:
        c, s = math.cos(math.radians(degrees)), math.sin(math.radians(degrees))
        return (start - centre) @ torch.tensor([[c, s], [-s, c]], dtype=torch.float64) + centre + 3.0

    tracker = PointTracker("ccot")
    tracked = torch.ones(len(start), dtype=torch.bool)
    for degrees, expected in ((2.0, 0.1), (4.0, 0.1 + 8 * (math.radians(4.0) - 0.05)), (6.0, 0.5)):
        assert tracker._memory_rate(start, turned(degrees), tracked).item() == pytest.approx(expected, rel=1e-9)
    few = torch.zeros_like(tracked)
    few[:9] = True
    assert tracker._memory_rate(start, turned(6.0), few).item() == pytest.approx(0.1)
    assert PointTracker("ccot", turn_limit=None)._memory_rate(start, turned(6.0), tracked).item() == pytest.approx(0.1)
    for name, value in (("turn_limit", -0.1), ("turn_gain", -1.0), ("eta_max", 0.0), ("eta_max", 1.5)):
        with pytest.raises(InputError, match=name):
            PointTracker("ccot", **{name: value})


def _turning_camera_within(seed: int, trackers: dict[str, PointTracker], radius: float) -> dict[str, float]:
    """A texture seen through homographies that turn by up to 10 degrees and zoom by up to 15 % a frame
    (``geometry=5``): per tracker, the fraction of the valid points not lost and within ``radius`` px of the truth
    at the last frame."""
    seq = homography_sequence(textured(192, 256, seed), "none", frames=6, seed=21, geometry=5.0)
    xs, ys = np.arange(40.0, 217.0, 12.0), np.arange(40.0, 153.0, 12.0)
    points = np.stack(np.meshgrid(xs, ys), -1).reshape(-1, 2)
    truth, valid = seq.track(points)
    frames = [torch.from_numpy(f.astype(np.float64)) for f in seq.frames]
    within = {}
    for name, tracker in trackers.items():
        tracks, lost, _ = tracker.double().track(frames, torch.from_numpy(points))
        close = (np.linalg.norm(tracks[-1].numpy() - truth[-1], axis=-1) < radius) & ~lost[-1].numpy()
        within[name] = close[valid[-1]].mean()
    return within


@pytest.mark.parametrize("seed", [0, 1])
def test_a_fast_turning_camera_is_tracked_with_the_faster_memory(seed):
    """Without turn matching: with the memory's rate raised by the frames' turn every point stays within 3 px of
    the truth at the last frame (measured 1.000 at both seeds); with the fixed rate (``turn_limit=None``, the
    tracker before) a quarter to a third of them drift away (0.76 and 0.65)."""
    within = _turning_camera_within(seed, {"turn": PointTracker("ccot", turn_match=None),
                                           "fixed": PointTracker("ccot", turn_limit=None, turn_match=None)}, 3.0)
    assert within["turn"] >= 0.97 and within["fixed"] <= 0.85, within


@pytest.mark.parametrize("seed", [0, 1])
def test_a_turn_matched_step_tracks_a_fast_turning_camera_to_a_pixel(seed):
    """Tracked again from the previous frame turned onto the new one wherever the points turn by more than
    ``turn_match``, every point ends within 1 px of the truth (measured 1.000 at both seeds); with the faster
    memory alone (``turn_match=None``) 0.83-0.89 of them."""
    within = _turning_camera_within(seed, {"matched": PointTracker("ccot"),
                                           "memory": PointTracker("ccot", turn_match=None)}, 1.0)
    assert within["matched"] >= 0.97 and within["memory"] <= 0.92, within
    with pytest.raises(InputError, match="turn_match"):
        PointTracker("ccot", turn_match=0.0)


def test_the_fifth_level_reaches_twice_as_far_in_a_large_frame():
    """A 704 px frame moved by (50, -45) px, beyond the fourth level's reach of about 40 px: the default tracker,
    whose fifth level searches in frames of 657 px and more, puts every point within 0.1 px of the exact
    translation; a 4-level tracker loses or misplaces many of them."""
    image = _smooth_image(704, 704, 3)
    moved = _translate(image, 50.0, -45.0)
    ys, xs = torch.meshgrid(torch.arange(200.0, 500.0, 50), torch.arange(200.0, 500.0, 50), indexing="ij")
    points = torch.stack([xs.flatten(), ys.flatten()], -1)
    truth = points + torch.tensor([50.0, -45.0])
    frames = [image.float(), moved.float()]
    tracks, lost, _ = PointTracker("ccot").track(frames, points.float())
    assert not lost[-1].any() and (tracks[-1] - truth).norm(dim=-1).max() < 0.1
    tracks, lost, _ = PointTracker("ccot", levels=4).track(frames, points.float())
    assert (~lost[-1] & ((tracks[-1] - truth).norm(dim=-1) < 0.5)).sum() < 30


def test_the_fifth_level_searches_only_where_the_frame_is_large_enough(monkeypatch):
    """A frame whose fifth-level image is under 42 px on its shorter side (below 657 px) tracks exactly as a
    4-level tracker; the level's gate reads the level image's shape alike as a bool in eager steps and as a bool
    tensor in an exported graph, ``min_levels`` 5 searches it in every frame, and the low-SNR twin has the same
    gate."""
    from models.tracking import point_tracker

    image = _smooth_image(240, 320, 4)
    points = torch.tensor([[100.0, 90.0], [160.0, 120.0], [220.0, 150.0]])
    frames = [image.float(), _translate(image, 3.5, -2.0).float()]
    five, four = PointTracker("ccot"), PointTracker("ccot", levels=4)
    for ours, ref in zip(five.track(frames, points), four.track(frames, points), strict=True):
        torch.testing.assert_close(ours, ref, rtol=0, atol=0)
    assert five.levels == 5 and five.min_levels == 4 and five.full_depth_side == 657
    for side, searched in ((656, False), (657, True)):  # the fifth-level image of the pyramid itself: 41 or 42 px
        fifth = image_pyramid(torch.zeros(1, 1, side, side + 40), 5)[4]
        assert five._level_gate(fifth, 4) is searched and min(fifth.shape[-2:]) == 41 + searched
    assert four.full_depth_side == 1 and PointTracker("ccot", levels=6).full_depth_side == 41 * 32 + 1
    sides = {(41, 80): False, (42, 42): True, (45, 80): True, (80, 41): False}
    for (h, w), searched in sides.items():
        assert five._level_gate(torch.zeros(1, 1, h, w), 4) is searched
        assert five._level_gate(torch.zeros(1, 1, h, w), 3) is True
        assert PointTracker("ccot", min_levels=5)._level_gate(torch.zeros(1, 1, h, w), 4) is True
    assert five.low_snr_tracker._level_gate(torch.zeros(1, 1, 42, 42), 4) is True  # its 31 px patches too
    assert PointTracker("ccot", min_level_side=80)._level_gate(torch.zeros(1, 1, 45, 80), 4) is False
    monkeypatch.setattr(point_tracker, "exporting", lambda: True)
    for (h, w), searched in sides.items():
        gate = five._level_gate(torch.zeros(1, 1, h, w), 4)
        assert isinstance(gate, torch.Tensor) and gate.dtype == torch.bool and bool(gate) is searched
    with pytest.raises(InputError, match="min_levels"):
        PointTracker("ccot", min_levels=0)
    with pytest.raises(InputError, match="min_level_side"):
        PointTracker("ccot", min_level_side=0)
