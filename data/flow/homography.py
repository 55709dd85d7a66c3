"""Point-tracking sequences from one real photograph: the image seen through a chain of small random homographies
(exact ground truth) and degraded more in every frame, in the way of the Oxford affine-region sets (Mikolajczyk
et al. 2005: ``bikes`` blur, ``ubc`` JPEG, ``leuven`` light), so that trackers meet real texture, not only the
synthetic generator's.

Frame ``t`` of ``T`` is the image warped by ``H_t`` (``H_0`` the identity; each step a rotation of up to 2
degrees, a scale change of up to 3 % and a perspective tilt about the image centre, all three times
``geometry`` (default 1; larger: a camera that turns, zooms and tilts faster, the way of a viewpoint sequence),
plus a translation of up to ``step`` px), then degraded at strength ``s = t / (T - 1)``:

- ``blur``: defocus, a Gaussian of std ``0.3 + 3.7 s`` px;
- ``motion``: motion blur of a panning camera, a straight streak of ``1 + 11 s`` px in one direction (drawn from
  the seed, the same in every frame);
- ``jpeg``: JPEG quality ``60 - 57 s`` (60 down to 3);
- ``light``: exposure ``1 - 0.85 s`` with a gamma of ``1 + 0.3 s`` (a darkening scene);
- ``none``: the geometry alone.

Every frame gets sensor noise of std 1 gray level before the 8-bit rounding. The geometry depends on the seed
only, so the conditions of one seed differ in the degradation alone. With ``moving=False`` the camera is fixed
(every ``H_t`` the identity), as in the Oxford sets themselves, whose frames differ in the degradation alone
(and in the noise). A point ``x`` of frame 0 is at
``H_t x`` in frame ``t``; it is valid while it stays 6 px inside every frame. Seeded: the same (image,
condition, seed) gives the same frames.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from core.errors import InputError
from core.streak import streak_blur

HOMOGRAPHY_CONDITIONS = ("blur", "jpeg", "light", "none", "motion")
_MARGIN = 6.0  # px a valid point keeps from the frame border


@dataclass
class HomographySequence:
    """Frames ``(T, H, W)`` float32 in [0, 255] and homographies ``(T, 3, 3)`` from frame 0 to each frame;
    ``sizes`` ``(T, 2)`` (height, width): each frame's own size where smaller frames were padded at the bottom and
    right to one size (None: every frame is ``(H, W)``)."""

    frames: np.ndarray
    homographies: np.ndarray
    sizes: np.ndarray | None = None

    def track(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Ground truth of frame-0 points ``(P, 2)`` (x, y): tracks ``(T, P, 2)`` and valid ``(T, P)`` (inside every
        frame so far, ``6`` px from the border of its own size)."""
        points = np.asarray(points, dtype=np.float64)
        if points.ndim != 2 or points.shape[1] != 2:
            raise InputError(f"points must have shape (P, 2), got {points.shape}")
        homogeneous = np.concatenate([points, np.ones((len(points), 1))], 1) @ self.homographies.transpose(0, 2, 1)
        tracks = homogeneous[..., :2] / homogeneous[..., 2:]
        sizes = np.broadcast_to(self.frames.shape[1:], (len(self.frames), 2)) if self.sizes is None else self.sizes
        h, w = sizes[:, :1], sizes[:, 1:]  # (T, 1) against the tracks' (T, P)
        x, y = tracks[..., 0], tracks[..., 1]
        inside = (x >= _MARGIN) & (x <= w - 1 - _MARGIN) & (y >= _MARGIN) & (y <= h - 1 - _MARGIN)
        return tracks, np.logical_and.accumulate(inside, axis=0)


def _homographies(rng: np.random.Generator, frames: int, width: int, height: int, step: float,
                  geometry: float = 1.0) -> np.ndarray:
    """``(T, 3, 3)`` chained random homographies about the image centre, the first the identity; ``geometry``
    multiplies each step's rotation, log scale and tilt (the draws themselves do not depend on it)."""
    centre = np.array([[1.0, 0.0, -width / 2], [0.0, 1.0, -height / 2], [0.0, 0.0, 1.0]])
    chain = [np.eye(3)]
    for _ in range(frames - 1):
        angle = np.deg2rad(geometry * rng.uniform(-2.0, 2.0))
        scale = np.exp(geometry * rng.uniform(-0.03, 0.03))
        tx, ty = rng.uniform(-step, step, 2)
        px, py = geometry * rng.uniform(-2e-5, 2e-5, 2)
        c, s = scale * np.cos(angle), scale * np.sin(angle)
        move = np.array([[c, -s, tx], [s, c, ty], [px, py, 1.0]])
        chain.append(np.linalg.inv(centre) @ move @ centre @ chain[-1])
    return np.stack(chain)


