"""The tracking bundle: its step, init, snr, streak and turn graphs match PyTorch in onnxruntime at other frame
sizes and point counts than exported, its manifest, bad export arguments."""

import math
from collections import Counter

import cv2
import numpy as np
import onnx
import pytest
import torch

from core.errors import InputError
from core.streak import streak_blur
from export.tracking_onnx import GRAPH_JOBS, bundle_tracker, example_inputs, export_bundle, export_graphs, parity
from models.tracking import PointTracker
from models.tracking.motion_blur import motion_blur_streak
from models.tracking.point_tracker import image_pyramid
from models.tracking.turn import TURN_POINTS, camera_turn, fit_similarity
from runtime.bundle import Bundle

pytestmark = pytest.mark.slow  # ONNX export


@pytest.mark.parametrize("large", [False, True])
def test_step_and_init_graphs_match_pytorch(tracking_bundle, large) -> None:
    """The 4-level graphs and the ``*_large`` graphs of every level against their trackers, also (``*_large``) at a
    frame large enough for the fifth level (its gate on, checked) and at smaller ones (off: its filters kept)."""
    bundle = Bundle(tracking_bundle, "tracking")
    suffix = "_large" * large
    step, init = bundle.graph(f"step{suffix}"), bundle.graph(f"init{suffix}")
    tracker = bundle_tracker("ccot", large)
    assert tracker.levels == (5 if large else 4) and bundle.section("input")["large_min_side"] == 657
    sizes = ((96, 128, 8), (120, 176, 40)) + (((672, 704, 20),) if large else ())
    for height, width, points in sizes:
        args = example_inputs(tracker, height, width, points, seed=3)
        with torch.no_grad():
            ref = tracker(*args)
        out = step(*(a.numpy() for a in args))
        np.testing.assert_array_equal(out[1], ref[1].numpy())  # lost flags
        for got, want in zip(out[:1] + out[2:], (ref[0], *ref[2:]), strict=True):
            np.testing.assert_allclose(got, want.numpy(), rtol=1e-4, atol=1e-4 * float(want.abs().max()))
        assert (~ref[1]).sum() > points // 2  # most points really tracked, so the comparison is meaningful
        state = tracker.init(args[1][0, 0], args[2])
        got = init(args[1].numpy(), args[2].numpy())
        for a, b in zip(got[4:], state.filters, strict=True):
            np.testing.assert_allclose(a, b.numpy(), rtol=1e-4, atol=1e-4 * float(b.abs().max()))
        if large:  # the fifth level searched (and learnt) only in the large frame
            fifth = tracker._level_gate(image_pyramid(args[0], 5)[4], 4)
            assert fifth is (min(height, width) >= tracker.full_depth_side)
            assert np.array_equal(out[-1], args[-1].numpy()) is not fifth
    assert bundle.section("settings")["method"] == "ccot" and bundle.section("thresholds")["psr_threshold"] == 2.5


def test_snr_graph_matches_pytorch(tracking_bundle) -> None:
    """At sizes other than exported, with points outside the frame and not finite among them (left out by both),
    and with none inside (inf)."""
    snr, tracker = Bundle(tracking_bundle, "tracking").graph("snr"), PointTracker("ccot").eval()
    for height, width, points in ((96, 128, 8), (150, 200, 41)):
        frame, _, positions, *_ = example_inputs(tracker, height, width, points, seed=4)
        away = torch.tensor([[-5.0, 10.0], [width + 2.0, 20.0], [float("nan"), 5.0], [10.0, height - 0.5]])
        for chosen in (positions, torch.cat([away[:2], positions, away[2:]]), away):
            want = tracker.signal_to_noise(frame, chosen)
            np.testing.assert_allclose(snr(frame.numpy(), chosen.numpy()), want.numpy(), rtol=1e-4)
        assert want.item() == np.inf
    assert Bundle(tracking_bundle, "tracking").section("thresholds")["low_snr"] == tracker.low_snr


def test_turn_graph_matches_pytorch(tracking_bundle) -> None:
    """At point counts other than exported, with untracked points among them: the turn and the fitted similarity
    of ``models.tracking.turn``, the turn 0 where fewer than ``TURN_POINTS`` (10) points are tracked (the runtime
    does not count them itself); the manifest's ``turn_match`` is the tracker's."""
    turn_graph = Bundle(tracking_bundle, "tracking").graph("turn")
    gen = torch.Generator().manual_seed(5)
    for points, degrees, count in ((12, 3.0, 9), (12, 3.0, 10), (300, 9.0, 200)):
        start = torch.rand(points, 2, generator=gen) * 200
        c, s = math.cos(math.radians(degrees)), math.sin(math.radians(degrees))
        moved = start @ torch.tensor([[c, s], [-s, c]]) * 1.05 + torch.randn(points, 2, generator=gen) + 4
        tracked = torch.randperm(points, generator=gen) < count
        turn, similarity = turn_graph(start.numpy(), moved.numpy(), tracked.numpy())
        weight = tracked.float()
        assert (turn[0] > 0.05) == (count >= TURN_POINTS), (count, turn)
        np.testing.assert_allclose(turn, camera_turn(start, moved, weight, TURN_POINTS).reshape(1).numpy(), rtol=1e-4)
        np.testing.assert_allclose(similarity, fit_similarity(start, moved, weight).numpy(), rtol=1e-4, atol=1e-4)
    thresholds = Bundle(tracking_bundle, "tracking").section("thresholds")
    assert thresholds["turn_match"] == PointTracker("ccot").turn_match


