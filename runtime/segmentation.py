"""The runtime's video object segmentation tracker for a bundle, chosen by the task its manifest names: FRTM on
a ``vos`` bundle (``runtime.vos``), DAVOS or LWL on a ``davos`` bundle (``runtime.davos``)."""

from __future__ import annotations

from pathlib import Path

from core.errors import InputError
from runtime.bundle import bundle_task
from runtime.davos import OnnxDAVOSTracker
from runtime.video_loop import NumpyVideoLoop
from runtime.vos import OnnxFRTMTracker

#: The tracker of each segmentation task's bundle.
SEGMENTATION_TRACKERS: dict[str, type[NumpyVideoLoop]] = {"vos": OnnxFRTMTracker, "davos": OnnxDAVOSTracker}


def segmentation_tracker_type(bundle: str | Path) -> type[NumpyVideoLoop]:
    """The tracker class for ``bundle`` (a ``vos`` or ``davos`` bundle folder), read from its manifest; a bundle of
    another task is an ``InputError`` naming it."""
    task = bundle_task(bundle)
    if task not in SEGMENTATION_TRACKERS:
        raise InputError(f"bundle {bundle} is a {task!r} bundle; segmentation runs a "
                         f"{' or '.join(repr(t) for t in SEGMENTATION_TRACKERS)} bundle")
    return SEGMENTATION_TRACKERS[task]


def segmentation_tracker(bundle: str | Path, threads: int | None = None, provider: str = "cpu") -> NumpyVideoLoop:
    """The tracker of ``bundle`` (``segmentation_tracker_type``) with ``threads`` and ``provider`` as
    ``runtime.session.Graph``."""
    return segmentation_tracker_type(bundle)(bundle, threads, provider)
