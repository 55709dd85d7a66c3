"""Distractor regeneration (eqs. 6.1-6.5) against a direct per-pixel implementation on crafted maps."""

import pytest
import torch

from core.errors import InputError
from models.vos.distractors import first_frame_distractors, regenerate_distractors


def _per_pixel(probs: list, labels: list, ids: list) -> list:
    """p_d,i(x) = 1_d,i(x) p_max(x) + (1 - 1_f(x)) p_min(x), written out pixel by pixel."""
    n, h, w = len(probs), len(labels), len(labels[0])
    out = [[[0.0] * w for _ in range(h)] for _ in range(n)]
    for y in range(h):
        for x in range(w):
            values = [probs[j][y][x] for j in range(n)]
            fg = 1.0 if labels[y][x] > 0 else 0.0
            for i in range(n):
                d = fg if labels[y][x] != ids[i] else 0.0
                out[i][y][x] = d * max(values) + (1 - fg) * min(values)
    return out


CASES = {
    # two overlapping objects: object 1 wins the left, object 2 the right, the middle column is shared
    "overlapping": ([[[0.9, 0.8, 0.6, 0.1], [0.7, 0.6, 0.5, 0.0]], [[0.1, 0.3, 0.7, 0.9], [0.0, 0.2, 0.6, 0.8]]],
                    [[1, 1, 2, 2], [1, 1, 2, 2]], [1, 2]),
    # no object anywhere: every pixel is background, the distractor is the least probable target
    "no objects": ([[[0.1, 0.2], [0.3, 0.05]], [[0.2, 0.1], [0.0, 0.4]]], [[0, 0], [0, 0]], [3, 5]),
    # one object: never its own distractor, background keeps its (low) probability
    "one object": ([[[0.9, 0.2, 0.7], [0.1, 0.0, 0.6]]], [[1, 0, 1], [0, 0, 1]], [1]),
    # three objects, ids not 1..N, a pixel won by each
    "three objects": ([[[0.8, 0.1, 0.3]], [[0.2, 0.7, 0.3]], [[0.1, 0.2, 0.9]]], [[4, 7, 9]], [4, 7, 9]),
}


@pytest.mark.parametrize("case", CASES)
def test_regeneration_equals_per_pixel_rule(case: str) -> None:
    probs, labels, ids = CASES[case]
    got = regenerate_distractors(torch.tensor(probs, dtype=torch.float64), torch.tensor(labels), torch.tensor(ids))
    torch.testing.assert_close(got, torch.tensor(_per_pixel(probs, labels, ids), dtype=torch.float64))


def test_winner_takes_all_keeps_uncertainty_and_the_ablation_is_the_soft_union() -> None:
    probs, labels, ids = CASES["overlapping"]
    p = torch.tensor(probs)
    got = regenerate_distractors(p, torch.tensor(labels), torch.tensor(ids))
    # not renormalised: target and distractor of an object may sum to more than 1 where objects overlap
    assert (p[0] + got[0]).max() > 1
    soft = regenerate_distractors(p, torch.tensor(labels), torch.tensor(ids), winner_takes_all=False)
    torch.testing.assert_close(soft, torch.stack([p[1], p[0]]))
    assert torch.equal(regenerate_distractors(p[:1], torch.tensor(labels), torch.tensor([1]), False),
                       torch.zeros_like(p[:1]))


def test_first_frame_distractors_are_the_other_labelled_objects() -> None:
    labels = torch.tensor([[0, 1, 2], [255, 3, 1]])
    got = first_frame_distractors(labels, torch.tensor([1, 3]))
    assert torch.equal(got, torch.tensor([[[0, 0, 1], [0, 1, 0]], [[0, 1, 1], [0, 0, 1]]], dtype=torch.float32))


def test_shape_errors() -> None:
    with pytest.raises(InputError, match="distractor regeneration"):
        regenerate_distractors(torch.rand(2, 3, 3), torch.zeros(3, 4), torch.tensor([1, 2]))
