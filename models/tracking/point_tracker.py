"""Batched DCF point tracker (thesis 3.4, paper B): one small gray-pixel correlation filter per point and
pyramid level, searched coarse to fine.

Per frame: build a 5-level pyramid (the fifth level searched only in frames of at least 657 px a side, where its
image is large enough: :meth:`PointTracker._level_gate`); from the coarsest level searched down, extract every
point's patch at its current estimate (one gather for all points), correlate with that level's filter, find the peak
(on the two finest levels weighted by a Gaussian prior around the coarser estimate) and add the scaled shift; the
filters' regulariser grows with the frame's noise (estimated once per frame) against each patch's contrast (the
noise counts the error of block coding, where a frame shows an 8 px codec grid), so frequencies that
hold only noise in a blurred, dark or compressed patch do not move the peak. Points that leave
the image, that have no peak (level-0 PSR below a floor: an absolute one, lowered in a frame where every point's
PSR is low, as in the dark) or whose peak is weak, both against the frame's
other points and against the point's own PSR history, and that either do not track back to where they came from
(a forward-backward test on level 0) or whose unweighted level-0 peak lies elsewhere than the prior's choice (an
ambiguous match) are flagged lost and frozen at their last position, with the filters they had. The cues are
needed together: each alone fires on correct tracks in dark, blurred or compressed frames or, frame after frame,
on points whose texture always gives a low PSR; together they still catch many of the points that an occluder
covers. A lost point is still searched from where it was frozen, and it comes back where its filters find a peak
that is strong both against the frame's tracked points and against its own history and that tracks back
(``psr_recover``; back to where it was frozen or to where the frame's mean step puts it in the previous frame):
an occluder has moved on, or the flag was a false alarm.
In a frame compressed until its 8 px codec blocks are nearly flat (a block-grid ratio above ``block_limit``,
:func:`~models.tracking.compression.block_grid_ratio`) the two finest levels, on which a block spans more than
2 px, match the blocks rather than the scene: their corrections are dropped and the coarser levels' estimate stands,
and a point is lost there only below a lower PSR floor (``block_psr_threshold``), since the blocks lower every
point's level-0 PSR and the tests on level 0 see the blocks rather than the scene.
Then the filters of the points still tracked learn, with weight ``eta``, a sample at the new position: the search
sample shifted in the Fourier domain; in a frame where the tracked points turn together (a camera that rolls or
zooms, :mod:`~models.tracking.turn`) the weight rises with the turn, since the memory's older samples no longer
look like the patches, and where they turn further the step is tracked again from the previous frame turned onto
this one (:meth:`PointTracker._turn_matched_step`). Before all this, a frame whose blur differs from that of the
frame the filters were last trained afresh on by more than ``blur_match`` px^2 (measured from the two power spectra) is
matched to it: the sharper of the two views is blurred to the other's level (:meth:`_blur_matched_step`), since a
sharp template matched against a blurred view is biased at every asymmetric structure. Straight motion blur
(a streak, found in each frame's power cepstrum, :mod:`~models.tracking.motion_blur`) is matched exactly instead:
the filters are retrained on the previous frame blurred by this frame's streak and the search runs on this frame
blurred by the previous frame's (:meth:`_streak_matched_step`), since a Gaussian stand-in for a streak leaves
about a pixel of scatter along it.

Cost: the patches are small (default 31 px at level 0, which sets the accuracy, and 21 px, KLT's window, at the
coarser levels; the fourth level's bounds the motion at about 40 px per frame, the fifth's, in large frames, about
80). Template and search patch both carry the Hann window, so the correlation weights a pixel by the window's
square, and where noise or compression limits the precision, the scatter of a weighted shift estimate (``sqrt(sum
w^4) / sum w^2`` per axis) is 1.36 times that of KLT's uniform 21 px window for a 21 px patch and 1.13 times for a
31 px one. The filters keep only the lower frequencies (half of level 0's, 0.7 of the coarser levels'; band-limited,
as in C-COT) and their DFTs are real matrix products (:class:`~models.dcf.dft.RealDft2`) with the window and the
spline interpolation folded in; Newton refinement on the Fourier series runs where it sets the output (level 0), the
coarser levels take the grid peak refined by a parabola. A sequence whose first frame is noisy (its points' median
patch-to-noise variance ratio below ``low_snr``: dark, noisy or heavily compressed video) goes to a low-SNR twin of
the tracker with Tukey windows (flat over the middle half: 0.94 times KLT's scatter per axis at 31 px), 31 px
patches at every level and at least 0.7 of level 0's frequencies (the noise regulariser already mutes those that
hold only noise); on clean frames the Hann window is the more precise (a real scene's patch deforms and is occluded
first at its border). A sequence whose first step has weak peaks and residuals that show noise the first frame's
estimate under-read (dark video stored at a high JPEG quality, where the codec thinned the noise's finest
differences) goes to the twin after that step, which is tracked again (:meth:`PointTracker._low_snr_retry`).
Patches, spectra, filters and responses are stored point-interleaved, ``(rows, P, columns)``, so that each transform
is one large matrix product per axis; the patch normalisation (zero mean, unit variance) is applied to the spectrum
(the mean as a multiple of the window's spectrum), so the pixel-sized arrays are only read, by two reductions and
the transform.

Variants: ``ccot`` (continuous filter, exponentially decaying sample weights = a sample memory), ``ccot_ff``
(continuous filter retrained from the newest sample only, ``eta = 1``) and ``mosse`` (grid peak plus parabola
at every level). A level-``l`` pixel ``i`` sits at level-0 coordinate ``2^l (i + 0.5) - 0.5``. Positions are
(x, y) pixels.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass, replace

import numpy as np
import torch
import torch.nn.functional as F
from kornia.filters import filter2d
from kornia.geometry.transform import warp_affine
from torch import Tensor, nn

from core.errors import InputError
from core.streak import (
    Streak,
    quarter_slices,
    streak_change,
    streak_found,
    streak_kernel,
    streak_uniform,
    streaks_matched,
)
from models.dcf import (
    continuous_label,
    cosine_window,
    cubic_spline_fourier,
    gaussian_label,
    image_noise_std,
    tukey_window,
)
from models.dcf._signal import full_frequencies, wrap_index
from models.dcf.continuous import fourier_series_refine
from models.dcf.dft import RealDft2, band_frequencies, band_index
from models.export_mode import exporting, outer_product, spread
from models.tracking.blur import gaussian_blur, profile_min_size, radial_power_profile, relative_blur
from models.tracking.compression import (
    BLOCK,
    GRID_RAMP,
    block_grid,
    block_grid_ratio,
    compression_error_variance,
)
from models.tracking.interleaved import interleaved_argmax, interleaved_peak, interleaved_psr
from models.tracking.motion_blur import MAX_LENGTH, motion_blur_streak
from models.tracking.turn import TURN_POINTS, camera_turn, fit_similarity

METHODS = ("ccot", "ccot_ff", "mosse")
DEFAULT_ETA = {"ccot": 0.1, "ccot_ff": 1.0, "mosse": 0.125}
# label std (px of each level) per method: the continuous filters 0.7 (more precise where patches deform, as in
# real video: the docstring of PointTracker), MOSSE the thesis's 1 px per level
DEFAULT_SIGMA = {"ccot": 0.7, "ccot_ff": 0.7, "mosse": 1.0}


# kornia's ``pyrdown`` (5-tap binomial blur, then 2x2 averaging) as one separable 6-tap filter at stride 2
_PYRDOWN_TAPS = (1.0, 5.0, 10.0, 10.0, 5.0, 1.0)
# the variance of white noise after one pyramid level: the squared taps summed, over both axes
_PYRDOWN_NOISE_GAIN = (sum(t * t for t in _PYRDOWN_TAPS) / sum(_PYRDOWN_TAPS) ** 2) ** 2
_SEARCH_SIGMA = 3.0  # px: the default displacement prior of the fine levels (PointTracker's search_sigma)
_FINE_PATCH, _COARSE_PATCH = 31, 21  # px: default patch side at level 0 and at the coarser levels (patch_size)
_FINE_NEWTON = 2  # default Newton steps at level 0 (newton_iterations); the coarser levels take the parabola
_LEVELS, _MIN_LEVELS = 5, 4  # default pyramid levels, and those searched in every frame (levels, min_levels)
# px: the least shorter side of a level image beyond min_levels that the level searches (min_level_side): two of
# the default 21 px coarse patches, the fifth level's from frames of 657 px a side
_MIN_LEVEL_SIDE = 42
# default fractions of each level's frequencies the filters keep at level 0 and at the coarser levels (band)
_FINE_BAND, _COARSE_BAND = 0.5, 0.7
_QUANTISATION_VAR = 1 / 12  # rounding to integer gray levels (8-bit frames): the least noise a level-0 pixel has
_BLOCK_LEVELS = 2  # the finest levels, on which an 8 px codec block spans more than 2 px (PointTracker's block_limit)
WINDOWS = ("hann", "tukey")
_TUKEY_TAPER = 0.5  # fraction of each patch axis in the tapers of the Tukey window (window "tukey")
_LOW_SNR_FINE_BAND = 0.7  # the least fraction of level 0's frequencies the low-SNR twin's filters keep
_LOW_SNR_FIRST_SIGMA = 2.0  # px: the low-SNR twin's displacement prior of the fine levels in a point's first step
# block-grid ratio up to which a frame counts as free of a codec grid (first_step_sigma): the end of the compression
# error's fade-in, from where the codec's error counts in full
_GRID_FREE = GRID_RAMP[1]
_FLOOR_POINTS = 10  # tracked points a frame needs before its PSRs lower the floor (PointTracker's floor_relative)
_LOW_SNR = 20.0  # default low_snr: median patch-to-noise variance ratio of a first frame tracked in low-SNR mode
_LOW_SNR_PSR = 16.0  # default low_snr_psr: geometric-mean PSR of a first step below which the noise is measured again
_TURN_LIMIT = 0.05  # default turn_limit: about 3 degrees or 5 % a frame where the turn explains the motion
_TURN_GAIN = 8.0  # default turn_gain: eta rises by 0.08 per 0.01 of turn beyond turn_limit
_TURN_MATCH = 0.08  # default turn_match: the turn beyond which a step is tracked again from the turned frame
_ETA_MAX = 0.5  # default eta_max: the fastest the memory learns where a camera turns (won the G = 5 rows)
_RESIDUAL_SNR_MARGIN = 4.0  # a first step's residual SNR sends a sequence to the twin below low_snr over this


def pyramid_min_size(levels: int) -> int:
    """The least frame side (px) of which :func:`image_pyramid` builds ``levels`` levels: every level it blurs
    must be at least 4 px, as its reflected border is 3 px, and level ``l + 1`` has ``(n + 1) // 2`` px of level
    ``l``'s ``n``."""
    return 1 if levels < 2 else 3 * 2 ** (levels - 2) + 1


