"""Synthetic stress conditions for point tracking: the synthetic sequence (:func:`synthetic_sequence`) under one
hard imaging condition each, with the same exact ground truth. Every condition starts from a moderate motion (up
to about 8 px per frame) and changes one thing:

- ``dark``: low light, the scene at 15 % of its brightness with shot noise (std ``sqrt(0.6 s)`` for a signal of
  ``s`` gray levels) and read noise (std 1.5), so the texture's contrast is a few gray levels;
- ``low_contrast``: the image compressed to a quarter of its contrast around mid-gray, with the usual noise;
- ``motion_blur``: motion up to about 15 px per frame with the shutter open 80 % of the frame interval (blur
  along every pixel's own motion, streaks of up to about 12 px), no defocus blur;
- ``fast_motion``: translations up to about 40 px per frame;
- ``illumination``: a global gain ramp from 1.0 down to 0.4 with a moving spatial light gradient (a linear
  shading of +-35 % that rotates over the sequence);
- ``jpeg``: every frame JPEG-compressed at quality 15 (blocking and ringing);
- ``long``: 60 frames, for drift and sample-memory effects over a long run;
- ``dark_jpeg``: the dark condition's frames stored as JPEG at quality 90, as a camera or a high-bitrate encoder
  stores them: the codec removes most of the noise's highest frequencies and keeps the rest, so an estimate of the
  noise from the finest pixel differences reads a fraction of it;
- ``occlusion``: six opaque textured discs (radius 20-45 px) that cross the scene on straight paths at 4-12 px
  per frame; the points they cover lose their ground truth (:attr:`SyntheticSequence.occluder`), so this is
  where a tracker should flag points lost.

Every condition is seeded: the same (condition, seed, size) gives the same frames. The photometric ones (dark, low
contrast, illumination, JPEG, dark JPEG) also apply to any frames, e.g. a real sequence's (:func:`stress_frames`).
"""

from __future__ import annotations

import cv2
import numpy as np

from core.errors import InputError
from data.flow.synthetic import SyntheticSequence, synthetic_sequence

STRESS_CONDITIONS = (
    "dark", "low_contrast", "motion_blur", "fast_motion", "illumination", "jpeg", "long", "occlusion", "dark_jpeg"
)
_DARK_JPEG_QUALITY = 90  # the JPEG quality of the dark_jpeg condition's frames

# synthetic_sequence arguments per condition, on top of a moderate base motion (8 px per frame), so that each
# condition isolates one difficulty
_BASE = {"max_motion": 8.0}
_RENDER = {
    "dark": {"noise": 0.0},
    "low_contrast": {},
    "motion_blur": {"max_motion": 15.0, "exposure": 0.8, "blur": 0.0},
    "fast_motion": {"max_motion": 40.0},
    "illumination": {"brightness": 0.0},
    "jpeg": {},
    "long": {"frames": 60},
    "occlusion": {},
    "dark_jpeg": {"noise": 0.0},
}


