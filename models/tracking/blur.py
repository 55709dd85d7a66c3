"""How much blurrier one frame is than another, from their power spectra, and blurring a frame to match.

A template matched against a blurrier view of itself is biased wherever the structure around a point is not
symmetric: the window that cuts the patch out weights the blurred structure differently from the sharp one, so
the correlation peak moves. Frame-to-frame tracking through a growing defocus accumulates that bias (about 0.3
px per frame at a 4 px blur). Blurring the sharper of the two views to the other's level removes it; this module
measures the level.

The measure compares radial power profiles. A Gaussian blur of variance ``s`` (px^2) multiplies the power at
angular frequency ``w`` by ``exp(-s |w|^2)``, so where both frames' power is well above their white noise,
``log(P_b / P_a)`` is a line in ``|w|^2``: the slope is ``-s`` and the intercept absorbs a change of contrast or
brightness. Translation does not change the power spectrum, and small rotations and scale changes move it
little, so the frames need not be aligned.
"""

from __future__ import annotations

import math

import torch
import torch.nn.functional as F
from kornia.filters import gaussian_blur2d
from torch import Tensor, nn

from core.errors import InputError
from models.dcf.noise import image_noise_std
from models.export_mode import exporting

_MIN_BINS = 3  # fitted bins below which a comparison says "no change"


def _check_images(image: Tensor, name: str) -> None:
    if image.dim() != 4 or image.shape[1] != 1 or min(image.shape[-2:]) < 8:
        raise InputError(f"{name} needs (B, 1, H, W) gray images with H, W >= 8, got {tuple(image.shape)}")


def symmetric_hann(n: int, like: Tensor) -> Tensor:
    """Symmetric Hann window of ``n`` samples (``torch.hann_window(n, periodic=False)``, written out so that an
    exported graph keeps ``n`` dynamic)."""
    return 0.5 - 0.5 * torch.cos(torch.arange(n, device=like.device).to(like.dtype) * (2 * math.pi / (n - 1)))


def block_mean(image: Tensor, reduce: int) -> Tensor:
    """Means of ``(B, C, H, W)`` images over ``reduce x reduce`` blocks, ``(B, C, H // reduce, W // reduce)``: the
    values of ``F.avg_pool2d(image, reduce)`` (to the bit on the CPU, whose pooling sums a block in the same row-major
    order), eager as a sum of strided slices (about 3x faster on a CPU), exported as the pooling."""
    if exporting():
        return F.avg_pool2d(image, reduce)
    h, w = image.shape[-2] // reduce * reduce, image.shape[-1] // reduce * reduce
    total = image[..., 0:h:reduce, 0:w:reduce].clone()
    for offset in range(1, reduce * reduce):
        i, j = divmod(offset, reduce)
        total += image[..., i:h:reduce, j:w:reduce]
    return total / (reduce * reduce)


def profile_min_size(reduce: int = 2) -> int:
    """The least image side (px) of which :func:`radial_power_profile` takes a profile at ``reduce``: 8 px a side
    after the reduction."""
    return 8 * reduce


