"""Seeded synthetic point-tracking sequences with exact chained ground truth.

A large random texture (multi-scale noise plus polygons, rectangles and ellipses, so it has corners) is viewed
through a smooth time-varying warp ``phi_t`` from image to texture coordinates: a similarity about the image
centre (rotation, scale, translation) plus a small sinusoidal non-rigid field. Frame ``t`` is the texture
sampled at ``phi_t(x)``, then blurred (Gaussian, random width per frame), given a smooth brightness gain and
offset, and noise. The translation velocity oscillates with amplitude close to ``max_motion`` px per frame, so
large motions need a coarse-to-fine search. A point ``x_0`` has the texture position ``u = phi_0(x_0)``; its
ground truth in frame ``t`` is ``phi_t^{-1}(u)``, solved by fixed-point iteration (the non-rigid part is a
contraction).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from core.errors import InputError


@dataclass
class _Motion:
    centre: np.ndarray  # (2,) image centre (x, y)
    rotation: np.ndarray  # (T,) rad
    scale: np.ndarray  # (T,)
    translation: np.ndarray  # (T, 2) texture px
    amplitude: np.ndarray  # (T,) non-rigid amplitude, px
    wave: np.ndarray  # (2, 2) spatial frequency vectors (rad / px) of the two non-rigid components
    phase: np.ndarray  # (T, 2) temporal phases

    def nonrigid(self, t: int, x: np.ndarray) -> np.ndarray:
        arg = x @ self.wave.T + self.phase[t]
        return self.amplitude[t] * np.stack([np.sin(arg[:, 0]), np.sin(arg[:, 1])], -1)

    def matrix(self, t: int) -> np.ndarray:
        c, s = math.cos(self.rotation[t]), math.sin(self.rotation[t])
        return self.scale[t] * np.array([[c, -s], [s, c]])

    def forward(self, t: int, x: np.ndarray) -> np.ndarray:
        """Texture coordinates ``phi_t(x)`` of ``(P, 2)`` image points."""
        return (x - self.centre) @ self.matrix(t).T + self.centre + self.translation[t] + self.nonrigid(t, x)

    def inverse(self, t: int, u: np.ndarray, iterations: int = 60) -> tuple[np.ndarray, np.ndarray]:
        """Image points ``x`` with ``phi_t(x) = u`` and the final residual ``|phi_t(x) - u|`` (px)."""
        inv = np.linalg.inv(self.matrix(t))
        x = (u - self.centre - self.translation[t]) @ inv.T + self.centre
        for _ in range(iterations):
            x = (u - self.centre - self.translation[t] - self.nonrigid(t, x)) @ inv.T + self.centre
        return x, np.linalg.norm(self.forward(t, x) - u, axis=1)


@dataclass
class SyntheticSequence:
    """Frames ``(T, H, W)`` float32 in [0, 255] and the warps that made them; :meth:`track` gives ground
    truth. ``occluder`` ``(T, H, W)`` bool, where set, marks the pixels that an occluding object covers in each
    frame (the scene's points there are hidden)."""

    frames: np.ndarray
    motion: _Motion
    occluder: np.ndarray | None = None

    def hidden(self, tracks: np.ndarray) -> np.ndarray:
        """``(T, P)`` bool: the ground-truth positions ``(T, P, 2)`` that lie under an occluder in their frame
        (nearest pixel; positions outside the image are not hidden)."""
        t, p = tracks.shape[:2]
        if self.occluder is None:
            return np.zeros((t, p), dtype=bool)
        h, w = self.occluder.shape[1:]
        x, y = np.rint(tracks[..., 0]).astype(np.int64), np.rint(tracks[..., 1]).astype(np.int64)
        inside = (x >= 0) & (x < w) & (y >= 0) & (y < h)
        frame = np.broadcast_to(np.arange(t)[:, None], (t, p))
        return inside & self.occluder[frame, y.clip(0, h - 1), x.clip(0, w - 1)]

    def track(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Ground-truth tracks ``(T, P, 2)`` of frame-0 points ``(P, 2)`` (x, y) and validity ``(T, P)``
        (inside the image, an exact inverse and not hidden by an occluder, in every frame so far)."""
        points = np.asarray(points, dtype=np.float64)
        if points.ndim != 2 or points.shape[1] != 2:
            raise InputError(f"points must have shape (P, 2), got {points.shape}")
        h, w = self.frames.shape[1:]
        u = self.motion.forward(0, points)
        tracks, valid = [], []
        ok = np.ones(len(points), dtype=bool)
        for t in range(len(self.frames)):
            x, residual = self.motion.inverse(t, u)
            ok = (
                ok
                & (residual < 1e-4)
                & (x[:, 0] >= 0)
                & (x[:, 0] <= w - 1)
                & (x[:, 1] >= 0)
                & (x[:, 1] <= h - 1)
            )
            tracks.append(x)
            valid.append(ok)
        tracks = np.stack(tracks)
        visible = np.logical_and.accumulate(~self.hidden(tracks), axis=0)
        return tracks, np.stack(valid) & visible


def _texture(rng: np.random.Generator, height: int, width: int) -> np.ndarray:
    tex = np.zeros((height, width), np.float32)
    for cell, amp in ((96, 50.0), (32, 30.0), (8, 15.0), (3, 6.0)):
        small = rng.standard_normal((height // cell + 2, width // cell + 2)).astype(np.float32)
        tex += amp * cv2.resize(small, (width, height), interpolation=cv2.INTER_CUBIC)
    n_shapes = height * width // 900
    for _ in range(n_shapes):
        value = float(rng.uniform(-90, 90))
        cx, cy = int(rng.integers(0, width)), int(rng.integers(0, height))
        size = int(rng.integers(4, 28))
        kind = rng.integers(0, 3)
        if kind == 0:
            cv2.rectangle(tex, (cx, cy), (cx + size, cy + int(rng.integers(4, 28))), value, -1)
        elif kind == 1:
            axes = (size, int(rng.integers(3, 20)))
            cv2.ellipse(tex, (cx, cy), axes, float(rng.uniform(0, 180)), 0, 360, value, -1)
        else:
            pts = np.array([cx, cy]) + rng.integers(-size, size + 1, (3, 2))
            cv2.fillPoly(tex, [pts.astype(np.int32)], value)
    tex = cv2.GaussianBlur(tex, (0, 0), 0.7)
    return 128 + tex * (45 / (tex.std() + 1e-6))


def _render(tex: np.ndarray, texture_xy: np.ndarray, size: tuple[int, int]) -> np.ndarray:
    """The texture sampled (bicubic) at ``(H * W, 2)`` texture coordinates, as an ``(H, W)`` image."""
    mx = texture_xy[:, 0].reshape(size).astype(np.float32)
    my = texture_xy[:, 1].reshape(size).astype(np.float32)
    return cv2.remap(tex, mx, my, cv2.INTER_CUBIC, borderMode=cv2.BORDER_REFLECT)


def _exposure_maps(maps: list[np.ndarray], t: int, exposure: float, samples: int = 9) -> list[np.ndarray]:
    """Texture coordinates of every pixel at ``samples`` instants in ``[t - exposure / 2, t + exposure / 2]``,
    linear between the frames' warps (the one-sided difference at the first and last frame)."""
    if exposure == 0:
        return [maps[t]]
    after = maps[t + 1] - maps[t] if t + 1 < len(maps) else maps[t] - maps[t - 1]
    before = maps[t] - maps[t - 1] if t > 0 else after
    return [maps[t] + s * (after if s > 0 else before) for s in np.linspace(-exposure / 2, exposure / 2, samples)]


def synthetic_sequence(
    frames: int = 24,
    size: tuple[int, int] = (384, 512),
    max_motion: float = 30.0,
    blur: float = 1.2,
    noise: float = 3.0,
    brightness: float = 0.25,
    seed: int = 0,
    exposure: float = 0.0,
) -> SyntheticSequence:
    """Render a sequence.

    Args:
        frames: number of frames T (>= 2). size: (H, W).
        max_motion: amplitude of the translation velocity in px per frame (rotation, scale and
            non-rigid motion add a few px on top).
        blur: largest Gaussian blur std (px), drawn uniformly per frame.
        noise: Gaussian noise std (gray levels).
        brightness: amplitude of the smooth relative gain change (offset changes by ``60 * brightness``).
        seed: random seed; the same arguments give the same sequence.
        exposure: motion blur, as the fraction of the frame interval the shutter is open (0: none). Frame
            ``t`` averages 9 renders along the warp from ``t - exposure / 2`` to ``t + exposure / 2`` (linear
            between frames), so the blur follows each pixel's own motion and is centred on the ground truth.
    """
    if frames < 2 or min(size) < 32:
        raise InputError(f"need at least 2 frames of at least 32x32 pixels, got {frames} frames of {size}")
    if not 0 <= exposure <= 1:
        raise InputError(f"exposure must lie in [0, 1] (a fraction of the frame interval), got {exposure}")
    rng = np.random.default_rng(seed)
    h, w = size
    t = np.arange(frames, dtype=np.float64)
    period = rng.uniform(10, 16, 6)
    phase0 = rng.uniform(0, 2 * np.pi, 6)
    velocity = (
        0.7
        * max_motion
        * np.stack(
            [np.cos(2 * np.pi * t / period[0] + phase0[0]), np.sin(2 * np.pi * t / period[1] + phase0[1])], -1
        )
    )
    translation = np.concatenate([np.zeros((1, 2)), np.cumsum(velocity[:-1], 0)])
    angles = rng.uniform(0, np.pi, 2)
    wave = (2 * np.pi / rng.uniform(60, 120, (2, 1))) * np.stack([np.cos(angles), np.sin(angles)], -1)
    motion = _Motion(
        centre=np.array([(w - 1) / 2, (h - 1) / 2]),
        rotation=0.05 * np.sin(2 * np.pi * t / period[2] + phase0[2]),
        scale=np.exp(0.05 * np.sin(2 * np.pi * t / period[3] + phase0[3])),
        translation=translation,
        amplitude=2.0 + 1.0 * np.sin(2 * np.pi * t / period[4]),
        wave=wave,
        phase=np.stack([0.3 * t + phase0[4], 0.25 * t + phase0[5]], -1),
    )
    ys, xs = np.mgrid[0:h, 0:w].astype(np.float64)
    pixels = np.stack([xs.ravel(), ys.ravel()], -1)
    maps = [motion.forward(i, pixels) for i in range(frames)]
    lo = np.floor(np.min([m.min(0) for m in maps], 0)) - 8
    hi = np.ceil(np.max([m.max(0) for m in maps], 0)) + 8
    tex = _texture(rng, int(hi[1] - lo[1]), int(hi[0] - lo[0]))
    gain = 1 + brightness * np.sin(2 * np.pi * t / period[5] + phase0[5])
    offset = 60 * brightness * np.cos(2 * np.pi * t / (1.3 * period[5]))
    out = np.empty((frames, h, w), np.float32)
    for i in range(frames):
        img = np.mean([_render(tex, m - lo, (h, w)) for m in _exposure_maps(maps, i, exposure)], 0)
        sigma = rng.uniform(0, blur)
        if sigma > 0.2:
            img = cv2.GaussianBlur(img, (0, 0), sigma)
        img = gain[i] * img + offset[i] + rng.normal(0, noise, img.shape)
        out[i] = np.clip(img, 0, 255)
    return SyntheticSequence(out, motion)
