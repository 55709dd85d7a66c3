"""The VOS bundle: the per-object filter of the graphs, onnxruntime parity of the frame and init graphs (rtol 1e-4;
the init graph starts from the tracker's seeded filters; the frame graph with the test-time flip too), the mask
parity of the runtime against PyTorch, the manifest's settings; an int8 export calibrated on real DAVIS frames."""

import dataclasses
from types import SimpleNamespace

import numpy as np
import pytest
import torch
import torch.nn.functional as F

from core.errors import InputError
from data.vos.davis import load_davis_videos
from data.vos.synthetic import synthetic_video
from export.onnx import export_onnx
from export.parity import mask_parity
from export.vos_onnx import FrameGraph, InsertGraph, apply_filter_per_object, export_bundle
from models.vos.memory import Memory
from models.vos.target_model import apply_filter
from models.vos.tracker import FRTMTracker, frame_memory_insert
from models.vos.tracker_settings import FRTMSettings
from runtime.bundle import Bundle
from runtime.session import Graph
from runtime.vos import OnnxFRTMTracker


def test_per_object_filter_equals_grouped_conv() -> None:
    z, wf = torch.randn(3, 5, 6, 7, dtype=torch.float64), torch.randn(3, 5, 3, 3, dtype=torch.float64)
    torch.testing.assert_close(apply_filter_per_object(z, wf), apply_filter(z[:, None], wf)[:, 0])


@pytest.mark.slow
def test_graph_parity(vos_setup) -> None:
    tracker, bundle = vos_setup["tracker"], Bundle(vos_setup["bundle"], "vos")
    g = torch.Generator().manual_seed(1)
    image = torch.rand(1, 3, 80, 112, generator=g)  # another size than the export example
    wp, wf = torch.randn(3, 8, 256, generator=g) / 16, torch.randn(3, 8, 3, 3, generator=g) / 8
    logits, z = bundle.graph("frame")(image.numpy(), wp.numpy(), wf.numpy())
    tracker.wp, tracker.wf = wp, wf
    with torch.no_grad():
        ref_logits, ref_z = tracker.segment_frame(image[0])
    np.testing.assert_allclose(z, ref_z.numpy(), rtol=1e-4, atol=1e-4)
    np.testing.assert_allclose(logits, ref_logits.numpy(), rtol=1e-4, atol=1e-4)
    x = torch.rand(1, 4, 256, 5, 7, generator=g)
    y = (torch.rand(1, 4, 40, 56, generator=g) > 0.6).float()
    v, gamma = torch.ones_like(y), torch.full((1, 4), 0.25)
    with torch.no_grad():
        ref = tracker.fit_target_models(x, y, v, gamma)
    got = bundle.graph("init")(x.numpy(), y.numpy(), v.numpy(), gamma.numpy())
    for a, b in zip(got, ref, strict=True):
        np.testing.assert_allclose(a, b.numpy(), rtol=1e-4, atol=1e-4)
    assert bundle.section("settings")["label_stride"] == 2 and bundle.section("input")["stride"] == 16


@pytest.mark.slow
def test_frame_graph_with_flip_test_parity(vos_setup, tmp_path) -> None:
    base = vos_setup["tracker"]
    tracker = FRTMTracker(base.backbone, base.decoder, dataclasses.replace(base.settings, flip_test=True)).eval()
    g = torch.Generator().manual_seed(2)
    wp, wf = torch.randn(2, 8, 256, generator=g) / 16, torch.randn(2, 8, 3, 3, generator=g) / 8
    export_onnx(FrameGraph(tracker), (torch.rand(1, 3, 64, 96, generator=g), wp, wf), tmp_path / "frame.onnx",
                ["image", "wp", "wf"], ["logits", "z"])
    image = torch.rand(1, 3, 64, 96, generator=g)
    logits, _ = Graph(tmp_path / "frame.onnx")(image.numpy(), wp.numpy(), wf.numpy())
    tracker.wp, tracker.wf = wp, wf
    with torch.no_grad():
        ref, _ = tracker.segment_frame(image[0])
        base.wp, base.wf = wp, wf
        plain, _ = base.segment_frame(image[0])
    np.testing.assert_allclose(logits, ref.numpy(), rtol=1e-4, atol=1e-4)
    assert np.abs(logits - plain.numpy()).max() > 1e-3  # the exported graph does read the mirrored frame


