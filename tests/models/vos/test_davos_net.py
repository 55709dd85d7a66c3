"""DAVOSNet: shapes through every part, frame scores equal per-object scores, frozen backbone."""

import torch

from models.vos.davos_net import DAVOSNet


def _net(distractors: bool = True) -> DAVOSNet:
    torch.manual_seed(0)
    return DAVOSNet("resnet18", None, feature_layer="layer2+layer3", projection_channels=8, encoding_channels=4,
                    distractors=distractors, mdim=8, encoder_dims=(4, 8, 8)).eval()


def test_shapes_and_frame_scores_equal_per_object_scores() -> None:
    net = _net()
    feats, x = net.features(torch.rand(1, 3, 64, 96))
    assert x.shape == (1, 8, 8, 12) and not any(p.requires_grad for p in net.backbone.parameters())
    tau = torch.randn(3, *net.filter_shape)
    per_object = net.scores(tau, x.expand(3, -1, -1, -1))
    torch.testing.assert_close(net.frame_scores(tau, x), per_object, rtol=1e-5, atol=1e-6)
    logits = net.decode(per_object, feats, (64, 96))
    assert logits.shape == (3, 2, 64, 96)
    e, w = net.encode(torch.rand(3, 2, 64, 96), x.shape[-2:])
    assert e.shape == w.shape == (3, 4, 8, 12)
    assert torch.equal(net.initial_filter(2, x), torch.zeros(2, 4, 8, 3, 3))


def test_lwl_network_has_one_label_channel_and_one_logit() -> None:
    net = _net(distractors=False)
    feats, x = net.features(torch.rand(1, 3, 64, 96))
    logits = net.decode(net.scores(net.initial_filter(1, x), x), feats, (64, 96))
    assert net.label_channels == 1 and logits.shape[1] == 1