def _dark(frames: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    signal = 0.15 * frames
    return signal + rng.normal(0, 1, frames.shape) * np.sqrt(0.6 * signal + 1.5**2)


def _low_contrast(frames: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    return 128 + 0.25 * (frames - 128)


def _illumination(frames: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    t, h, w = frames.shape
    ys, xs = np.mgrid[0:h, 0:w]
    u, v = (xs - w / 2) / (w / 2), (ys - h / 2) / (h / 2)  # [-1, 1]
    angle = rng.uniform(0, 2 * np.pi) + np.linspace(0, np.pi, t)
    gain = np.linspace(1.0, 0.4, t)
    shading = 1 + 0.35 * (np.cos(angle)[:, None, None] * u + np.sin(angle)[:, None, None] * v)
    return frames * gain[:, None, None] * shading


def _jpeg(frames: np.ndarray, rng: np.random.Generator, quality: int = 15) -> np.ndarray:
    out = np.empty_like(frames)
    for i, frame in enumerate(frames.round().clip(0, 255).astype(np.uint8)):
        ok, data = cv2.imencode(".jpg", frame, [cv2.IMWRITE_JPEG_QUALITY, quality])
        out[i] = cv2.imdecode(data, cv2.IMREAD_GRAYSCALE)
    return out


def _occluders(seq: SyntheticSequence, rng: np.random.Generator, count: int = 6) -> None:
    """Paste ``count`` moving textured discs over the frames of ``seq`` and record where they are."""
    t, h, w = seq.frames.shape
    ys, xs = np.mgrid[0:h, 0:w]
    covered = np.zeros((t, h, w), dtype=bool)
    for _ in range(count):
        radius = rng.uniform(20, 45)
        start = rng.uniform([0, 0], [w, h])
        speed, angle = rng.uniform(4, 12), rng.uniform(0, 2 * np.pi)
        velocity = speed * np.array([np.cos(angle), np.sin(angle)])
        texture = cv2.GaussianBlur(rng.uniform(0, 255, (h, w)).astype(np.float32), (0, 0), 2.0)
        texture = rng.uniform(60, 200) + (texture - texture.mean()) * (40 / (texture.std() + 1e-6))
        texture = texture.clip(0, 255)
        for i in range(t):
            cx, cy = start + i * velocity
            disc = (xs - cx) ** 2 + (ys - cy) ** 2 <= radius**2
            shifted = np.roll(texture, (int(round(i * velocity[1])), int(round(i * velocity[0]))), (0, 1))
            seq.frames[i][disc] = shifted[disc]  # the disc's texture moves with it
            covered[i] |= disc
    seq.occluder = covered


def _dark_jpeg(frames: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    return _jpeg(_dark(frames, rng), rng, _DARK_JPEG_QUALITY)


_POST = {
    "dark": _dark, "low_contrast": _low_contrast, "illumination": _illumination, "jpeg": _jpeg, "dark_jpeg": _dark_jpeg
}
PHOTOMETRIC_CONDITIONS = tuple(_POST)  # the conditions that change the frames alone, not the motion


def stress_frames(frames: np.ndarray, condition: str, seed: int = 0) -> np.ndarray:
    """Frames ``(T, H, W)`` (gray levels in [0, 255], e.g. a real sequence's) under one of the photometric stress
    conditions (:data:`PHOTOMETRIC_CONDITIONS`: dark, low_contrast, illumination, jpeg, dark_jpeg) exactly as the stress
    sequences get it; float32 in [0, 255], seeded (the same frames, condition and seed give the same result)."""
    if condition not in PHOTOMETRIC_CONDITIONS:
        raise InputError(
            f"unknown photometric stress condition {condition!r}; choose one of {', '.join(PHOTOMETRIC_CONDITIONS)}"
        )
    frames = np.asarray(frames)
    if frames.ndim != 3 or 0 in frames.shape:
        raise InputError(f"stress frames must have shape (T, H, W) with T, H, W > 0, got {frames.shape}")
    rng = np.random.default_rng([seed, STRESS_CONDITIONS.index(condition)])
    return np.clip(_POST[condition](frames.astype(np.float64), rng), 0, 255).astype(np.float32)


def stress_sequence(
    condition: str, frames: int = 24, size: tuple[int, int] = (384, 512), seed: int = 0
) -> SyntheticSequence:
    """The synthetic sequence under ``condition`` (one of :data:`STRESS_CONDITIONS`); ``frames`` is ignored by
    ``long`` (60 frames). Frames ``(T, H, W)`` float32 in [0, 255], ground truth as the plain sequence's (minus the
    hidden points under ``occlusion``)."""
    if condition not in STRESS_CONDITIONS:
        raise InputError(f"unknown stress condition {condition!r}; choose one of {', '.join(STRESS_CONDITIONS)}")
    render = {"frames": frames, "size": size, "seed": seed, **_BASE, **_RENDER[condition]}
    seq = synthetic_sequence(**render)
    if condition in PHOTOMETRIC_CONDITIONS:
        seq.frames = stress_frames(seq.frames, condition, seed)
    if condition == "occlusion":
        _occluders(seq, np.random.default_rng([seed, STRESS_CONDITIONS.index(condition)]))
    return seq
