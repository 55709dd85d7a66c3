"""ONNX export of FRTM (thesis ch. 5): one graph per component, with the tracker's state (filters, memory, CG
state) outside the graphs, run by ``models.vos.onnx_tracker.OnnxFRTMTracker``.

    python -m export.vos_onnx --ckpt CKPT --out DIR [--height H --width W] [--check-videos N]

Graphs (dynamo exporter, opset 20; H, W, the number of objects N, samples K and memory slots M dynamic):

- ``frtm_frame.onnx``: image (1, 3, H, W), W_p (N, C, D), W_f (N, C, k, k) -> logits (N, H, W), projected
  features z (N, C, h, w): backbone + target-model application + decoder for every object of a frame.
- ``frtm_features.onnx``: images (K, 3, H, W) -> target-model features (K, D, h, w) (first-frame samples).
- ``frtm_init.onnx``: the joint W_p/W_f Gauss-Newton fit of one object on its K augmented samples.
- ``frtm_insert.onnx``: one memory insertion (memory tensors in and out, hinge weights and the size test inside).
- ``frtm_update.onnx``: one W_f optimizer update over M memory slots with the CG state in and out.

The per-object graphs (init, insert, update) take one object (B = 1, grouped convolutions need a static group
count); ``OnnxFRTMTracker`` loops over objects. ``frtm_onnx.json`` stores the tracker settings (``FRTMSettings``)
and the target-model input channels.
"""

from __future__ import annotations

import json
import os
import shutil
from pathlib import Path

import torch
from torch import nn
from torch.export import Dim

from core.files import writable_folder
from export.onnx import export_onnx
from models.vos.memory import Memory
from models.vos.onnx_tracker import SETTINGS_FILE, OnnxFRTMTracker
from models.vos.optimizer import SteepestDescent
from models.vos.tracker import FRTMTracker, frame_memory_insert


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
        return self.decoder(score, shared, size)[:, 0], z


class FeaturesGraph(nn.Module):
    def __init__(self, tracker: FRTMTracker) -> None:
        super().__init__()
        self.backbone = tracker.backbone
        self.target_input = tracker.target_input

    def forward(self, images: torch.Tensor) -> torch.Tensor:
        return self.target_input(self.backbone(images))


class InitGraph(nn.Module):
    """Joint W_p/W_f fit; float32 in and out, computed in the tracker's ``optimizer_dtype``."""

    def __init__(self, tracker: FRTMTracker) -> None:
        super().__init__()
        self.optimizer = tracker.init_optimizer
        self.pixel_weighting = tracker.settings.pixel_weighting
        self.dtype = getattr(torch, tracker.settings.optimizer_dtype)

    def forward(self, x, labels, pixel_weights, gamma, wp, wf):
        dt, keep = self.dtype, x.dtype
        v = pixel_weights.to(dt) if self.pixel_weighting else None
        wp, wf, _, _ = self.optimizer(x.to(dt), labels.to(dt), v, gamma.to(dt), wf.to(dt), wp.to(dt))
        return wp.to(keep), wf.to(keep)


class InsertGraph(nn.Module):
    def __init__(self, tracker: FRTMTracker) -> None:
        super().__init__()
        s = tracker.settings
        self.t = {"lr": s.learning_rate, "pixel_weighting": s.pixel_weighting, "fg_target": s.fg_target,
                  "min_pixels": s.min_update_pixels}

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


@torch.no_grad()
def export_frtm(tracker: FRTMTracker, out_dir: str | Path, height: int = 96, width: int = 160) -> dict[str, Path]:
    """Export the five FRTM graphs of ``tracker`` and its settings file into ``out_dir`` (example size ``height`` x
    ``width``). The graphs are written to a hidden sibling folder first and moved in when all of them passed the
    checker, so a failed export leaves no part of an export behind."""
    final = writable_folder(out_dir)
    out = final.with_name(f".{final.name}.partial")
    shutil.rmtree(out, ignore_errors=True)
    out.mkdir()
    try:
        paths = _export_graphs(tracker.eval(), out, height, width)
        for name, path in paths.items():
            os.replace(path, final / path.name)
            paths[name] = final / path.name
        os.replace(out / SETTINGS_FILE, final / SETTINGS_FILE)
    finally:
        shutil.rmtree(out, ignore_errors=True)
    return paths


