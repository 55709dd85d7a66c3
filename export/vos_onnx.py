"""Export FRTM (thesis ch. 5) as a deployment bundle: one graph per component, with the tracker's state (filters,
memory, CG state) outside the graphs, run by ``runtime.vos.OnnxFRTMTracker``.

    python -m export.vos_onnx --ckpt CKPT --out DIR [--height H --width W] [--workers N] [--check] [--check-videos N]
                              [--int8 [--calibration-videos N | --calibration-davis ROOT --calibration-sequences A,B]]

Graphs (dynamo exporter, opset 20; H, W, the number of objects N, samples K and memory slots M dynamic):

- ``frame.onnx``: image (1, 3, H, W) RGB in [0, 1], W_p (N, C, D), W_f (N, C, k, k) -> logits (N, H, W),
  projected features z (N, C, h, w): backbone + target-model application + decoder for every object of a frame.
- ``features.onnx``: images (K, 3, H, W) -> target-model features (K, D, h, w) (first-frame samples).
- ``init.onnx``: the joint W_p/W_f Gauss-Newton fit of one object on its K augmented samples, from the tracker's
  seeded starting filters (built into the graph).
- ``insert.onnx``: one memory insertion (memory tensors in and out, hinge weights and the size test inside).
- ``update.onnx``: one W_f optimizer update over M memory slots with the CG state in and out.

The per-object graphs (init, insert, update) take one object (B = 1, grouped convolutions need a static group
count); the runtime loops over objects. ``bundle.json`` holds the tracker settings (``FRTMSettings``).
The graphs export side by side, one process each (``--workers``, default one per core; 1: in this process).
``--check`` compares the runtime's masks with the PyTorch tracker's on held-out synthetic videos (IoU per frame
and object). ``--int8`` replaces the frame and features graphs (backbone, decoder) by static int8 QDQ versions
calibrated on synthetic validation videos, or on real frames with ``--calibration-davis`` (DAVIS sequences of the
checkpoint's training split, never the held-out ones; ``export.int8``; the optimiser graphs stay float32), and
stores J&F of both versions on held-out synthetic videos in the manifest.
"""

from __future__ import annotations

import argparse
import shutil
import tempfile
from pathlib import Path

import numpy as np
import torch
from torch import nn
from torch.export import Dim
from tqdm import tqdm

from core.command import CommandParser, run_command
from core.errors import InputError
from data.vos.davis import load_davis_videos
from export.bundle import staged_bundle
from export.int8 import RecordingGraph, quantize_bundle_graphs
from export.onnx import OPSET, export_onnx
from export.parity import mask_parity
from export.pool import GraphJob, export_jobs
from models.vos.decoder import flip_averaged_logits
from models.vos.memory import Memory
from models.vos.optimizer import SteepestDescent
from models.vos.target_model import target_model_init
from models.vos.tracker import FRTMTracker, frame_memory_insert
from runtime.bundle import write_manifest
from runtime.vos import OnnxFRTMTracker

#: Largest frame side the graphs accept.
MAX_SIZE = 4096


