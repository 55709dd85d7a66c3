"""The DAVOS bundle: its graphs against the PyTorch modules they come from, the manifest, mask parity."""

import json

import numpy as np
import pytest
import torch

from data.vos.composite_datamodule import lookalike_videos
from export.parity import mask_parity
from runtime.bundle import Bundle
from runtime.davos import OnnxDAVOSTracker


@pytest.mark.slow  # uses an exported bundle
def test_graphs_match_pytorch_and_the_manifest_holds_the_settings(davos_setup) -> None:
    tracker, bundle = davos_setup["tracker"], Bundle(davos_setup["bundle"], "davos", threads=1)
    net = tracker.net
    manifest = json.loads((davos_setup["bundle"] / "bundle.json").read_text())
    assert manifest["settings"] == tracker.settings.to_dict() and manifest["network"]["label_channels"] == 2
    g = torch.Generator().manual_seed(1)
    image = torch.rand(1, 3, 72, 88, generator=g)  # another size than the export's
    tau = 0.2 * torch.randn(3, *net.filter_shape, generator=g)
    with torch.no_grad():
        feats, x = net.features(image)
        logits = net.decode(net.frame_scores(tau, x), feats, (72, 88))
        enc, wts = net.label_encoder(torch.rand(3, 2, 72, 88, generator=g))
        mem = torch.randn(1, 4, *x.shape[1:], generator=g)
        memory = (mem, enc[:1, None].expand(1, 4, -1, -1, -1), wts[:1, None].expand(1, 4, -1, -1, -1),
                  torch.full((1, 4), 0.25))
        fitted = net.optimizer(tau[:1], *memory, tracker.settings.update_iters)[0]
    got_logits, got_x = bundle.graph("frame")(image.numpy(), tau.numpy())
    np.testing.assert_allclose(got_x, x.numpy(), rtol=1e-4, atol=1e-5)
    np.testing.assert_allclose(got_logits, logits.numpy(), rtol=1e-4, atol=1e-4)
    odd = torch.rand(3, 2, 75, 91, generator=g)  # sizes that are no multiple of the stride
    with torch.no_grad():
        odd_enc, odd_wts = net.label_encoder(odd)
    got_enc, got_wts = bundle.graph("encode")(odd.numpy())
    np.testing.assert_allclose(got_enc, odd_enc.numpy(), rtol=1e-4, atol=1e-5)
    np.testing.assert_allclose(got_wts, odd_wts.numpy(), rtol=1e-4, atol=1e-5)
    got_fit = bundle.graph("fit_update")(tau[:1].numpy(), *(t.contiguous().numpy() for t in memory))
    np.testing.assert_allclose(got_fit, fitted.numpy(), rtol=1e-4, atol=1e-5)


@pytest.mark.slow  # uses an exported bundle
def test_masks_match_pytorch_on_lookalike_videos(davos_setup) -> None:
    videos = lookalike_videos(1, seed=5, n_frames=6, height=64, width=96, n_objects=3)
    ious = mask_parity(davos_setup["tracker"], OnnxDAVOSTracker(davos_setup["bundle"]), videos)
    assert len(ious) >= 12 and min(ious) >= 0.99
