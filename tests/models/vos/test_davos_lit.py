"""DAVOSSegmentation: the meta-learnt parts get gradients through the unrolled steepest descent, the frozen
backbone none; fit and test through the project's LightningCLI on tiny data."""

import pytest
import torch

import train
from data.vos.datamodule import SyntheticTrainingSamples
from models.vos.davos_lit import DAVOSSegmentation

TINY = {"backbone": "resnet18", "weights": None, "projection_channels": 8, "encoding_channels": 4, "mdim": 8,
        "encoder_dims": (4, 8, 8), "train_init_iters": 2, "train_refine_iters": 2}


@pytest.mark.parametrize(("distractors", "pass_labels"), [(True, False), (True, True), (False, False)])
def test_training_step_reaches_every_meta_learnt_part(distractors: bool, pass_labels: bool) -> None:
    ds = SyntheticTrainingSamples(2, n_test_frames=3, max_gap=4, height=48, width=64, n_objects=2)
    batch = torch.utils.data.default_collate([ds[0], ds[1]])
    torch.manual_seed(0)
    model = DAVOSSegmentation(**TINY, distractors=distractors, pass_labels=pass_labels, loss="bce_iou").train()
    logged = {}
    model.log = lambda name, value, **k: logged.__setitem__(name, float(value))
    loss = model.training_step(batch, 0)
    loss.backward()
    assert torch.isfinite(loss) and set(logged) == {"train/loss", "train/iou", "train/lambda"}
    net = model.net
    for part in (net.label_encoder, net.projection, net.decoder):
        grads = [p.grad for p in part.parameters()]
        assert all(g is not None for g in grads) and sum(float(g.abs().sum()) for g in grads) > 0
    assert net.optimizer.reg.grad is not None and net.optimizer.reg.grad != 0  # lambda is learnt
    assert all(p.grad is None for p in net.backbone.parameters()) and not net.backbone.training


@pytest.mark.slow
def test_cli_fit_and_test(tmp_path) -> None:
    common = [
        "--model", "models.vos.davos_lit.DAVOSSegmentation", "--model.backbone", "resnet18", "--model.weights", "null",
        "--model.projection_channels", "8", "--model.encoding_channels", "4", "--model.mdim", "8",
        "--model.encoder_dims", "[4, 8, 8]", "--model.train_init_iters", "2", "--model.train_refine_iters", "1",
        "--model.tracker", '{"init_iters": 2, "update_iters": 1, "memory_size": 4}',
        "--data", "data.vos.datamodule.SyntheticVOSDataModule", "--data.train_samples", "2",
        "--data.val_videos", "1", "--data.test_videos", "1", "--data.n_frames", "4", "--data.height", "48",
        "--data.width", "64", "--data.batch_size", "2", "--data.max_gap", "3", "--data.n_objects", "2",
        "--data.eval_objects", "2", "--data.n_test_frames", "2",
        "--trainer.accelerator", "cpu", "--trainer.default_root_dir", str(tmp_path), "--trainer.logger", "false",
        "--trainer.enable_checkpointing", "false",
    ]
    cli = train.main(["fit", *common, "--trainer.fast_dev_run", "1"])
    assert cli.trainer.state.finished
    cli = train.main(["test", *common, "--trainer.limit_test_batches", "1"])
    result = cli.trainer.callback_metrics
    assert 0 <= float(result["test/jf"]) <= 1 and float(result["test/fps"]) > 0
