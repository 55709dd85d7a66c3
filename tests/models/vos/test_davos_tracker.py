"""DAVOSTracker on small untrained networks: shapes and schedule, late objects, distractor maps, switches."""

import pytest
import torch

from data.vos.synthetic import synthetic_video
from models.vos.davos_net import DAVOSNet
from models.vos.davos_settings import DAVOSSettings
from models.vos.davos_tracker import DAVOSTracker


def _net(distractors: bool = True) -> DAVOSNet:
    torch.manual_seed(0)
    return DAVOSNet("resnet18", None, projection_channels=8, encoding_channels=4, distractors=distractors, mdim=8,
                    encoder_dims=(4, 8, 8)).eval()


SMALL = {"init_iters": 3, "update_iters": 2, "memory_size": 4}


@pytest.mark.parametrize("distractors", [True, False])
def test_segments_every_frame_with_the_memory_filling_up(distractors: bool) -> None:
    frames, labels = synthetic_video(1, n_frames=6, height=48, width=64, n_objects=2)
    tracker = DAVOSTracker(_net(distractors), DAVOSSettings(**SMALL))
    out = list(tracker.segment(frames, {0: labels[0]}))
    assert len(out) == 6 and all(o.shape == (48, 64) for o in out)
    assert set(torch.cat([o.unique() for o in out]).tolist()) <= {0, 1, 2}
    mem = tracker.memory
    assert mem.features.shape[:2] == (2, 4) and (mem.weights > 0).all()  # 1 first frame + 5 inserts, 4 slots
    assert float(mem.weights[0, 0]) >= 0.25 - 1e-6  # the first frame keeps its share
    assert (tracker.distractors is not None) == distractors
    if distractors:
        assert tracker.distractors.shape == (2, 48, 64)
    assert set(tracker.timings) == {"init", "backbone", "target_model", "decoder", "update"}


def test_late_object_and_distractor_switches() -> None:
    frames, labels = synthetic_video(2, n_frames=5, height=48, width=64, n_objects=2)
    first = torch.where(labels[0] == 2, 0, labels[0])
    tracker = DAVOSTracker(_net(), DAVOSSettings(**SMALL, use_distractors=False, winner_takes_all=False))
    out = list(tracker.segment(frames, {0: first, 3: labels[3]}))
    assert tracker.ids == [1, 2] and tracker.tau.shape[0] == 2 and torch.equal(out[3][labels[3] == 2],
                                                                                labels[3][labels[3] == 2])
    assert 2 not in out[1].unique().tolist()


def test_update_every_and_zero_update_iterations_keep_the_filters() -> None:
    frames, labels = synthetic_video(3, n_frames=4, height=48, width=64)
    tracker = DAVOSTracker(_net(), DAVOSSettings(**{**SMALL, "update_iters": 0}))
    list(tracker.segment(frames[:1], {0: labels[0]}))
    tau0 = tracker.tau.clone()
    run = tracker.segment(frames, {0: labels[0]})
    list(run)
    assert torch.equal(tracker.tau, tau0)  # same first frame, no updates
