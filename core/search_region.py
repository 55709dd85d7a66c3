"""A search region for mask trackers: an object is looked for near where it was (the DCF trackers' search area,
thesis ch. 3 and 5), so that mask components far from the object's previous mask (a similar-looking distractor
elsewhere in the frame) are dropped before they enter the object's memory; mask components that the target model's
score does not support can be dropped as well; and the memory may learn from each object's main component only.
Shared by the PyTorch trackers and the deployment runtime. Torch-free (numpy and OpenCV).
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from core.errors import InputError

#: Logit given to dropped pixels: a probability far below the merge's clamp of 1e-7 (a logit of about -16).
DROPPED_LOGIT = -30.0


def check_search_radius(radius: float, name: str = "search_radius") -> float:
    """``radius`` when it is 0 (off) or a positive finite number, else an ``InputError`` naming the setting
    ``name`` (``search_radius``, ``ignore_band``: multiples of an object's size)."""
    if isinstance(radius, bool) or not isinstance(radius, int | float) or not (math.isfinite(radius) and radius >= 0):
        raise InputError(f"{name} must be 0 (off) or a positive multiple of the object's size, got {radius}")
    return float(radius)


def outside_search_region(labels: np.ndarray, previous: np.ndarray, ids: list[int], radius: float) -> np.ndarray:
    """Pixels of each object's mask that lie in connected components far from the object's previous mask.

    Object ``i``'s mask ``labels == ids[i]`` is split into 8-connected components; a component is *near* when
    one of its pixels is at most ``radius * sqrt(A)`` px (Euclidean) from the object's previous mask of ``A``
    pixels. Components that are not near are returned, except when none is near (the object moved further than
    the region: nothing is dropped) or when the object had no previous mask (it may appear anywhere).

    Args:
        labels: (H, W) integer label map of the current frame.
        previous: (H, W) integer label map of the previous frame.
        ids: the N object ids.
        radius: the region's reach in units of the square root of the previous mask's area (> 0).

    Returns:
        (N, H, W) bool, True where object ``ids[i]``'s pixels are dropped.
    """
    labels, previous = np.asarray(labels), np.asarray(previous)
    if labels.ndim != 2 or labels.shape != previous.shape:
        raise InputError(f"search region needs two (H, W) label maps of one size, got {labels.shape} and "
                         f"{previous.shape}")
    if check_search_radius(radius) == 0:
        raise InputError("search region needs a positive radius")
    drop = np.zeros((len(ids), *labels.shape), bool)
    for n, obj in enumerate(ids):  # one distance transform per object, not per pixel
        before = previous == obj
        area = int(before.sum())
        if area == 0:  # no previous mask: the object may be anywhere
            continue
        count, components = cv2.connectedComponents((labels == obj).astype(np.uint8), connectivity=8)
        if count <= 2:  # at most one component
            continue
        distance = cv2.distanceTransform((~before).astype(np.uint8), cv2.DIST_L2, cv2.DIST_MASK_PRECISE)
        near = np.unique(components[(distance <= radius * math.sqrt(area)) & (components > 0)])
        if near.size:
            drop[n] = (components > 0) & ~np.isin(components, near)
    return drop


def unsupported_components(labels: np.ndarray, score: np.ndarray, ids: list[int], threshold: float = 0.5) -> np.ndarray:
    """Pixels of each object's mask that lie in connected components its target model does not support.

    Object ``i``'s target-model score ``score[i]`` is upsampled bilinearly to the label map's size (half-pixel
    centres, as ``F.interpolate(align_corners=False)``); its mask ``labels == ids[i]`` is split into 8-connected
    components, and a component is *supported* when the upsampled score exceeds ``threshold`` on at least one of
    its pixels. The decoder refines what the target model detects; a component without support is something
    the target model does not see (a look-alike, or a guess while the object is hidden) and is returned.

    Args:
        labels: (H, W) integer label map of the current frame.
        score: (N, h, w) float target-model scores of the N objects (labels 1 on the object, 0 elsewhere).
        ids: the N object ids.
        threshold: the score above which a pixel supports a component (0.5, between the labels 0 and 1).

    Returns:
        (N, H, W) bool, True where object ``ids[i]``'s pixels are dropped.
    """
    labels, score = np.asarray(labels), np.asarray(score, np.float32)
    if labels.ndim != 2 or score.ndim != 3 or score.shape[0] != len(ids):
        raise InputError(f"score support needs an (H, W) label map and (N = {len(ids)}, h, w) scores, got "
                         f"{labels.shape} and {score.shape}")
    h, w = labels.shape
    drop = np.zeros((len(ids), h, w), bool)
    for n, obj in enumerate(ids):  # one labelling per object, not per pixel
        count, components = cv2.connectedComponents((labels == obj).astype(np.uint8), connectivity=8)
        if count <= 1:
            continue
        support = cv2.resize(score[n], (w, h), interpolation=cv2.INTER_LINEAR) > threshold
        supported = np.unique(components[support & (components > 0)])
        drop[n] = (components > 0) & ~np.isin(components, supported)
    return drop


def main_component(masks: np.ndarray) -> np.ndarray:
    """The largest 8-connected component of each mask (the first one in scan order on a tie).

    Args:
        masks: (N, H, W) bool.

    Returns:
        (N, H, W) bool, all False for an empty mask.
    """
    masks = np.asarray(masks)
    if masks.ndim != 3 or masks.dtype != bool:
        raise InputError(f"main component needs (N, H, W) bool masks, got {masks.dtype} {masks.shape}")
    out = np.zeros_like(masks)
    for n, mask in enumerate(masks):  # one labelling per object, not per pixel
        count, components, stats, _ = cv2.connectedComponentsWithStats(mask.astype(np.uint8), connectivity=8)
        if count > 1:
            out[n] = components == 1 + int(np.argmax(stats[1:, cv2.CC_STAT_AREA]))
    return out


def ignore_band(masks: np.ndarray, width: float) -> np.ndarray:
    """Pixels outside each mask within ``width * sqrt(A)`` px (Euclidean) of the mask of ``A`` pixels.

    Neither object nor background for the memory: when a mask misses part of its object (an object that grows or
    turns faster than the target model learns), the missed part lies next to the mask, and without the band it
    would train the target model as background.

    Args:
        masks: (N, H, W) bool. width: the band's width in units of the square root of the mask's area (> 0).

    Returns:
        (N, H, W) bool, all False for an empty mask.
    """
    masks = np.asarray(masks)
    if masks.ndim != 3 or masks.dtype != bool:
        raise InputError(f"ignore band needs (N, H, W) bool masks, got {masks.dtype} {masks.shape}")
    if check_search_radius(width, "ignore_band") == 0:
        raise InputError("ignore band needs a positive width")
    band = np.zeros_like(masks)
    for n, mask in enumerate(masks):  # one distance transform per object, not per pixel
        area = int(mask.sum())
        if area:
            distance = cv2.distanceTransform((~mask).astype(np.uint8), cv2.DIST_L2, cv2.DIST_MASK_PRECISE)
            band[n] = ~mask & (distance <= width * math.sqrt(area))
    return band
