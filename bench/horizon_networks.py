"""HorizonFinder and HorizonSegmenter against the ground truth and against the classical labels (ch. 4.3).

    python -m bench.horizon_networks --finder F.ckpt --segmenter S.ckpt --data DIR [--input-width 512]
                                     [--onnx BUNDLE [BUNDLE ...]] [--threads 1] [--json] [--plot networks.png]

DIR is a held-out dataset written by ``python infer.py render-dataset`` (or a DataModule's test set). Prints
median errors and failure rates of both networks and of the classical pipeline on the same frames, for the clean
and the degraded frames (the metrics of ``train.py test``; the segmenter there sees truly levelled panoramas),
and of the deployed chain (finder -> levelling with its angles -> segmenter; failure = median error > 2 px).
``demo()`` renders a small set (192 + 48 panoramas at 512 x 64 px), trains both networks on it at 256 px input
for 20 epochs each and prints this table for them (``--input-width 256``). ``--onnx BUNDLE`` adds the speed of the
chain in images per second, PyTorch eager (``models.horizon.localizer.panorama_profiles``) and the deployment
runtime on each bundle (``runtime.horizon.HorizonChain``, e.g. a float32 and an int8 bundle of the same
checkpoints), in the same run on the same panoramas, best of ``--repeats``, with ``--threads`` threads.
"""

from __future__ import annotations

import argparse
import json
import math
import tempfile
from pathlib import Path

from core.errors import InputError


def evaluate(finder: Path, segmenter: Path, data: Path, input_width: int = 512) -> dict[str, float]:
    """``trainer.test`` of both checkpoints on ``data``; returns the merged metrics."""
    from lightning.pytorch import Trainer

    from data.horizon.datamodule import HorizonDataModule
    from models.checkpoint import load_system
    from models.horizon.lit import HorizonFinderSystem, HorizonSegmenterSystem

    metrics: dict[str, float] = {}
    for name, system, ckpt in (("finder", HorizonFinderSystem, finder),
                               ("segmenter", HorizonSegmenterSystem, segmenter)):
        model = load_system(system, ckpt)
        datamodule = HorizonDataModule(root=str(data), test_root=str(data), task=name, input_width=input_width,
                                       create=False, val_fraction=0.5)
        trainer = Trainer(accelerator="cpu", logger=False, enable_progress_bar=False, enable_model_summary=False)
        result = trainer.test(model, datamodule, verbose=False)[0]
        metrics.update({f"{name}/{k.removeprefix('test/')}": v for k, v in result.items()})
    return metrics


def evaluate_chain(finder: Path, segmenter: Path, data: Path, input_width: int = 512) -> dict[str, float]:
    """The deployed chain on every frame: finder -> levelling with its angles -> segmenter, vs ground truth.

    Returns median horizon-row errors (px at ``input_width``, per-frame medians) and the share of frames above
    2 px, overall and for clean and degraded frames.
    """
    import numpy as np
    import torch

    from core.cylinder import warp_panorama
    from data.horizon.datamodule import read_panorama, resize_panorama
    from data.horizon.dataset import read_split
    from models.builders import horizon_finder, horizon_segmenter
    from models.horizon.finder import sincos_to_angles

    find, segment = horizon_finder(ckpt=finder), horizon_segmenter(ckpt=segmenter)
    truth = read_split(data, "truth")
    focal = input_width / (2 * np.pi)
    errors = []
    with torch.no_grad():
        for start in range(0, len(truth["pitch"]), 8):
            index = range(start, min(start + 8, len(truth["pitch"])))
            image = torch.stack([read_panorama(Path(data) / "images" / f"{k:06d}.png") for k in index])
            pitch, roll = sincos_to_angles(find(resize_panorama(image, input_width)))
            profile = segment(resize_panorama(warp_panorama(image, pitch, roll), input_width))[:, 0].numpy()
            true = torch.from_numpy(truth["horizon"][list(index)]).float()
            true = torch.nn.functional.interpolate(true[:, None], size=input_width, mode="linear",
                                                   align_corners=False)[:, 0].numpy()
            errors.append(np.median(np.abs(profile - true), axis=1) * focal)
    error = np.concatenate(errors)
    degraded = truth["degraded"].astype(bool)
    out = {}
    for subset, mask in (("all", np.ones_like(degraded)), ("clean", ~degraded), ("degraded", degraded)):
        if mask.any():
            out[f"chain/{subset}/horizon_px_median"] = float(np.median(error[mask]))
            out[f"chain/{subset}/failure_rate"] = float(np.mean(error[mask] > 2.0))
    return out


