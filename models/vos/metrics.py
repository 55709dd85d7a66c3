"""DAVIS evaluation (Perazzi et al., CVPR 2016): region similarity J, boundary accuracy F and their statistics.

Follows the official davis2017-evaluation protocol: J is the IoU (1 when both masks are empty); F compares
1-px boundary maps dilated by a disk of radius ``ceil(0.008 * ||(H, W)||)`` px (8 px at 480x854); void
pixels are excluded; per object the mean, the recall (fraction of frames > 0.5) and the decay (first
quarter minus last quarter) are taken over all frames except the first and the last; J-Mean and F-Mean
average over objects and J&F is their mean.
"""

from __future__ import annotations

import csv
import io
import math
from pathlib import Path

import torch
import torch.nn.functional as F

from core.errors import InputError
from core.files import write_text

BOUND_TH = 0.008
CSV_COLUMNS = ("J&F-Mean", "J-Mean", "J-Recall", "J-Decay", "F-Mean", "F-Recall", "F-Decay")


def _check_masks(pred: torch.Tensor, gt: torch.Tensor, void: torch.Tensor | None) -> torch.Tensor:
    if pred.ndim != 3 or pred.shape != gt.shape:
        raise InputError(f"masks must be (T, H, W) alike, got {tuple(pred.shape)} and {tuple(gt.shape)}")
    if void is None:
        return torch.zeros_like(gt, dtype=torch.bool)
    if void.shape != gt.shape:
        raise InputError(f"void mask shape {tuple(void.shape)} differs from masks {tuple(gt.shape)}")
    return void.bool()


def jaccard(pred: torch.Tensor, gt: torch.Tensor, void: torch.Tensor | None = None) -> torch.Tensor:
    """Region similarity J per frame.

    Args:
        pred, gt: (T, H, W) binary masks of one object.
        void: (T, H, W) pixels to ignore, or None.

    Returns:
        (T,) float64 IoU; frames where both masks are empty score 1.
    """
    keep = ~_check_masks(pred, gt, void)
    p, g = pred.bool() & keep, gt.bool() & keep
    inter = (p & g).flatten(1).sum(1).double()
    union = (p | g).flatten(1).sum(1).double()
    return torch.where(union > 0, inter / union.clamp_min(1), torch.ones_like(union))


def boundary_map(mask: torch.Tensor) -> torch.Tensor:
    """1-px boundary of binary masks as the official ``_seg2bmap``: a pixel differs from its right, lower or
    lower-right neighbour (neighbours outside the image are ignored).

    Args:
        mask: (T, H, W) binary.

    Returns:
        (T, H, W) bool boundary map.
    """
    m = mask.bool()
    e = torch.zeros_like(m)
    s = torch.zeros_like(m)
    se = torch.zeros_like(m)
    e[:, :, :-1] = m[:, :, 1:]
    s[:, :-1, :] = m[:, 1:, :]
    se[:, :-1, :-1] = m[:, 1:, 1:]
    b = (m ^ e) | (m ^ s) | (m ^ se)
    b[:, -1, :] = m[:, -1, :] ^ e[:, -1, :]
    b[:, :, -1] = m[:, :, -1] ^ s[:, :, -1]
    b[:, -1, -1] = False
    return b


def dilate_disk(mask: torch.Tensor, radius: int) -> torch.Tensor:
    """Binary dilation by the disk {(dx, dy): dx^2 + dy^2 <= radius^2} (skimage ``disk``), zero outside.

    Args:
        mask: (T, H, W) binary.
        radius: disk radius in pixels (>= 0).

    Returns:
        (T, H, W) bool.
    """
    x = mask.float().unsqueeze(1)
    h = x.shape[-2]
    out = torch.zeros_like(x)
    for dy in range(-radius, radius + 1):
        w = math.isqrt(radius * radius - dy * dy)
        row = F.max_pool2d(x, (1, 2 * w + 1), stride=1, padding=(0, w)) if w > 0 else x
        # out[y] |= row[y + dy]
        if dy >= 0:
            out[..., : h - dy, :] = torch.maximum(out[..., : h - dy, :], row[..., dy:, :])
        else:
            out[..., -dy:, :] = torch.maximum(out[..., -dy:, :], row[..., : h + dy, :])
    return out.squeeze(1) > 0


def boundary_radius(height: int, width: int, bound_th: float = BOUND_TH) -> int:
    """Tolerance in pixels: ``bound_th`` if >= 1, else ``ceil(bound_th * ||(H, W)||)`` (8 at 480x854)."""
    return int(bound_th) if bound_th >= 1 else math.ceil(bound_th * math.hypot(height, width))