def apply_filter_per_object(z: torch.Tensor, wf: torch.Tensor) -> torch.Tensor:
    """W_f,i * z_i for N objects without grouped convolutions (k^2 shifted einsums): (N, C, h, w),
    (N, C, k, k) -> (N, h, w). Equals ``apply_filter(z[:, None], wf)[:, 0]``; exports with dynamic N."""
    n, c, h, w = z.shape
    k = wf.shape[-1]
    zp = torch.nn.functional.pad(z, (k // 2, k // 2, k // 2, k // 2))
    out = z.new_zeros(n, h, w)
    for dy in range(k):
        for dx in range(k):
            out = out + torch.einsum("nchw,nc->nhw", zp[:, :, dy : dy + h, dx : dx + w], wf[:, :, dy, dx])
    return out


class FrameGraph(nn.Module):
    """Backbone + target models + decoder of one frame (``FRTMTracker.segment_frame``)."""

    def __init__(self, tracker: FRTMTracker) -> None:
        super().__init__()
        self.backbone = tracker.backbone
        self.decoder = tracker.decoder if tracker.use_decoder else None
        self.target_input = tracker.target_input
        self.flip_test = tracker.flip_test

    def forward(self, image: torch.Tensor, wp: torch.Tensor, wf: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        feats = self.backbone(image)
        n = wp.shape[0]
        z = torch.einsum("ncd,dhw->nchw", wp, self.target_input(feats)[0])
        score = apply_filter_per_object(z, wf)[:, None]
        size = (image.shape[-2], image.shape[-1])
        if self.decoder is None:
            up = torch.nn.functional.interpolate(score, size=size, mode="bilinear", align_corners=False)
            return (up[:, 0] - 0.5) * 10, z
        shared = {k: v.expand(n, -1, -1, -1) for k, v in feats.items()}
        if not self.flip_test:
            return self.decoder(score, shared, size)[:, 0], z
        mirrored = {k: v.expand(n, -1, -1, -1) for k, v in self.backbone(image.flip(-1)).items()}
        return flip_averaged_logits(self.decoder, score, shared, mirrored, size)[:, 0], z


class FeaturesGraph(nn.Module):
    def __init__(self, tracker: FRTMTracker) -> None:
        super().__init__()
        self.backbone = tracker.backbone
        self.target_input = tracker.target_input

    def forward(self, images: torch.Tensor) -> torch.Tensor:
        return self.target_input(self.backbone(images))


class InitGraph(nn.Module):
    """Joint W_p/W_f fit from the tracker's seeded starting filters (``target_model_init``, built in); float32 in
    and out, computed in the tracker's ``optimizer_dtype``."""

    def __init__(self, tracker: FRTMTracker) -> None:
        super().__init__()
        s = tracker.settings
        self.optimizer = tracker.init_optimizer
        self.pixel_weighting = s.pixel_weighting
        self.dtype = getattr(torch, s.optimizer_dtype)
        wp0, wf0 = target_model_init(1, tracker.target_input.channels, s.channels, s.kernel_size, s.seed)
        self.register_buffer("wp0", wp0)
        self.register_buffer("wf0", wf0)

    def forward(self, x, labels, pixel_weights, gamma):
        dt, keep = self.dtype, x.dtype
        v = pixel_weights.to(dt) if self.pixel_weighting else None
        wp, wf, _, _ = self.optimizer(x.to(dt), labels.to(dt), v, gamma.to(dt), self.wf0.to(dt), self.wp0.to(dt))
        return wp.to(keep), wf.to(keep)


class InsertGraph(nn.Module):
    def __init__(self, tracker: FRTMTracker) -> None:
        super().__init__()
        s = tracker.settings
        self.t = {"lr": s.learning_rate, "pixel_weighting": s.pixel_weighting, "fg_target": s.fg_target,
                  "min_pixels": s.min_update_pixels, "keep_first": s.keep_first}

    def forward(self, features, labels, pixel_weights, weights, newest, z, label):
        mem = frame_memory_insert(Memory(features, labels, pixel_weights, weights, newest), z, label, **self.t)
        return tuple(mem)


class UpdateGraph(nn.Module):
    """One W_f update with the CG state; float32 in and out, computed in the tracker's ``optimizer_dtype``."""

    def __init__(self, tracker: FRTMTracker) -> None:
        super().__init__()
        self.optimizer = tracker.update_optimizer
        self.dtype = getattr(torch, tracker.settings.optimizer_dtype)

    def forward(self, features, labels, pixel_weights, weights, wf, p, rho, r_prev):
        dt, keep = self.dtype, wf.dtype
        args = (features.to(dt), labels.to(dt), pixel_weights.to(dt), weights.to(dt), wf.to(dt))
        if isinstance(self.optimizer, SteepestDescent):
            _, wf, _, _ = self.optimizer(*args)
            return wf.to(keep), p, rho, r_prev
        _, wf, (p, rho, r_prev), _ = self.optimizer(*args, state=([p.to(dt)], rho.to(dt), [r_prev.to(dt)]))
        return wf.to(keep), p[0].to(keep), rho.to(keep), r_prev[0].to(keep)


#: The graphs of a VOS bundle, heaviest first (about 41, 16, 11, 3 and 2 s for the tracker of configs/demo/frtm.yaml
#: at 96 x 160 on one core), so that a pool of workers ends together.
GRAPHS = ("init", "frame", "update", "features", "insert")


@torch.no_grad()
def export_graph(name: str, tracker: FRTMTracker, out: Path, height: int, width: int) -> None:
    """Write the graph ``name`` (one of :data:`GRAPHS`) of ``tracker`` into ``out`` as ``name.onnx`` (example
    frames of ``height`` x ``width``). A module-level function, so that a pool's worker process can run it."""
    c, k, d = tracker.settings.channels, tracker.settings.kernel_size, tracker.target_input.channels
    stride = tracker.target_input.stride
    h, w = -(-height // stride), -(-width // stride)
    lh, lw = tracker._label_size((height, width))
    n_obj, n_aug, n_mem = 2, max(tracker.settings.num_aug, 2), 3
    big_h, big_w = Dim("H", min=2 * stride, max=MAX_SIZE), Dim("W", min=2 * stride, max=MAX_SIZE)
    fh, fw, lbh, lbw = Dim("h", min=2), Dim("w", min=2), Dim("Hl", min=2), Dim("Wl", min=2)
    nd, kd, md = Dim("N", min=1, max=64), Dim("K", min=2, max=256), Dim("M", min=2, max=4096)
    g = torch.Generator().manual_seed(0)

    def rnd(*shape: int) -> torch.Tensor:
        return torch.rand(*shape, generator=g)

    path = out / f"{name}.onnx"
    memory = {"features": {1: md, 3: fh, 4: fw}, "labels": {1: md, 2: lbh, 3: lbw},
              "pixel_weights": {1: md, 2: lbh, 3: lbw}, "weights": {1: md}}

    def mem() -> tuple[torch.Tensor, ...]:
        return rnd(1, n_mem, c, h, w), rnd(1, n_mem, lh, lw), rnd(1, n_mem, lh, lw), rnd(1, n_mem)

    if name == "frame":
        export_onnx(FrameGraph(tracker), (rnd(1, 3, height, width), rnd(n_obj, c, d), rnd(n_obj, c, k, k)), path,
                    ["image", "wp", "wf"], ["logits", "z"], dynamic_shapes=({2: big_h, 3: big_w}, {0: nd}, {0: nd}))
    elif name == "features":
        export_onnx(FeaturesGraph(tracker), (rnd(n_aug, 3, height, width),), path, ["images"], ["features"],
                    dynamic_shapes=({0: kd, 2: big_h, 3: big_w},))
    elif name == "init":
        export_onnx(InitGraph(tracker), (rnd(1, n_aug, d, h, w), rnd(1, n_aug, lh, lw), rnd(1, n_aug, lh, lw) + 0.5,
                                         rnd(1, n_aug)), path, ["x", "labels", "pixel_weights", "gamma"], ["wp", "wf"],
                    dynamic_shapes=({1: kd, 3: fh, 4: fw}, {1: kd, 2: lbh, 3: lbw}, {1: kd, 2: lbh, 3: lbw}, {1: kd}),
                    optimize=False)  # the unrolled optimiser: see export_onnx
    elif name == "insert":
        export_onnx(InsertGraph(tracker), (*mem(), torch.tensor([1]), rnd(1, c, h, w), rnd(1, lh, lw)), path,
                    [*memory, "newest", "z", "label"],
                    ["features_out", "labels_out", "pixel_weights_out", "weights_out", "newest_out"],
                    dynamic_shapes=(*memory.values(), None, {2: fh, 3: fw}, {1: lbh, 2: lbw}))
    elif name == "update":
        export_onnx(UpdateGraph(tracker), (*mem(), rnd(1, c, k, k), rnd(1, c, k, k), torch.ones(1), rnd(1, c, k, k)),
                    path, [*memory, "wf", "p", "rho", "r_prev"], ["wf_out", "p_out", "rho_out", "r_prev_out"],
                    dynamic_shapes=(*memory.values(), None, None, None, None), optimize=False)
    else:
        raise InputError(f"unknown VOS graph {name!r}; choose one of {', '.join(GRAPHS)}")


def _sections(tracker: FRTMTracker) -> dict:
    """The manifest sections of a VOS bundle of ``tracker``."""
    s, target = tracker.settings, tracker.target_input
    return {
        "input": {"image": "(1, 3, H, W) RGB float32 in [0, 1]", "min_size": 2 * target.stride, "max_size": MAX_SIZE,
                  "stride": target.stride, "in_channels": target.channels},
        "normalisation": {"scale": 1 / 255, "order": "RGB", "mean_std": "inside the backbone graph"},
        "thresholds": {"min_update_pixels": s.min_update_pixels, "fg_target": s.fg_target},
        "settings": s.to_dict(),
    }


Videos = list[tuple[str, torch.Tensor, torch.Tensor]]


def videos_jf(tracker: OnnxFRTMTracker, videos: Videos, desc: str = "J&F") -> float:
    """J&F mean (DAVIS protocol, %) of the runtime ``tracker`` on videos (name, frames uint8, labels)."""
    from models.vos.metrics import evaluate_sequence, summarize

    per_seq = {}
    for name, frames, labels in tqdm(videos, desc=desc, unit="video"):
        pred = torch.from_numpy(np.stack(list(tracker.segment(frames.numpy(), {0: labels[0].numpy()}))))
        per_seq[name] = evaluate_sequence(pred, torch.where(labels < 0, 0, labels))
    return float(summarize(per_seq)["J&F-Mean"]) * 100


@torch.no_grad()
def export_bundle(tracker: FRTMTracker, out: str | Path, height: int = 96, width: int = 160, int8: bool = False,
                  calibration: Videos | None = None, held_out: Videos | None = None,
                  workers: int | None = None) -> dict:
    """Write the VOS bundle of ``tracker`` to the folder ``out`` (example frames ``height`` x ``width``), its graphs
    exported by ``workers`` processes at once (:func:`export.pool.export_jobs`; default one per core). With
    ``int8`` the frame and features graphs are quantized, calibrated on the ``calibration`` videos (name, frames
    uint8 (T, 3, H, W), labels (T, H, W)), and J&F of both versions on the ``held_out`` videos goes into the
    manifest; returns that int8 report (empty without ``int8``)."""
    tracker = tracker.eval()
    sections = _sections(tracker)
    report: dict = {}
    if int8 and (not calibration or not held_out):
        raise InputError("an int8 export needs calibration and held-out videos")
    with staged_bundle(out) as folder, tempfile.TemporaryDirectory() as tmp:
        export_jobs("export.vos_onnx", [GraphJob(name, export_graph, (name, tracker, folder, height, width))
                                        for name in GRAPHS], workers)
        write_manifest(folder, "vos", OPSET, **sections)
        if int8:
            fp32 = Path(tmp) / "fp32"
            shutil.copytree(folder, fp32)
            runtime = OnnxFRTMTracker(fp32)
            recorded = {name: RecordingGraph(runtime.graphs[name]) for name in ("frame", "features")}
            runtime.graphs.update(recorded)
            for _, frames, labels in tqdm(calibration, desc="int8 calibration", unit="video"):
                list(runtime.segment(frames.numpy(), {0: labels[0].numpy()}))
            report["graphs"] = quantize_bundle_graphs(folder, recorded)
            write_manifest(folder, "vos", OPSET, precision="int8", **sections)
            report["accuracy"] = {"float32_jf": videos_jf(OnnxFRTMTracker(fp32), held_out, "J&F float32"),
                                  "int8_jf": videos_jf(OnnxFRTMTracker(folder), held_out, "J&F int8"),
                                  "videos": len(held_out)}
            write_manifest(folder, "vos", OPSET, precision="int8", **sections, int8=report)
    return report


def main(argv: list[str] | None = None) -> int:
    p = CommandParser(prog="export.vos_onnx", description=__doc__,
                      formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--ckpt", required=True, help="FRTMSegmentation checkpoint")
    p.add_argument("--out", required=True, help="bundle folder to write")
    p.add_argument("--height", type=int, default=96, help="example frame height (the graphs accept any)")
    p.add_argument("--width", type=int, default=160, help="example frame width")
    p.add_argument("--workers", type=int, default=None,
                   help="graphs exported at once, one process each (default: one per core)")
    p.add_argument("--check", action="store_true", help="compare the runtime's masks with PyTorch's")
    p.add_argument("--check-videos", type=int, default=4,
                   help="held-out synthetic test videos for --check and the int8 report (the checkpoint's data "
                   "settings; default 4)")
    p.add_argument("--check-frames", type=int, default=20, help="frames per held-out video")
    p.add_argument("--int8", action="store_true", help="int8 frame and features graphs, with a J&F report")
    p.add_argument("--calibration-videos", type=int, default=4, help="synthetic validation videos to calibrate on")
    p.add_argument("--calibration-davis", metavar="ROOT",
                   help="calibrate on real DAVIS frames instead (with --calibration-sequences)")
    p.add_argument("--calibration-sequences", default="bear,boat,dog-agility,kite-walk",
                   help="comma-separated DAVIS sequences to calibrate on (training sequences, not held-out ones)")
    p.add_argument("--calibration-split", default="train", help="DAVIS ImageSets split of those sequences")
    p.add_argument("--calibration-resolution", default="240p", help="DAVIS resolution folder")
    args = p.parse_args(argv)
    return run_command("export.vos_onnx", lambda: _export_and_check(args))


def _export_and_check(args: argparse.Namespace) -> None:
    from data.vos.datamodule import synthetic_videos
    from models.builders import frtm_tracker
    from models.vos.inference import checkpoint_test_videos, synthetic_test_settings

    tracker = frtm_tracker(ckpt=args.ckpt)
    need = args.check or args.int8
    held_out = checkpoint_test_videos(args.ckpt, args.check_videos if need else 0, args.check_frames)
    calibration = None
    if args.int8 and args.calibration_davis:
        calibration = load_davis_videos(args.calibration_davis, args.calibration_split, args.calibration_resolution,
                                        args.calibration_sequences.split(","), args.check_frames)
    elif args.int8:
        calibration = synthetic_videos("val", args.calibration_videos, 0, n_frames=args.check_frames,
                                       **synthetic_test_settings(args.ckpt))
    report = export_bundle(tracker, args.out, args.height, args.width, args.int8, calibration, held_out,
                           args.workers)
    print(f"wrote {args.out}")
    if args.check:
        ious = np.array(mask_parity(tracker, OnnxFRTMTracker(args.out), held_out))
        print(f"mask parity runtime vs PyTorch on {len(held_out)} held-out synthetic videos: {len(ious)} "
              f"frame-objects, IoU mean {ious.mean():.4f}, min {ious.min():.4f}, below 0.99: "
              f"{int((ious < 0.99).sum())}")
    for name, g in report.get("graphs", {}).items():
        print(f"int8 {name}: {g['fp32_bytes'] / 1e6:.2f} -> {g['int8_bytes'] / 1e6:.2f} MB, {g['fp32_ms']:.1f} -> "
              f"{g['int8_ms']:.1f} ms per call (1 thread)")
    if "accuracy" in report:
        a = report["accuracy"]
        print(f"J&F on {a['videos']} held-out synthetic videos: float32 {a['float32_jf']:.2f}, int8 {a['int8_jf']:.2f}")


if __name__ == "__main__":
    raise SystemExit(main())