def radial_power_profile(image: Tensor, bins: int = 64, noise_stride: int = 4, reduce: int = 2) -> Tensor:
    """Radial power profile of Hann-windowed, mean-free images.

    Args:
        image: ``(B, 1, H, W)`` gray images, ``H, W >= 8 reduce``. bins: rings centred on ``|w| = i pi / (bins
        reduce)`` rad/px, ``i = 0 .. bins - 1``, each frequency shared between the two nearest by linear weights
        (frequencies beyond the last, the spectrum's corners, are left out). noise_stride: pixel
        stride of the noise estimate (:func:`~models.dcf.image_noise_std`). reduce: the profile is taken of the
        images averaged over ``reduce x reduce`` blocks (4x cheaper at 2; blurs of 1 px^2 and more still
        attenuate the remaining band by a factor of 10 and more), its frequencies given in the input's units.
    Returns:
        ``(B, 3, bins)``: per ring the mean power, the power of the (reduced) images' white noise (its variance,
        at least the 8-bit rounding's 1/12 over ``reduce^2``, times the window's energy) and the mean ``|w|^2``
        (rad^2 per input px^2).
    """
    _check_images(image, "radial_power_profile")
    if bins < _MIN_BINS:
        raise InputError(f"a radial power profile needs at least {_MIN_BINS} bins, got {bins}")
    if reduce < 1 or min(image.shape[-2:]) < profile_min_size(reduce):
        raise InputError(f"reduce must be a positive integer that leaves 8 px a side, got {reduce} for "
                         f"{tuple(image.shape)}")
    if reduce > 1:
        image = block_mean(image, reduce)
    h, w = image.shape[-2:]
    window = symmetric_hann(h, image)[:, None] * symmetric_hann(w, image)
    mean = (image * window).sum((-2, -1), keepdim=True) / window.sum()
    spectrum = torch.fft.rfft2(((image - mean) * window)[:, 0])
    power = (spectrum.real.square() + spectrum.imag.square()).flatten(1)  # (B, H (W // 2 + 1))
    rows = torch.arange(h, device=image.device)
    wy = torch.where(rows > (h - 1) // 2, rows - h, rows).to(image.dtype)[:, None] * (2 * math.pi / h)  # fftfreq
    wx = torch.arange(w // 2 + 1, device=image.device).to(image.dtype) * (2 * math.pi / w)  # rfftfreq
    radius2 = (wy.square() + wx.square()).flatten()
    # linear ring weights: a frequency between ring centres i and i + 1 (multiples of pi / bins) is shared
    # between them by distance, so that rounding cannot move a whole frequency from one ring to the next;
    # frequencies beyond the last centre are left out
    position = radius2.sqrt() * (bins / math.pi)
    inside = (position <= bins - 1).to(image.dtype)
    lower = position.floor().clamp_max(bins - 1)
    upper_weight = (position - lower) * inside
    lower_weight = (1 - position + lower) * inside
    values = torch.cat([power, radius2[None], torch.ones_like(radius2)[None]])  # (B + 2, F): power, |w|^2, count
    sums = torch.zeros(values.shape[0], bins + 1, dtype=image.dtype, device=image.device)
    index = lower.long()
    sums = sums.index_add(1, index, values * lower_weight).index_add(1, index + 1, values * upper_weight)
    count = sums[-1, :bins].clamp_min(1e-12)
    ring_power = sums[:-2, :bins] / count
    ring_radius2 = sums[-2, :bins] / count / reduce**2
    noise = image_noise_std(image, noise_stride).square().clamp_min(1 / 12 / reduce**2) * window.square().sum()
    return torch.stack([ring_power, noise[:, None].expand_as(ring_power), ring_radius2.expand_as(ring_power)], 1)


def relative_blur(reference: Tensor, profile: Tensor, snr: float = 4.0) -> Tensor:
    """Variance ``s`` (px^2) of the Gaussian blur that takes the reference frames to the others.

    A least-squares line ``log((P - N) / (P_ref - N_ref)) = c - s |w|^2`` over the rings where both noise-free
    powers exceed ``snr`` times the noise power (:func:`radial_power_profile`); ``s`` is 0 when fewer than 3
    rings qualify (nothing to compare, e.g. flat frames).

    Args:
        reference, profile: ``(B, 3, bins)`` radial power profiles of frames of equal size.
    Returns:
        ``(B,)``: positive where ``profile``'s frame is blurrier, negative where it is sharper.
    """
    if reference.shape != profile.shape or reference.dim() != 3 or reference.shape[1] != 3:
        raise InputError(
            f"relative_blur needs two (B, 3, bins) radial power profiles of one shape, got {tuple(reference.shape)} "
            f"and {tuple(profile.shape)}"
        )
    signal_ref, signal = reference[:, 0] - reference[:, 1], profile[:, 0] - profile[:, 1]
    used = (signal_ref > snr * reference[:, 1]) & (signal > snr * profile[:, 1])
    weight = used.to(profile.dtype)
    x = profile[:, 2]
    one = torch.ones_like(signal)
    y = torch.log(torch.where(used, signal, one) / torch.where(used, signal_ref, one))
    n, sx, sy = weight.sum(1), (weight * x).sum(1), (weight * y).sum(1)
    sxx, sxy = (weight * x * x).sum(1), (weight * x * y).sum(1)
    spread = n * sxx - sx * sx
    slope = (n * sxy - sx * sy) / torch.where(spread > 0, spread, torch.ones_like(spread))
    return torch.where((n >= _MIN_BINS) & (spread > 0), -slope, torch.zeros_like(slope))


def gaussian_blur(image: Tensor, variance: float) -> Tensor:
    """``image`` ``(B, 1, H, W)`` blurred by a Gaussian of ``variance`` px^2 (``kornia.filters.gaussian_blur2d``
    with OpenCV's kernel size for float images, ``2 round(4 sigma) + 1``, and reflected borders, so that
    ``cv2.GaussianBlur`` gives the same values); a variance of 0 returns the image."""
    if not variance >= 0:
        raise InputError(f"a blur variance must be a non-negative number, got {variance}")
    if variance == 0:
        return image
    sigma = math.sqrt(variance)
    size = min(int(round(sigma * 8 + 1)) | 1, 2 * min(image.shape[-2:]) - 1)  # reflection needs a smaller pad
    sigmas = torch.tensor([[sigma, sigma]], dtype=image.dtype, device=image.device)
    return gaussian_blur2d(image, size, sigmas, border_type="reflect")


class RadialPowerProfile(nn.Module):
    """Module form of :func:`radial_power_profile`: ``(B, 1, H, W)`` -> ``(B, 3, bins)``."""

    def __init__(self, bins: int = 64, noise_stride: int = 4, reduce: int = 2) -> None:
        super().__init__()
        self.bins, self.noise_stride, self.reduce = bins, noise_stride, reduce

    def forward(self, image: Tensor) -> Tensor:
        return radial_power_profile(image, self.bins, self.noise_stride, self.reduce)
