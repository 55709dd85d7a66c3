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