def chain_speed(find, segment, bundles: list[Path], data: Path, input_width: int = 512, repeats: int = 3,
                batch: int = 8) -> dict[str, float]:
    """Images per second of the chain (finder -> levelling -> segmenter, profiles at the panorama width) on the
    panoramas of ``data``, ``batch`` at a time: PyTorch eager with the networks ``find`` and ``segment``
    (``speed/pytorch_images_per_s``) and the runtime on each bundle (``speed/onnx:<folder>_images_per_s``); the
    methods take turns and the best run counts."""
    import time

    import numpy as np
    import torch

    from data.horizon.dataset import read_split
    from models.horizon.localizer import panorama_profiles
    from runtime.horizon import HorizonChain, read_panorama

    count = len(read_split(data, "truth")["pitch"])
    images = np.concatenate([read_panorama(Path(data) / "images" / f"{k:06d}.png") for k in range(count)])
    tensor = torch.from_numpy(images)
    runs = {"pytorch": lambda chunk: panorama_profiles(tensor[chunk], find, segment, input_width)}
    for bundle in bundles:
        chain = HorizonChain(bundle, threads=torch.get_num_threads())
        if chain.input_width != input_width:
            raise InputError(f"bundle {bundle} takes networks of width {chain.input_width}, not --input-width "
                             f"{input_width}")
        runs[f"onnx:{Path(bundle).name}"] = lambda chunk, chain=chain: chain(images[chunk])
    best = dict.fromkeys(runs, float("inf"))
    for _ in range(repeats + 1):  # the first round warms up
        for name, run in runs.items():
            start = time.perf_counter()
            for i in range(0, count, batch):
                run(slice(i, i + batch))
            best[name] = min(best[name], time.perf_counter() - start)
    return {f"speed/{name}_images_per_s": count / seconds for name, seconds in best.items()}


def print_table(metrics: dict[str, float]) -> None:
    """One row per held-out frame set (all, clean, degraded): failure rates and medians of the networks against
    the classical pipeline (``net / classical``), and of the chain finder -> levelling -> segmenter."""
    def get(key: str) -> float:
        return metrics.get(key, float("nan"))

    print(f"{'frames':9s} {'finder fail %':>14s} {'pitch deg':>12s} {'roll deg':>12s} {'segm. fail %':>13s} "
          f"{'horizon px':>13s} {'chain fail %':>12s} {'chain px':>8s}")
    print(f"{'':9s} {'net / class.':>14s} {'net / class.':>12s} {'net / class.':>12s} {'net / class.':>13s} "
          f"{'net / class.':>13s}")
    for subset in ("all", "clean", "degraded"):
        f, s, c = f"finder/{subset}/", f"segmenter/{subset}/", f"chain/{subset}/"
        print(f"{subset:9s} {100 * get(f + 'failure_rate'):6.1f} / {100 * get(f + 'classical_failure_rate'):5.1f} "
              f"{get(f + 'pitch_deg_median'):5.2f} / {get(f + 'classical_pitch_deg_median'):4.2f} "
              f"{get(f + 'roll_deg_median'):5.2f} / {get(f + 'classical_roll_deg_median'):4.2f} "
              f"{100 * get(s + 'failure_rate'):5.1f} / {100 * get(s + 'classical_failure_rate'):5.1f} "
              f"{get(s + 'horizon_px_median'):5.3f} / {get(s + 'classical_horizon_px_median'):5.3f} "
              f"{100 * get(c + 'failure_rate'):12.1f} {get(c + 'horizon_px_median'):8.3f}")


