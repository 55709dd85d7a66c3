"""Synthetic VOS videos, the embedded default data set: textured objects of varied shapes that move, scale,
rotate and occlude each other over a textured, moving background, plus unlabelled distractors that copy a
target's texture. Every video is a pure function of its seed.
"""

from __future__ import annotations

import math

import torch
import torch.nn.functional as F

from core.errors import InputError


def _noise(gen: torch.Generator, size: tuple[int, int], octaves: int = 4) -> torch.Tensor:
    """(H, W) smooth value noise in [0, 1] from bilinearly upsampled random grids."""
    h, w = size
    out = torch.zeros(1, 1, h, w)
    for o in range(octaves):
        cells = 2 ** (o + 1)
        grid = torch.rand(1, 1, cells + 1, cells + 1, generator=gen)
        out += F.interpolate(grid, size=(h, w), mode="bicubic", align_corners=True) / 2**o
    out = out[0, 0]
    return (out - out.min()) / (out.max() - out.min()).clamp_min(1e-6)


def _texture(gen: torch.Generator, size: tuple[int, int], stripes: bool = True) -> torch.Tensor:
    """(3, H, W) texture in [0, 1]: two random colours mixed by noise, optionally with oriented stripes."""
    h, w = size
    colours = torch.rand(2, 3, 1, 1, generator=gen)
    mix = _noise(gen, size)
    if stripes:
        yy, xx = torch.meshgrid(torch.linspace(-1, 1, h), torch.linspace(-1, 1, w), indexing="ij")
        ang = float(torch.rand((), generator=gen)) * math.pi
        freq = 3 + 9 * float(torch.rand((), generator=gen))
        wave = 0.5 + 0.5 * torch.sin(freq * math.pi * (xx * math.cos(ang) + yy * math.sin(ang)))
        mix = 0.6 * mix + 0.4 * wave
    return colours[0] * (1 - mix) + colours[1] * mix


def _shape(gen: torch.Generator, size: int) -> torch.Tensor:
    """(size, size) soft alpha in [0, 1] of a random star/blob/ellipse in [-1, 1]^2 (radius <= ~0.95)."""
    yy, xx = torch.meshgrid(torch.linspace(-1, 1, size), torch.linspace(-1, 1, size), indexing="ij")
    aspect = 0.5 + 0.5 * float(torch.rand((), generator=gen))
    xx = xx / aspect
    rho, phi = torch.sqrt(xx**2 + yy**2), torch.atan2(yy, xx)
    radius = torch.ones_like(phi)
    for k in range(2, 6):
        amp = 0.25 * float(torch.rand((), generator=gen)) ** 2
        radius = radius + amp * torch.cos(k * phi + 2 * math.pi * float(torch.rand((), generator=gen)))
    radius = 0.9 * radius / radius.max()
    return ((radius - rho) * size / 2).clamp(0, 1)


def _bounce(x: torch.Tensor, low: float, high: float) -> torch.Tensor:
    """Fold positions into [low, high] by reflection (a bouncing trajectory)."""
    span = high - low
    y = torch.remainder(x - low, 2 * span)
    return low + torch.where(y > span, 2 * span - y, y)


