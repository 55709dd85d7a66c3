"""core.threads: torch and OpenCV thread counts are set together and restored after the block."""

import cv2
import pytest
import torch

from core.errors import InputError
from core.threads import cpu_threads, set_cpu_threads


def test_cpu_threads_sets_and_restores_both_pools() -> None:
    before = torch.get_num_threads(), cv2.getNumThreads()
    with cpu_threads(1):
        assert torch.get_num_threads() == 1 and cv2.getNumThreads() == 1
    assert (torch.get_num_threads(), cv2.getNumThreads()) == before


def test_restored_after_an_exception() -> None:
    before = torch.get_num_threads()
    with pytest.raises(RuntimeError), cpu_threads(1):
        raise RuntimeError("inside")
    assert torch.get_num_threads() == before


@pytest.mark.parametrize("bad", [0, -2, 1.5])
def test_bad_counts(bad) -> None:
    with pytest.raises(InputError, match="positive integer"):
        set_cpu_threads(bad)