def paired_trackers(vos_setup, logits: torch.Tensor, **settings) -> tuple[FRTMTracker, OnnxFRTMTracker]:
    """The PyTorch tracker and the runtime of the test bundle, with ``settings`` changed in both, each segmenting
    every frame with the crafted decoder ``logits`` (N, H, W) (their features and target models stay their own)."""
    base = vos_setup["tracker"]
    tracker = FRTMTracker(base.backbone, base.decoder, dataclasses.replace(base.settings, **settings)).eval()
    runtime = OnnxFRTMTracker(vos_setup["bundle"])
    runtime.settings = {**runtime.settings, **settings}
    segment_frame, frame_graph = tracker.segment_frame, runtime.graphs["frame"]
    tracker.segment_frame = lambda image: (logits.clone(), segment_frame(image)[1])
    runtime.graphs["frame"] = lambda *args: (logits.numpy(), frame_graph(*args)[1])
    return tracker, runtime


@pytest.mark.slow
def test_search_region_parity(vos_setup) -> None:
    """The runtime applies the search region and the memory's main component as the PyTorch tracker does: on a
    crafted frame (the object moved, a small blob beside it, a look-alike far away) both give the far blob to the
    background, keep the near one in the labels, and insert the same memory labels (the object's component only)."""
    frames = torch.rand(3, 3, 64, 96, generator=torch.Generator().manual_seed(3))
    first = torch.zeros(64, 96, dtype=torch.long)
    first[10:20, 10:20] = 1
    logits = torch.full((1, 64, 96), -5.0)
    logits[0, 12:22, 13:23] = logits[0, 12:16, 26:30] = logits[0, 40:50, 60:70] = 5.0
    tracker, runtime = paired_trackers(vos_setup, logits, search_radius=1.0, memory_main_component=True)
    inserted = {"torch": [], "runtime": []}
    insert, insert_graph = tracker.insert_samples, runtime.graphs["insert"]
    tracker.insert_samples = lambda z, y, *rest: (inserted["torch"].append(y.numpy()), insert(z, y, *rest))[1]
    runtime.graphs["insert"] = lambda *args: (inserted["runtime"].append(args[-1]), insert_graph(*args))[1]
    with torch.no_grad():
        ours = [p.numpy() for p in tracker.segment(frames, {0: first})]
    theirs = list(runtime.segment(frames.numpy(), {0: first.numpy()}))
    expected = np.zeros((64, 96), np.int64)
    expected[12:22, 13:23] = expected[12:16, 26:30] = 1
    for a, b in zip(ours[1:], theirs[1:], strict=True):
        assert np.array_equal(a, expected) and np.array_equal(b, expected)
    assert len(inserted["torch"]) == len(inserted["runtime"]) == 2
    for a, b in zip(inserted["torch"], inserted["runtime"], strict=True):  # labels at half resolution
        np.testing.assert_allclose(a, b, rtol=1e-5, atol=1e-6)
        assert a[0, 6:11, 7:11].min() > 0.5 and a[0, 6:8, 13:15].max() == 0 and a[0, 20:25, 30:35].max() == 0


@pytest.mark.slow
def test_score_support_parity(vos_setup) -> None:
    """The runtime drops the mask components without target-model support as the PyTorch tracker does, after the
    search region: a static video whose first frame the target model was fitted on, crafted decoder logits with the
    object, a blob in the search region's reach and one beyond it; both trackers keep the object (its score is
    high) and give both blobs to the background (the far one by the search region, the near one by the support)."""
    frames = torch.rand(1, 3, 64, 96, generator=torch.Generator().manual_seed(4)).expand(3, -1, -1, -1)
    first = torch.zeros(64, 96, dtype=torch.long)
    first[16:32, 16:40] = 1
    logits = torch.full((1, 64, 96), -5.0)
    logits[0, 16:32, 16:40] = logits[0, 44:60, 64:88] = logits[0, 16:32, 52:58] = 5.0
    tracker, runtime = paired_trackers(vos_setup, logits, search_radius=1.0, score_support=True)
    with torch.no_grad():
        ours = [p.numpy() for p in tracker.segment(frames, {0: first})]
    theirs = list(runtime.segment(frames.numpy(), {0: first.numpy()}))
    for a, b in zip(ours[1:], theirs[1:], strict=True):
        assert np.array_equal(a, first.numpy()) and np.array_equal(b, first.numpy())