def synthetic_video(
    seed: int,
    n_frames: int = 24,
    height: int = 128,
    width: int = 224,
    n_objects: int = 1,
    n_distractors: int = 1,
    late_objects: bool = False,
    motion: float = 1.0,
    times: list[int] | None = None,
    object_scale: tuple[float, float] | list[float] = (0.15, 0.3),
    lookalike: bool = False,
) -> tuple[torch.Tensor, torch.Tensor]:
    """One synthetic video.

    Args:
        seed: the video is a pure function of it.
        n_frames, height, width: frames T and size in pixels.
        n_objects: labelled objects (ids 1..n_objects).
        n_distractors: unlabelled objects with a colour-jittered copy of a target's texture.
        late_objects: if True, objects 2.. may first appear after frame 0.
        motion: scales speeds, rotations and scale changes (0 = static objects).
        times: render only these frame indices (same pixels as in the full video); None = all n_frames.
        object_scale: (low, high) range of an object's base radius as a fraction of min(height, width); the
            drawn shape reaches ~0.9 of it (default (0.15, 0.3): objects 27-54 % of the short side across).
        lookalike: the labelled objects 2.. are look-alikes of object 1: its shape, and its texture with the
            distractors' colour jitter (they still move, scale and turn on their own).

    Returns:
        frames (T, 3, H, W) float32 RGB in [0, 1] and labels (T, H, W) int64 (0 = background); T = len(times)
        when given.
    """
    if n_frames < 1 or height < 16 or width < 16 or n_objects < 1 or n_distractors < 0:
        raise InputError(
            f"synthetic video needs n_frames >= 1, size >= 16 px, n_objects >= 1, n_distractors >= 0; got "
            f"{n_frames}, {height}x{width}, {n_objects}, {n_distractors}"
        )
    if len(object_scale) != 2 or not 0 < object_scale[0] <= object_scale[1] <= 1:
        raise InputError(f"synthetic object_scale must be (low, high) with 0 < low <= high <= 1, got {object_scale}")
    gen = torch.Generator().manual_seed(seed)
    idx = torch.arange(n_frames) if times is None else torch.tensor(times, dtype=torch.int64)
    if idx.numel() == 0 or idx.min() < 0 or idx.max() >= n_frames:
        raise InputError(f"synthetic video times must lie in [0, {n_frames}), got {times}")
    t = idx.float()
    n_out = idx.numel()
    yy, xx = torch.meshgrid(torch.arange(height) + 0.5, torch.arange(width) + 0.5, indexing="ij")

    def rnd(low: float, high: float) -> float:
        return low + (high - low) * float(torch.rand((), generator=gen))

    # background: a larger texture panned (and slowly zoomed) over time
    bg = _texture(gen, (2 * height, 2 * width), stripes=rnd(0, 1) < 0.5)
    pan = torch.stack([rnd(-1, 1) * width * 0.004 * motion * t, rnd(-1, 1) * height * 0.004 * motion * t], -1)
    zoom = 0.55 + 0.05 * torch.sin(rnd(0, 0.2) * motion * t)
    gx = (xx / width * 2 - 1)[None] * zoom[:, None, None] + pan[:, None, None, 0] / width
    gy = (yy / height * 2 - 1)[None] * zoom[:, None, None] + pan[:, None, None, 1] / height
    frames = F.grid_sample(
        bg[None].expand(n_out, -1, -1, -1), torch.stack([gx, gy], -1), align_corners=False,
        padding_mode="reflection",
    )
    labels = torch.zeros(n_out, height, width, dtype=torch.int64)

    n_layers = n_objects + n_distractors
    textures = [_texture(gen, (64, 64)) for _ in range(n_objects)]
    for d in range(n_distractors):
        jitter = 1 + 0.15 * (torch.rand(3, 1, 1, generator=gen) - 0.5)
        textures.append((textures[d % n_objects] * jitter).clamp(0, 1))
    order = torch.randperm(n_layers, generator=gen).tolist()
    shared_shape = None
    if lookalike:
        shared_shape = _shape(gen, 64)
        for i in range(1, n_objects):
            textures[i] = (textures[0] * (1 + 0.15 * (torch.rand(3, 1, 1, generator=gen) - 0.5))).clamp(0, 1)
    size = min(height, width)
    for layer in order:
        label = layer + 1 if layer < n_objects else 0
        alpha = _shape(gen, 64)
        if shared_shape is not None and layer < n_objects:
            alpha = shared_shape
        r0 = rnd(float(object_scale[0]), float(object_scale[1])) * size
        start = int(rnd(1, n_frames / 2)) if late_objects and 1 <= layer < n_objects and n_frames > 2 else 0
        speed = rnd(0.005, 0.025) * width * motion
        heading = rnd(0, 2 * math.pi)
        cx = _bounce(rnd(0.2, 0.8) * width + speed * math.cos(heading) * t, r0 * 0.5, width - r0 * 0.5)
        cy = _bounce(rnd(0.2, 0.8) * height + speed * math.sin(heading) * t, r0 * 0.5, height - r0 * 0.5)
        scale = r0 * torch.exp(rnd(0.1, 0.3) * motion * torch.sin(rnd(0.05, 0.3) * t + rnd(0, 6.3)))
        angle = rnd(0, 2 * math.pi) + rnd(-0.06, 0.06) * motion * t
        flip = 1.0 if rnd(0, 1) < 0.5 else -1.0
        cos, sin = torch.cos(angle)[:, None, None], torch.sin(angle)[:, None, None]
        dx, dy = xx[None] - cx[:, None, None], yy[None] - cy[:, None, None]
        s = scale[:, None, None]
        grid = torch.stack([flip * (cos * dx + sin * dy) / s, (-sin * dx + cos * dy) / s], -1)
        rgba = torch.cat([textures[layer], alpha[None]], 0)[None].expand(n_out, -1, -1, -1)
        layer_img = F.grid_sample(rgba, grid, align_corners=False, padding_mode="zeros")
        a = layer_img[:, 3:4]
        a[t < start] = 0
        frames = frames * (1 - a) + layer_img[:, :3] * a
        labels = torch.where(a[:, 0] > 0.5, label, labels)
    brightness = 1 + 0.1 * torch.sin(rnd(0, 0.3) * t + rnd(0, 6.3))
    noise = 0.01 * torch.randn((n_frames, *frames.shape[1:]), generator=gen)[idx]
    frames = (frames * brightness[:, None, None, None] + noise).clamp(0, 1)
    return frames.contiguous(), labels


def synthetic_video_seeds(split: str, n_videos: int, base_seed: int = 0) -> list[int]:
    """Disjoint seed ranges per split (train / val / test) so held-out videos never repeat training ones."""
    offsets = {"train": 0, "val": 1_000_000, "test": 2_000_000}
    if split not in offsets:
        raise InputError(f"synthetic split {split!r} is not one of {sorted(offsets)}")
    return [base_seed + offsets[split] + i for i in range(n_videos)]
