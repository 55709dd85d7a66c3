"""Straight motion-blur streaks, torch-free: the kernel of a camera or object moving in a line during the
exposure, and a frame blurred by it (used by the homography sets that make such blur, by the point tracker that
matches it and by the deployment runtime)."""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable

import cv2
import numpy as np

from core.errors import InputError

Streak = tuple[float, float]  # a straight streak: length in px, angle in rad (x towards y)
_BLOCK = 8  # px: the block size of JPEG and MPEG compression
# block-grid ratio (models.tracking.compression.block_grid_ratio) above which a frame shows a codec's block grid:
# 0.97-1.03 for uncompressed frames and DAVIS's high-quality JPEGs, 1.15 and more at JPEG quality 60 and below
BLOCK_GRID_PRESENT = 1.1
MIN_QUARTER = 64  # px: the least side of a frame's quarter whose streak is read (streak_uniform)
UNIFORM_TOLERANCE = 2.0  # px: how far a quarter's streak may end from the frame's in a uniform blur
CONTINUE_ANGLE = math.radians(20)  # rad: how far a streak's direction may turn from the previous frame's and continue


def streak_kernel(length: float, angle: float) -> np.ndarray:
    """Motion-blur kernel: a straight streak of ``length`` px at ``angle`` radians (x towards y) through the
    centre of an odd square, as the mean of 256 bilinear splats along it; float32, sums to 1."""
    if not (np.isfinite(length) and length >= 0 and np.isfinite(angle)):
        raise InputError(f"a streak needs a finite length >= 0 and a finite angle, got {length} px, {angle} rad")
    half = int(np.ceil(length / 2)) + 1
    kernel = np.zeros((2 * half + 1, 2 * half + 1), np.float64)
    t = np.linspace(-length / 2, length / 2, 256)
    x, y = half + t * np.cos(angle), half + t * np.sin(angle)
    x0, y0 = np.floor(x).astype(int), np.floor(y).astype(int)
    fx, fy = x - x0, y - y0
    for dy, dx, weight in ((0, 0, (1 - fx) * (1 - fy)), (0, 1, fx * (1 - fy)), (1, 0, (1 - fx) * fy), (1, 1, fx * fy)):
        np.add.at(kernel, (y0 + dy, x0 + dx), weight)
    return (kernel / kernel.sum()).astype(np.float32)


def streak_blur(image: np.ndarray, length: float, angle: float, border: int = cv2.BORDER_REFLECT_101) -> np.ndarray:
    """A float32 gray image ``(H, W)`` convolved with :func:`streak_kernel` (``border``: OpenCV's border mode;
    the default reflects without repeating the edge, as ``torch`` and ``kornia`` do)."""
    image = np.asarray(image, np.float32)
    if image.ndim != 2:
        raise InputError(f"streak_blur needs a (H, W) gray image, got shape {image.shape}")
    return cv2.filter2D(image, -1, streak_kernel(length, angle), borderType=border)


def streak_covariance(streaks: Iterable[Streak]) -> tuple[float, float, float]:
    """Covariance ``(xx, xy, yy)`` in px^2 of the blur of a chain of streaks: ``L^2 / 12`` (a box's variance)
    along each streak's direction, summed (the covariances of convolved kernels add)."""
    xx = xy = yy = 0.0
    for length, angle in streaks:
        variance, c, s = length * length / 12, math.cos(angle), math.sin(angle)
        xx, xy, yy = xx + variance * c * c, xy + variance * c * s, yy + variance * s * s
    return xx, xy, yy


def streak_change(after: Iterable[Streak], before: Iterable[Streak]) -> float:
    """How much two chains of streaks differ: the largest absolute eigenvalue (px^2) of the difference of their
    covariances (:func:`streak_covariance`), i.e. the largest change of blur variance in any direction."""
    (axx, axy, ayy), (bxx, bxy, byy) = streak_covariance(after), streak_covariance(before)
    dxx, dxy, dyy = axx - bxx, axy - bxy, ayy - byy
    return abs((dxx + dyy) / 2) + math.hypot((dxx - dyy) / 2, dxy)