def degrade(
    image: np.ndarray, condition: str, strength: float, rng: np.random.Generator, angle: float = 0.0
) -> np.ndarray:
    """A gray frame ``(H, W)`` in [0, 255] under ``condition`` (one of :data:`HOMOGRAPHY_CONDITIONS`) at
    ``strength`` in [0, 1] (the scales of the module docstring), with sensor noise of std 1 from ``rng`` and 8-bit
    rounding, as float32 (``angle``: the motion blur's direction in radians)."""
    if condition not in HOMOGRAPHY_CONDITIONS:
        raise InputError(f"unknown condition {condition!r}; choose one of {', '.join(HOMOGRAPHY_CONDITIONS)}")
    if not 0 <= strength <= 1:
        raise InputError(f"the degradation's strength must lie in [0, 1], got {strength}")
    if condition == "blur":
        image = cv2.GaussianBlur(image, (0, 0), 0.3 + 3.7 * strength)
    elif condition == "motion":
        image = streak_blur(image, 1 + 11 * strength, angle, cv2.BORDER_REFLECT)
    elif condition == "light":
        image = 255 * (image * (1 - 0.85 * strength) / 255) ** (1 + 0.3 * strength)
    image = np.clip(image + rng.normal(0, 1.0, image.shape), 0, 255).round().astype(np.uint8)
    if condition == "jpeg":
        quality = int(round(60 - 57 * strength))
        image = cv2.imdecode(cv2.imencode(".jpg", image, [cv2.IMWRITE_JPEG_QUALITY, quality])[1], cv2.IMREAD_GRAYSCALE)
    return image.astype(np.float32)


def homography_sequence(
    image: np.ndarray, condition: str, frames: int = 6, seed: int = 0, step: float = 6.0,
    motion_angle: float | None = None, moving: bool = True, geometry: float = 1.0,
) -> HomographySequence:
    """``frames`` views of a gray ``image`` ``(H, W)`` (values in [0, 255]) under ``condition`` (one of
    :data:`HOMOGRAPHY_CONDITIONS`), moving up to about ``step`` px per frame plus the rotation and scale
    (``motion_angle``: the motion blur's direction in radians, x towards y; None: drawn from the seed;
    ``moving=False``: a fixed camera, every homography the identity, the frames degraded as in the moving
    sequence of the same seed; ``geometry``: the multiplier of each step's rotation, scale change and tilt, the
    module docstring; ``step``: the largest translation of a step along each axis, in px)."""
    if condition not in HOMOGRAPHY_CONDITIONS:
        choices = ", ".join(HOMOGRAPHY_CONDITIONS)
        raise InputError(f"unknown homography condition {condition!r}; choose one of {choices}")
    image = np.asarray(image)
    if image.ndim != 2 or min(image.shape) < 32:
        raise InputError(f"the image must be (H, W) gray and at least 32 px on each side, got shape {image.shape}")
    if frames < 2:
        raise InputError(f"a sequence needs at least 2 frames, got {frames}")
    if not (geometry >= 0 and np.isfinite(geometry)):
        raise InputError(f"the geometry multiplier must be a finite number >= 0, got {geometry}")
    if not (step >= 0 and np.isfinite(step)):
        raise InputError(f"the translation step must be a finite number of px >= 0, got {step}")
    height, width = image.shape
    # the same chain for every condition
    chain = _homographies(np.random.default_rng(seed), frames, width, height, step, geometry)
    if not moving:
        chain = np.broadcast_to(np.eye(3), chain.shape).copy()
    rng = np.random.default_rng([seed, HOMOGRAPHY_CONDITIONS.index(condition)])
    angle = rng.uniform(0, np.pi) if condition == "motion" and motion_angle is None else (motion_angle or 0.0)
    source = image.astype(np.float32)
    views = [cv2.warpPerspective(source, h, (width, height), flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT)
             for h in chain]
    out = np.stack([degrade(v, condition, t / (frames - 1), rng, angle) for t, v in enumerate(views)])
    return HomographySequence(out, chain)