def plot_failures(metrics: dict[str, float], path: Path) -> None:
    """Bar chart of the failure rates of the networks and of the classical pipeline, clean and degraded frames."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 3.5))
    labels, values = [], []
    for net in ("finder", "segmenter"):
        for subset in ("clean", "degraded"):
            for who in ("failure_rate", "classical_failure_rate"):
                key = f"{net}/{subset}/{who}"
                if key in metrics:
                    labels.append(f"{net}\n{subset}\n{'classical' if who.startswith('classical') else 'net'}")
                    values.append(metrics[key])
    ax.bar(range(len(values)), values, color=["C0", "C1"] * (len(values) // 2))
    ax.set_xticks(range(len(values)), labels, fontsize=7)
    ax.set_ylabel("failure rate")
    fig.tight_layout()
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def plot_chain(data: Path, finder, segmenter, path: Path, frames: int = 3, input_width: int = 512) -> None:
    """The first ``frames`` panoramas of dataset ``data``, levelled with HorizonFinder's pitch and roll, with
    HorizonSegmenter's horizon on them, the classical pipeline's and the ground truth (both in the truly levelled
    frame: they coincide with the network's where the finder's angles are right). The networks see the panoramas
    resized to ``input_width``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import torch

    from core.cylinder import tangent_to_row, warp_panorama
    from data.horizon.datamodule import read_panorama
    from data.horizon.dataset import read_split
    from models.horizon.localizer import panorama_profiles
    from models.horizon.segmenter import PanoramaSegmenter

    truth, labels = read_split(data, "truth"), read_split(data, "labels")
    fig, axes = plt.subplots(frames, 1, figsize=(12, 1.9 * frames), squeeze=False)
    for k, ax in enumerate(axes[:, 0]):
        image = read_panorama(data / "images" / f"{k:06d}.png")[None]
        height, width = image.shape[-2:]
        with torch.no_grad():
            profiles, pitch, roll = panorama_profiles(image, finder, PanoramaSegmenter(segmenter), input_width)
            level = warp_panorama(image, pitch, roll)[0]
        ax.imshow(level.permute(1, 2, 0).clamp(0, 1).numpy())
        ax.plot(truth["level_horizon_rows"][k], color="lime", lw=1.2, label="ground truth")
        classical = tangent_to_row(torch.as_tensor(labels["horizon"][k]), height, width)
        ax.plot(classical.numpy(), color="red", lw=0.9, ls="--", label="classical")
        ax.plot(tangent_to_row(profiles[0, 0], height, width).numpy(), color="cyan", lw=0.9, ls=":",
                label="networks")
        ax.set_title(f"held-out frame {k}{' (degraded)' if truth['degraded'][k] else ''}", fontsize=8, loc="left")
        ax.set_axis_off()
        ax.legend(loc="lower right", fontsize=6, ncol=3)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)


#: Demo sizes: 192 + 48 renders of a 5 km archipelago at 512 x 64 px (the size at which the classical pipeline
#: rejects about half of the degraded frames), networks at 256 px input (4x cheaper, pitch and roll still well
#: under a degree), 20 epochs; the quick smoke run (``DEMO_QUICK``) renders 24 + 12 frames at 256 px, 3 epochs.
DEMO_DATA = dict(count=192, test_count=48, width=512, height=64, dem_size_m=5000.0, dem_cell_m=10.0,
                 degraded_fraction=0.2, test_degraded_fraction=0.5, input_width=256, batch_size=8)
DEMO_QUICK = dict(count=24, test_count=12, width=256, height=32, dem_size_m=3000.0)
DEMO_NETWORK = dict(backbone="resnet18", stage="layer2", heads=2, head_channels=8, channels=16, lr=3e-3)


