"""first_masks: where objects first appear in (sparsely) annotated label videos."""

import torch

from models.vos.lit_evaluation import first_masks


def test_first_masks_keep_frame_0_and_the_frames_where_new_ids_appear() -> None:
    labels = torch.zeros(5, 2, 3, dtype=torch.long)
    labels[:, 0, 0] = 1
    labels[1] = -1  # not annotated
    labels[3, 1, 2] = 2  # object 2 first annotated at frame 3
    labels[4, 1, 2] = 2
    masks = first_masks(labels)
    assert sorted(masks) == [0, 3] and torch.equal(masks[3], labels[3])
    labels[2] = -1
    labels[2, 0, 1] = 3  # a partly annotated frame: -1 becomes background
    assert masks is not first_masks(labels) and first_masks(labels)[2].min() == 0
