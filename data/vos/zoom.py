"""Zoom a frame around its object: a training augmentation that shows the decoder an object larger (zoom > 1) or
smaller (zoom < 1) than in the reference frame its target model was fitted on (the object grows or shrinks between
the given mask and a later frame, e.g. a car driving towards or away from the camera)."""

from __future__ import annotations

import torch
import torch.nn.functional as F

from core.errors import InputError


def zoom_window(mask: torch.Tensor, zoom: float) -> tuple[int, int, int, int] | None:
    """The window (top, left, height, width) in pixels that, resized to the mask's size, scales the object by
    ``zoom``: 1/zoom of each side, centred on the object's centroid and shifted inside the frame (zoom > 1) or
    shifted to hold the whole frame (zoom < 1: the window reaches past the frame's borders); None when the mask
    (H, W) is empty."""
    if not zoom > 0:
        raise InputError(f"zoom must be positive, got {zoom}")
    ys, xs = torch.nonzero(mask > 0.5, as_tuple=True)
    if ys.numel() == 0:
        return None
    h, w = mask.shape
    ch, cw = max(1, round(h / zoom)), max(1, round(w / zoom))
    top = min(max(round(float(ys.float().mean()) + 0.5 - ch / 2), min(0, h - ch)), max(0, h - ch))
    left = min(max(round(float(xs.float().mean()) + 0.5 - cw / 2), min(0, w - cw)), max(0, w - cw))
    return top, left, ch, cw


def zoom_on_object(
    images: torch.Tensor, masks: torch.Tensor, zoom: float
) -> tuple[torch.Tensor, torch.Tensor, list[bool]]:
    """Scale each frame by ``zoom`` around the object in its mask (bilinear; masks thresholded back to {0, 1}).
    Below 1 the frame shrinks onto a black canvas of its own size, the canvas labelled background.

    Args:
        images: (T, C, H, W) float frames; masks: (T, H, W) float object masks in [0, 1].

    Returns:
        images (T, C, H, W), masks (T, H, W), and per frame whether it was zoomed (frames with an empty mask
        are left as they are).
    """
    if images.ndim != 4 or masks.ndim != 3 or images.shape[0] != masks.shape[0] \
            or images.shape[-2:] != masks.shape[-2:]:
        raise InputError(f"zoom_on_object needs images (T, C, H, W) and masks (T, H, W), got {tuple(images.shape)} "
                         f"and {tuple(masks.shape)}")
    size = tuple(masks.shape[-2:])
    out_images, out_masks, zoomed = [], [], []
    for image, mask in zip(images, masks, strict=True):
        window = zoom_window(mask, zoom)
        zoomed.append(window is not None)
        if window is None:
            out_images.append(image)
            out_masks.append(mask)
            continue
        top, left, ch, cw = window
        h, w = size
        pad = (max(0, -left), max(0, left + cw - w), max(0, -top), max(0, top + ch - h))
        stacked = F.pad(torch.cat([image, mask[None]]), pad)
        top, left = top + pad[2], left + pad[0]
        crop = stacked[:, top : top + ch, left : left + cw]
        big = F.interpolate(crop[None], size=size, mode="bilinear", align_corners=False)[0]
        out_images.append(big[:-1])
        out_masks.append((big[-1] > 0.5).to(mask.dtype))
    return torch.stack(out_images), torch.stack(out_masks), zoomed