@pytest.mark.slow
def test_ignore_band_parity(vos_setup) -> None:
    """The runtime gives the memory's pixels next to each mask zero weight as the PyTorch tracker does: after a
    crafted frame (a 16 x 24 mask: band 0.5 x sqrt(384) ~ 9.8 px at full label resolution, 4.9 at the bundle's), the
    memories' pixel weights agree and are zero on the band."""
    frames = torch.rand(2, 3, 64, 96, generator=torch.Generator().manual_seed(5))
    first = torch.zeros(64, 96, dtype=torch.long)
    first[16:32, 16:40] = 1
    tracker, runtime = paired_trackers(vos_setup, torch.where(first.bool(), 5.0, -5.0)[None], ignore_band=0.5)
    with torch.no_grad():
        list(tracker.segment(frames, {0: first}))
    list(runtime.segment(frames.numpy(), {0: first.numpy()}))
    slot = int(tracker.memory.newest[0])
    assert slot > 0 and int(runtime.memory[4][0]) == slot
    ours, theirs = tracker.memory.pixel_weights[0, slot].numpy(), runtime.memory[2][0, slot]
    np.testing.assert_allclose(theirs, ours, rtol=1e-6)
    assert (ours == 0).sum() > 0 and (ours[tracker.memory.labels[0, slot].numpy() > 0.5] > 0).all()


@pytest.mark.slow
def test_mask_parity(vos_setup) -> None:
    frames, labels = synthetic_video(5, n_frames=6, height=64, width=96, n_objects=2)
    videos = [("v", (frames * 255).round().byte(), labels)]
    ious = mask_parity(vos_setup["tracker"], OnnxFRTMTracker(vos_setup["bundle"]), videos)
    assert len(ious) >= 6 and min(ious) >= 0.99


@pytest.mark.slow
def test_int8_export_calibrated_on_davis_frames(vos_setup, shared_data, tmp_path) -> None:
    calibration = load_davis_videos(shared_data / "davis2016", "train", "240p", ["bear", "boat"], 3)
    assert [name for name, _, _ in calibration] == ["bear", "boat"]
    frames, labels = calibration[0][1:]
    assert frames.dtype == torch.uint8 and frames.shape[:2] == (3, 3) and labels.shape == (3, *frames.shape[2:])
    held_out_frames, held_out_labels = synthetic_video(7, n_frames=4, height=64, width=96, n_objects=1)
    held_out = [("v", (held_out_frames * 255).round().byte(), held_out_labels)]
    small = [(name, F.interpolate(f.float(), (64, 96), mode="area").round().byte(),  # keep it fast
              F.interpolate(y[:, None].float(), (64, 96), mode="nearest")[:, 0].long()) for name, f, y in calibration]
    report = export_bundle(vos_setup["tracker"], tmp_path / "int8", 64, 96, True, small, held_out)
    assert set(report["graphs"]) == {"frame", "features"}
    assert report["graphs"]["frame"]["calibration_samples"] == 4  # one call per frame after the first
    assert report["graphs"]["frame"]["int8_bytes"] < report["graphs"]["frame"]["fp32_bytes"]
    assert Bundle(tmp_path / "int8", "vos").manifest["precision"] == "int8"
    with pytest.raises(InputError, match="not in DAVIS split"):
        load_davis_videos(shared_data / "davis2016", "train", "240p", ["no-such-sequence"], 3)


def test_insert_graph_keeps_the_first_frame(tmp_path) -> None:
    """The exported insertion carries ``keep_first``: over more insertions than slots, onnxruntime's memory equals
    PyTorch's (``frame_memory_insert``) and the first slot keeps its features and share of the weight."""
    tracker = SimpleNamespace(settings=FRTMSettings(keep_first=0.3))  # the graph reads only the settings
    g = torch.Generator().manual_seed(4)
    mem = Memory(torch.rand(1, 4, 8, 5, 6, generator=g), torch.rand(1, 4, 10, 12, generator=g),
                 torch.ones(1, 4, 10, 12), torch.tensor([[0.4, 0.2, 0.2, 0.2]]), torch.tensor([2]))
    z, label = torch.rand(1, 8, 5, 6, generator=g), torch.zeros(1, 10, 12)
    label[0, 2:8, 3:9] = 1
    graph = Graph(export_onnx(InsertGraph(tracker), (*mem, z, label), tmp_path / "insert.onnx",
                              ["features", "labels", "pixel_weights", "weights", "newest", "z", "label"],
                              ["features_out", "labels_out", "pixel_weights_out", "weights_out", "newest_out"]))
    ours, theirs = mem, [t.numpy() for t in mem]
    for _ in range(6):
        ours = frame_memory_insert(ours, z, label, keep_first=0.3)
        theirs = graph(*theirs, z.numpy(), label.numpy())
    for a, b in zip(theirs, ours, strict=True):
        np.testing.assert_allclose(a, b.numpy(), rtol=1e-5, atol=1e-6)
    assert np.array_equal(theirs[0][0, 0], mem.features[0, 0].numpy()) and theirs[3][0, 0] >= 0.3 - 1e-6