def test_first_step_noise_graph_and_floored_step_match_pytorch(tracking_bundle) -> None:
    """The ``first_step_noise`` graph after a first step and the low-SNR step with a noise floor (0: none, and one
    above the frame's noise) against PyTorch, at sizes and point counts other than exported, lost points among
    them; with every point lost the residual SNR and noise read inf."""
    bundle = Bundle(tracking_bundle, "tracking")
    graph, floored = bundle.graph("first_step_noise"), bundle.graph("step_low_snr")
    tracker = bundle_tracker("ccot")
    twin = tracker.low_snr_tracker
    for height, width, points in ((96, 128, 8), (150, 200, 41)):
        frame, previous, positions, lost, _, *filters = example_inputs(tracker, height, width, points, seed=6)
        lost = lost.clone()
        lost[::3] = True
        with torch.no_grad():
            moved, moved_lost = tracker(frame, previous, positions, lost, torch.full_like(lost, math.inf,
                                                                                           dtype=frame.dtype),
                                        *filters)[:2]
            want = torch.cat(tracker.first_step_noise(frame, filters[0], moved, moved_lost))
        got = graph(frame.numpy(), filters[0].numpy(), moved.numpy(), moved_lost.numpy())
        np.testing.assert_allclose(got, want.numpy(), rtol=1e-4)
        everyone = torch.ones_like(lost)
        assert np.isinf(graph(frame.numpy(), filters[0].numpy(), moved.numpy(), everyone.numpy())[:2]).all()
        twin_args = example_inputs(twin, height, width, points, seed=6)
        tracks = []
        for floor in (0.0, 50.0 * float(want[2])):
            with torch.no_grad():
                ref = twin(*twin_args, noise_floor=torch.full((1,), floor))
            out = floored(*(a.numpy() for a in twin_args[:5]), np.full(1, floor, np.float32),
                          *(a.numpy() for a in twin_args[5:]))
            np.testing.assert_array_equal(out[1], ref[1].numpy())
            np.testing.assert_allclose(out[0], ref[0].numpy(), rtol=1e-4, atol=1e-3)
            tracks.append(out[0])
        assert np.abs(tracks[0] - tracks[1]).max() > 0.01  # the floor changes the step
    assert bundle.section("thresholds")["low_snr_psr"] == tracker.low_snr_psr == 16.0
    assert bundle.section("thresholds")["low_snr_residual"] == tracker.low_snr_residual == 5.0


def test_streak_graph_matches_pytorch(tracking_bundle) -> None:
    """The streak graph (its cepstrum as matrix products) against PyTorch's FFTs, at sizes other than exported,
    odd ones too, with a streak and without."""
    graph = Bundle(tracking_bundle, "tracking").graph("streak")
    rng = np.random.default_rng(5)
    for height, width, length in ((97, 131, 9.0), (150, 203, 0.0), (120, 176, 14.0)):
        texture = cv2.GaussianBlur(rng.normal(128, 40, (height, width)), (0, 0), 1.0).astype(np.float32)
        frame = streak_blur(texture, length, 0.6) if length else texture
        want = motion_blur_streak(torch.from_numpy(frame)[None, None])[0].numpy()
        np.testing.assert_allclose(graph(frame[None, None])[0, :4], want, rtol=1e-3, atol=1e-3)


def test_parity_on_the_synthetic_sequence(tracking_bundle) -> None:
    error, flags = parity(tracking_bundle, frames=4, points=50)
    assert error < 0.01 and flags == 0


def test_step_graph_gathers_element_wise(tracking_bundle) -> None:
    """The patch crops (one per level, and the previous frame's for the forward-backward test) and the peak reads
    are GatherElements, which onnxruntime runs several times faster than Gather or GatherND at a flat index."""
    graph = onnx.load(tracking_bundle / "step.onnx")
    ops = Counter(node.op_type for node in graph.graph.node)
    ops.update(node.op_type for function in graph.functions for node in function.node)
    levels = Bundle(tracking_bundle, "tracking").section("input")["levels"]
    assert ops["GatherElements"] >= 2 * levels + 6  # the patches of both frames, the peak and the PSR window reads
    assert ops["GatherND"] <= 6  # the selections of the points the forward-backward test takes, not pixel reads


def test_bad_export_arguments(tmp_path) -> None:
    with pytest.raises(InputError, match="unknown tracking method"):
        export_bundle(tmp_path / "b", "klt")
    with pytest.raises(InputError, match="must lie in"):
        export_bundle(tmp_path / "b", "ccot", height=32)
    with pytest.raises(InputError, match="--workers must be at least 1"):
        export_bundle(tmp_path / "b", "ccot", workers=0)
    assert not (tmp_path / "b").exists()


@pytest.mark.parametrize("workers", [1, 2])
def test_an_export_error_ends_the_export(tmp_path, capsys, workers) -> None:
    """An error in a graph's export (here every job's: an unknown method, which export_bundle would have refused
    before), in this process or in a worker process, reaches the caller as itself, with no graph written and no
    line claiming one."""
    with pytest.raises(InputError, match="unknown tracking method 'klt'"):
        export_graphs(tmp_path, "klt", 96, 128, workers=workers)
    assert list(tmp_path.iterdir()) == []
    assert "exported" not in capsys.readouterr().err


def test_the_bundle_holds_every_graph_job(tracking_bundle) -> None:
    """The parallel export (the fixture's default: one worker per core) wrote each job's graphs."""
    names = {name.strip() for job in GRAPH_JOBS for name in job.split(",")}
    assert names == {"init.onnx", "step.onnx", "profile.onnx", "relative_blur.onnx", "streak.onnx", "snr.onnx",
                     "init_low_snr.onnx", "step_low_snr.onnx", "first_step_noise.onnx", "turn.onnx",
                     "init_large.onnx", "step_large.onnx", "init_low_snr_large.onnx", "step_low_snr_large.onnx"}
    assert names <= {path.name for path in tracking_bundle.iterdir()}