def demo(report_dir: Path | None = None, quick: bool = False) -> list[tuple[str, str]]:
    """Render a training and a held-out set (``DEMO_DATA``, ``DEMO_QUICK``), train both networks on the classical
    labels, save them and measure them with ``evaluate`` and ``evaluate_chain`` on the held-out set.
    With ``report_dir``, writes the figures there and returns them."""
    from lightning.pytorch import Trainer, seed_everything

    from data.horizon.datamodule import HorizonDataModule
    from models.horizon.lit import HorizonFinderSystem, HorizonSegmenterSystem

    seed_everything(0)
    epochs = 3 if quick else 20
    width = DEMO_DATA["input_width"]
    with tempfile.TemporaryDirectory() as tmp:
        test = Path(tmp) / "test"
        data = dict(DEMO_DATA, **(DEMO_QUICK if quick else {}), root=f"{tmp}/train", test_root=str(test))
        HorizonDataModule(**data).prepare_data()
        nets, ckpts = {}, {}
        for name, system in (("finder", HorizonFinderSystem), ("segmenter", HorizonSegmenterSystem)):
            extra = {"fail_mrad": 2 * 2 * math.pi / width * 1e3} if name == "segmenter" else {}  # 2 px
            model = system(**DEMO_NETWORK, **extra)
            trainer = Trainer(accelerator="cpu", max_epochs=epochs, logger=False, enable_progress_bar=False,
                              enable_model_summary=False, enable_checkpointing=False, num_sanity_val_steps=0)
            trainer.fit(model, HorizonDataModule(**data, task=name))
            ckpts[name] = Path(tmp) / f"{name}.ckpt"
            trainer.save_checkpoint(ckpts[name], weights_only=True)
            nets[name] = model.net.eval()
        metrics = evaluate(ckpts["finder"], ckpts["segmenter"], test, width)
        metrics.update(evaluate_chain(ckpts["finder"], ckpts["segmenter"], test, width))
        print_table(metrics)
        if report_dir is None:
            return []
        plot_chain(test, nets["finder"], nets["segmenter"], report_dir / "horizon_chain.png", input_width=width)
    plot_failures(metrics, report_dir / "horizon_networks.png")
    return [("horizon_chain.png", "Held-out panoramas levelled with HorizonFinder's angles, with HorizonSegmenter's "
             "horizon, the classical pipeline's and the ground truth"),
            ("horizon_networks.png", "Failure rates of HorizonFinder and HorizonSegmenter (trained here on the "
             "classical labels for about two minutes) against the classical pipeline, on clean and degraded "
             "held-out frames")]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--finder", type=Path, required=True, help="HorizonFinderSystem checkpoint")
    parser.add_argument("--segmenter", type=Path, required=True, help="HorizonSegmenterSystem checkpoint")
    parser.add_argument("--data", type=Path, required=True, help="held-out dataset directory")
    parser.add_argument("--input-width", type=int, default=512)
    parser.add_argument("--onnx", type=Path, nargs="+", default=[], metavar="BUNDLE",
                        help="also time the chain in the deployment runtime on these horizon bundles")
    parser.add_argument("--repeats", type=int, default=3, help="timed rounds of --onnx speed (best counts)")
    parser.add_argument("--threads", type=int, default=1, help="CPU threads for torch, OpenCV and onnxruntime")
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    parser.add_argument("--plot", type=Path, help="bar chart of the failure rates (PNG)")
    args = parser.parse_args()
    from core.threads import set_cpu_threads

    try:
        set_cpu_threads(args.threads)
        metrics = evaluate(args.finder, args.segmenter, args.data, args.input_width)
        metrics.update(evaluate_chain(args.finder, args.segmenter, args.data, args.input_width))
        if args.onnx:
            from models.builders import horizon_finder, horizon_segmenter

            metrics.update(chain_speed(horizon_finder(ckpt=args.finder), horizon_segmenter(ckpt=args.segmenter),
                                       args.onnx, args.data, args.input_width, args.repeats))
    except InputError as err:
        raise SystemExit(f"bench/horizon_networks.py: error: {err}") from err
    if args.json:
        print(json.dumps(metrics))
    else:
        print_table(metrics)
        for key, value in metrics.items():
            if key.startswith("speed/"):
                print(f"{key}: {value:.2f}")
    if args.plot:
        plot_failures(metrics, args.plot)

if __name__ == "__main__":
    main()