def image_pyramid(frame: Tensor, levels: int) -> list[Tensor]:
    """``levels`` images ``(1, 1, H / 2^l, W / 2^l)`` of a ``(1, 1, H, W)`` frame, finest first.

    Each level is the previous one blurred by the binomial ``[1, 4, 6, 4, 1] / 16`` (reflected borders) and
    averaged over 2x2 blocks (as ``kornia.geometry.transform.pyrdown``), so level pixel ``i`` sits at
    ``2 i + 0.5`` of the level below. Both are one separable 6-tap filter at stride 2, applied as weighted sums
    of strided slices (faster than a one-channel convolution on a CPU). In an exported graph it is one strided
    convolution per axis: the slices' bounds, nested floor divisions of the dynamic frame size, made the
    exporter's shape reasoning take more than half of the tracking graphs' export time.
    """
    smallest = pyramid_min_size(levels)
    if min(frame.shape[-2:]) < smallest:
        raise InputError(f"a frame of {tuple(frame.shape[-2:])} px is too small for a {levels}-level pyramid: it "
                         f"needs at least {smallest} px a side")
    taps = [t / 32 for t in _PYRDOWN_TAPS]
    pyramid = [frame]
    for _ in range(levels - 1):
        image = F.pad(pyramid[-1], (2, 3, 2, 3), mode="reflect")
        if exporting():
            kernel = torch.tensor(taps, dtype=image.dtype, device=image.device)
            rows = F.conv2d(image, kernel.view(1, 1, -1, 1), stride=(2, 1))
            pyramid.append(F.conv2d(rows, kernel.view(1, 1, 1, -1), stride=(1, 2)))
            continue
        h, w = (image.shape[-2] - 4) // 2, (image.shape[-1] - 4) // 2
        rows = _tap_sum([image[..., i : i + 2 * h - 1 : 2, :] for i in range(len(taps))], taps)
        pyramid.append(_tap_sum([rows[..., i : i + 2 * w - 1 : 2] for i in range(len(taps))], taps))
    return pyramid


def _tap_sum(slices: list[Tensor], taps: list[float]) -> Tensor:
    """``taps[0] slices[0] + taps[1] slices[1] + ...`` summed left to right, into one accumulator through one
    scratch tensor (no temporary per term; the same rounding as the plain sum)."""
    total = slices[0] * taps[0]
    scratch = torch.empty_like(total)
    for part, tap in zip(slices[1:], taps[1:], strict=True):
        total += torch.mul(part, tap, out=scratch)
    return total


def _lerp(start: Tensor, end: Tensor, weight: Tensor) -> Tensor:
    """``torch.lerp`` (one fused kernel) in eager mode; ``start + weight (end - start)`` in an exported graph, where
    ``lerp`` becomes a broadcast ``Where`` over two branches that onnxruntime runs several times slower; there a
    per-point weight (last axis 1) is first spread along the last axis (:func:`~models.export_mode.spread`)."""
    if not exporting():
        return torch.lerp(start, end, weight)
    if isinstance(weight, Tensor) and weight.dim() and weight.shape[-1] == 1:
        weight = spread(weight, start.shape[-1])
    return start + weight * (end - start)


def extract_patches(image: Tensor, centres: Tensor, size: int) -> Tensor:
    """Bilinear ``size x size`` patches around sub-pixel centres, natural order (centre at ``size // 2``),
    point-interleaved.

    All pixels of a patch share the centre's sub-pixel offset, so a patch is an integer crop one pixel larger,
    interpolated once along each axis: the values of ``grid_sample`` (bilinear, border padding) at a fraction
    of its cost. Centres are clamped to the image.

    Args:
        image: ``(1, 1, h, w)``; centres: ``(P, 2)`` (x, y) pixels of that image (border pixels repeat
        outside).
    Returns:
        ``(size, P, size)`` patches (rows, points, columns).
    """
    h, w = image.shape[-2:]
    r, n = size // 2, size + 1
    limit = torch.tensor([w - 1, h - 1], device=centres.device, dtype=centres.dtype)
    centres = torch.minimum(centres.clamp_min(0), limit)
    corner = centres.floor()
    frac = (centres - corner)[None, :, :, None]  # (1, P, 2, 1)
    padded = F.pad(image, (r, r + 1, r, r + 1), mode="replicate")[0, 0]  # pixel (x, y) at (x + r, y + r)
    x0, y0 = corner.long().unbind(-1)
    if exporting():
        # ONNX: one gather at flat indices (as_strided has no ONNX equivalent); the same values. torch.gather
        # exports as GatherElements, whose element loop onnxruntime runs about 8x faster than Gather (index_select),
        # which copies each element alone, and Gather several times faster than advanced indexing's GatherND. The
        # indices are each patch's top row (P, n) plus each row's offset (n, 1, 1): a broadcast over outer axes
        # only, which onnxruntime runs in long runs (models.export_mode.spread)
        offsets = torch.arange(n, device=centres.device)
        top_rows = (y0 * padded.shape[-1] + x0)[:, None] + offsets
        flat = top_rows + (offsets * padded.shape[-1])[:, None, None]
        crops = torch.gather(padded.flatten()[None], 1, flat.flatten()[None]).view(flat.shape)
    else:
        # every run of n pixels of the flat padded image as a row of an overlapping view; a crop is the n rows that
        # start at its rows' first pixels, (n, P) flat indices. index_select copies whole rows, several times faster
        # than advanced indexing, which computes each element's address alone
        stride = padded.stride(0)
        flat_image = padded.reshape(-1)
        runs = flat_image.as_strided((flat_image.numel() - n + 1, n), (1, 1))
        starts = (y0 * stride + x0)[None] + (torch.arange(n, device=centres.device) * stride)[:, None]
        crops = runs.index_select(0, starts.flatten()).view(n, -1, n)  # (size + 1, P, size + 1)
    rows = _lerp(crops[:-1], crops[1:], frac[:, :, 1])
    return _lerp(rows[..., :-1], rows[..., 1:], frac[:, :, 0])


def _level_centres(positions: Tensor, level: int) -> Tensor:
    """Level-``level`` pixel coordinates ``(P, 2)`` of level-0 positions ``(P, 2)`` (level pixel ``i`` sits at
    ``2^l (i + 0.5) - 0.5``)."""
    return (positions + 0.5) / 2**level - 0.5


def displacement_prior(n: int, sigma: float) -> Tensor:
    """Gaussian weight ``exp(-|d|^2 / (2 sigma^2))`` of the displacements ``d`` (bins) of an ``n x n`` score map
    (odd ``n``, as the patches) in FFT order (shift 0 first, negative shifts wrapped to the end), ``(n, 1, n)``
    float32 to broadcast over the points of ``(n, P, n)`` maps (MOSSE's :func:`~models.dcf.gaussian_label`); all
    ones for ``sigma`` 0 (free search)."""
    return torch.ones(n, 1, n) if sigma == 0 else gaussian_label((n, n), sigma)[:, None, :]


