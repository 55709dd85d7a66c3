"""The DAVOS part of ``make demo`` (thesis ch. 6): a small DAVOS trained on the project's synthetic look-alike
videos, then segmenting held-out ones beside its no-winner-takes-all ablation and the first mask copied, with
the masks and the regenerated distractor maps drawn over the frames. ``bench.vos`` is the benchmark;
``configs/davos_davis2016_cpu.yaml`` the real CPU training."""

from __future__ import annotations

from pathlib import Path

import torch

from bench.vos import plot, plot_masks, print_table, run_method
from data.vos.composite_datamodule import lookalike_videos
from models.vos.davos_lit import DAVOSSegmentation


def plot_distractors(model: DAVOSSegmentation, video: tuple[str, torch.Tensor, torch.Tensor], path: str | Path,
                     columns: int = 6) -> None:
    """Every object's regenerated distractor map (rows) over ``columns`` frames, under the frames themselves."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    name, frames, labels = video
    tracker = model.make_tracker()
    times = torch.linspace(1, frames.shape[0] - 1, columns).round().long().tolist()
    maps = {}
    for t, _ in enumerate(tracker.segment(frames, {0: labels[0]})):
        if t in times:
            maps[t] = tracker.distractor_maps(tuple(labels.shape[-2:])).clone()
    ids = tracker.ids
    fig, axes = plt.subplots(1 + len(ids), columns, figsize=(1.9 * columns, 1.3 * (1 + len(ids))), squeeze=False)
    for c, t in enumerate(times):
        axes[0, c].imshow(frames[t].permute(1, 2, 0).numpy())
        axes[0, c].set_title(f"frame {t}", fontsize=7)
        for r, obj in enumerate(ids):
            axes[r + 1, c].imshow(maps[t][r].numpy(), vmin=0, vmax=1, cmap="magma")
            if c == 0:
                axes[r + 1, c].set_ylabel(f"distractor of {obj}", fontsize=7)
    for ax in axes.flat:
        ax.set_xticks([])
        ax.set_yticks([])
    fig.suptitle(f"{name}: the distractor each object's target model is told to reject (eqs. 6.1-6.5)", fontsize=8)
    fig.tight_layout()
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def demo(report_dir: Path | None = None, quick: bool = False, height: int = 96, width: int = 160) -> list:
    """Train a small DAVOS (frozen ImageNet EfficientNet-Lite0, 300 steps; 40 quick; at most 150 s) on synthetic
    videos of 1-3 labelled look-alikes, then segment 2 held-out videos of 3 look-alikes and an unlabelled one;
    prints the table. With ``report_dir``, writes the masks, the distractor maps and J&F against speed there and
    returns the figures."""
    import lightning as L

    from data.vos.datamodule import SyntheticVOSDataModule

    steps, limit_s = (40, 40.0) if quick else (300, 150.0)  # fixed steps: the same model on every run
    torch.manual_seed(0)
    model = DAVOSSegmentation(projection_channels=32, encoding_channels=8, mdim=16, encoder_dims=(8, 16, 32),
                              pass_labels=True, train_init_iters=3, train_refine_iters=2, loss="bce_iou",
                              boundary_weight=4.0, tracker={"init_iters": 10, "update_iters": 3, "memory_size": 10})
    data = SyntheticVOSDataModule(train_samples=4096, height=height, width=width, batch_size=4, max_gap=4,
                                  n_objects=3, n_distractors=1, object_scale=(0.2, 0.35), lookalike=True,
                                  n_test_frames=2)
    trainer = L.Trainer(accelerator="cpu", max_steps=steps, max_time={"seconds": limit_s}, logger=False,
                        enable_checkpointing=False, enable_progress_bar=False, enable_model_summary=False,
                        limit_val_batches=0)
    trainer.fit(model, datamodule=data)
    print(f"trained DAVOS {trainer.global_step} steps on synthetic look-alike videos (frozen ImageNet "
          f"EfficientNet-Lite0, batch 4; at most {limit_s:.0f} s)")
    model.eval()
    videos = lookalike_videos(2, n_frames=8 if quick else 16, height=height, width=width, n_objects=3)
    factories = {"davos": model.make_tracker, "davos_no_wta": lambda: model.make_tracker(winner_takes_all=False),
                 "first_frame_copy": None}
    result = {"dataset": f"lookalike:2x{height}x{width} objects 3",
              "checkpoints": dict.fromkeys(factories, "demo (in memory)"),
              "methods": {m: run_method(f, videos) for m, f in factories.items()}}
    print_table(result)
    if report_dir is None:
        return []
    plot_masks(factories, videos[0], report_dir / "davos_masks.png")
    plot_distractors(model, videos[0], report_dir / "davos_distractors.png")
    plot(result, str(report_dir / "davos_speed.png"))
    return [("davos_masks.png", "DAVOS on a held-out video of three labelled look-alikes (and an unlabelled one): "
             "ground truth, davos, its no-winner-takes-all ablation and the first mask copied, over the frames"),
            ("davos_distractors.png", "The distractor maps DAVOS regenerates for each object after every frame"),
            ("davos_speed.png", "J&F against frames per second (same run)")]

