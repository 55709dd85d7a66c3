"""Export DAVOS or LWL (thesis ch. 6) as a deployment bundle: one graph per component, with the tracker's state
(filters, memory) outside the graphs, run by ``runtime.davos.OnnxDAVOSTracker``.

    python -m export.davos_onnx --ckpt CKPT --out DIR [--height H --width W] [--workers N] [--check [--davis ROOT ...]]

Graphs (dynamo exporter, opset 20; H, W, the number of objects N and memory slots M dynamic):

- ``features.onnx``: image (1, 3, H, W) RGB in [0, 1] -> target-model features x (1, P, h, w) (new objects).
- ``frame.onnx``: image (1, 3, H, W), filters tau (N, K, P, k, k) -> logits (N, L, H, W) ([target] or [target,
  distractor]), features x (1, P, h, w): backbone, target-model features, every object's scores, decoder.
- ``encode.onnx``: labels (N, L, H, W) in [0, 1] -> mask encodings E and weights W (N, K, h, w).
- ``insert.onnx``: one memory insertion per object (memory tensors in and out, the decay rule and the first
  frame's share inside).
- ``fit_init.onnx`` / ``fit_update.onnx``: ``init_iters`` / ``update_iters`` steepest-descent steps of one
  object's filter on its memory samples (B = 1: the grouped convolutions need a static group count).

The merging of objects (soft aggregation) and the distractor regeneration (eqs. 6.1-6.5) run on the host, in
numpy. ``bundle.json`` holds the tracker settings (``DAVOSSettings``) and the network's label channels.
The graphs export side by side, one process each (``--workers``, default one per core; 1: in this process).
``--check`` compares the runtime's masks with the PyTorch tracker's, per frame and object: on held-out twin
composites of ``--davis`` sequences when given, else on synthetic look-alike videos.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import torch
from torch import nn
from torch.export import Dim

from core.command import CommandParser, run_command
from core.errors import InputError
from export.bundle import staged_bundle
from export.onnx import OPSET, export_onnx
from export.parity import mask_parity
from export.pool import GraphJob, export_jobs
from models.vos.davos_net import DAVOSNet
from models.vos.davos_tracker import DAVOSTracker
from models.vos.memory import Memory, memory_insert
from runtime.bundle import write_manifest
from runtime.davos import OnnxDAVOSTracker

#: Largest frame side the graphs accept.
MAX_SIZE = 4096


class FeaturesGraph(nn.Module):
    def __init__(self, net: DAVOSNet) -> None:
        super().__init__()
        self.net = net

    def forward(self, image: torch.Tensor) -> torch.Tensor:
        return self.net.features(image)[1]


class FrameGraph(nn.Module):
    """Backbone, target-model features, the scores of N objects and the decoder (``DAVOSTracker.step``)."""

    def __init__(self, net: DAVOSNet) -> None:
        super().__init__()
        self.net = net

    def forward(self, image: torch.Tensor, tau: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        feats = self.net.stages(image)
        x = self.net.target_features(feats)
        scores = self.net.frame_scores(tau, x)
        shared = {k: v.expand(tau.shape[0], -1, -1, -1) for k, v in feats.items()}
        return self.net.decode(scores, shared, (image.shape[-2], image.shape[-1])), x


class EncodeGraph(nn.Module):
    def __init__(self, net: DAVOSNet) -> None:
        super().__init__()
        self.encoder = net.label_encoder

    def forward(self, labels: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        return self.encoder(labels)


class InsertGraph(nn.Module):
    def __init__(self, tracker: DAVOSTracker) -> None:
        super().__init__()
        self.lr, self.keep_first = tracker.settings.learning_rate, tracker.settings.keep_first

    def forward(self, features, encodings, weights, sample_weights, newest, x, encoding, weight):
        valid = torch.ones_like(newest, dtype=torch.bool)
        mem = memory_insert(Memory(features, encodings, weights, sample_weights, newest), x, encoding, weight, valid,
                            self.lr, self.keep_first)
        return tuple(mem)


class FitGraph(nn.Module):
    """``iters`` steepest-descent steps of one object's filter."""

    def __init__(self, net: DAVOSNet, iters: int) -> None:
        super().__init__()
        self.optimizer, self.iters = net.optimizer, iters

    def forward(self, tau, x, encodings, weights, sample_weights):
        return self.optimizer(tau, x, encodings, weights, sample_weights, self.iters)[0]


