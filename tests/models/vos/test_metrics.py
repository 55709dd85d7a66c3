"""DAVIS J/F metrics against a direct re-implementation of the definitions (pixel loops, point distances)."""

import math

import numpy as np
import pytest
import torch

from core.errors import InputError
from models.vos.metrics import (
    boundary_f,
    boundary_radius,
    evaluate_sequence,
    jaccard,
    statistics,
    summarize,
    write_csv,
)


def ref_boundary(m: np.ndarray) -> np.ndarray:
    """Pixels that differ from an in-image right, lower or lower-right neighbour."""
    h, w = m.shape
    b = np.zeros_like(m, dtype=bool)
    for dy, dx in ((0, 1), (1, 0), (1, 1)):
        b[: h - dy, : w - dx] |= m[: h - dy, : w - dx] != m[dy:, dx:]
    return b


def ref_f(pred: np.ndarray, gt: np.ndarray, radius: float) -> float:
    bp, bg = np.argwhere(ref_boundary(pred)), np.argwhere(ref_boundary(gt))
    if len(bp) == 0 and len(bg) == 0:
        return 1.0
    if len(bp) == 0 or len(bg) == 0:
        return 0.0
    d = np.sqrt(((bp[:, None, :] - bg[None, :, :]) ** 2).sum(-1))
    precision = (d.min(1) <= radius).mean()
    recall = (d.min(0) <= radius).mean()
    return 0.0 if precision + recall == 0 else 2 * precision * recall / (precision + recall)


def ref_j(pred: np.ndarray, gt: np.ndarray) -> float:
    union = np.logical_or(pred, gt).sum()
    return 1.0 if union == 0 else np.logical_and(pred, gt).sum() / union


def crafted(h: int, w: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[:h, :w]
    cy, cx, r = rng.uniform(0.3, 0.7) * h, rng.uniform(0.3, 0.7) * w, rng.uniform(0.15, 0.3) * h
    gt = (yy - cy) ** 2 + (xx - cx) ** 2 < r**2
    pred = (np.abs(yy - cy - rng.normal(0, 2)) < r * 0.9) & (np.abs(xx - cx - rng.normal(0, 2)) < r)
    pred |= (yy < 3) & (xx > w - 5)  # a blob touching the border
    return pred, gt


def test_j_and_f_match_definitions_on_small_masks() -> None:
    preds, gts = zip(*(crafted(40, 56, s) for s in range(4)), strict=True)
    preds, gts = list(preds), list(gts)
    preds.append(np.zeros((40, 56), bool))  # empty prediction, non-empty ground truth
    gts.append(gts[0])
    preds.append(np.zeros((40, 56), bool))  # both empty
    gts.append(np.zeros((40, 56), bool))
    preds.append(gts[0])  # only the ground truth empty
    gts.append(np.zeros((40, 56), bool))
    p, g = torch.from_numpy(np.stack(preds)), torch.from_numpy(np.stack(gts))
    radius = math.ceil(0.008 * math.hypot(40, 56))
    j, f = jaccard(p, g), boundary_f(p, g)
    for i in range(len(preds)):
        assert j[i].item() == pytest.approx(ref_j(preds[i], gts[i]), abs=1e-12)
        assert f[i].item() == pytest.approx(ref_f(preds[i], gts[i], radius), abs=1e-12)
    assert j[-3:].tolist() == [0.0, 1.0, 0.0] and f[-3:].tolist() == [0.0, 1.0, 0.0]


@pytest.mark.parametrize("shift, inside", [(8, True), (9, False)])
def test_eight_pixel_tolerance_at_480p(shift: int, inside: bool) -> None:
    h, w = 480, 854
    assert boundary_radius(h, w) == 8 and boundary_radius(240, 427) == 4 and boundary_radius(1080, 1920) == 18
    gt = np.zeros((h, w), bool)
    gt[100:300, 200:500] = True
    pred = np.roll(gt, shift, axis=1)
    f = boundary_f(torch.from_numpy(pred)[None], torch.from_numpy(gt)[None]).item()
    # vertical edges move by `shift` px; horizontal edges overlap except for the `shift` px at the ends
    assert f == pytest.approx(ref_f(pred, gt, 8), abs=1e-12)
    assert (f == pytest.approx(1.0)) == inside


def test_statistics_match_official_formulas() -> None:
    rng = np.random.default_rng(0)
    for n in (3, 7, 50, 300):
        v = rng.uniform(0, 1, n)
        ids = (np.round(np.linspace(1, n, 5) + 1e-10) - 1).astype(np.int64)
        bins = [v[ids[i] : ids[i + 1] + 1] for i in range(4)]
        m, r, d = statistics(torch.from_numpy(v))
        assert m == pytest.approx(v.mean()) and r == pytest.approx((v > 0.5).mean())
        assert d == pytest.approx(bins[0].mean() - bins[3].mean())


def test_sequence_excludes_first_and_last_frames_and_averages_objects(tmp_path) -> None:
    gt = torch.zeros(5, 20, 30, dtype=torch.long)
    gt[:, 2:10, 2:10] = 1
    gt[:, 12:18, 15:25] = 2
    gt[:, 0, 0] = 255  # void
    pred = gt.clone()
    pred[pred == 255] = 0
    pred[0] = 0  # wrong first and last frames do not count
    pred[-1] = 0
    pred[2][pred[2] == 2] = 0  # object 2 missing in one evaluated frame
    per_seq = {"seq": evaluate_sequence(pred, gt)}
    assert per_seq["seq"][1]["J-Mean"] == 1.0 and per_seq["seq"][1]["F-Mean"] == 1.0
    obj2 = per_seq["seq"][2]
    assert obj2["J-Mean"] == pytest.approx(2 / 3) and obj2["J-Recall"] == pytest.approx(2 / 3)
    glob = write_csv(per_seq, tmp_path / "per_sequence.csv")
    assert glob == summarize(per_seq) and glob["J-Mean"] == pytest.approx((1 + 2 / 3) / 2)
    lines = (tmp_path / "per_sequence.csv").read_text().splitlines()
    assert lines[0].startswith("Sequence,J&F-Mean") and lines[2].startswith("seq_1,") and len(lines) == 4
    with pytest.raises(InputError, match="object id 3"):
        evaluate_sequence(torch.where(gt == 1, 3, 0), gt)
    with pytest.raises(InputError, match="no object"):
        evaluate_sequence(pred, torch.zeros_like(gt))
