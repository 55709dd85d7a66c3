"""``core.progress``: the runtime's progress line."""

import io

from core.progress import progress


def test_every_item_passes_and_the_last_line_counts_them():
    stream = io.StringIO()
    assert list(progress(range(5), "track", stream=stream, interval_s=0)) == [0, 1, 2, 3, 4]
    lines = stream.getvalue().split("\r")[1:]
    assert [line.split(" frames")[0] for line in lines] == [f"track: {i}/5" for i in (1, 2, 3, 4, 5, 5)]
    assert stream.getvalue().endswith("/s)\n")


def test_without_a_length_the_count_alone_and_disabled_writes_nothing():
    stream = io.StringIO()
    assert list(progress((i for i in range(3)), "loop", unit="step", stream=stream, interval_s=3600)) == [0, 1, 2]
    assert stream.getvalue().startswith("\rloop: 3 steps (") and stream.getvalue().count("\r") == 1
    quiet = io.StringIO()
    assert list(progress([1, 2], "x", enabled=False, stream=quiet)) == [1, 2] and quiet.getvalue() == ""
    assert list(progress([], "x", stream=quiet)) == [] and quiet.getvalue() == ""