#: The graphs of a DAVOS bundle, heaviest first (about 19, 12, 11, 4, 2 and 2 s for the network of
#: configs/davos_davis2016_cpu.yaml at 96 x 160 on one core), so that a pool of workers ends together.
GRAPHS = ("frame", "fit_init", "features", "fit_update", "insert", "encode")


@torch.no_grad()
def export_graph(name: str, tracker: DAVOSTracker, out: Path, height: int, width: int) -> None:
    """Write the graph ``name`` (one of :data:`GRAPHS`) of ``tracker`` into ``out`` as ``name.onnx`` (example
    frames of ``height`` x ``width``). A module-level function, so that a pool's worker process can run it."""
    net, s = tracker.net, tracker.settings
    k, p, size, _ = net.filter_shape
    stride, labels = net.target_input.stride, net.label_channels
    h, w = -(-height // stride), -(-width // stride)
    big_h, big_w = Dim("H", min=2 * stride, max=MAX_SIZE), Dim("W", min=2 * stride, max=MAX_SIZE)
    fh, fw = Dim("h", min=2), Dim("w", min=2)
    nd, md = Dim("N", min=1, max=64), Dim("M", min=1, max=4096)
    g = torch.Generator().manual_seed(0)

    def rnd(*shape: int) -> torch.Tensor:
        return torch.rand(*shape, generator=g)

    path, n_mem = out / f"{name}.onnx", 3
    if name == "features":
        export_onnx(FeaturesGraph(net), (rnd(1, 3, height, width),), path, ["image"], ["x"],
                    dynamic_shapes=({2: big_h, 3: big_w},))
    elif name == "frame":
        export_onnx(FrameGraph(net), (rnd(1, 3, height, width), 0.1 * rnd(2, k, p, size, size)), path,
                    ["image", "tau"], ["logits", "x"], dynamic_shapes=({2: big_h, 3: big_w}, {0: nd}))
    elif name == "encode":
        export_onnx(EncodeGraph(net), (rnd(2, labels, height, width),), path, ["labels"], ["encodings", "weights"],
                    dynamic_shapes=({0: nd, 2: big_h, 3: big_w},))
    elif name == "insert":
        memory, sample = {0: nd, 1: md, 3: fh, 4: fw}, {0: nd, 2: fh, 3: fw}
        mem = (rnd(2, n_mem, p, h, w), rnd(2, n_mem, k, h, w), rnd(2, n_mem, k, h, w), rnd(2, n_mem),
               torch.tensor([1, -1]))
        export_onnx(InsertGraph(tracker), (*mem, rnd(2, p, h, w), rnd(2, k, h, w), rnd(2, k, h, w)), path,
                    ["features", "encodings", "weights", "sample_weights", "newest", "x", "encoding", "weight"],
                    ["features_out", "encodings_out", "weights_out", "sample_weights_out", "newest_out"],
                    dynamic_shapes=(memory, memory, memory, {0: nd, 1: md}, {0: nd}, sample, sample, sample))
    elif name in ("fit_init", "fit_update"):
        iters = s.init_iters if name == "fit_init" else s.update_iters
        fit_args = (0.1 * rnd(1, k, p, size, size), rnd(1, n_mem, p, h, w), rnd(1, n_mem, k, h, w),
                    rnd(1, n_mem, k, h, w), rnd(1, n_mem))
        memory = {1: md, 3: fh, 4: fw}
        export_onnx(FitGraph(net, iters), fit_args, path, ["tau", "x", "encodings", "weights", "sample_weights"],
                    ["tau_out"], dynamic_shapes=(None, memory, memory, memory, {1: md}))
    else:
        raise InputError(f"unknown DAVOS graph {name!r}; choose one of {', '.join(GRAPHS)}")


@torch.no_grad()
def export_bundle(tracker: DAVOSTracker, out: str | Path, height: int = 96, width: int = 160,
                  workers: int | None = None) -> Path:
    """Write the DAVOS bundle of ``tracker`` to the folder ``out`` (example frames ``height`` x ``width``), its graphs
    exported by ``workers`` processes at once (:func:`export.pool.export_jobs`; default one per core)."""
    tracker = tracker.eval()
    net = tracker.net
    sections = {
        "input": {"image": "(1, 3, H, W) RGB float32 in [0, 1]", "min_size": 2 * net.target_input.stride,
                  "max_size": MAX_SIZE, "stride": net.target_input.stride},
        "normalisation": {"scale": 1 / 255, "order": "RGB", "mean_std": "inside the backbone graph"},
        "thresholds": {},
        "settings": tracker.settings.to_dict(),
        "network": {"label_channels": net.label_channels, "filter_shape": list(net.filter_shape)},
    }
    with staged_bundle(out) as folder:
        export_jobs("export.davos_onnx", [GraphJob(name, export_graph, (name, tracker, folder, height, width))
                                          for name in GRAPHS], workers)
        write_manifest(folder, "davos", OPSET, **sections)
    return Path(out)


def check_videos(args: argparse.Namespace) -> tuple[str, list]:
    """The ``--check`` videos: twin composites of ``--davis`` sequences, else synthetic look-alike videos."""
    from data.vos.composite_datamodule import held_out_composites, lookalike_videos

    if args.davis:
        from data.vos.davis import davis_sequences

        names = args.sequences.split(",") if args.sequences else None
        seqs = davis_sequences(args.davis, args.split, args.resolution, names)
        return "twin composites", held_out_composites(seqs, "twins", max_frames=args.check_frames)
    return "synthetic look-alike videos", lookalike_videos(args.check_videos, n_frames=args.check_frames,
                                                           height=args.height, width=args.width)


def main(argv: list[str] | None = None) -> int:
    p = CommandParser(prog="export.davos_onnx", description=__doc__,
                      formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--ckpt", required=True, help="DAVOSSegmentation checkpoint (DAVOS or LWL)")
    p.add_argument("--out", required=True, help="bundle folder to write")
    p.add_argument("--height", type=int, default=96, help="example frame height (the graphs accept any)")
    p.add_argument("--width", type=int, default=160, help="example frame width")
    p.add_argument("--workers", type=int, default=None,
                   help="graphs exported at once, one process each (default: one per core)")
    p.add_argument("--check", action="store_true", help="compare the runtime's masks with PyTorch's")
    p.add_argument("--davis", help="with --check: DAVIS root whose sequences make twin composites")
    p.add_argument("--split", default="train", help="DAVIS split (default train)")
    p.add_argument("--resolution", default="240p", help="DAVIS resolution folder (default 240p)")
    p.add_argument("--sequences", help="comma-separated DAVIS sequences (default: the whole split)")
    p.add_argument("--check-videos", type=int, default=2, help="synthetic look-alike videos without --davis")
    p.add_argument("--check-frames", type=int, default=20, help="frames per check video")
    args = p.parse_args(argv)
    return run_command("export.davos_onnx", lambda: _export_and_check(args))


def _export_and_check(args: argparse.Namespace) -> None:
    from models.builders import davos_tracker

    if args.check_frames < 3:
        raise InputError(f"--check-frames must be at least 3, got {args.check_frames}")
    tracker = davos_tracker(args.ckpt)
    export_bundle(tracker, args.out, args.height, args.width, args.workers)
    print(f"wrote {args.out}")
    if args.check:
        what, videos = check_videos(args)
        ious = np.array(mask_parity(tracker, OnnxDAVOSTracker(args.out), videos))
        print(f"mask parity runtime vs PyTorch on {len(videos)} {what}: {len(ious)} frame-objects, IoU mean "
              f"{ious.mean():.4f}, min {ious.min():.4f}, below 0.99: {int((ious < 0.99).sum())}")


if __name__ == "__main__":
    raise SystemExit(main())
