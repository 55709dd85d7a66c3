"""FRTMSegmentation through the project's LightningCLI: fit and test run on tiny synthetic data."""

import pytest
import torch

import train
from core.errors import InputError
from data.vos.datamodule import SyntheticTrainingSamples
from models.vos.lit import FRTMSegmentation


def test_training_step_backpropagates_through_the_optimizer() -> None:
    ds = SyntheticTrainingSamples(2, n_test_frames=2, max_gap=3, height=48, width=64)
    batch = torch.utils.data.default_collate([ds[0], ds[1]])
    assert batch["test_images"].shape == (2, 2, 3, 48, 64)
    model = FRTMSegmentation(train_backbone=True, backprop_through_optimizer=True, mdim=8, train_channels=8,
                             train_num_aug=2, train_schedule=(2, 2))
    model.log = lambda *a, **k: None
    loss = model.training_step(batch, 0)
    loss.backward()
    # layer3 gets gradient through the decoder and through the fitted filters (unrolled optimizer)
    g = model.backbone.layers["layer3"][0].conv1.weight.grad
    assert torch.isfinite(loss) and g is not None and g.abs().sum() > 0


@pytest.mark.slow
def test_cli_fit_and_test(tmp_path) -> None:
    common = [
        "--model", "models.vos.lit.FRTMSegmentation", "--model.mdim", "8", "--model.train_channels", "8",
        "--model.train_num_aug", "2", "--model.train_schedule", "[2]",
        "--model.tracker", '{"channels": 8, "num_aug": 2, "memory_size": 6, "init_schedule": [2], '
        '"update_schedule": [2]}',
        "--data", "data.vos.datamodule.SyntheticVOSDataModule", "--data.train_samples", "2",
        "--data.val_videos", "1", "--data.test_videos", "1", "--data.n_frames", "4", "--data.height", "48",
        "--data.width", "64", "--data.batch_size", "2", "--data.max_gap", "3",
        "--trainer.accelerator", "cpu", "--trainer.default_root_dir", str(tmp_path), "--trainer.logger", "false",
        "--trainer.enable_checkpointing", "false",
    ]
    cli = train.main(["fit", *common, "--trainer.fast_dev_run", "1"])
    assert cli.trainer.state.finished
    cli = train.main(["test", *common, "--trainer.limit_test_batches", "1"])
    result = cli.trainer.callback_metrics
    assert 0 <= float(result["test/jf"]) <= 1 and float(result["test/fps"]) > 0


def test_init_checkpoint_loads_weights_for_fit_only(tmp_path):
    torch.manual_seed(0)
    source = FRTMSegmentation(mdim=8)
    path = tmp_path / "source.ckpt"
    torch.save({"state_dict": source.state_dict()}, path)
    target = FRTMSegmentation(mdim=8, init_checkpoint=str(path))
    target.setup("validate")  # evaluation keeps the weights it was given
    name = next(n for n in source.state_dict() if n.startswith("decoder.") and n.endswith("weight"))
    assert not torch.equal(target.state_dict()[name], source.state_dict()[name])
    target.setup("fit")
    for name, value in source.state_dict().items():
        torch.testing.assert_close(target.state_dict()[name], value, rtol=0, atol=0)
    with pytest.raises(InputError, match="does not match"):
        FRTMSegmentation(mdim=16, init_checkpoint=str(path)).setup("fit")
    with pytest.raises(InputError, match="does not exist"):
        FRTMSegmentation(mdim=8, init_checkpoint=str(tmp_path / "missing.ckpt")).setup("fit")
    (tmp_path / "bad.ckpt").write_bytes(b"not a checkpoint")
    with pytest.raises(InputError, match="not a readable"):
        FRTMSegmentation(mdim=8, init_checkpoint=str(tmp_path / "bad.ckpt")).setup("fit")


def test_target_loss_adds_the_weighted_target_model_error() -> None:
    ds = SyntheticTrainingSamples(2, n_test_frames=2, max_gap=3, height=48, width=64)
    batch = torch.utils.data.default_collate([ds[0], ds[1]])
    losses, logged = [], []
    for weight in (0.0, 2.0):
        torch.manual_seed(0)
        model = FRTMSegmentation(train_backbone=True, mdim=8, train_channels=8, train_num_aug=2,
                                 train_schedule=(2, 2), feature_layer="layer2", target_loss_weight=weight)
        model.log = lambda name, value, **k: logged.append(float(value)) if name == "train/target_loss" else None
        losses.append(model.training_step(batch, 0))
    assert len(logged) == 1 and logged[0] > 0
    torch.testing.assert_close(losses[1] - losses[0], torch.tensor(2 * logged[0]), rtol=1e-4, atol=1e-6)
    losses[1].backward()  # the target term reaches the stage the target model reads
    assert model.backbone.layers["layer2"][0].conv1.weight.grad.abs().sum() > 0


def test_frozen_pretrained_backbone_trains_only_the_decoder() -> None:
    ds = SyntheticTrainingSamples(2, n_test_frames=2, max_gap=3, height=48, width=64)
    batch = torch.utils.data.default_collate([ds[0], ds[1]])
    model = FRTMSegmentation(backbone="efficientnet_lite0", weights="imagenet", feature_layer="layer2",
                             feature_norm="instance_l2", mdim=8, train_channels=8, train_num_aug=2,
                             train_schedule=(2, 2)).train()
    model.log = lambda *a, **k: None
    assert not model.backbone.training
    model.training_step(batch, 0).backward()
    assert all(p.grad is None for p in model.backbone.parameters())
    assert all(p.grad is not None for p in model.decoder.parameters() if p.requires_grad)
    tracker = model.make_tracker(channels=8, num_aug=2, memory_size=4, init_schedule=[2], update_schedule=[2])
    frames = (batch["test_images"][0] * 255).to(torch.uint8)
    labels = list(tracker.segment(frames, {0: batch["test_masks"][0, 0].long()}))
    assert tracker.settings.feature_norm == "instance_l2" and len(labels) == 2 and labels[0].shape == (48, 64)


def test_feature_dropout_zeroes_whole_decoder_channels_in_training_only() -> None:
    ds = SyntheticTrainingSamples(2, n_test_frames=2, max_gap=3, height=48, width=64)
    batch = torch.utils.data.default_collate([ds[0], ds[1]])
    torch.manual_seed(0)
    model = FRTMSegmentation(mdim=8, train_channels=8, train_num_aug=2, train_schedule=(2,), feature_dropout=0.5)
    model.log = lambda *a, **k: None
    seen = []
    decode = model.decoder.forward
    model.decoder.forward = lambda score, feats, size: seen.append(feats) or decode(score, feats, size)
    with torch.no_grad():
        reference = model.backbone(batch["test_images"].flatten(0, 1))
        model.train().training_step(batch, 0)
        model.eval().training_step(batch, 0)
    dropped, kept = seen
    for name, x in reference.items():
        zero = dropped[name].flatten(2).abs().amax(-1) == 0  # (N, C) channels the dropout removed
        expected = torch.where(zero[..., None, None], torch.zeros_like(x), 2 * x)  # the rest scaled by 1 / (1 - p)
        torch.testing.assert_close(dropped[name], expected)
        assert 0.3 < zero.float().mean() < 0.7
        torch.testing.assert_close(kept[name], x)  # not in eval mode
    with pytest.raises(InputError, match="feature_dropout"):
        FRTMSegmentation(mdim=8, feature_dropout=1.0)
