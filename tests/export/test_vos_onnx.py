"""FRTM ONNX export: the per-object filter of the graphs, onnxruntime parity per graph (rtol 1e-4), and masks of
the onnxruntime tracker (models/vos/onnx_tracker.py) on the export vs PyTorch."""

import pytest
import torch

from data.vos.synthetic import synthetic_video
from export.vos_onnx import apply_filter_per_object, export_frtm
from models.backbones import ResNetBackbone
from models.vos.decoder import SegmentationDecoder
from models.vos.onnx_tracker import OnnxFRTMTracker
from models.vos.target_model import apply_filter
from models.vos.tracker import FRTMTracker
from models.vos.tracker_settings import FRTMSettings


@pytest.fixture(scope="module")
def exported(tmp_path_factory):
    torch.manual_seed(0)
    backbone = ResNetBackbone("resnet18")
    decoder = SegmentationDecoder(backbone.channels, mdim=8).eval()
    settings = FRTMSettings(channels=8, num_aug=3, memory_size=8, init_schedule=(3, 5), update_schedule=(5,),
                            update_every=2)
    tracker = FRTMTracker(backbone, decoder, settings).eval()
    out = tmp_path_factory.mktemp("frtm_onnx")
    export_frtm(tracker, out, 64, 96)
    return tracker, out


def test_per_object_filter_equals_grouped_conv() -> None:
    z, wf = torch.randn(3, 5, 6, 7, dtype=torch.float64), torch.randn(3, 5, 3, 3, dtype=torch.float64)
    torch.testing.assert_close(apply_filter_per_object(z, wf), apply_filter(z[:, None], wf)[:, 0])


@pytest.mark.slow
def test_graph_parity(exported) -> None:
    tracker, out = exported
    ox = OnnxFRTMTracker(out)
    g = torch.Generator().manual_seed(1)
    image = torch.rand(1, 3, 80, 112, generator=g)  # another size than the export example
    wp, wf = torch.randn(3, 8, 256, generator=g) / 16, torch.randn(3, 8, 3, 3, generator=g) / 8
    logits, z = ox.graphs["frame"](image, wp, wf)
    tracker.wp, tracker.wf = wp, wf
    ref_logits, ref_z = tracker.segment_frame(image[0])
    torch.testing.assert_close(z, ref_z, rtol=1e-4, atol=1e-4)
    torch.testing.assert_close(logits, ref_logits, rtol=1e-4, atol=1e-4)
    x = torch.rand(1, 4, 256, 5, 7, generator=g)
    y = (torch.rand(1, 4, 80, 112, generator=g) > 0.6).float()
    v, gamma = torch.ones_like(y), torch.full((1, 4), 0.25)
    ref = tracker.fit_target_models(x, y, v, gamma)
    got = ox.fit_target_models(x, y, v, gamma)
    for a, b in zip(got, ref, strict=True):
        torch.testing.assert_close(a, b, rtol=1e-4, atol=1e-4)


@pytest.mark.slow
def test_onnx_tracker_reproduces_pytorch_masks(exported) -> None:
    tracker, out = exported
    frames, labels = synthetic_video(5, n_frames=8, height=64, width=96, n_objects=2)
    ref = list(tracker.segment(frames, {0: labels[0]}))
    got = list(OnnxFRTMTracker(out).segment(frames, {0: labels[0]}))
    for a, b in zip(ref, got, strict=True):
        for k in (1, 2):
            union = ((a == k) | (b == k)).sum()
            assert union == 0 or ((a == k) & (b == k)).sum() / union >= 0.99
