"""The VOS bundle: the per-object filter of the graphs, onnxruntime parity of the frame and init graphs (rtol 1e-4;
the init graph starts from the tracker's seeded filters), the mask parity of the runtime against PyTorch, the
manifest's settings."""

import numpy as np
import pytest
import torch

from data.vos.synthetic import synthetic_video
from export.parity import mask_parity
from export.vos_onnx import apply_filter_per_object
from models.vos.target_model import apply_filter
from runtime.bundle import Bundle
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
def test_mask_parity(vos_setup) -> None:
    frames, labels = synthetic_video(5, n_frames=6, height=64, width=96, n_objects=2)
    videos = [("v", (frames * 255).round().byte(), labels)]
    ious = mask_parity(vos_setup["tracker"], OnnxFRTMTracker(vos_setup["bundle"]), videos)
    assert len(ious) >= 6 and min(ious) >= 0.99
