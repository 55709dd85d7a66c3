"""The runtime's numpy frame loop: late objects, given masks overriding predictions, bad first masks; the folder
writer."""

import numpy as np
import pytest

from core.errors import InputError
from runtime.video_loop import NumpyVideoLoop, segment_folder
from runtime.vos_io import read_mask, write_mask


class CopyLoop(NumpyVideoLoop):
    """Predicts every object where it was last given, recording the calls."""

    min_size, max_size = 2, 64

    def reset(self) -> None:
        super().reset()
        self.last, self.calls = None, []

    def add_objects(self, image, labels, ids):
        self.calls.append(("add", self.frame, tuple(ids)))
        self.ids += ids
        self.last = labels.copy()

    def step(self, image):
        self.calls.append(("step", self.frame))
        return self.last.copy(), np.stack([(self.last == i).astype(np.float32) for i in self.ids]), image

    def update(self, memory_labels, features):
        self.calls.append(("update", self.frame, memory_labels.sum(axis=(1, 2)).tolist()))


def test_late_objects_and_bad_first_masks() -> None:
    frames = np.zeros((4, 3, 4, 5), np.uint8)
    first = np.zeros((4, 5), np.int64)
    first[0, :2] = 1
    late = first.copy()
    late[3, 3:] = 2
    loop = CopyLoop()
    out = list(loop.segment(frames, {0: first, 2: late}))
    assert (out[1] == first).all() and (out[2] == late).all() and loop.ids == [1, 2]
    assert [c[0] for c in loop.calls] == ["add", "step", "update", "step", "update", "add", "step", "update"]
    assert loop.calls[4] == ("update", 2, [2.0])
    with pytest.raises(InputError, match="first frame has no mask"):
        list(CopyLoop().segment(frames, {1: first}))
    with pytest.raises(InputError, match="labels no object"):
        list(CopyLoop().segment(frames, {0: np.zeros((4, 5), np.int64)}))
    with pytest.raises(InputError, match="frame 0 is"):
        list(CopyLoop().segment(np.zeros((1, 3, 1, 5), np.uint8), {0: first}))


def test_segment_folder_writes_masks_named_after_frames(tmp_path) -> None:
    import cv2

    (tmp_path / "video").mkdir()
    for t in range(3):
        cv2.imwrite(str(tmp_path / "video" / f"f{t}.png"), np.full((4, 5, 3), 40 * t, np.uint8))
    first = np.zeros((4, 5), np.int64)
    first[1:3, 1:4] = 3
    write_mask(tmp_path / "first.png", first)
    n, seconds = segment_folder(CopyLoop(), tmp_path / "video", tmp_path / "first.png", tmp_path / "out")
    assert n == 3 and seconds >= 0
    assert [(read_mask(tmp_path / "out" / f"f{t}.png") == first).all() for t in range(3)] == [True] * 3
    write_mask(tmp_path / "empty.png", np.zeros((4, 5), np.int64))
    with pytest.raises(InputError, match="labels no object"):
        segment_folder(CopyLoop(), tmp_path / "video", tmp_path / "empty.png", tmp_path / "o2")
    assert not (tmp_path / "o2").exists() or not any((tmp_path / "o2").iterdir())


def test_process_height_matches_the_pytorch_loop() -> None:
    import torch

    from tests.models.vos.test_video_loop import ThresholdLoop

    class NumpyThresholdLoop(CopyLoop):
        def step(self, image):
            self.calls.append(("step", self.frame, image.shape[-2:]))
            labels = np.where(image[0] > 0.5, 1, 0).astype(np.int64)
            return labels, (labels == 1).astype(np.float32)[None], image

    rng = np.random.default_rng(0)
    frames = rng.random((3, 3, 12, 20)).astype(np.float32)
    first = np.zeros((12, 20), np.int64)
    first[2:8, 3:9] = 1
    late = first.copy()
    late[10:, 15:] = 2  # a late object, given at the input size
    for height in (18, 8):  # up and down
        ours = list(NumpyThresholdLoop(process_height=height).segment(frames, {0: first, 2: late}))
        reference = list(ThresholdLoop(process_height=height).segment(torch.from_numpy(frames),
                                                                      {0: torch.from_numpy(first),
                                                                       2: torch.from_numpy(late)}))
        for a, b in zip(ours, reference, strict=True):
            assert a.shape == (12, 20) and (a == b.numpy()).all()
        assert (ours[2][10:, 15:] == 2).all()