def _lower_median(values: Tensor, counted: Tensor) -> Tensor:
    """The lower median ``(1,)`` (as ``torch.median``) of ``values`` ``(P,)`` where ``counted`` ``(P,)``; inf where
    none counts. A sort with the others last and a gather at a computed index: a fixed shape, which exports."""
    ordered = torch.where(counted, values, torch.full_like(values, math.inf)).sort().values
    return ordered.gather(0, ((counted.sum() - 1) // 2).clamp_min(0).reshape(1))


def _peak_gap(a: tuple[Tensor, Tensor, Tensor], b: tuple[Tensor, Tensor, Tensor], n: int) -> Tensor:
    """Chebyshev distance ``(P,)`` in bins between two :func:`interleaved_argmax` results on ``(n, P, n)`` maps
    (shifts taken circularly)."""
    rows, columns = wrap_index(a[1] - b[1], n), wrap_index(a[2] - b[2], n)
    return torch.maximum(rows.abs(), columns.abs())


def _per_level(value, levels: int, name: str, kind: type = int) -> tuple:
    """One value per pyramid level from a scalar or a sequence (``kind``: int or float)."""
    values = (kind(value),) * levels if isinstance(value, int | float) else tuple(kind(v) for v in value)
    if len(values) != levels:
        raise InputError(f"{name} needs one value per pyramid level ({levels}), got {values}")
    return values


@dataclass
class TrackerState:
    """Tracker state: the last frame ``(1, 1, H, W)``, positions ``(P, 2)``, lost ``(P,)`` bool, last PSR ``(P,)``,
    each point's running geometric-mean PSR ``(P,)`` (inf before its first step, :meth:`PointTracker._psr_mean`)
    and per pyramid level (finest first) the filters ``(3, 2M + 1, P, M + 1)``: real and imaginary parts of the
    numerators ``A`` and the denominators ``B`` of the level's band-limited half spectra (``M`` = the level's
    band), point-interleaved. With blur matching, ``reference`` is the radial power profile ``(1, 3, bins)``
    (:func:`~models.tracking.blur.radial_power_profile`) of the frame the filters were last trained afresh on and
    ``profile`` that of ``frame`` (None: not measured yet). With streak matching, ``streak`` is the straight motion
    blur ``(length px, angle rad)`` found in ``frame`` (None: none) and ``template`` the streaks that blur the views
    the filters were last trained afresh on (:meth:`PointTracker._streak_matched_step`). ``low_snr``: the
    sequence is tracked by the low-SNR twin (:meth:`PointTracker.init`). ``noise_floor``: ``(1,)`` the least noise
    variance (gray levels^2) of the next frame, for one step (:meth:`PointTracker._low_snr_retry`; None: the frame's
    estimate alone)."""

    frame: Tensor
    positions: Tensor
    lost: Tensor
    psr: Tensor
    psr_mean: Tensor
    filters: tuple[Tensor, ...]
    reference: Tensor | None = None
    profile: Tensor | None = None
    streak: Streak | None = None
    template: tuple[Streak, ...] = ()
    low_snr: bool = False
    noise_floor: Tensor | None = None


class PointTracker(nn.Module):
    """Batched DCF point tracker.

    Args:
        method: ``ccot``, ``ccot_ff`` or ``mosse``.
        levels: pyramid levels (coarse-to-fine search). min_levels, min_level_side: the levels searched in every
        frame, and the least shorter side (px) of a deeper level's image for that level to search
        (:meth:`_level_gate`; the default fifth level from frames of 657 px a side, 720p video and larger). A 21
        px patch at the fourth level bounds the motion at about 40 px a frame, which is little in a large frame;
        a fifth level doubles the reach, but on a small image its patch sees most of the frame and, where the
        scene changes much, can send every point of a frame astray (docs/results.md). patch_size: odd patch side
        (px of that level), one for all levels or one per level, finest first; None: 31 px at level 0, 21 px at
        the coarser levels. The coarsest patch bounds the largest motion (about a quarter of its side, in
        coarsest-level pixels); the finer levels only correct the coarser estimate, and level 0's sets the
        precision (the module docstring).
        sigma: label std in px of each level (default per method: 0.7, 0.7, 1.0). The label's spectrum weights the
        frequencies of the response. On a pure translation the 1 px label is slightly the more precise; where the
        patch deforms (rotation, scale, real video) a narrower one is, and on the real benchmark sets the
        continuous filters win more rows with 0.7 (the wider label stays the more robust where heavy noise or
        motion blur leaves little fine texture over many frames: docs/results.md). eta: learning rate (default per
        method: 0.1, 1.0, 0.125).
        reg_rel: regulariser relative to the mean sample energy (``beta^2`` / ``eps``).
        newton_iterations: sub-pixel Newton steps of the continuous variants, one for all levels or one per
        level (finest first); 0 takes the grid peak refined by a parabola (MOSSE always does). None: 2 at level 0,
        whose estimate is the output, and 0 at the coarser levels, for any number of levels.
        search_sigma: per level (finest first), the std in px of that level of a Gaussian displacement prior
        that weights the level's score map around the estimate handed down from the coarser levels before its
        peak is taken; 0 searches the whole map. The coarser levels have placed a point within about a pixel of
        theirs (2 px of the next finer level), so a far peak at a fine level is more often a response to noise,
        compression blocks or a neighbouring structure than a correction; the weighting keeps such peaks from
        pulling the point away. Sub-pixel refinement and the PSR use the unweighted map. None: 3 px at the two finest
        levels, free search at the others (the large motion is found there).
        first_step_sigma: the prior's std per level (as ``search_sigma``; 0: free search) for the points in their
        first step (no PSR history yet) in a frame free of a codec grid (block-grid ratio up to 1.5, where
        :func:`~models.tracking.compression.compression_error_variance` counts in full); None: ``search_sigma``
        throughout. Filters trained on one noisy frame carry all of its noise, and in a dark frame the fine levels'
        peaks then stray to noise 4-5 px from the coarser estimate more often than KLT's local search does; from
        the second step the sample memory averages the noise, and a tight prior there would only add the coarser
        levels' error to every step (it lowered the precision of dark round trips). In JPEG 15 frames the fine
        levels need the usual search. The low-SNR twin uses 2 px at the levels where ``search_sigma`` weights.
        psr_relative, psr_rate, fb_threshold, psr_threshold: a point is lost when its level-0 PSR falls below
        ``psr_relative`` times the geometric mean PSR of the frame's tracked points (:meth:`_lost_threshold`)
        and below ``psr_relative`` times its own running geometric-mean PSR (the newest PSR weighted
        ``psr_rate`` against the mean of the frames before; None: the frame test alone, :meth:`_psr_mean`)
        and either tracking it back to the previous frame misses by more than ``fb_threshold`` px
        (:meth:`_backward_error`) or its unweighted level-0 peak is more than ``fb_threshold`` px from the peak
        the displacement prior chose (None: the PSR test alone), or when its PSR is below ``psr_threshold``
        (no peak at all; in a compressed frame only ``block_psr_threshold`` applies, below) and below
        ``floor_relative`` times the geometric mean PSR of the frame's tracked points, where there are at least
        10 (None: the absolute floor alone). In a dark or noisy frame every point's PSR is low (geometric means of
        5-6 on the real pairs under the stress sets' darkness, 25-45 as they are), and a fixed floor there flags
        correct tracks; a few points say little about the frame, and a point tracked alone would set its own
        floor. psr_recover: a lost
        point comes back when its PSR passes the frame test above and is at least ``psr_recover`` times its
        running mean from before it was lost and it passes the forward-backward test, back to where it was frozen
        or to where the frame's mean step puts it in the previous frame (:meth:`_origin`; one with no history, lost in
        its first step or outside the image from the start, never does); None: lost is final. psr_exclude: PSR
        exclusion window.
        band: fraction of each level's highest frequency ``N // 2`` that the filters keep (band-limited
        filters as in C-COT; 1 keeps all), one for all levels or one per level, finest first. The filters,
        the sample spectra and the transforms shrink with it. None (default): 0.5 at level 0, whose 31 px patch
        then has the spectrum size of a 21 px patch at 0.7 (as precise on the clean real pairs, the wider patch's
        precision in noise), and 0.7 at the coarser levels, whose estimates the finer levels start from: there the
        finer frequencies keep more points on their peak in noise and JPEG than 0.5 did, at about a tenth of the
        step's time (docs/results.md).
        noise_reg: weight of the noise-adaptive regulariser (0: off): the filter's denominator gains
        ``noise_reg`` times the expected power of the frame's noise in every frequency of the point's
        normalised sample (:meth:`_noise_power`), so frequencies where a blurred, dark or low-contrast patch
        has less signal than noise do not steer the peak (a Wiener filter's regulariser, over-weighted).
        blur_match: blur variance (px^2) between a frame and the frame the filters were trained on above which
        the two are matched before the search (:meth:`step`); None: never.
        streak_score: cepstral score (:func:`~models.tracking.motion_blur.motion_blur_streak`) below which a frame
        counts as blurred by a straight streak (if no other direction scores below half of it, or below half the
        streak's score in a frame without a codec block grid, :func:`core.streak.streak_found`), which is then
        matched exactly (:meth:`_streak_matched_step`); None:
        streaks are treated as any other blur. The default, -10, lies between the scores of the shared real
        frames (-2.2 to -9.8) and those of streaks of 5.4 px and longer (-11.2 to -20.8). A streak found in the
        previous frame continues at half of it (hysteresis, :func:`core.streak.streak_found`): long streaks over
        fine texture such as water score -9 to -10.
        streak_match: change of blur variance (px^2, in the direction it changes most) between a frame's streak
        and those of the views the filters were last trained afresh on above which the streaks are matched;
        twice ``blur_match`` by default, since streaks near the detection limit (about 5 px) flicker in and out
        of detection in real video while the blur they stand for barely changes, and every matched step
        restarts the sample memory. A streak that reads the same in the frame's four quarters (a camera's blur,
        :meth:`_uniform`) is matched beyond ``blur_match``, as any other blur: the flicker came from partial
        blur, a pan that follows a sharp object.
        block_limit: block-grid ratio of a frame (:func:`~models.tracking.compression.block_grid_ratio`: about 1
        uncompressed, 1.2-2.4 at JPEG qualities 37-60, 6-26 at quality 3) above which the corrections of the levels on
        which an 8 px codec block spans more than 2 px (levels 0 and 1, never the coarsest) are dropped
        (:meth:`_fine_weight`); None: never.
        block_psr_threshold: the absolute PSR floor (``psr_threshold``) in such a frame, and there the only lost
        test. Its flat blocks lower every point's level-0 PSR (they replace the fine texture the filters learnt)
        and make the level-0 peaks, forward and backward, respond to the block grid, while the position comes
        from the coarser levels; so the usual floor and the tests on level 0 (against the frame, the point's
        history, the backward search and the prior's choice) there flag points that are still tracked.
        window: the patch window, ``hann`` (:func:`~models.dcf.cosine_window`) or ``tukey``
        (:func:`~models.dcf.tukey_window`, half of each axis tapered): flat over the middle, so more of the patch
        counts fully, which lowers the scatter of the peak in noise (per axis 0.94 times that of KLT's uniform 21 px
        window for a 31 px patch, against 1.13 for a Hann window of 31 px) and raises the weight of the patch's
        border, where real scenes deform and occlude first.
        compression_reg: weight of the compression error in the noise variance (:meth:`_noise_variance`): the error
        of block coding (:func:`~models.tracking.compression.compression_error_variance`) counts this many times as
        much as white noise of the same variance, since it lies where the signal is weak (the codec removes the
        fine texture it cannot afford) rather than spread evenly over the frequencies.
        low_snr: the median signal-to-noise ratio (level-0 patch variance over the noise variance,
        :meth:`signal_to_noise`) of the first frame's points below which :meth:`init` hands the whole sequence to a
        low-SNR twin of this tracker: the same settings with Tukey windows and 31 px patches at every level, the
        largest windows it can afford, and at least 0.7 of level 0's frequencies (``band``): in noise the
        regulariser mutes the frequencies that hold only noise, and the others carry the fine texture that sets
        the precision. The start points of the shared real pairs read 64-8458 (29-529 at a quarter
        of their contrast), of the first DAVIS frames 14-6480, under the stress sets' darkness or JPEG 15 1-9. The
        default, 20, sends the latter and the two noisiest DAVIS videos (soccerball, mallard-fly) to the twin.
        None: never.
        low_snr_psr: the geometric-mean PSR of a sequence's first step below which :meth:`step` measures that step's
        residual noise and, where it shows an SNR below ``low_snr / 4`` that the frame's noise estimate missed,
        tracks the step again with the twin (:meth:`_low_snr_retry`). The first steps of the shared real pairs
        read 20-43 (as they are and under the stress sets' low contrast or illumination), those of dark frames
        stored as JPEG 5-13. None: never (and where ``low_snr`` is None).
        turn_limit, turn_gain, eta_max: the sample memory learns faster in a frame whose tracked points turn
        (:func:`~models.tracking.turn.camera_turn`: the rotation in rad and log scale change of the similarity
        fitted to their steps, weighed by the share of the steps it explains): ``eta`` plus ``turn_gain`` times the
        turn beyond ``turn_limit``, at most ``eta_max`` (:meth:`_memory_rate`). A camera that rolls or zooms turns
        every patch away from the samples the memory holds; the default limit, 0.05 (about 3 degrees or 5 % a
        frame), lies above the turns of the shared real videos (the 30 DAVIS videos: at most 0.013 frame to frame,
        and at every fourth frame 0.059 in one step of bmx-bumps, the next 0.039: the steps of a non-rigid scene
        are not a similarity) and of the synthetic sequences (at most 0.041). None: ``eta`` always.
        turn_match: the turn beyond which a step is tracked again from the previous frame turned onto the new one
        (:meth:`_turn_matched_step`: warped by the similarity fitted to the points' steps, the filters trained
        afresh there); None: never. Beyond about 8 degrees or 12 % a frame a faster memory no longer keeps the
        points (docs/results.md).
    """

    def __init__(
        self,
        method: str = "ccot",
        levels: int = _LEVELS,
        min_levels: int = _MIN_LEVELS,
        min_level_side: int = _MIN_LEVEL_SIDE,
        patch_size: int | tuple[int, ...] | None = None,
        sigma: float | None = None,
        eta: float | None = None,
        reg_rel: float = 1e-2,
        newton_iterations: int | tuple[int, ...] | None = None,
        search_sigma: float | tuple[float, ...] | None = None,
        first_step_sigma: float | tuple[float, ...] | None = None,
        psr_threshold: float = 2.5,
        floor_relative: float | None = 0.4,
        psr_relative: float = 0.3,
        psr_rate: float | None = 0.3,
        psr_recover: float | None = 0.7,
        fb_threshold: float | None = 1.0,
        psr_exclude: int = 7,
        band: float | tuple[float, ...] | None = None,
        noise_reg: float = 30.0,
        blur_match: float | None = 2.0,
        streak_score: float | None = -10.0,
        streak_match: float = 4.0,
        block_limit: float | None = 3.0,
        block_psr_threshold: float = 1.5,
        window: str = "hann",
        compression_reg: float = 3.0,
        low_snr: float | None = _LOW_SNR,
        low_snr_psr: float | None = _LOW_SNR_PSR,
        turn_limit: float | None = _TURN_LIMIT,
        turn_gain: float = _TURN_GAIN,
        eta_max: float = _ETA_MAX,
        turn_match: float | None = _TURN_MATCH,
    ) -> None:
        settings = {name: value for name, value in locals().items() if name not in ("self", "__class__")}
        super().__init__()
        if method not in METHODS:
            raise InputError(f"unknown tracking method {method!r}; choose one of {', '.join(METHODS)}")
        if window not in WINDOWS:
            raise InputError(f"unknown patch window {window!r}; choose one of {', '.join(WINDOWS)}")
        if not compression_reg >= 0:
            raise InputError(f"compression_reg must be a non-negative weight, got {compression_reg}")
        if low_snr is not None and not low_snr > 0:
            raise InputError(f"low_snr must be a positive signal-to-noise ratio or None, got {low_snr}")
        if low_snr_psr is not None and not low_snr_psr > 0:
            raise InputError(f"low_snr_psr must be a positive PSR or None, got {low_snr_psr}")
        self.window, self.compression_reg, self.low_snr = window, compression_reg, low_snr
        self.low_snr_psr = low_snr_psr
        # the residual SNR below which a retried first step hands the sequence to the twin (_low_snr_retry)
        self.low_snr_residual = None if low_snr is None else low_snr / _RESIDUAL_SNR_MARGIN
        if patch_size is None:
            patch_size = (_FINE_PATCH,) + (_COARSE_PATCH,) * (levels - 1)
        self.sizes = _per_level(patch_size, levels, "patch_size")
        if any(n % 2 == 0 for n in self.sizes) or self.sizes[0] < psr_exclude + 2:
            raise InputError(f"patch sizes must be odd and larger than the PSR window, got {self.sizes}")
        if newton_iterations is None:
            newton_iterations = (_FINE_NEWTON,) + (0,) * (levels - 1)
        self.newton = (0,) * levels if method == "mosse" else _per_level(newton_iterations, levels, "newton")
        if search_sigma is None:  # the two finest levels, never the coarsest
            search_sigma = tuple(_SEARCH_SIGMA if lv < min(2, levels - 1) else 0.0 for lv in range(levels))
        self.search_sigmas = _per_level(search_sigma, levels, "search_sigma", float)
        if not all(s >= 0 for s in self.search_sigmas):
            raise InputError(f"search_sigma must be non-negative (0: free search), got {self.search_sigmas}")
        self.first_step_sigmas = None
        if first_step_sigma is not None:
            self.first_step_sigmas = _per_level(first_step_sigma, levels, "first_step_sigma", float)
            if not all(s >= 0 for s in self.first_step_sigmas):
                raise InputError(f"first_step_sigma must be non-negative (0: free search) or None, "
                                 f"got {self.first_step_sigmas}")
        if not 1 <= min_levels:
            raise InputError(f"min_levels must be at least 1, got {min_levels}")
        if not min_level_side >= 1:
            raise InputError(f"min_level_side must be a side of at least 1 px, got {min_level_side}")
        self.method, self.levels, self.min_levels, self.min_level_side = method, levels, min_levels, min_level_side
        self.eta = DEFAULT_ETA[method] if eta is None else eta
        if turn_limit is not None and not turn_limit >= 0:
            raise InputError(f"turn_limit must be a turn >= 0 or None, got {turn_limit}")
        if not turn_gain >= 0:
            raise InputError(f"turn_gain must be >= 0, got {turn_gain}")
        if not 0 < eta_max <= 1:
            raise InputError(f"eta_max must lie in (0, 1], got {eta_max}")
        self.turn_limit, self.turn_gain, self.eta_max = turn_limit, turn_gain, max(eta_max, self.eta)
        if turn_match is not None and not turn_match > 0:
            raise InputError(f"turn_match must be a positive turn or None, got {turn_match}")
        self.turn_match = turn_match
        sigma = DEFAULT_SIGMA[method] if sigma is None else sigma
        if not sigma > 0:
            raise InputError(f"label sigma must be a positive std in px, got {sigma}")
        self.reg_rel, self.psr_threshold, self.psr_exclude = reg_rel, psr_threshold, psr_exclude
        self.psr_relative, self.fb_threshold = psr_relative, fb_threshold
        if floor_relative is not None and not floor_relative > 0:
            raise InputError(f"floor_relative must be a positive factor or None, got {floor_relative}")
        self.floor_relative = floor_relative
        if psr_rate is not None and not 0 < psr_rate <= 1:
            raise InputError(f"psr_rate must lie in (0, 1] or be None, got {psr_rate}")
        self.psr_rate = psr_rate
        if psr_recover is not None and not psr_recover > 0:
            raise InputError(f"psr_recover must be positive or None, got {psr_recover}")
        self.psr_recover = psr_recover
        if not noise_reg >= 0:
            raise InputError(f"noise_reg must be a non-negative number, got {noise_reg}")
        self.noise_reg = noise_reg
        if blur_match is not None and not blur_match > 0:
            raise InputError(f"blur_match must be a positive variance in px^2 or None, got {blur_match}")
        self.blur_match = blur_match
        if streak_score is not None and not streak_score < 0:
            raise InputError(f"streak_score must be a negative score or None, got {streak_score}")
        self.streak_score = streak_score
        if not streak_match > 0:
            raise InputError(f"streak_match must be a positive variance in px^2, got {streak_match}")
        self.streak_match = streak_match
        if block_limit is not None and not block_limit > 1:
            raise InputError(f"block_limit must be a block-grid ratio above 1 or None, got {block_limit}")
        self.block_limit = block_limit
        if not block_psr_threshold >= 0:
            raise InputError(f"block_psr_threshold must be a PSR >= 0, got {block_psr_threshold}")
        self.block_psr_threshold = block_psr_threshold
        if band is None:
            band = (_FINE_BAND,) + (_COARSE_BAND,) * (levels - 1)
        fractions = _per_level(band, levels, "band", float)
        if not all(0 < f <= 1 for f in fractions):
            raise InputError(f"band fractions must lie in (0, 1], got {fractions}")
        self.bands = tuple(max(1, round(f * (n // 2))) for f, n in zip(fractions, self.sizes, strict=True))
        self.dfts = nn.ModuleList()
        for level, (n, m) in enumerate(zip(self.sizes, self.bands, strict=True)):
            if window == "hann":
                taper = cosine_window((n,), dtype=torch.float64).roll(n // 2)  # natural order
            else:
                taper = tukey_window((n,), _TUKEY_TAPER, dtype=torch.float64).roll(n // 2)
            if method == "mosse":
                scale = None
                label = torch.fft.rfft2(gaussian_label((n, n), sigma, dtype=torch.float64)).real
            else:  # Fourier coefficients of the cubic-spline interpolated sample (eq. 3.6) and of the label
                scale = cubic_spline_fourier(full_frequencies(n, None, torch.float64) / n) / n
                label = continuous_label((n, n), sigma, dtype=torch.float64)
            dft = RealDft2(n, taper, scale, band=m)
            self.dfts.append(dft)
            label = label[band_index(n, m), : m + 1, None].transpose(1, 2)
            self.register_buffer(f"label_{level}", label.float(), persistent=False)  # (2M + 1, 1, M + 1)
            mean_spectrum = torch.stack(dft(torch.ones(n, 1, n)))  # a constant patch's [re, im] (2, 2M + 1, 1, M + 1)
            # expected power per frequency of unit white noise through the sample transform: the sum of |DFT|^2
            # of all n^2 unit impulses, (2M + 1, 1, M + 1)
            impulses = torch.eye(n * n).view(n * n, n, n).transpose(0, 1)  # (n, n^2, n)
            noise_spectrum = sum(part.square().sum(1, keepdim=True) for part in dft(impulses))
            self.register_buffer(f"noise_spectrum_{level}", noise_spectrum, persistent=False)
            self.register_buffer(f"mean_spectrum_{level}", mean_spectrum, persistent=False)
            omega = band_frequencies(n, m, False) * (2 * math.pi / n)  # angular frequencies of the rows, per px
            self.register_buffer(f"omega_y_{level}", omega[:, None].float(), persistent=False)  # (2M + 1, 1)
            self.register_buffer(f"omega_x_{level}", omega[: m + 1].float(), persistent=False)  # (M + 1,)
            # the displacement priors over the score map, FFT order (N, 1, N); 1 where the search is free
            if self._weighted(level):
                self.register_buffer(f"search_prior_{level}", displacement_prior(n, self.search_sigmas[level]),
                                     persistent=False)
                if self.first_step_sigmas is not None:
                    prior = displacement_prior(n, self.first_step_sigmas[level])
                    self.register_buffer(f"first_step_prior_{level}", prior, persistent=False)
        # the low-SNR twin: the same settings with Tukey windows, the level-0 patch size at every level, a wider
        # level-0 band and a tighter prior in a point's first step
        twin_band = (max(fractions[0], _LOW_SNR_FINE_BAND), *fractions[1:])
        twin_first = tuple(_LOW_SNR_FIRST_SIGMA if s > 0 else 0.0 for s in self.search_sigmas)
        self.low_snr_tracker = None if low_snr is None else PointTracker(
            **{**settings, "patch_size": self.sizes[0], "window": "tukey", "band": twin_band, "low_snr": None,
               "low_snr_psr": None, "first_step_sigma": twin_first})

    def _weighted(self, level: int) -> bool:
        """Whether a displacement prior weights ``level``'s score map (``search_sigma`` or ``first_step_sigma``)."""
        first = self.first_step_sigmas is not None and self.first_step_sigmas[level] > 0
        return self.search_sigmas[level] > 0 or first

    def _search_weight(self, level: int, first: Tensor | None) -> Tensor:
        """The displacement prior over ``level``'s score maps: ``(N, 1, N)``, or ``(N, P, N)`` with the first-step
        prior for the points ``first`` ``(P,)`` (:meth:`_first_step`; None: none of them)."""
        prior = getattr(self, f"search_prior_{level}")
        if first is None:
            return prior
        return torch.where(first[:, None], getattr(self, f"first_step_prior_{level}"), prior)

    def _first_step(self, ratio: Tensor | None, psr_mean: Tensor) -> Tensor | None:
        """The points ``(P,)`` that take the first-step prior (``first_step_sigma``): no PSR history yet
        (``psr_mean`` inf) in a frame whose block-grid ratio ``ratio`` is at most 1.5; None where the tracker has no
        such prior, the frame's grid was not measured (under two blocks a side), or, in an eager step, no point takes
        it (every step after the first: the plain prior, without a map per point)."""
        if self.first_step_sigmas is None or ratio is None:
            return None
        first = torch.isinf(psr_mean) & (ratio <= _GRID_FREE)
        traced = exporting() or torch.compiler.is_compiling()
        return first if traced or bool(first.any()) else None

    def _sample(self, image: Tensor, centres: Tensor, level: int,
                patches: Tensor | None = None) -> tuple[Tensor, Tensor, Tensor]:
        """Band-limited spectrum (real, imaginary ``(2M + 1, P, M + 1)``) of the normalised (zero mean, unit
        variance), windowed patches around ``centres`` ``(P, 2)`` (pixels of that level), and the patches' std
        ``(P,)`` before the normalisation. ``patches``: those patches (:func:`extract_patches`), where already
        extracted.

        The normalisation is linear per patch, so it is applied to the spectrum: the mean times the spectrum of a
        constant patch is subtracted, then the result is divided by the standard deviation. A patch flatter than
        ``1e-3 (|mean| + 1)`` (below the 8-bit quantisation step) has no structure, and what the subtraction
        leaves of it is rounding: its spectrum is set to zero, so its filter scores nothing and the point is
        lost."""
        x = extract_patches(image, centres, self.sizes[level]) if patches is None else patches
        mean, variance = self._moments(x)
        std = variance.sqrt()
        flat = std <= 1e-3 * (mean.abs() + 1)
        scale = torch.where(flat, torch.zeros_like(std), 1 / (std + 1e-5))[:, None]
        mean = mean[:, None]
        (dr, di), (zr, zi) = getattr(self, f"mean_spectrum_{level}"), self.dfts[level](x)
        scale = spread(scale, zr.shape[-1])
        return (zr - outer_product(mean, dr)) * scale, (zi - outer_product(mean, di)) * scale, std

    @staticmethod
    def _moments(x: Tensor) -> tuple[Tensor, Tensor]:
        """Mean and variance ``(P,)`` of point-interleaved patches ``(n, P, n)`` (sums over the outer axis first:
        much faster than over both at once)."""
        count = x.shape[0] * x.shape[2]
        mean = x.sum(0).sum(1) / count
        return mean, (x.square().sum(0).sum(1) / count - mean.square()).clamp_min(0)

    def _noise_variance(self, frame: Tensor, compression: Tensor | None = None) -> Tensor | None:
        """Variance ``(1,)`` of the noise of a ``(1, 1, H, W)`` frame: the white noise
        (:func:`~models.dcf.image_noise_std` on every 4th pixel), at least the 8-bit rounding's, plus
        ``compression_reg`` times the compression error
        (:func:`~models.tracking.compression.compression_error_variance`; frames of at least two 8 px blocks a
        side; ``compression``: that error when already measured); None when ``noise_reg`` is 0. Estimated on the
        frame, not on the coarser pyramid levels, where texture has become as fine as noise."""
        if self.noise_reg == 0:
            return None
        variance = image_noise_std(frame, stride=4).square().clamp_min(_QUANTISATION_VAR)
        if self.compression_reg > 0 and min(frame.shape[-2:]) >= 2 * BLOCK:
            compression = compression_error_variance(frame) if compression is None else compression
            variance = variance + self.compression_reg * compression
        return variance

    def signal_to_noise(self, frame: Tensor, points: Tensor) -> Tensor:
        """Median signal-to-noise ratio ``(1,)`` of the points ``(P, 2)`` inside a ``(1, 1, H, W)`` frame: the variance
        of each point's level-0 patch (``patch_size[0]`` px, as :meth:`_sample` measures it) over the frame's noise
        variance (:meth:`_noise_variance`, at least the 8-bit rounding's). The lower median, as ``torch.median``;
        inf where no point is inside (non-finite points count as outside) or ``noise_reg`` is 0 (no noise model)."""
        return self._signal_to_noise(frame, points)[0]

    def _signal_to_noise(self, frame: Tensor, points: Tensor) -> tuple[Tensor, Tensor | None]:
        """:meth:`signal_to_noise` and the level-0 patches ``(n, P, n)`` it measured (None without a noise model):
        those :meth:`_train` samples on the same frame (outside points at (0, 0), as there)."""
        noise = self._noise_variance(frame)
        if noise is None:
            return torch.full((1,), math.inf, dtype=frame.dtype, device=frame.device), None
        inside = self._inside(points, frame)
        centres = torch.where(inside.unsqueeze(-1), points, torch.zeros_like(points))
        # level-0 centres as _train computes them ((x + 0.5) - 0.5 may round): the same patches to the bit
        patches = extract_patches(frame, _level_centres(centres, 0), self.sizes[0])
        return _lower_median(self._moments(patches)[1] / noise, inside), patches

    @staticmethod
    def _noise_power(variance: Tensor | None, std: Tensor, level: int) -> Tensor | None:
        """Noise variance ``(P,)`` of the normalised level-``level`` samples of patches with std ``std`` ``(P,)``:
        the frame's noise ``variance`` reduced by ``level`` pyramid reductions, over each patch's variance
        (None passes through)."""
        if variance is None:
            return None
        return variance * _PYRDOWN_NOISE_GAIN**level / (std.square() + 1e-12)

    @property
    def min_frame_size(self) -> int:
        """The least frame side (px) this tracker takes: its pyramid's (:func:`pyramid_min_size`) and, with blur
        matching, the blur profile's (:func:`~models.tracking.blur.profile_min_size`)."""
        return max(pyramid_min_size(self.levels), profile_min_size() if self.blur_match is not None else 1)

    def _frame(self, frame: Tensor) -> Tensor:
        if frame.dim() == 2:
            frame = frame[None, None]
        if frame.dim() != 4 or frame.shape[:2] != (1, 1):
            raise InputError(f"a frame must be (H, W) or (1, 1, H, W) gray, got shape {tuple(frame.shape)}")
        if min(frame.shape[-2:]) < self.min_frame_size:
            raise InputError(f"a frame of {tuple(frame.shape[-2:])} px is too small to track points in: the "
                             f"{self.levels}-level tracker needs at least {self.min_frame_size} px a side")
        return frame

    @staticmethod
    def _points(points: Tensor, frame: Tensor) -> Tensor:
        """Start points as a ``(P, 2)`` tensor of ``frame``'s dtype and device; ``InputError`` for another shape or
        none."""
        points = torch.as_tensor(points, dtype=frame.dtype, device=frame.device)
        if points.dim() != 2 or points.shape[1] != 2:
            raise InputError(f"points must have shape (P, 2), got {tuple(points.shape)}")
        if points.shape[0] == 0:
            raise InputError("the point set is empty: nothing to track")
        return points

    def _inside(self, positions: Tensor, frame: Tensor) -> Tensor:
        h, w = frame.shape[-2:]
        x, y = positions[:, 0], positions[:, 1]
        return torch.isfinite(positions).all(-1) & (x >= 0) & (x <= w - 1) & (y >= 0) & (y <= h - 1)

    def _learn(self, filters: Tensor | None, zr: Tensor, zi: Tensor, eta: Tensor | None, level: int) -> Tensor:
        """Blend one sample per point (band-limited spectrum ``(2M + 1, P, M + 1)``) into a level's filters with
        weight ``eta`` ``(P,)`` (MOSSE's running update; for C-COT the sample memory with exponentially decaying
        weights, kept as running sums). ``filters`` None starts from scratch (``eta`` unused)."""
        y = spread(getattr(self, f"label_{level}"), zr.shape[1], -2)
        new = torch.stack([zr * y, -zi * y, zr.square() + zi.square()])
        return new if filters is None else _lerp(filters, new, eta[:, None])

    def _memory_rate(self, start: Tensor, moved: Tensor, tracked: Tensor) -> Tensor:
        """The learning rate ``(1,)`` of this frame's samples: ``eta``, raised by ``turn_gain`` per unit of the
        frame's turn beyond ``turn_limit`` (:func:`~models.tracking.turn.camera_turn` of the steps ``start`` ->
        ``moved`` ``(P, 2)`` of the points ``tracked`` ``(P,)`` into and out of the previous frame, where there are
        at least ``TURN_POINTS``), at most ``eta_max`` and never below ``eta`` (``ccot_ff``'s 1 stays 1)."""
        rate = torch.full((1,), self.eta, dtype=start.dtype, device=start.device)
        if self.turn_limit is None:
            return rate
        turn = camera_turn(start, moved, tracked.to(start.dtype), TURN_POINTS)
        return (rate + self.turn_gain * (turn - self.turn_limit).clamp_min(0)).clamp(max=self.eta_max)

    def init(self, frame: Tensor, points: Tensor, switch: bool = True) -> TrackerState:
        """Train every point's filters on ``frame`` ``(H, W)``; points ``(P, 2)`` outside the image start
        lost. Where the median signal-to-noise ratio of the points inside (:meth:`signal_to_noise`) is below
        ``low_snr`` and ``switch`` is on, the low-SNR twin (Tukey windows, the level-0 patch size at every level)
        takes the sequence: its state says so (``low_snr``) and :meth:`step` hands it on. ``switch`` False (and an
        exported graph, whose runtime decides with a graph of its own) keeps this tracker's filters."""
        frame = self._frame(frame)
        points = self._points(points, frame)
        tracker, patches = self, None
        if switch and self.low_snr_tracker is not None and not exporting():
            snr, patches = self._signal_to_noise(frame, points)  # the twin has the same level-0 patch size
            tracker = self.low_snr_tracker if float(snr) < self.low_snr else self
        state = tracker._train(frame, points, patches)
        streak = tracker._streak(state.frame)
        return replace(state, streak=streak, template=(streak,) if streak else (), low_snr=tracker is not self)

    def _train(self, frame: Tensor, points: Tensor, patches: Tensor | None = None) -> TrackerState:
        """:meth:`init` on a ``(1, 1, H, W)`` frame, without measuring its motion blur; ``patches``: the level-0
        patches at the points (outside points at (0, 0)), where :meth:`_signal_to_noise` already extracted them."""
        points = self._points(points, frame)
        lost = ~self._inside(points, frame)
        positions = torch.where(lost.unsqueeze(-1), torch.zeros_like(points), points)
        pyramid = image_pyramid(frame, self.levels)
        ones = torch.ones_like(points[:, 0])
        filters = tuple(
            self._learn(None, *self._sample(pyramid[lv], _level_centres(positions, lv), lv,
                                            patches if lv == 0 else None)[:2], ones, lv)
            for lv in range(self.levels)
        )
        psr = torch.full_like(points[:, 0], float("inf"))
        return TrackerState(frame, torch.where(lost.unsqueeze(-1), points, positions), lost, psr, psr, filters)

    def _peak(self, spectrum: Tensor, score: Tensor, argmax: tuple[Tensor, Tensor, Tensor], level: int) -> Tensor:
        """Sub-pixel shift ``(P, 2)`` (x, y) of the score maximum at ``level`` (``spectrum``: ``[re | im]``
        ``(2M + 1, P, 2M + 2)``; ``score`` ``(N, P, N)`` and its ``interleaved_argmax``)."""
        if self.newton[level] == 0:
            return interleaved_peak(score, argmax=argmax)[0]
        n, k = self.sizes[level], self.bands[level] + 1
        srsi = spectrum.transpose(0, 1).contiguous()  # (P, 2M + 1, 2M + 2), read by every Newton step
        value, row, column = argmax
        index = torch.stack([row, column], -1)
        return fourier_series_refine(srsi[..., :k], srsi[..., k:], (n, n), self.newton[level], index, value, srsi)[0]

    def _shift(self, zr: Tensor, zi: Tensor, shift: Tensor, level: int) -> tuple[Tensor, Tensor]:
        """Spectra of samples moved by ``shift`` ``(P, 2)`` (x, y) level pixels: ``x'(t) = x(t + shift)``."""
        ay = getattr(self, f"omega_y_{level}") * shift[:, 1]  # (2M + 1, P)
        ax = getattr(self, f"omega_x_{level}") * shift[:, 0:1]  # (P, M + 1)
        cy, sy = (spread(f(ay)[:, :, None], ax.shape[-1]) for f in (torch.cos, torch.sin))
        cx, sx = torch.cos(ax), torch.sin(ax)
        pr, pi = cy * cx - sy * sx, sy * cx + cy * sx
        return zr * pr - zi * pi, zr * pi + zi * pr

    def forward(
        self, frame: Tensor, previous: Tensor, positions: Tensor, lost: Tensor, psr_mean: Tensor, *filters: Tensor,
        noise_floor: Tensor | None = None,
    ) -> tuple[Tensor, ...]:
        """One tracking step (exportable: real tensors in and out).

        Args:
            frame: ``(1, 1, H, W)`` gray frame; previous: the frame before it (same size, for the
            forward-backward test). positions: ``(P, 2)``. lost: ``(P,)`` bool. psr_mean: ``(P,)`` each point's
            running geometric-mean PSR (inf: none yet). filters: per level, finest first, ``(3, 2M + 1, P, M + 1)``
            (see :class:`TrackerState`). noise_floor: ``(1,)`` the least noise variance of the frame (gray
            levels^2; :meth:`step` measures it for a first step tracked again, :meth:`_low_snr_retry`); None: the
            estimate alone.
        Returns:
            positions, lost, psr ``(P,)``, psr_mean and the filters after this frame.
        """
        pyramid = image_pyramid(frame, self.levels)
        # the block grid's strength and the compression error, from one pass over the frame's pixel steps
        measured = min(frame.shape[-2:]) >= 2 * BLOCK and (self.block_limit is not None or self.compression_reg > 0)
        ratio, compression = block_grid(frame) if measured else (None, None)
        noise = self._noise_variance(frame, compression)
        if noise is not None and noise_floor is not None:
            noise = torch.maximum(noise, noise_floor)
        start = torch.where(torch.isfinite(positions), positions, torch.zeros_like(positions))  # lost: where frozen
        d = torch.zeros_like(positions)
        fine_weight = self._fine_weight(ratio)
        first = self._first_step(ratio, psr_mean)
        spectra, centres, gates = [], [], []
        for level in reversed(range(self.levels)):
            gate = self._level_gate(pyramid[level], level)
            gates.insert(0, gate)
            if gate is False:  # a level the frame is too small for (eager): not searched, its filters kept
                spectra.insert(0, None)
                centres.insert(0, None)
                continue
            centre = _level_centres(start + d, level)
            zr, zi, std = self._sample(pyramid[level], centre, level)
            spectrum = self._response(filters[level], zr, zi, self._noise_power(noise, std, level), level)
            score = self.dfts[level].inverse(spectrum)  # (N, P, N)
            weighted = self._weighted(level)
            if level == 0 or not weighted:
                argmax = interleaved_argmax(score)
                psr_argmax = argmax  # the PSR judges the unweighted level-0 map
            if weighted:  # the peak of the prior-weighted map, refined on the map itself
                argmax = interleaved_argmax(score, self._search_weight(level, first))
            step = 2**level * self._peak(spectrum, score, argmax, level)
            if level < min(_BLOCK_LEVELS, self.levels - 1):
                step = step * fine_weight
            if gate is not True:  # an exported graph: the level counts only in a frame large enough for it
                step = torch.where(gate, step, torch.zeros_like(step))
            d = d + step
            spectra.insert(0, (zr, zi))
            centres.insert(0, centre)
        psr = interleaved_psr(score, self.psr_exclude, psr_argmax)
        moved = start + d
        # Training samples at the new positions: the search samples shifted in the Fourier domain (as C-COT
        # centres its samples on the target), cheaper than extracting again and at least as accurate. Level 0's
        # also serves the forward-backward test; lost points learn nothing (eta 0), whatever their sample.
        sample = self._shift(*spectra[0], moved - centres[0], 0)
        inside = self._inside(moved, frame)
        was_lost, lost = lost, lost | ~inside
        threshold = self._lost_threshold(psr, lost)
        weak = ~lost & ~(psr >= threshold)  # of the points still tracked
        if self.psr_rate is not None:  # and weak against the point's own history (always, before it has one)
            weak = weak & ~(psr >= self.psr_relative * psr_mean)
        # in a blocked frame level 0 shows the blocks, not the scene: only the (lower) floor flags points there
        weak = weak & (fine_weight > 0)
        # a lost point comes back where its frozen filters find a peak as strong as the frame's tracked points'
        # and nearly as strong as its own were before (never: a point without history, psr_mean inf)
        back = torch.zeros_like(lost)
        if self.psr_recover is not None:
            strong = (psr >= threshold) & (psr >= self.psr_threshold) & (psr >= self.psr_recover * psr_mean)
            back = was_lost & inside & strong
        if self.fb_threshold is not None:
            # a weak point whose unweighted level-0 peak lies elsewhere than the prior's choice is ambiguous;
            # the other weak points, and the lost points that would come back, take the forward-backward test
            ambiguous = (weak | back) & (_peak_gap(psr_argmax, argmax, score.shape[0]) > self.fb_threshold)
            misses = self._fails_backward((weak | back) & ~ambiguous, previous, start, *sample, noise)
            # a returning point that does not track back to where it was frozen may track back to where the frame's
            # mean step puts it (it moved on while frozen)
            origin = self._origin(start, moved, lost, back)
            misses = (misses & ~back) | self._fails_backward(misses & back, previous, origin, *sample, noise)
            weak, back = weak & (ambiguous | misses), back & ~(ambiguous | misses)
        floor = fine_weight * self.psr_threshold + (1 - fine_weight) * self.block_psr_threshold
        if self.floor_relative is not None:  # lowered where the whole frame's PSRs are low
            counted = (~lost & torch.isfinite(psr)).sum() >= _FLOOR_POINTS
            relative = torch.where(counted, self.floor_relative * self._frame_psr(psr, lost), math.inf)
            floor = torch.minimum(relative, floor) if isinstance(floor, Tensor) else relative.clamp_max(floor)
        lost = (lost | weak | ~(psr >= floor)) & ~back
        psr_mean = self._psr_mean(psr_mean, psr, lost)
        positions = torch.where(lost.unsqueeze(-1), positions, moved)
        target = torch.where(lost.unsqueeze(-1), start, moved)
        rate = self._memory_rate(start, moved, ~(lost | was_lost))
        eta = torch.where(lost, torch.zeros_like(psr), rate.expand_as(psr))
        updated = [self._learn(filters[0], *sample, eta, 0)]
        for level in range(1, self.levels):
            if spectra[level] is None:
                updated.append(filters[level])
                continue
            shift = _level_centres(target, level) - centres[level]
            learned = self._learn(filters[level], *self._shift(*spectra[level], shift, level), eta, level)
            # in an exported graph a level the frame is too small for keeps its filters, as in an eager step
            updated.append(learned if gates[level] is True else torch.where(gates[level], learned, filters[level]))
        return positions, lost, psr, psr_mean, *updated

    @property
    def full_depth_side(self) -> int:
        """The least shorter frame side (px) at which every level searches: level ``l``'s image has ``ceil(n /
        2^l)`` px of a frame's ``n`` (:func:`image_pyramid`), so the deepest needs ``(min_level_side - 1) 2^(L - 1) +
        1`` (657 px for the default 5 levels); 1 where no level is gated."""
        if self.levels <= self.min_levels:
            return 1
        return (self.min_level_side - 1) * 2 ** (self.levels - 1) + 1

    def _level_gate(self, image: Tensor, level: int) -> bool | Tensor:
        """Whether ``level`` searches in a frame whose level image is ``image`` ``(1, 1, h, w)``: always for the
        first ``min_levels``, beyond them where ``min(h, w)`` is at least ``min_level_side``. A bool from the
        shape in eager and compiled steps; in an exported graph a ``()`` bool tensor computed from the image's
        shape, so the graph stays dynamic in the frame size: there the level is searched in every frame, and
        where the gate is off its step counts as zero and its filters stay as they were, as in an eager step."""
        if level < self.min_levels:
            return True
        if not exporting():
            return min(image.shape[-2:]) >= self.min_level_side
        rows, columns = (torch.ones_like(line).sum() for line in (image[0, 0, :, 0], image[0, 0, 0, :]))
        return torch.minimum(rows, columns) >= self.min_level_side

    @staticmethod
    def _origin(start: Tensor, moved: Tensor, lost: Tensor, back: Tensor) -> Tensor:
        """Where a point ``(P, 2)`` was in the previous frame if it moved as the frame does: its start, or for a
        point coming ``back`` (frozen while it may have moved on) its new position less the mean step ``moved -
        start`` of the points tracked into this frame (not ``lost``). A returning point passes the
        forward-backward test if it tracks back to where it was frozen or to this origin."""
        tracked = (~lost).to(start.dtype).unsqueeze(-1)
        step = ((moved - start) * tracked).sum(0) / tracked.sum().clamp_min(1)
        return torch.where(back.unsqueeze(-1), moved - step, start)

    def _fails_backward(
        self, weak: Tensor, previous: Tensor, start: Tensor, zr: Tensor, zi: Tensor, noise: Tensor | None = None
    ) -> Tensor:
        """``weak`` ``(P,)`` and-ed with a forward-backward miss above ``fb_threshold`` (see
        :meth:`_backward_error`; ``noise``: the frames' noise variance, :meth:`_noise_variance`). Eager runs test
        only the weak points (a few per cent, so the test costs almost nothing), and so does an exported graph
        (a shape that depends on the data); a compiled step, which would break its graph there, tests all of
        them. All give the same flags. One spare search (the last point's, its flag written to a slot past the
        points and dropped) keeps the exported set from being empty, which onnxruntime's scatter does not take; an
        eager step without weak points searches nothing (most steps' second test, of the points coming back)."""
        if torch.compiler.is_compiling() and not exporting():
            return weak & ~(self._backward_error(previous, start, zr, zi, noise) <= self.fb_threshold)
        if not exporting() and not bool(weak.any()):
            return weak
        spare = torch.arange(weak.shape[0], device=weak.device)[-1:] + 1  # slot P, as a tensor (P is symbolic)
        index = torch.cat([weak.nonzero()[:, 0], spare])  # the weak points and the spare slot
        source = index.clamp_max(weak.shape[0] - 1)
        miss = self._backward_error(previous, start[source], zr[:, source], zi[:, source], noise)
        flags = weak.new_zeros(weak.shape[0] + 1).index_put((index,), ~(miss <= self.fb_threshold))
        return flags[:-1]

    def _backward_error(
        self, previous: Tensor, start: Tensor, zr: Tensor, zi: Tensor, noise: Tensor | None = None
    ) -> Tensor:
        """Forward-backward error ``(P,)`` in px (Kalal et al. 2010, on level 0): a filter trained on the new
        sample alone (band-limited spectrum ``(2M + 1, P, M + 1)`` centred on the new position) searches the
        previous frame around the start positions ``(P, 2)``; the distance of its peak from the start is how far
        tracking back would miss (one search: the sample window pulls the peak towards the centre, so misses of a
        few px read up to about 20 % short). A point that an occluder covered or that locked onto another
        structure comes back elsewhere; one tracked correctly through blur, noise or a brightness change comes
        back home. ``noise``: the frames' noise variance (:meth:`_noise_variance`; None: no noise term)."""
        new_sample_filter = self._learn(None, zr, zi, None, 0)
        sr, si, std = self._sample(previous, start, 0)
        score = self.dfts[0].inverse(self._response(new_sample_filter, sr, si, self._noise_power(noise, std, 0), 0))
        return interleaved_peak(score)[0].norm(dim=-1)

    def _response(self, filters: Tensor, zr: Tensor, zi: Tensor, noise: Tensor | None, level: int) -> Tensor:
        """Score spectrum ``[re | im]`` ``(2M + 1, P, 2M + 2)`` of a level's filters ``(3, 2M + 1, P, M + 1)`` (see
        :class:`TrackerState`) on sample spectra ``(2M + 1, P, M + 1)``: ``A Z / (B + reg_rel mean(B) + noise_reg
        noise S)``, with ``noise`` ``(P,)`` from :meth:`_noise_power` (None: no noise term) and ``S`` the
        level's per-frequency power of unit white noise in a sample."""
        ar, ai, b = filters.unbind(0)
        mean_energy = b.sum(0).sum(1, keepdim=True) / (b.shape[0] * b.shape[2])  # (P, 1), outer axis first
        regulariser = spread(self.reg_rel * mean_energy, b.shape[-1])
        if noise is not None:
            noise_spectrum = getattr(self, f"noise_spectrum_{level}")
            regulariser = regulariser + outer_product(self.noise_reg * noise[:, None], noise_spectrum)
        inv = 1 / (b + regulariser)
        return torch.cat([(ar * zr - ai * zi) * inv, (ar * zi + ai * zr) * inv], -1)

    def _fine_weight(self, ratio: Tensor | None) -> Tensor | float:
        """Weight of the corrections of the levels on which a codec block spans more than 2 px (levels 0 and 1,
        never the coarsest): 1, or 0 in a frame whose 8 px compression grid is stronger than ``block_limit``
        (``ratio``: the frame's :func:`~models.tracking.compression.block_grid_ratio`; None where it was not
        measured, a frame under two blocks a side: 1). There the blocks are nearly flat inside and step at their
        borders, and that is the structure these levels' filters match; the coarser levels, on which a block is at
        most 2 px, give the better estimate."""
        if self.block_limit is None or ratio is None:
            return 1.0
        return (ratio <= self.block_limit).to(ratio.dtype)

    def _lost_threshold(self, psr: Tensor, lost: Tensor) -> Tensor:
        """The PSR below which a point's peak is weak in this frame: ``psr_relative`` times the geometric mean PSR
        of the points still tracked (:meth:`_frame_psr`). Relative to the frame, the test follows what lowers every
        point's PSR alike (darkness, blur, compression) and singles out the points whose peak collapses against
        the rest (occlusion, a wrong match). It needs other points to compare with: a point tracked alone is lost
        only by the floor ``psr_threshold`` or by leaving the image."""
        return self.psr_relative * self._frame_psr(psr, lost)

    @staticmethod
    def _frame_psr(psr: Tensor, lost: Tensor) -> Tensor:
        """Geometric mean of the finite PSRs ``(P,)`` of the points not ``lost`` (1 where there are none), a
        0-dim tensor."""
        tracked = (~lost & torch.isfinite(psr)).to(psr.dtype)
        log_psr = torch.log(torch.where(tracked > 0, psr, torch.ones_like(psr)).clamp_min(1e-3)) * tracked
        return torch.exp(log_psr.sum() / tracked.sum().clamp_min(1))

    def _psr_mean(self, psr_mean: Tensor, psr: Tensor, lost: Tensor) -> Tensor:
        """Each point's running geometric-mean PSR ``(P,)`` after a frame with PSR ``psr`` ``(P,)``: ``mean^(1 - r)
        psr^r`` (``r = psr_rate``), the PSR itself for a point without history (inf); points lost in this frame
        keep theirs. A point whose texture always gives a low PSR is weak against the frame's other points in
        every frame, and every frame's forward-backward test is another chance of a false alarm; against its own
        history it is weak only when its match collapses, as under an occluder."""
        if self.psr_rate is None:
            return psr_mean
        psr = psr.clamp_min(1e-3)
        new = torch.where(torch.isinf(psr_mean), psr, torch.exp(_lerp(psr_mean.log(), psr.log(), self.psr_rate)))
        return torch.where(lost | ~torch.isfinite(psr), psr_mean, new)

    def step(self, frame: Tensor, state: TrackerState, compile: bool = False) -> TrackerState:
        """Track all points of ``state`` into ``frame`` ``(H, W)``; ``compile``: run :meth:`forward` through
        ``torch.compile`` (see :meth:`track`). A first step whose matches are weak and whose residuals show
        noise that the frame's estimate under-read is tracked again by the low-SNR twin (:meth:`_low_snr_retry`); a
        step whose points turn is tracked again from the turned previous frame (:meth:`_turn_matched_step`).

        Both can meet in a first step: a turn also weakens the matches and deforms the residuals, so the retry
        fires on a fast-turning first step, noise or not. The twin's step (its wider coarse patches reach further)
        then gives the turn, the tracker tracks the step again from the previous frame turned by it, and the retry
        decides again on that step, from which the turn has gone: the twin keeps the sequence only where the
        noise remains. Where the first decision alone counted, the twin kept the fast-turning sequences the retry
        caught and lost precision on them (docs/results.md)."""
        if state.low_snr:
            return replace(self.low_snr_tracker.step(frame, replace(state, low_snr=False), compile), low_snr=True)
        frame = self._frame(frame)
        return self._turn_matched_step(frame, state, self._matched_step(frame, state, compile), compile)

    def _matched_step(self, frame: Tensor, state: TrackerState, compile: bool) -> TrackerState:
        """:meth:`step` into a ``(1, 1, H, W)`` frame before the turn matching: with blur or streak matching and the
        low-SNR retry."""
        forward = self._compiled() if compile else self
        if self.blur_match is None:
            return self._low_snr_retry(frame, state, self._advance(forward, frame, state), compile)
        streak = self._streak(frame, state.streak)
        if streak is not None or state.template:
            previous = None if state.template else state.frame  # a first streak: was it there already?
            new = self._streak_matched_step(forward, frame, state, streak, previous)
        else:
            new = self._blur_matched_step(forward, frame, state)
        return self._low_snr_retry(frame, state, new, compile)

    def _turn_matched_step(self, frame: Tensor, state: TrackerState, new: TrackerState,
                           compile: bool) -> TrackerState:
        """``new``, the step from ``state`` into ``frame``, or, where its tracked points turn by more than
        ``turn_match`` (:func:`~models.tracking.turn.camera_turn`; at least ``TURN_POINTS`` points tracked into and
        out of the previous frame), the step tracked again from the previous frame turned onto this one: warped by the
        similarity fitted to the points' steps (:func:`~models.tracking.turn.fit_similarity`), the points moved
        with it and their filters trained afresh there. A filter only finds a patch that looks like its samples,
        and a camera that rolls or zooms by more than a few degrees or percent a frame turns every patch away
        from them; the turned previous frame looks like this frame up to the points' own motion. The sample
        memory restarts, as in blur matching."""
        if self.turn_match is None:
            return new
        tracked = ~(state.lost | new.lost)
        weight = tracked.to(state.positions.dtype)
        if not float(camera_turn(state.positions, new.positions, weight, TURN_POINTS)) > self.turn_match:
            return new
        similarity = fit_similarity(state.positions, new.positions, weight)
        turned = warp_affine(state.frame, similarity[None], tuple(state.frame.shape[-2:]), padding_mode="reflection",
                             align_corners=True)
        moved = state.positions @ similarity[:, :2].T + similarity[:, 2]
        start = replace(state, frame=turned, positions=moved, reference=None, profile=None, streak=None, template=())
        return self._matched_step(frame, self._retrained(turned, start), compile)

    def _low_snr_retry(self, frame: Tensor, state: TrackerState, new: TrackerState, compile: bool) -> TrackerState:
        """``new``, the first step from ``state`` (no point has a PSR history yet) into ``frame`` ``(1, 1, H, W)``, or
        that step tracked again by the low-SNR twin where its matches are weak and its residuals show the SNR of noise
        that the frame's estimate under-read.

        :meth:`init` decides on the first frame's noise estimate, and a codec that stored dark frames at a high quality
        removed the noise's finest differences, which that estimate reads (a fifth to a third of the noise on the real
        pairs under ``dark_jpeg``), while the filters' band keeps the rest. Where the first step's geometric-mean PSR
        (:meth:`_frame_psr`) is below ``low_snr_psr``, its residual SNR (:meth:`first_step_noise`) below a quarter of
        ``low_snr`` (registration error and deformation lower the residual SNR of clean frames to 7.5-170 on the shared
        real pairs, also under the stress sets' low contrast and illumination, and to 11-28 on the synthetic sequences;
        noise gives the dark ones 1-3) and its residual noise above the frame's estimate, the twin is trained on the
        first frame and tracks this one with that noise as the frame's least noise (``noise_floor``). Only this step:
        its filters were trained on one frame and carry all of its noise, and from the second step on the sample memory
        averages the noise (kept for every later frame, the floor lowered the precision of the DAVIS round trips of surf
        and mallard-water, 0.107 -> 0.330 and 0.124 -> 0.428 px). Eager and compiled steps only; an exported step keeps
        the first decision (the runtime retries with graphs of its own)."""
        if (self.low_snr_tracker is None or self.low_snr_psr is None or self.noise_reg == 0 or exporting()
                or not bool(torch.isinf(state.psr_mean).all())):
            return new
        if not float(self._frame_psr(new.psr, new.lost)) < self.low_snr_psr:
            return new
        snr, noise, estimate = self.first_step_noise(frame, state.filters[0], new.positions, new.lost)
        if not (float(snr) < self.low_snr_residual and float(noise) > float(estimate)):
            return new
        twin = self.low_snr_tracker
        start = replace(twin.init(state.frame, state.positions, switch=False), noise_floor=noise)
        return replace(twin.step(frame, start, compile), low_snr=True)

    def first_step_noise(
        self, frame: Tensor, template: Tensor, positions: Tensor, lost: Tensor
    ) -> tuple[Tensor, Tensor, Tensor]:
        """Residual SNR and noise variance ``(1,)`` (gray levels^2) of a first step, measured in the band of level
        0's filters, and the frame's noise variance as estimated on the frame (:meth:`_noise_variance`) to compare
        with: each point's level-0 sample in ``frame`` ``(1, 1, H, W)`` at its new position ``(P, 2)`` less
        its sample in the first frame, which ``template``, the level-0 filters :meth:`init` trained on that one
        sample ``(3, 2M + 1, P, M + 1)``, holds (``A = Y conj(X)``), in power over twice the power of unit white
        noise in a sample (two noisy samples): the noise variance over the patch variance (the samples are
        normalised). The SNR is the lower median over the points not ``lost`` ``(P,)`` of its inverse, the noise
        the lower median of it times the patch variance (inf where every point is lost). Registration error and
        deformation add to both, so the noise reads above the frame's on clean frames (2-40 times the estimate on
        the shared real pairs) and near it in noise (0.6-1.6 times on them under the stress sets' darkness)."""
        keep = ~lost
        centres = torch.where(keep.unsqueeze(-1), positions, torch.zeros_like(positions))
        zr, zi, std = self._sample(frame, _level_centres(centres, 0), 0)
        ar, ai, _ = template.unbind(0)
        label = self.label_0
        residual = ((zr - ar / label).square() + (zi + ai / label).square()).sum(0).sum(1)  # (P,)
        relative = residual / (2 * self.noise_spectrum_0.sum())
        snr, noise = _lower_median(1 / relative, keep), _lower_median(relative * std.square(), keep)
        return snr, noise, self._noise_variance(frame)

    def _streak(self, frame: Tensor, previous: Streak | None = None) -> Streak | None:
        """The straight motion blur ``(length, angle)`` of a ``(1, 1, H, W)`` frame; None where its cepstral scores
        show none (:func:`core.streak.streak_found` with ``streak_score``, continuing the ``previous`` frame's
        streak at half of it), where streak matching is off, where the frame is too small to measure and while the
        graph of :meth:`init` is being exported (the runtime measures streaks with a graph of their own)."""
        too_small = min(frame.shape[-2:]) <= 2 * MAX_LENGTH
        if self.streak_score is None or self.blur_match is None or too_small or exporting():
            return None
        length, angle, score, rival = motion_blur_streak(frame).double()[0].tolist()
        # only a candidate streak needs the block grid (the rival and lattice tests): a score below the threshold,
        # or below half of it where the previous frame had a streak; otherwise streak_found is False anyway
        candidate = score < (self.streak_score if previous is None else self.streak_score / 2)
        block_grid = float(block_grid_ratio(frame)) if candidate else math.inf
        found = streak_found(length, angle, score, rival, self.streak_score, block_grid, previous)
        return (length, angle) if found else None

    def _uniform(self, frame: Tensor, streak: Streak | None, previous: Tensor | None = None) -> bool:
        """Whether ``streak``, found in the ``(1, 1, H, W)`` frame, blurs the whole frame: it reads the same in the
        frame's four quarters (:func:`core.streak.streak_uniform`). False without a streak, where the quarters are
        too small to read (:func:`core.streak.quarter_slices`) and where the ``previous`` frame (given where the
        filters know no streak yet) reads a streak that ends at the same place with a score below
        ``streak_score``: it was there already, missed only by the rival or lattice test, so this is no new
        blur."""
        quarters = quarter_slices(*frame.shape[-2:])
        if streak is None or quarters is None:
            return False
        if previous is not None:
            length, angle, score = motion_blur_streak(previous).double()[0, :3].tolist()
            if score < self.streak_score and streak_uniform(streak, [(length, angle)]):
                return False
        crops = torch.cat([frame[..., rows, columns] for rows, columns in quarters])
        return streak_uniform(streak, motion_blur_streak(crops).double()[:, :2].tolist())

    def _streak_matched_step(self, forward, frame: Tensor, state: TrackerState, streak: Streak | None,
                             previous: Tensor | None = None) -> TrackerState:
        """:meth:`forward` where this frame or the views the filters were last trained afresh on show a straight
        motion blur (``streak``: this frame's; ``previous``: the frame before where the filters know no streak yet,
        for :meth:`_uniform`).

        When the two blurs differ by more than ``streak_match`` px^2 in some direction
        (:func:`core.streak.streak_change`; ``blur_match`` for a uniform streak), each view gets the other's
        streak: the filters are retrained on the previous frame blurred by this frame's streak and search this
        frame blurred by the previous frame's, so both carry the same two streaks and no bias (a streak's
        sidelobes have the opposite sign of a Gaussian's, which a correlation filter reads as a shift along the
        streak). Otherwise the plain step runs. The radial power profiles of the Gaussian matching restart after
        such a step."""
        change = streak_change([streak] if streak else [], state.template)
        if not streaks_matched(change, self.streak_match, self.blur_match,
                               lambda: self._uniform(frame, streak, previous)):
            return replace(self._advance(forward, frame, state), streak=streak, template=state.template)
        retrained = self._retrained(self._streak_blurred(state.frame, streak), state)
        new = self._advance(forward, self._streak_blurred(frame, state.streak), retrained)
        template = tuple(s for s in (state.streak, streak) if s is not None)
        return replace(new, frame=frame, streak=streak, template=template)

    @staticmethod
    def _streak_blurred(frame: Tensor, streak: Streak | None) -> Tensor:
        """A ``(1, 1, H, W)`` frame convolved with a streak (:func:`core.streak.streak_kernel`, reflected borders;
        None: the frame)."""
        if streak is None:
            return frame
        kernel = torch.from_numpy(streak_kernel(*streak)).to(frame)
        return filter2d(frame, kernel[None], border_type="reflect")

    @staticmethod
    def _advance(forward, frame: Tensor, state: TrackerState) -> TrackerState:
        """One :meth:`forward` (or its compiled form) from ``state`` into ``frame`` ``(1, 1, H, W)``."""
        positions, lost, psr, psr_mean, *filters = forward(
            frame, state.frame, state.positions, state.lost, state.psr_mean, *state.filters,
            noise_floor=state.noise_floor,
        )
        return TrackerState(frame, positions, lost, psr, psr_mean, tuple(filters))

    def _retrained(self, frame: Tensor, state: TrackerState) -> TrackerState:
        """``state`` with the filters of every tracked point trained afresh on ``frame`` ``(1, 1, H, W)`` at its
        position; lost points stay lost and keep the filters they were lost with (they may come back)."""
        fresh = self._train(frame, state.positions)
        keep = state.lost[None, None, :, None]
        filters = tuple(torch.where(keep, old, new) for old, new in zip(state.filters, fresh.filters, strict=True))
        return replace(fresh, lost=fresh.lost | state.lost, psr=state.psr, psr_mean=state.psr_mean, filters=filters,
                       noise_floor=state.noise_floor)

    def _blur_matched_step(self, forward, frame: Tensor, state: TrackerState) -> TrackerState:
        """:meth:`forward` with the frame and the filters brought to one blur level (``blur_match``).

        The blur of ``frame`` relative to the frame the filters were last trained afresh on is measured from
        their radial power spectra (:func:`~models.tracking.blur.relative_blur`). Within ``blur_match`` px^2 the
        step is the plain one. A blurrier frame (defocus or motion blur setting in) has the filters retrained on
        the previous frame blurred by the measured difference, then searched; a sharper one (blur wearing off)
        is searched as a copy blurred to the filters' level, then the filters are retrained on it as it is. Either
        way the sample memory restarts, at this frame's blur."""
        previous = radial_power_profile(state.frame) if state.profile is None else state.profile
        reference = previous if state.reference is None else state.reference
        profile = radial_power_profile(frame)
        change = float(relative_blur(reference, profile))
        if change > self.blur_match:
            step_blur = max(float(relative_blur(previous, profile)), 0.0)
            new = self._advance(forward, frame, self._retrained(gaussian_blur(state.frame, step_blur), state))
            reference = profile
        elif change < -self.blur_match:
            searched = self._advance(forward, gaussian_blur(frame, -change), state)
            new = self._retrained(frame, searched)
            reference = profile
        else:
            new = self._advance(forward, frame, state)
        return replace(new, reference=reference, profile=profile)

    def _compiled(self):
        """:meth:`forward` compiled by ``torch.compile`` for fixed shapes (made once per tracker)."""
        if getattr(self, "_compiled_forward", None) is None:
            self._compiled_forward = torch.compile(self.forward, dynamic=False)
        return self._compiled_forward

    @torch.no_grad()
    def track(
        self, frames: Iterable[Tensor | np.ndarray], points: Tensor, compile: bool = False
    ) -> tuple[Tensor, Tensor, Tensor]:
        """Track points ``(P, 2)`` given in the first frame through gray frames ``(H, W)`` of equal size.

        ``compile`` runs the per-frame step through ``torch.compile`` (fused element-wise kernels, about a
        quarter less CPU time per frame), at the price of a compilation of about a minute on the first frame
        pair of every new frame size and point count.

        Returns:
            tracks ``(T, P, 2)``, lost ``(T, P)`` and PSR ``(T, P)`` (inf in frame 0).
        """
        param = self.label_0
        tracks, lost, psr, state, shape = [], [], [], None, None
        for t, frame in enumerate(frames):  # progress: the caller's (models.tracking.run.track_points)
            frame = torch.as_tensor(frame, dtype=param.dtype, device=param.device)
            if frame.dim() != 2:
                raise InputError(f"frame {t}: expected a (H, W) gray image, got shape {tuple(frame.shape)}")
            if shape is not None and frame.shape != shape:
                raise InputError(f"frame {t} has size {tuple(frame.shape)}, frame 0 has {tuple(shape)}")
            shape = frame.shape
            state = self.init(frame, points) if state is None else self.step(frame, state, compile)
            tracks.append(state.positions)
            lost.append(state.lost)
            psr.append(state.psr)
        if state is None:
            raise InputError("no frames to track")
        return torch.stack(tracks), torch.stack(lost), torch.stack(psr)