def boundary_f(
    pred: torch.Tensor, gt: torch.Tensor, void: torch.Tensor | None = None, bound_th: float = BOUND_TH
) -> torch.Tensor:
    """Boundary accuracy F per frame (official ``f_measure``).

    Args:
        pred, gt: (T, H, W) binary masks of one object.
        void: (T, H, W) pixels to ignore, or None.
        bound_th: tolerance, a fraction of the image diagonal if < 1, else pixels.

    Returns:
        (T,) float64 F-measure.
    """
    keep = ~_check_masks(pred, gt, void)
    radius = boundary_radius(gt.shape[-2], gt.shape[-1], bound_th)
    bp, bg = boundary_map(pred.bool() & keep), boundary_map(gt.bool() & keep)
    n_p = bp.flatten(1).sum(1).double()
    n_g = bg.flatten(1).sum(1).double()
    p_match = (bp & dilate_disk(bg, radius)).flatten(1).sum(1).double()
    g_match = (bg & dilate_disk(bp, radius)).flatten(1).sum(1).double()
    precision = torch.where(n_p > 0, p_match / n_p.clamp_min(1), torch.ones_like(n_p))
    recall = torch.where(n_g > 0, g_match / n_g.clamp_min(1), torch.ones_like(n_g))
    precision = torch.where((n_p > 0) & (n_g == 0), torch.zeros_like(precision), precision)
    recall = torch.where((n_p == 0) & (n_g > 0), torch.zeros_like(recall), recall)
    denom = precision + recall
    return torch.where(denom > 0, 2 * precision * recall / denom.clamp_min(1e-300), torch.zeros_like(denom))


def statistics(values: torch.Tensor) -> tuple[float, float, float]:
    """Mean, recall (fraction > 0.5) and decay (mean of the first quarter minus the last) of per-frame scores.

    Quarter bounds are the official ``round(linspace(1, n, 5) + 1e-10) - 1`` with inclusive ends, computed in
    int64 (the official uint8 cast overflows beyond 255 frames).
    """
    v = values.double()
    if v.ndim != 1 or v.numel() == 0:
        raise InputError(f"statistics need a non-empty 1-D tensor of per-frame scores, got {tuple(v.shape)}")
    n = v.numel()
    ids = [int(math.floor(1 + k * (n - 1) / 4 + 1e-10 + 0.5)) - 1 for k in range(5)]
    first = v[ids[0] : ids[1] + 1].mean()
    last = v[ids[3] : ids[4] + 1].mean()
    return float(v.mean()), float((v > 0.5).double().mean()), float(first - last)


def evaluate_sequence(
    pred: torch.Tensor, gt: torch.Tensor, void: torch.Tensor | None = None, bound_th: float = BOUND_TH
) -> dict[int, dict[str, float]]:
    """Per-object J and F statistics of one sequence.

    Args:
        pred: (T, H, W) integer label map (0 = background, 1..N objects) predicted for every frame.
        gt: (T, H, W) ground-truth label map; N = the largest id in the first frame; 255 = void.
        void: optional (T, H, W) void mask; by default the 255 pixels of ``gt``.
        bound_th: boundary tolerance (see ``boundary_f``).

    Returns:
        ``{object id: {"J-Mean", "J-Recall", "J-Decay", "F-Mean", "F-Recall", "F-Decay", "J&F-Mean"}}``;
        the first and last frames are excluded.
    """
    if pred.ndim != 3 or pred.shape != gt.shape:
        raise InputError(f"prediction {tuple(pred.shape)} and ground truth {tuple(gt.shape)} differ in shape")
    if gt.shape[0] < 3:
        raise InputError(f"a sequence needs at least 3 frames to evaluate, got {gt.shape[0]}")
    gt = gt.long()
    pred = pred.long()
    if void is None:
        void = gt == 255
    gt = torch.where(void.bool(), torch.zeros_like(gt), gt)
    n_obj = int(gt[0].max())
    if n_obj == 0:
        raise InputError("the first ground-truth frame has no object")
    pred_max = int(pred.max())
    if pred_max > n_obj:
        raise InputError(f"prediction has object id {pred_max} but the sequence has only {n_obj} objects")
    inner = slice(1, -1)
    out: dict[int, dict[str, float]] = {}
    for obj in range(1, n_obj + 1):
        p, g, v = pred[inner] == obj, gt[inner] == obj, void[inner]
        jm, jr, jd = statistics(jaccard(p, g, v))
        fm, fr, fd = statistics(boundary_f(p, g, v, bound_th))
        out[obj] = {"J-Mean": jm, "J-Recall": jr, "J-Decay": jd, "F-Mean": fm, "F-Recall": fr, "F-Decay": fd}
        out[obj]["J&F-Mean"] = (jm + fm) / 2
    return out


def summarize(per_sequence: dict[str, dict[int, dict[str, float]]]) -> dict[str, float]:
    """Global statistics averaged over all objects of all sequences (``CSV_COLUMNS`` keys)."""
    rows = [stats for objects in per_sequence.values() for stats in objects.values()]
    if not rows:
        raise InputError("no evaluated objects to summarize")
    mean = {k: sum(r[k] for r in rows) / len(rows) for k in CSV_COLUMNS if k != "J&F-Mean"}
    mean["J&F-Mean"] = (mean["J-Mean"] + mean["F-Mean"]) / 2
    return {k: mean[k] for k in CSV_COLUMNS}


def write_csv(per_sequence: dict[str, dict[int, dict[str, float]]], path: str | Path) -> dict[str, float]:
    """Write the per-object CSV (``Sequence`` = ``name_id``) after a ``Global`` row; return the latter."""
    glob = summarize(per_sequence)
    text = io.StringIO()
    writer = csv.writer(text)
    writer.writerow(("Sequence", *CSV_COLUMNS))
    writer.writerow(("Global", *(f"{glob[k]:.6f}" for k in CSV_COLUMNS)))
    for name, objects in per_sequence.items():
        for obj, stats in objects.items():
            writer.writerow((f"{name}_{obj}", *(f"{stats[k]:.6f}" for k in CSV_COLUMNS)))
    write_text(path, text.getvalue())
    return glob
