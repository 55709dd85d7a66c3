"""Multi-object composite videos made from annotated videos: training and evaluation data for distractor-aware
VOS (thesis ch. 6) where only single-object annotations exist (DAVIS 2016).

- ``paste``: the annotated object of another video is cut out and pasted into the host video, following its own
  motion (its masks over time), scaled, maybe mirrored and shifted;
- ``twin``: a scaled, shifted and/or mirrored copy of one of the host's own objects is pasted into the same video
  and moves with it: the hardest look-alike there is.

Pasted objects get new ids after the host's, are drawn in front of it in id order with a 1-px feathered edge,
and their brightness is jittered by a few percent. Every random choice comes from a ``torch.Generator``, so a
composite is a pure function of its seed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import torch
import torch.nn.functional as F

from core.errors import InputError

#: A video: frames (T, 3, H, W) uint8 and labels (T, H, W) int64 (0 background, 255 void, -1 not annotated).
Video = tuple[torch.Tensor, torch.Tensor]
KINDS = ("twin", "paste")


@dataclass(frozen=True)
class Paste:
    """One object pasted into a host video.

    Attributes:
        source: index of the video the object comes from (the host itself for a twin); source_id: its id there.
        offset: source frame shown at host frame 0 (later host frames run on, back and forth at the ends).
        scale: size factor; flip: mirrored left-right; gain: brightness factor.
        centre: (x, y) source pixel about which the object is scaled and mirrored; shift: (dx, dy) pixels it moves
            by, so source point q lands at host point centre + A (q - centre) + shift, A = diag(+-scale, scale).
    """

    source: int
    source_id: int
    offset: int
    scale: float
    flip: bool
    gain: float
    centre: tuple[float, float]
    shift: tuple[float, float]


def pingpong(t: torch.Tensor, length: int) -> torch.Tensor:
    """Frame indices that run forwards and backwards over ``length`` frames: 0, 1, .., n-1, n-2, .., 0, 1, .."""
    if length == 1:
        return torch.zeros_like(t)
    period = 2 * (length - 1)
    r = torch.remainder(t, period)
    return torch.where(r < length, r, period - r)


def _centroid(mask: torch.Tensor) -> tuple[float, float]:
    ys, xs = torch.nonzero(mask, as_tuple=True)
    return float(xs.float().mean()) + 0.5, float(ys.float().mean()) + 0.5


def _warp(image: torch.Tensor, size: tuple[int, int], paste: Paste) -> torch.Tensor:
    """Source layers (N, C, h, w) resampled into host frames of ``size`` by the paste's transform; bilinear, zero
    outside."""
    h, w = size
    src_h, src_w = image.shape[-2:]
    cx, cy = paste.centre
    dx, dy = paste.shift
    ys, xs = torch.meshgrid(torch.arange(h) + 0.5, torch.arange(w) + 0.5, indexing="ij")
    sx = cx + (xs - cx - dx) / paste.scale * (-1.0 if paste.flip else 1.0)
    sy = cy + (ys - cy - dy) / paste.scale
    grid = torch.stack([sx / src_w * 2 - 1, sy / src_h * 2 - 1], -1)
    return F.grid_sample(image, grid[None].expand(image.shape[0], -1, -1, -1), align_corners=False)


def _layers(source: Video, paste: Paste, times: torch.Tensor, size: tuple[int, int]) -> tuple[torch.Tensor, ...]:
    """(rgb (T, 3, H, W) in [0, 1], alpha (T, 1, H, W)) of one pasted object at host ``times``."""
    frames, labels = source
    idx = pingpong(times + paste.offset, frames.shape[0])
    alpha = (labels[idx] == paste.source_id).float()[:, None]
    alpha = F.avg_pool2d(alpha, 3, 1, 1, count_include_pad=False)  # 1-px feathered edge
    layer = torch.cat([frames[idx].float() / 255 * paste.gain, alpha], 1)
    warped = _warp(layer, size, paste)
    return warped[:, :3].clamp(0, 1), warped[:, 3:]


def compose(host: Video, sources: list[Video], pastes: list[Paste], times: list[int] | None = None) -> Video:
    """The host video at ``times`` (None: all frames) with ``pastes`` drawn over it.

    Args:
        host: frames (T, 3, H, W) uint8 and labels (T, H, W).
        sources: the videos ``Paste.source`` indexes.
        pastes: objects in drawing order; paste j gets id ``max host id + 1 + j``.

    Returns:
        frames (T', 3, H, W) uint8 and labels (T', H, W) int64.
    """
    frames, labels = host
    t = torch.arange(frames.shape[0]) if times is None else torch.tensor(times, dtype=torch.int64)
    if t.numel() == 0 or t.min() < 0 or t.max() >= frames.shape[0]:
        raise InputError(f"composite times must lie in [0, {frames.shape[0]}), got {times}")
    out = frames[t].float() / 255
    lab = labels[t].clone()
    first_id = int(labels.clamp(0, 254).max()) + 1
    for j, paste in enumerate(pastes):
        if not 0 <= paste.source < len(sources):
            raise InputError(f"paste source {paste.source} is not one of the {len(sources)} videos")
        rgb, alpha = _layers(sources[paste.source], paste, t, tuple(frames.shape[-2:]))
        out = out * (1 - alpha) + rgb * alpha
        lab = torch.where(alpha[:, 0] > 0.5, first_id + j, lab)
    return (out * 255).round().clamp(0, 255).to(torch.uint8), lab


def _object_ids(labels: torch.Tensor, min_pixels: int) -> list[int]:
    return [k for k in labels.unique().tolist() if 0 < k < 255 and int((labels == k).sum()) >= min_pixels]


def random_pastes(
    gen: torch.Generator,
    host: int,
    videos: list[Video],
    kinds: list[str],
    anchor: int = 0,
    min_pixels: int = 100,
    tries: int = 30,
) -> list[Paste]:
    """Random pastes into video ``host``, one per entry of ``kinds`` (``twin`` or ``paste``), placed so that at
    host frame ``anchor`` each new object lies at least 70 % inside the frame and at most 25 % over the objects
    drawn before it (the best of ``tries`` positions otherwise).

    A twin copies one of the host's objects at 0.8-1.1x its size, mirrored with probability 0.5; a pasted object
    comes from another video (at a random frame), scaled to 0.5-1.5 times the host object's area (scale 0.3-1.5)
    and mirrored with probability 0.5. Gains lie in [0.93, 1.07].
    """
    if any(k not in KINDS for k in kinds):
        raise InputError(f"composite kinds must be in {KINDS}, got {kinds}")
    frames, labels = videos[host]
    h, w = frames.shape[-2:]
    host_ids = _object_ids(labels[anchor], min_pixels)
    if not host_ids:
        raise InputError(f"host video {host} has no object of {min_pixels} pixels in frame {anchor}")
    others = [i for i in range(len(videos)) if i != host]
    if "paste" in kinds and not others:
        raise InputError("pasting another video's object needs at least two videos")
    occupied = (labels[anchor] > 0) & (labels[anchor] != 255)
    host_area = int((labels[anchor] == host_ids[0]).sum())

    def uniform(low: float, high: float) -> float:
        return low + (high - low) * float(torch.rand((), generator=gen))

    def pick(n: int) -> int:
        return int(torch.randint(n, (), generator=gen))

    pastes = []
    for kind in kinds:
        for _ in range(100):  # a source frame that shows the object
            if kind == "twin":
                source, offset = host, anchor
                source_id = host_ids[pick(len(host_ids))]
            else:
                source = others[pick(len(others))]
                offset = pick(videos[source][0].shape[0])
                ids = _object_ids(videos[source][1][offset], min_pixels)
                if not ids:
                    continue
                source_id = ids[pick(len(ids))]
            break
        else:
            raise InputError(f"no source video shows an object of {min_pixels} pixels")
        area = int((videos[source][1][offset] == source_id).sum())
        if kind == "twin":
            scale = uniform(0.8, 1.1)
        else:
            scale = min(1.5, max(0.3, math.sqrt(uniform(0.5, 1.5) * host_area / area)))
        flip, gain = uniform(0, 1) < 0.5, uniform(0.93, 1.07)
        mask = (videos[source][1][offset] == source_id).float()[None, None]
        cx, cy = _centroid(mask[0, 0] > 0)
        best, best_score = None, -math.inf
        for _ in range(tries):
            candidate = Paste(source, source_id, offset - anchor, scale, flip, gain, (cx, cy),
                              (uniform(0, w) - cx, uniform(0, h) - cy))
            placed = _warp(mask, (h, w), candidate)[0, 0] > 0.5
            inside = float(placed.sum()) / max(area * scale * scale, 1.0)
            overlap = float((placed & occupied).sum()) / max(float(placed.sum()), 1.0)
            score = min(inside, 1.0) - overlap
            if score > best_score:
                best, best_score = (candidate, placed), score
            if inside >= 0.7 and overlap <= 0.25:
                break
        candidate, placed = best
        pastes.append(candidate)
        occupied = occupied | placed
    return pastes


def composite_video(gen: torch.Generator, host: int, videos: list[Video], kinds: list[str],
                    min_pixels: int = 100) -> Video:
    """A whole composite video: ``random_pastes`` anchored at frame 0, drawn over every host frame."""
    pastes = random_pastes(gen, host, videos, kinds, min_pixels=min_pixels)
    return compose(videos[host], videos, pastes)
