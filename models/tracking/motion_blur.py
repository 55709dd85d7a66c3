"""Straight motion blur of a frame, from its power cepstrum (read by the point tracker's streak matching).

A streak of length ``L`` px in direction ``u`` multiplies the spectrum by ``sinc(L u . w / 2)``, whose zeros
repeat every ``2 pi / L`` rad/px along ``u``. The log power spectrum then carries a ripple of that period, and
its inverse DFT (the power cepstrum) a strong negative peak at ``L u`` (Cannon 1976; Gennery 1973), far below
the values around it, while a sharp frame, a Gaussian (defocus) blur or compression noise leave that part of the
cepstrum without an outstanding minimum. The peak gives the streak's length and direction directly. The block
grid of a heavily compressed frame also leaves deep minima, at the grid's lattice points: in several directions,
where a streak leaves one.

The point tracker needs this because a Gaussian stand-in for a streak matches its spectrum only below the first
zero: beyond it the streak's sidelobes have the opposite sign, and a correlation filter, which whitens the
spectrum, reads them as a shift along the streak (about 1 px of scatter on 12 px streaks). Blurring each view by
the other's streak gives both views exactly the same blur.
"""

from __future__ import annotations

import math

import numpy as np
import torch
from torch import Tensor, nn

from core.errors import InputError
from models.dcf.noise import image_noise_std
from models.export_mode import exporting
from models.tracking.blur import symmetric_hann

_MAD_TO_STD = 1.482602218505602  # std of a normal distribution over its median absolute deviation
_RIVAL_ANGLE = math.radians(20)  # rad: directions this far from the streak's hold its rival
MAX_LENGTH = 24  # px: the longest streak searched by default; frames need more than twice that a side


def _search_offsets(min_length: float, max_length: int) -> tuple[Tensor, Tensor]:
    """Integer cepstrum offsets ``(dy, dx)`` ``(K,)`` of the half plane ``dy > 0`` or ``dy = 0, dx > 0`` (the
    cepstrum of a real image is even) with ``min_length <= |(dy, dx)| <= max_length`` (constants of a graph)."""
    dy, dx = np.meshgrid(np.arange(max_length + 1), np.arange(-max_length, max_length + 1), indexing="ij")
    radius2 = dy * dy + dx * dx
    keep = (radius2 >= min_length**2) & (radius2 <= max_length**2) & ((dy > 0) | (dx > 0))
    return torch.from_numpy(dy[keep]), torch.from_numpy(dx[keep])


def _dft_matrices(n: int, columns: int, like: Tensor) -> tuple[Tensor, Tensor]:
    """``cos`` and ``sin`` of ``2 pi k m / n`` for ``k < n``, ``m < columns``: ``(n, columns)`` of ``like``'s dtype,
    the phase ``k m mod n`` taken in integers so that the angles are exact for any ``n``."""
    k = torch.arange(n, device=like.device)
    period = k[-1:] + 1  # n as a tensor: an exported graph takes the remainder by a tensor, not a symbolic size
    angle = ((k[:, None] * k[:columns]) % period).to(like.dtype) * (2 * math.pi / n)
    return angle.cos(), angle.sin()


def _cepstrum_by_products(image: Tensor, noise: Tensor, columns: int) -> Tensor:
    """Power cepstrum ``(B, H, columns)`` (columns ``0 .. columns - 1``, ``columns <= W // 2 + 1``) of centred,
    windowed images ``(B, H, W)`` with ``noise`` ``(B,)`` added to the power, as matrix products: the values of
    the FFT path of :func:`motion_blur_streak` (``rfft2`` of the log power, real part). The power spectrum of a
    real image is even, so its columns ``0 .. W // 2`` hold it all; the others enter the cepstrum's sum by
    doubling the columns that have a mirror."""
    h, w = image.shape[-2:]
    half = w // 2 + 1
    cos_h, sin_h = _dft_matrices(h, h, image)
    cos_w, sin_w = _dft_matrices(w, half, image)
    re, im = image @ cos_w, image @ sin_w  # along rows: X (cos - i sin), imaginary part negated
    power = (cos_h @ re - sin_h @ im).square() + (sin_h @ re + cos_h @ im).square()
    v = torch.arange(half, device=image.device)
    mirrored = 2 - (v == 0).to(image.dtype) - (2 * v == w).to(image.dtype)  # columns 0 and W / 2 are their own
    log_power = torch.log(power + noise[:, None, None]) * mirrored
    cos_c, sin_c = cos_w[:half, :columns], sin_w[:half, :columns]  # frequency v to cepstrum column x
    return cos_h @ (log_power @ cos_c) - sin_h @ (log_power @ sin_c)


