"""The processing size of the video trackers: rows as asked, aspect kept, 0 for the input size."""

import pytest

from core.errors import InputError
from core.processing_size import processing_size


def test_processing_size_keeps_the_aspect() -> None:
    assert processing_size((240, 427), 0) == (240, 427)
    assert processing_size((240, 427), 360) == (360, 640)  # 427 * 1.5 = 640.5 -> 640 (round half to even)
    assert processing_size((480, 854), 360) == (360, 640)  # 854 * 0.75 = 640.5
    assert processing_size((100, 3), 10) == (10, 1) and processing_size((100, 1), 10) == (10, 1)
    assert processing_size((240, 427), 240) == (240, 427)


def test_processing_size_refuses_negative_heights() -> None:
    with pytest.raises(InputError, match="process_height"):
        processing_size((240, 427), -1)