def streaks_matched(change: float, streak_match: float, blur_match: float, uniform: Callable[[], bool]) -> bool:
    """Whether two views whose streaks differ by ``change`` px^2 (:func:`streak_change`) are matched: beyond
    ``streak_match``, or beyond ``blur_match`` where the new streak blurs the whole frame (``uniform()``, asked only
    where the two limits disagree, since it reads the frame's quarters)."""
    if min(streak_match, blur_match) < change <= max(streak_match, blur_match):
        return change > (blur_match if uniform() else streak_match)
    return change > streak_match


def streak_found(length: float, angle: float, score: float, rival: float, threshold: float,
                 block_grid: float = math.inf, previous: Streak | None = None) -> bool:
    """Whether the cepstral reading of a frame (``models.tracking.motion_blur.motion_blur_streak``: a streak of
    ``length`` px at ``angle`` rad, its ``score`` and ``rival``) shows a straight streak: the score below
    ``threshold`` (negative), nothing below half of it in other directions (in a frame without a codec's block
    grid, nothing below half of the score: a directional texture, such as waves, may hold a rival below half the
    threshold, while a block grid's minima lie in several directions, as deep) and, in a frame that shows a codec's
    block grid (``block_grid``, its block-grid ratio, above :data:`BLOCK_GRID_PRESENT`; inf: assume it does), the
    streak's end not on the 8 px lattice of block-transform compression (JPEG, MPEG: 8 x 8 blocks aligned with the
    pixel grid leave their deepest cepstral minima at multiples of 8 px along x and y; in such a frame a real
    streak within half a pixel of such a point, e.g. a pan of 8 or 16 px along x or y, is missed, and its blur is
    matched as a Gaussian's). Without a block grid such a minimum is the streak's, and it counts.

    Hysteresis: a streak found in the ``previous`` frame continues at half the threshold. A score below
    ``threshold / 2`` and at least ``-threshold / 2`` below the rival (5 below it at -10), in a direction within
    :data:`CONTINUE_ANGLE` of the previous streak's, is found too. A long streak over fine texture scores
    weaker (the blur leaves fewer of its spectral zeros above the noise), while a sharp frame reads no lead of
    that size over the other directions, and a single weak reading does not start a streak."""
    x, y = length * math.cos(angle), length * math.sin(angle)
    on_lattice = abs(x - _BLOCK * round(x / _BLOCK)) < 0.5 and abs(y - _BLOCK * round(y / _BLOCK)) < 0.5
    deep = score < threshold
    if previous is not None and not deep:
        turn = abs((angle - previous[1] + math.pi / 2) % math.pi - math.pi / 2)  # directions modulo pi
        deep = score < threshold / 2 and score - rival < threshold / 2 and turn <= CONTINUE_ANGLE
    grid = block_grid > BLOCK_GRID_PRESENT
    alone = rival > threshold / 2 or (not grid and rival > score / 2)
    return deep and alone and not (on_lattice and grid)


def quarter_slices(height: int, width: int) -> list[tuple[slice, slice]] | None:
    """The (rows, columns) slices of the four quarters of a ``height x width`` frame, each ``height // 2 x
    width // 2``; None where that is below :data:`MIN_QUARTER` px a side (too small to read a streak)."""
    h, w = height // 2, width // 2
    if min(h, w) < MIN_QUARTER:
        return None
    return [(slice(r, r + h), slice(c, c + w)) for r in (0, h) for c in (0, w)]


def streak_uniform(streak: Streak, readings: Iterable[Streak], tolerance: float = UNIFORM_TOLERANCE) -> bool:
    """Whether the ``streak`` (length px, angle rad) found in a frame is the blur of the whole frame: the streak
    read in each of its quarters (``readings``, see :func:`quarter_slices`) ends within ``tolerance`` px of it (a
    streak and its reverse are the same blur). A camera's pan or shake blurs every quarter alike; a pan that
    follows an object leaves it sharp and its quarter reads another streak, or noise."""
    x, y = streak[0] * math.cos(streak[1]), streak[0] * math.sin(streak[1])
    for length, angle in readings:
        qx, qy = length * math.cos(angle), length * math.sin(angle)
        if min(math.hypot(qx - x, qy - y), math.hypot(qx + x, qy + y)) > tolerance:
            return False
    return True