def motion_blur_streak(image: Tensor, min_length: float = 4.4, max_length: int = MAX_LENGTH, noise_stride: int = 4,
                       crop: int = 320) -> Tensor:
    """The straight streak that best explains each image's blur, and how clearly the image shows it.

    Args:
        image: ``(B, 1, H, W)`` gray images, ``H, W > 2 max_length``. min_length, max_length: px, the streak
        lengths searched (shorter streaks barely blur; the default 4.4 px is a variance of about 1.6 px^2).
        noise_stride: pixel stride of the noise estimate (:func:`~models.dcf.image_noise_std`), whose power
        is added to the spectrum before the logarithm so that frequencies holding only noise stay flat.
        crop: the cepstrum is taken of the central ``crop x crop`` px at most (a camera's streak is the same
        everywhere; 4x cheaper on a 1024 x 436 frame).
    Returns:
        ``(B, 4)``: length (px), angle (rad in ``[0, pi)``, x towards y), score: the cepstral minimum's
        distance below the median of the searched offsets, in robust standard deviations (median absolute
        deviation; strongly negative, e.g. below -10, for a streak, about -2 to -9 for frames without one) and
        rival: the same for the lowest offset in a direction more than 20 degrees away (about -2 to -4 for a
        streak; as low as the score for the block grid of a heavily compressed frame, whose minima lie in
        several directions; :func:`core.streak.streak_found` decides with both).
    """
    if image.dim() != 4 or image.shape[1] != 1 or min(image.shape[-2:]) <= 2 * max_length:
        raise InputError(f"motion_blur_streak needs (B, 1, H, W) gray images larger than {2 * max_length} px a "
                         f"side, got {tuple(image.shape)}")
    if not 1 <= min_length < max_length or crop <= 2 * max_length:
        raise InputError(f"need 1 <= min_length < max_length < crop / 2, got {min_length}, {max_length}, {crop}")
    top, left = max(0, (image.shape[-2] - crop) // 2), max(0, (image.shape[-1] - crop) // 2)
    image = image[..., top : top + crop, left : left + crop]
    h, w = image.shape[-2:]
    window = symmetric_hann(h, image)[:, None] * symmetric_hann(w, image)
    mean = (image * window).sum((-2, -1), keepdim=True) / window.sum()
    noise = image_noise_std(image, noise_stride).square().clamp_min(1 / 12) * window.square().sum()
    # the power cepstrum: the log power is real and even, so its inverse DFT is the real part of its forward DFT
    # over H W, read at columns 0 .. W // 2 (the rest by the same symmetry); the scale does not change the score
    centred = ((image - mean) * window)[:, 0]
    if exporting():  # onnxruntime's DFT of a length that is not a power of 2 is a slow direct sum
        cepstrum = _cepstrum_by_products(centred, noise, max_length + 2)
    else:
        spectrum = torch.fft.fft2(centred)  # full: the log power is transformed as a real image
        power = spectrum.real.square() + spectrum.imag.square()
        cepstrum = torch.fft.rfft2(torch.log(power + noise[:, None, None])).real  # (B, H, W // 2 + 1)
    columns_kept = cepstrum.shape[-1]
    cepstrum = cepstrum.flatten(1)
    dy, dx = (v.to(image.device) for v in _search_offsets(min_length, max_length))

    def read(rows: Tensor, columns: Tensor) -> Tensor:  # offsets within one period; C(-y, -x) = C(y, x)
        flip = columns < 0
        rows, columns = torch.where(flip, -rows, rows), torch.where(flip, -columns, columns)
        return cepstrum.gather(1, torch.where(rows < 0, rows + h, rows) * columns_kept + columns)

    values = read(*(v.expand(image.shape[0], -1) for v in (dy[None], dx[None])))  # (B, K)
    k = values.shape[1]
    median = values.topk(k // 2 + 1, dim=1, largest=False).values[:, -1:]
    spread = (values - median).abs().topk(k // 2 + 1, dim=1, largest=False).values[:, -1] * _MAD_TO_STD
    low, best = values.min(1)
    y, x = dy[best][:, None], dx[best][:, None]
    centre = low[:, None]

    def vertex(before: Tensor, after: Tensor) -> Tensor:  # parabola through three samples, within half a pixel
        curvature = before - 2 * centre + after
        offset = 0.5 * (before - after) / torch.where(curvature > 0, curvature, torch.ones_like(curvature))
        return torch.where(curvature > 0, offset, torch.zeros_like(offset)).clamp(-0.5, 0.5)[:, 0]

    fy = y[:, 0].to(image.dtype) + vertex(read(y - 1, x), read(y + 1, x))
    fx = x[:, 0].to(image.dtype) + vertex(read(y, x - 1), read(y, x + 1))
    length = (fy.square() + fx.square()).sqrt()
    angle = torch.remainder(torch.atan2(fy, fx), math.pi)
    score = (low - median[:, 0]) / spread.clamp_min(1e-12)
    off_angle = torch.atan2(dy.to(image.dtype), dx.to(image.dtype))[None] - torch.atan2(fy, fx)[:, None]
    apart = torch.remainder(off_angle + math.pi / 2, math.pi) - math.pi / 2
    rival_low = torch.where(apart.abs() > _RIVAL_ANGLE, values, torch.full_like(values, float("inf"))).min(1).values
    rival = (rival_low - median[:, 0]) / spread.clamp_min(1e-12)
    return torch.stack([length, angle, score, rival], -1)


class MotionBlurStreak(nn.Module):
    """Module form of :func:`motion_blur_streak`: ``(B, 1, H, W)`` -> ``(B, 4)``."""

    def __init__(self, min_length: float = 4.4, max_length: int = MAX_LENGTH, noise_stride: int = 4,
                 crop: int = 320) -> None:
        super().__init__()
        self.min_length, self.max_length, self.noise_stride, self.crop = min_length, max_length, noise_stride, crop

    def forward(self, image: Tensor) -> Tensor:
        return motion_blur_streak(image, self.min_length, self.max_length, self.noise_stride, self.crop)