def _export_graphs(tracker: FRTMTracker, out: Path, height: int, width: int) -> dict[str, Path]:
    """The graphs and the settings file of ``export_frtm`` written into ``out``."""
    c, k, d = tracker.settings.channels, tracker.settings.kernel_size, tracker.target_input.channels
    stride = tracker.target_input.stride
    h, w = -(-height // stride), -(-width // stride)
    lh, lw = tracker._label_size((height, width))
    n_obj, n_aug, n_mem = 2, max(tracker.settings.num_aug, 2), 3
    big_h, big_w = Dim("H", min=2 * stride, max=4096), Dim("W", min=2 * stride, max=4096)
    fh, fw, lbh, lbw = Dim("h", min=2), Dim("w", min=2), Dim("Hl", min=2), Dim("Wl", min=2)
    nd, kd, md = Dim("N", min=1, max=64), Dim("K", min=2, max=256), Dim("M", min=2, max=4096)
    g = torch.Generator().manual_seed(0)

    def rnd(*shape: int) -> torch.Tensor:
        return torch.rand(*shape, generator=g)

    paths = {}
    paths["frame"] = export_onnx(
        FrameGraph(tracker), (rnd(1, 3, height, width), rnd(n_obj, c, d), rnd(n_obj, c, k, k)),
        out / "frtm_frame.onnx", ["image", "wp", "wf"], ["logits", "z"],
        dynamic_shapes=({2: big_h, 3: big_w}, {0: nd}, {0: nd}))
    paths["features"] = export_onnx(
        FeaturesGraph(tracker), (rnd(n_aug, 3, height, width),), out / "frtm_features.onnx", ["images"],
        ["features"], dynamic_shapes=({0: kd, 2: big_h, 3: big_w},))
    paths["init"] = export_onnx(
        InitGraph(tracker),
        (rnd(1, n_aug, d, h, w), rnd(1, n_aug, lh, lw), rnd(1, n_aug, lh, lw) + 0.5, rnd(1, n_aug),
         rnd(1, c, d), rnd(1, c, k, k)),
        out / "frtm_init.onnx", ["x", "labels", "pixel_weights", "gamma", "wp0", "wf0"], ["wp", "wf"],
        dynamic_shapes=({1: kd, 3: fh, 4: fw}, {1: kd, 2: lbh, 3: lbw}, {1: kd, 2: lbh, 3: lbw}, {1: kd}, None,
                        None))
    mem = (rnd(1, n_mem, c, h, w), rnd(1, n_mem, lh, lw), rnd(1, n_mem, lh, lw), rnd(1, n_mem),
           torch.tensor([1]))
    paths["insert"] = export_onnx(
        InsertGraph(tracker), (*mem, rnd(1, c, h, w), rnd(1, lh, lw)), out / "frtm_insert.onnx",
        ["features", "labels", "pixel_weights", "weights", "newest", "z", "label"],
        ["features_out", "labels_out", "pixel_weights_out", "weights_out", "newest_out"],
        dynamic_shapes=({1: md, 3: fh, 4: fw}, {1: md, 2: lbh, 3: lbw}, {1: md, 2: lbh, 3: lbw}, {1: md}, None,
                        {2: fh, 3: fw}, {1: lbh, 2: lbw}))
    paths["update"] = export_onnx(
        UpdateGraph(tracker), (*mem[:4], rnd(1, c, k, k), rnd(1, c, k, k), torch.ones(1), rnd(1, c, k, k)),
        out / "frtm_update.onnx",
        ["features", "labels", "pixel_weights", "weights", "wf", "p", "rho", "r_prev"],
        ["wf_out", "p_out", "rho_out", "r_prev_out"],
        dynamic_shapes=({1: md, 3: fh, 4: fw}, {1: md, 2: lbh, 3: lbw}, {1: md, 2: lbh, 3: lbw}, {1: md}, None,
                        None, None, None))
    settings = {"settings": tracker.settings.to_dict(), "in_channels": d}
    (out / SETTINGS_FILE).write_text(json.dumps(settings, indent=2))
    return paths


def mask_parity(
    tracker: FRTMTracker, onnx_dir: str | Path, videos: list[tuple[str, torch.Tensor, torch.Tensor]]
) -> list[float]:
    """Per frame and object IoU between the PyTorch tracker's and the onnxruntime tracker's masks, each run
    closed loop (own memory and filter updates) from the first-frame labels; frames where neither segments
    the object are skipped (IoU undefined)."""
    ious = []
    ox = OnnxFRTMTracker(onnx_dir)
    for _, frames, labels in videos:
        ids = [i for i in labels[0].unique().tolist() if i not in (0, 255)]
        ref = list(tracker.segment(frames, {0: labels[0]}))
        got = list(ox.segment(frames, {0: labels[0]}))
        for a, b in zip(ref, got, strict=True):
            for k in ids:
                union = int(((a == k) | (b == k)).sum())
                if union:
                    ious.append(int(((a == k) & (b == k)).sum()) / union)
    return ious


def main(argv: list[str] | None = None) -> int:
    """``python -m export.vos_onnx --ckpt CKPT --out DIR [--height H --width W] [--check-videos N]``: export,
    then optionally compare the onnxruntime tracker's masks with PyTorch's on N held-out synthetic videos."""
    from core.command import CommandParser, run_command

    p = CommandParser(prog="export.vos_onnx",
                      description="Export an FRTMSegmentation checkpoint to the FRTM ONNX graphs.")
    p.add_argument("--ckpt", required=True, help="FRTMSegmentation checkpoint")
    p.add_argument("--out", required=True, help="output folder")
    p.add_argument("--height", type=int, default=96, help="example frame height (the graphs accept any)")
    p.add_argument("--width", type=int, default=160, help="example frame width")
    p.add_argument("--check-videos", type=int, default=0,
                   help="mask parity on this many held-out synthetic test videos (the checkpoint's data settings)")
    p.add_argument("--check-frames", type=int, default=20, help="frames per parity video")
    args = p.parse_args(argv)
    return run_command("export.vos_onnx", lambda: _export_and_check(args))


def _export_and_check(args) -> None:
    from models.builders import frtm_tracker
    from models.vos.inference import checkpoint_test_videos

    tracker = frtm_tracker(ckpt=args.ckpt)
    videos = checkpoint_test_videos(args.ckpt, args.check_videos, args.check_frames)
    paths = export_frtm(tracker, args.out, args.height, args.width)
    for name, path in paths.items():
        print(f"{name:>9}: {path}")
    if videos:
        ious = torch.tensor(mask_parity(tracker, args.out, videos))
        print(f"mask parity onnxruntime vs PyTorch on {len(videos)} held-out synthetic videos: {len(ious)} "
              f"frame-objects, IoU mean {ious.mean():.4f}, min {ious.min():.4f}, below 0.99: "
              f"{int((ious < 0.99).sum())}")


if __name__ == "__main__":
    raise SystemExit(main())
