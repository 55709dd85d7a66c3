"""The shared frame loop: first-frame and late objects, given masks overriding predictions, bad first masks."""

import pytest
import torch

from core.errors import InputError
from models.vos.video_loop import VideoLoop


class CopyLoop(VideoLoop):
    """Predicts every tracked object where it was last given (a first-frame copy), recording the calls."""

    def reset(self) -> None:
        super().reset()
        self.last = None
        self.calls: list[tuple] = []

    def add_objects(self, image, labels, ids):
        self.calls.append(("add", self.frame, tuple(ids), labels.clone()))
        self.ids += ids
        self.last = labels.clone()

    def step(self, image):
        self.calls.append(("step", self.frame))
        memory = torch.stack([(self.last == i).float() for i in self.ids])
        return self.last.clone(), memory, image

    def update(self, memory_labels, features):
        self.calls.append(("update", self.frame, memory_labels.sum(dim=(1, 2)).tolist()))


def test_late_object_starts_at_its_mask_and_others_keep_being_updated() -> None:
    frames = torch.zeros(4, 3, 4, 5)
    first = torch.zeros(4, 5, dtype=torch.long)
    first[0, :2] = 1
    late = first.clone()
    late[3, 3:] = 2
    loop = CopyLoop()
    out = list(loop.segment(frames, {0: first, 2: late}))
    assert torch.equal(out[0], first) and torch.equal(out[1], first) and torch.equal(out[2], late)
    assert [c[0] for c in loop.calls] == ["add", "step", "update", "step", "update", "add", "step", "update"]
    # at frame 2 the memory label of object 1 is kept (its pixels are not the new object's), object 2 starts
    assert loop.calls[4] == ("update", 2, [2.0]) and loop.calls[5][:3] == ("add", 2, (2,))
    assert torch.equal(loop.calls[5][3], late)  # new objects see the whole merged label map
    assert loop.ids == [1, 2]


def test_first_masks_must_exist_and_label_something() -> None:
    frames = torch.zeros(2, 3, 4, 5)
    with pytest.raises(InputError, match="first frame has no mask"):
        list(CopyLoop().segment(frames, {1: torch.ones(4, 5, dtype=torch.long)}))
    with pytest.raises(InputError, match="labels no object"):
        list(CopyLoop().segment(frames, {0: torch.zeros(4, 5, dtype=torch.long)}))
    with pytest.raises(InputError, match="mask of frame 0"):
        list(CopyLoop().segment(frames, {0: torch.ones(3, 5, dtype=torch.long)}))


class ThresholdLoop(CopyLoop):
    """Labels object 1 where the first channel exceeds 0.5 (the other objects where last given), recording the
    image sizes it sees."""

    def step(self, image):
        self.calls.append(("step", self.frame, tuple(image.shape[-2:])))
        labels = torch.where(image[0] > 0.5, 1, 0)
        return labels, (labels == 1).float()[None], image


def _nearest_exact(labels, size):
    """Brute-force nearest-neighbour resize by pixel centres: output pixel i reads input floor((i + 0.5) n / m)."""
    from fractions import Fraction

    rows = [int((i + Fraction(1, 2)) * labels.shape[0] / size[0]) for i in range(size[0])]
    cols = [int((j + Fraction(1, 2)) * labels.shape[1] / size[1]) for j in range(size[1])]
    return labels[rows][:, cols]


def test_process_height_works_at_the_processing_size_and_answers_at_the_input_size() -> None:
    import cv2
    import numpy as np

    gen = torch.Generator().manual_seed(0)
    frames = torch.rand(3, 3, 6, 10, generator=gen)
    first = torch.zeros(6, 10, dtype=torch.long)
    first[1:4, 2:6] = 1
    loop = ThresholdLoop(process_height=9)  # 6 x 10 -> 9 x 15
    out = list(loop.segment(frames, {0: first}))
    assert [c[2] for c in loop.calls if c[0] == "step"] == [(9, 15), (9, 15)]
    assert torch.equal(out[0], first)  # the given first mask, unchanged by the round trip
    assert torch.equal(loop.calls[0][3], _nearest_exact(first, (9, 15)))  # the object starts at the working size
    for t in (1, 2):  # the reference: cv2's bilinear resize, the threshold, nearest back to 6 x 10
        work = cv2.resize(frames[t, 0].numpy(), (15, 9), interpolation=cv2.INTER_LINEAR)
        expected = _nearest_exact(torch.from_numpy((work > 0.5).astype(np.int64)), (6, 10))
        assert out[t].shape == (6, 10) and torch.equal(out[t], expected)


def test_process_height_must_not_be_negative() -> None:
    with pytest.raises(InputError, match="process_height"):
        CopyLoop(process_height=-2)
