"""FRTM first-frame augmentation (thesis ch. 5.3; paper D) in numpy and OpenCV, shared by the PyTorch tracker
(``models.vos.augment``) and the deployment runtime (``runtime.vos``), so both train their target models on the
same samples: the target is cut out, the hole inpainted (OpenCV Telea, radius 1), and the target pasted back at
grid locations with rotation, scale, flip, skew and motion blur over a zoomed and blurred background. Sample 0 is
the original frame. The random choices come from ``numpy.random.default_rng(seed)``.
"""

from __future__ import annotations

import itertools
import math

import cv2
import numpy as np

from core.errors import InputError

ROTATIONS = (5.0, -5.0, 10.0, -10.0, 20.0, -20.0, 30.0, -30.0, 45.0, -45.0)
SCALES = (0.5, 0.7, 1.0, 1.5, 2.0, 2.5)
FLIP_P = 0.2
SKEW, SKEW_P = 0.1, 1 / 3
MOTION_BLUR_SIZES = (0, 0, 0, 2)
MOTION_BLUR_ANGLES = (0.0, 45.0, 90.0, 135.0)
BG_SCALES = (1.0, 1.0, 1.2)
BG_BLURS = (0.0, 0.0, 1.0, 2.0, 5.0)


def inpaint_target(image: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """Background (3, H, W) float32 with the target removed: OpenCV Telea inpainting (radius 1) of the dilated mask.

    Args:
        image: (3, H, W) RGB in [0, 1]; mask: (H, W), target where > 0.5.
    """
    rgb = np.round(np.clip(image.transpose(1, 2, 0), 0, 1) * 255).astype(np.uint8)
    hole = cv2.dilate((mask > 0.5).astype(np.uint8), np.ones((5, 5), np.uint8))
    out = cv2.inpaint(np.ascontiguousarray(rgb), hole, 1, cv2.INPAINT_TELEA)
    return out.transpose(2, 0, 1).astype(np.float32) / np.float32(255)


def _reflect(coordinate: np.ndarray, size: int) -> np.ndarray:
    """Coordinates reflected into [-0.5, size - 0.5] and clipped to the pixel centres (``grid_sample``'s
    ``reflection`` padding with ``align_corners=False``)."""
    period = np.abs(coordinate + 0.5) % (2 * size)
    return np.clip(np.where(period >= size, 2 * size - period, period) - 0.5, 0, size - 1)


def sample_bilinear(image: np.ndarray, x: np.ndarray, y: np.ndarray, reflect: bool = False) -> np.ndarray:
    """``image`` (C, H, W) at pixel coordinates x, y (H', W') (pixel centres at integers), bilinear; outside the
    image zeros, or with ``reflect`` mirrored at the borders. Returns (C, H', W')."""
    c, h, w = image.shape
    if reflect:
        x, y = _reflect(x, w), _reflect(y, h)
    x0, y0 = np.floor(x).astype(np.int64), np.floor(y).astype(np.int64)
    fx, fy = (x - x0).astype(np.float32), (y - y0).astype(np.float32)
    out = np.zeros((c, *x.shape), np.float32)
    for dy, wy in ((0, 1 - fy), (1, fy)):
        for dx, wx in ((0, 1 - fx), (1, fx)):
            xi, yi = x0 + dx, y0 + dy
            inside = (xi >= 0) & (xi < w) & (yi >= 0) & (yi < h)
            values = image[:, np.clip(yi, 0, h - 1), np.clip(xi, 0, w - 1)]
            out += values * (wx * wy * inside)
    return out


def _filter(image: np.ndarray, kernel: np.ndarray, border: int) -> np.ndarray:
    """Correlate every channel of (C, H, W) with a 2-D ``kernel`` (OpenCV border mode ``border``)."""
    planes = [cv2.filter2D(p, -1, kernel, borderType=border) for p in image]
    return np.stack(planes).astype(np.float32)


def gaussian_blur(image: np.ndarray, sigma: float) -> np.ndarray:
    """Separable Gaussian blur (radius ceil(3 sigma)) of (C, H, W) with mirrored borders (edge pixels repeated
    along an axis shorter than the radius); sigma 0 returns the image."""
    if sigma <= 0:
        return image
    r = max(1, int(math.ceil(3 * sigma)))
    k = np.exp(-0.5 * (np.arange(-r, r + 1, dtype=np.float32) / np.float32(sigma)) ** 2)
    k = (k / k.sum()).astype(np.float32)
    border_x = cv2.BORDER_REFLECT_101 if image.shape[-1] > r else cv2.BORDER_REPLICATE
    border_y = cv2.BORDER_REFLECT_101 if image.shape[-2] > r else cv2.BORDER_REPLICATE
    return _filter(_filter(image, k[None], border_x), k[:, None], border_y)


def motion_blur(image: np.ndarray, size: int, angle_deg: float) -> np.ndarray:
    """Blur (C, H, W) along a line of ``size`` px each side in direction ``angle_deg`` (zeros outside); size 0
    returns the image."""
    if size <= 0:
        return image
    k = np.zeros((2 * size + 1, 2 * size + 1), np.float32)
    a = math.radians(angle_deg)
    for t in np.linspace(-size, size, 4 * size + 1).tolist():
        k[round(size + t * math.sin(a)), round(size + t * math.cos(a))] = 1
    return _filter(image, k / k.sum(), cv2.BORDER_CONSTANT)


def _warp(image: np.ndarray, src_of_dst: np.ndarray, offset_src: np.ndarray, offset_dst: np.ndarray,
          reflect: bool) -> np.ndarray:
    """``image`` (C, H, W) resampled at src = offset_src + M (dst - offset_dst) for every output pixel dst."""
    h, w = image.shape[-2:]
    ys, xs = np.meshgrid(np.arange(h, dtype=np.float32), np.arange(w, dtype=np.float32), indexing="ij")
    dx, dy = xs - offset_dst[0], ys - offset_dst[1]
    x = src_of_dst[0, 0] * dx + src_of_dst[0, 1] * dy + offset_src[0]
    y = src_of_dst[1, 0] * dx + src_of_dst[1, 1] * dy + offset_src[1]
    return sample_bilinear(image, x, y, reflect)


def first_frame_augment(
    image: np.ndarray, mask: np.ndarray, num_aug: int = 5, seed: int = 0
) -> tuple[np.ndarray, np.ndarray]:
    """Augmented copies of the first frame and its target mask.

    Args:
        image: (3, H, W) RGB in [0, 1].
        mask: (H, W) target mask (binary or soft); must not be empty.
        num_aug: K, the number of samples including the original (FRTM 5 at inference, 15 in training).
        seed: seeds the transform choices.

    Returns:
        images (K, 3, H, W) and masks (K, H, W) float32 in [0, 1]; index 0 is the input.
    """
    image, mask = np.asarray(image, np.float32), np.asarray(mask, np.float32)
    if image.ndim != 3 or image.shape[0] != 3 or mask.shape != image.shape[-2:]:
        raise InputError(f"augmentation needs a (3, H, W) image and an (H, W) mask, got {image.shape}, {mask.shape}")
    fg = mask > 0.5
    if not fg.any():
        raise InputError("the first-frame target mask is empty")
    if num_aug < 1:
        raise InputError(f"num_aug must be >= 1, got {num_aug}")
    if num_aug == 1:
        return image[None], mask[None]
    h, w = mask.shape
    rng = np.random.default_rng(seed)
    background = inpaint_target(image, mask)
    ys, xs = np.nonzero(fg)
    centre = np.array([xs.mean(), ys.mean()], np.float32)
    extent = np.array([xs.max() - xs.min() + 1, ys.max() - ys.min() + 1], np.float32)
    combos = list(itertools.product(ROTATIONS, SCALES))
    order = rng.permutation(len(combos))
    cells = [((i + 0.5) / 3, (j + 0.5) / 3) for i in range(3) for j in range(3)]
    cell_order = rng.permutation(len(cells))
    rgba = np.concatenate([image * mask, mask[None]], 0)
    centre_img = np.array([(w - 1) / 2, (h - 1) / 2], np.float32)
    images, masks = [image], [mask]

    def pick(options: tuple) -> float:
        return options[int(rng.integers(len(options)))]

    for i in range(num_aug - 1):
        rot, scale = combos[order[i % len(combos)]]
        scale = min(scale, 0.9 * w / float(extent[0]), 0.9 * h / float(extent[1]))
        flip = -1.0 if rng.random() < FLIP_P else 1.0
        skew = SKEW * (1 if rng.random() < 0.5 else -1)
        skew = skew if rng.random() < SKEW_P else 0.0
        a = math.radians(rot)
        fwd = np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]]) @ np.array(
            [[1.0, skew], [0.0, 1.0]]) @ np.diag([scale * flip, scale])
        cx, cy = cells[cell_order[i % len(cells)]]
        half = np.abs(fwd) @ (extent / 2)  # half size of the transformed bounding box
        dst = np.array([min(max(cx * w, half[0]), max(half[0], w - half[0])),
                        min(max(cy * h, half[1]), max(half[1], h - half[1]))], np.float32)
        target = _warp(rgba, np.linalg.inv(fwd), centre, dst, reflect=False)
        target = motion_blur(target, int(pick(MOTION_BLUR_SIZES)), pick(MOTION_BLUR_ANGLES))
        bg_scale = pick(BG_SCALES)
        bg = _warp(background, np.eye(2) / bg_scale, centre_img, centre_img, reflect=True)
        bg = gaussian_blur(bg, pick(BG_BLURS))
        alpha = np.clip(target[3:4], 0, 1)
        images.append(np.clip(bg * (1 - alpha) + target[:3], 0, 1))
        masks.append(alpha[0])
    return np.stack(images).astype(np.float32), np.stack(masks).astype(np.float32)
