"""Video object segmentation benchmark: FRTM, LWL and DAVOS against their baselines, with DAVIS J&F.

    python -m bench.vos [--ckpt CKPT] [--davos-ckpt CKPT] [--lwl-ckpt CKPT] [--extra NAME=CKPT ...]
                        [--davis ROOT --split NAME --resolution 240p [--composites twins|pastes]]
                        [--synthetic | --lookalike] [--speed [--speed-config YAML ...]] [--onnx BUNDLE ...]
                        [--max-frames N] [--json] [--plot FILE.png]

Methods, side by side on the same videos: ``davos`` (thesis ch. 6: the meta-learnt target model with a
distractor channel, ``--davos-ckpt``), ``davos_no_wta`` (the same network, distractors regenerated without
winner-takes-all), ``lwl`` (no distractor channel, ``--lwl-ckpt``), any ``--extra`` DAVOS-family checkpoint
(e.g. ``davos_hard_loss=CKPT``), ``frtm`` (thesis ch. 5: target model + decoder, ``--ckpt``),
``target_model_only`` (FRTM's upsampled target-model score thresholded at 0.5, same memory updates) and
``first_frame_copy`` (the first mask repeated). Each gets ``jf``, ``j``, ``f`` (DAVIS 2017 protocol: means over
objects; per object of each sequence under ``per_sequence``), ``fps`` and milliseconds per frame per component
(backbone, target_model, decoder, update, init; init is per video, spread over its frames).

Videos: a DAVIS split (``--davis``), held-out multi-object composites of its sequences (``--composites``:
``twins``, a copy of each sequence's own object; ``pastes``, two objects of the other sequences), held-out
synthetic videos like the FRTM checkpoint's training data (``--synthetic``, the default) or synthetic look-alike
videos (``--lookalike``: ``--objects`` labelled look-alikes and one unlabelled one). ``--speed`` adds FPS of the
trackers at 240p and 480p (synthetic frames) for every model given and, side by side in the same run, for the
models of any ``--speed-config`` YAML files. Without ``--ckpt`` the FRTM system is built untrained from
``--backbone``/``--weights``/``--feature-layer``/``--feature-norm`` and the paper's tracker settings: with
``--weights imagenet`` the ``target_model_only`` row measures the pretrained features alone (the decoder is
random, so the ``frtm`` row means nothing then). ``--onnx BUNDLE`` adds the deployment runtime of a VOS or
DAVOS bundle (``runtime.vos`` or ``runtime.davos``: the bundle's graphs in onnxruntime with ``--threads``
threads, the host loop in numpy) as method ``onnx:<bundle folder name>``, in the J&F rows and, with
``--speed``, in the speed table of the same run. Prints one JSON object with ``--json``, else a table.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections.abc import Callable
from pathlib import Path

import torch

from core.errors import InputError
from core.settings import parse_tracker
from core.threads import set_cpu_threads
from data.vos.composite_datamodule import EVAL_SETS, held_out_composites, lookalike_videos
from data.vos.davis import davis_sequences, load_davis_videos
from models.builders import davos_system, frtm_system
from models.vos.inference import checkpoint_test_videos, synthetic_test_settings
from models.vos.lit import FRTMSegmentation
from models.vos.metrics import evaluate_sequence, jaccard, summarize
from models.vos.target_features import FEATURE_NORMS
from models.vos.tracker import COMPONENTS

METHODS = ("davos", "davos_no_wta", "lwl", "frtm", "target_model_only", "first_frame_copy")
#: Methods of the FRTM system (``--ckpt``, or untrained).
FRTM_METHODS = ("frtm", "target_model_only")


def onnx_tracker(bundle: str) -> Callable[[], object]:
    """A factory of the runtime's tracker on ``bundle``, a VOS (FRTM) or DAVOS bundle (onnxruntime with torch's
    thread count); a bundle of another task is an ``InputError`` now, not at the first video."""
    from runtime.segmentation import segmentation_tracker_type

    tracker = segmentation_tracker_type(bundle)
    return lambda: tracker(bundle, threads=torch.get_num_threads())


def frame_curves(pred: torch.Tensor, labels: torch.Tensor) -> dict[str, dict[str, list[float]]]:
    """Per object of a sequence, per frame: J and the predicted and true object areas as fractions of the frame.

    Args:
        pred, labels: ``(T, H, W)`` label maps (``labels`` 255 = void, ignored by J).
    Returns:
        ``{object id: {"j": [T], "area": [T], "gt_area": [T]}}``; J is 1 where both masks are empty.
    """
    void = labels == 255
    curves = {}
    for obj in range(1, int(torch.where(void, 0, labels)[0].max()) + 1):
        p, g = pred == obj, labels == obj
        curves[str(obj)] = {"j": jaccard(p, g, void).tolist(), "area": p.flatten(1).double().mean(1).tolist(),
                            "gt_area": g.flatten(1).double().mean(1).tolist()}
    return curves


def run_method(make_tracker: Callable[[], object] | None, videos: list[tuple[str, torch.Tensor, torch.Tensor]],
               label: str = "", per_frame: bool = False) -> dict:
    """Segment ``videos`` (name, frames uint8, labels) with the trackers of ``make_tracker`` (None: the first mask
    copied); J&F statistics, FPS and ms/frame; ``per_frame`` adds each object's ``frame_curves`` under its
    per-sequence entry (key ``frames``). A progress bar named ``label`` goes to a terminal's stderr."""
    from tqdm import tqdm

    per_seq, curves, frames_total, seconds = {}, {}, 0, 0.0
    timings = dict.fromkeys(COMPONENTS, 0.0)
    for name, frames, labels in tqdm(videos, desc=label or "videos", unit="video", disable=None, leave=False):
        start = time.perf_counter()
        if make_tracker is None:
            pred = labels[:1].expand_as(labels).clone()
            pred[pred == 255] = 0
        else:
            tracker = make_tracker()
            pred = torch.stack([torch.as_tensor(p) for p in tracker.segment(frames, {0: labels[0]})])
            for k, v in tracker.timings.items():
                timings[k] = timings.get(k, 0.0) + v
        seconds += time.perf_counter() - start
        frames_total += frames.shape[0]
        per_seq[name] = evaluate_sequence(pred, labels)
        if per_frame:
            curves[name] = frame_curves(pred, labels)
    glob = summarize(per_seq)
    out = {"jf": glob["J&F-Mean"], "j": glob["J-Mean"], "f": glob["F-Mean"], "fps": frames_total / seconds}
    if make_tracker is not None:
        out["ms_per_frame"] = {k: v / frames_total for k, v in timings.items()}
    out["per_sequence"] = {name: {str(o): {"jf": s["J&F-Mean"], "j": s["J-Mean"], "f": s["F-Mean"]}
                                  for o, s in objects.items()} for name, objects in per_seq.items()}
    for name, objects in curves.items():
        for o, curve in objects.items():
            out["per_sequence"][name][o]["frames"] = curve
    return out


SPEED_SIZES = {"240p": (240, 427), "480p": (480, 854)}


def _speed_once(make_tracker: Callable[[], object], frames: torch.Tensor, labels: torch.Tensor) -> dict:
    tracker = make_tracker()
    wall, cpu = time.perf_counter(), time.process_time()
    list(tracker.segment(frames, {0: labels[0]}))
    wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
    n = frames.shape[0]
    per_frame = {k: v / n for k, v in tracker.timings.items()}
    steady = sum(v for k, v in per_frame.items() if k != "init")
    return {"fps": n / wall, "cpu_s_per_frame": cpu / n, "fps_after_init": 1000 / steady, "ms_per_frame": per_frame}


def speed(models: dict[str, Callable[[], object]], n_frames: int = 24, repeats: int = 2) -> dict:
    """Tracker FPS, process CPU seconds and ms/frame per component at 240p (240x427) and 480p (480x854) on a
    synthetic video of ``n_frames`` (first-frame init included; ``fps_after_init`` leaves it out), for each of
    ``models`` (name -> tracker factory, e.g. ``FRTMSegmentation.make_tracker``). The models take turns,
    ``repeats`` runs each after one warm-up, and the fastest run counts."""
    from data.vos.synthetic import synthetic_video

    out: dict[str, dict] = {name: {} for name in models}
    for res, (h, w) in SPEED_SIZES.items():
        frames, labels = synthetic_video(3, n_frames=n_frames, height=h, width=w)
        for make_tracker in models.values():  # warm-up (allocations, thread pools)
            list(make_tracker().segment(frames[:3], {0: labels[0]}))
        for _ in range(repeats):
            for name, make_tracker in models.items():
                run = _speed_once(make_tracker, frames, labels)
                if res not in out[name] or run["fps"] > out[name][res]["fps"]:
                    out[name][res] = run
    return out


def load_videos(args: argparse.Namespace) -> tuple[str, list[tuple[str, torch.Tensor, torch.Tensor]]]:
    if args.davis:
        names = args.sequences.split(",") if args.sequences else None
        where = f"{Path(args.davis).name}/{args.split}@{args.resolution}"
        if args.composites:
            seqs = davis_sequences(args.davis, args.split, args.resolution, names)
            return (f"composites:{args.composites} of davis:{where}",
                    held_out_composites(seqs, args.composites, max_frames=args.max_frames))
        return f"davis:{where}", load_davis_videos(args.davis, args.split, args.resolution, names, args.max_frames)
    if args.composites:
        raise InputError("--composites are made from DAVIS sequences: give --davis too")
    if args.lookalike:
        h, w, n = args.height or 240, args.width or 427, args.objects or 3
        return (f"lookalike:{args.videos}x{h}x{w} objects {n}",
                lookalike_videos(args.videos, n_frames=args.max_frames or 40, height=h, width=w, n_objects=n))
    given = {"height": args.height, "width": args.width, "n_objects": args.objects,
             "n_distractors": args.distractors, "object_scale": args.object_scale}
    v = synthetic_test_settings(args.ckpt, **given)
    videos = checkpoint_test_videos(args.ckpt, args.videos, args.max_frames or 20, **given)
    name = (f"synthetic:{args.videos}x{v['height']}x{v['width']} objects {v['n_objects']} distractors "
            f"{v['n_distractors']} object_scale {list(v['object_scale'])}")
    return name, videos


def parse_extra(items: list[str] | None) -> dict[str, str]:
    """``["davos_hard_loss=a.ckpt"]`` -> ``{"davos_hard_loss": "a.ckpt"}``."""
    out = {}
    for item in items or []:
        name, sep, path = item.partition("=")
        if not sep or not name or not path or name in METHODS:
            raise InputError(f"--extra item {item!r} is not NAME=CKPT with a new method name")
        out[name] = path
    return out


def frtm_model(args: argparse.Namespace) -> FRTMSegmentation:
    """The FRTM system of ``--ckpt`` (its tracker settings overridden by ``--tracker``) or an untrained one."""
    tracker = parse_tracker(args.tracker)
    weights = None if args.weights in (None, "none") else args.weights
    untrained = {} if args.ckpt else {"backbone": args.backbone, "weights": weights, "tracker": tracker,
                                      "feature_layer": args.feature_layer, "feature_norm": args.feature_norm,
                                      "feature_scale": args.feature_scale}
    model = frtm_system(args.ckpt, **untrained)
    if args.ckpt and tracker:  # the checkpoint's tracker settings, overridden
        model.hparams.tracker = {**(model.hparams.tracker or {}), **tracker}
    return model


def trackers(args: argparse.Namespace, methods: list[str]) -> tuple[dict[str, Callable | None], dict]:
    """Tracker factories of ``methods`` (None for ``first_frame_copy``) and a description of the models used."""
    davos = parse_tracker(args.davos_tracker, "--davos-tracker")
    ckpts = {"davos": args.davos_ckpt, "davos_no_wta": args.davos_ckpt, "lwl": args.lwl_ckpt,
             **parse_extra(args.extra)}
    out: dict[str, Callable | None] = {}
    info: dict = {"checkpoints": {}}
    frtm = None
    for method in methods:
        if method == "first_frame_copy":
            out[method] = None
        elif method in FRTM_METHODS:
            frtm = frtm or frtm_model(args)
            out[method] = lambda use=method == "frtm", m=frtm: m.make_tracker(use_decoder=use)
            info["checkpoints"][method] = args.ckpt
        else:
            if not ckpts.get(method):
                flag = "--davos-ckpt" if method.startswith("davos") else "--lwl-ckpt"
                raise InputError(f"method {method} needs a checkpoint ({flag}, or --extra {method}=CKPT)")
            system = davos_system(ckpts[method])
            settings = {**davos, **({"winner_takes_all": False} if method == "davos_no_wta" else {})}
            system.tracker_settings(**settings)  # a bad setting fails before any video runs
            out[method] = lambda m=system, kw=settings: m.make_tracker(**kw)
            info["checkpoints"][method] = ckpts[method]
    if frtm is not None:
        h = frtm.hparams
        info["frtm"] = {"backbone": h.backbone, "weights": h.weights, "feature_layer": h.feature_layer,
                        "feature_norm": h.feature_norm, "feature_scale": h.feature_scale, "tracker": h.tracker}
    return out, info


def default_methods(args: argparse.Namespace) -> list[str]:
    """Every method the given checkpoints allow (FRTM's always: untrained without ``--ckpt``)."""
    methods = [m for m, given in (("davos", args.davos_ckpt), ("davos_no_wta", args.davos_ckpt),
                                  ("lwl", args.lwl_ckpt)) if given]
    return [*methods, *parse_extra(args.extra), "frtm", "target_model_only", "first_frame_copy"]


def run(args: argparse.Namespace) -> dict:
    extra = parse_extra(args.extra)
    methods = args.methods.split(",") if args.methods else default_methods(args)
    unknown = [m for m in methods if m not in METHODS and m not in extra]
    if unknown:
        raise InputError(f"--methods names {unknown}, not one of {', '.join([*METHODS, *extra])}")
    factories, info = trackers(args, methods)
    result: dict = {**info, "threads": torch.get_num_threads(), "methods": {}}
    bundles = {f"onnx:{Path(b).name}": b for b in args.onnx or []}
    factories.update({name: onnx_tracker(b) for name, b in bundles.items()})
    if args.davis or args.synthetic or args.lookalike or not args.speed:
        result["dataset"], videos = load_videos(args)
        for method, make_tracker in factories.items():
            result["methods"][method] = run_method(make_tracker, videos, method, args.per_frame)
    if args.speed:
        models = {name: f for name, f in factories.items() if f is not None and name != "target_model_only"}
        models.update({Path(c).stem: frtm_system(config=c).make_tracker for c in args.speed_config or []})
        result["speed"] = speed(models, args.speed_frames)
    return result


def print_table(result: dict) -> None:
    ckpts = ", ".join(f"{m} {c or 'untrained'}" for m, c in result["checkpoints"].items())
    print(f"dataset {result.get('dataset', '-')}; checkpoints: {ckpts or '-'}")
    print(f"{'method':<20}{'J&F':>7}{'J':>7}{'F':>7}{'FPS':>10}  ms/frame " + " ".join(COMPONENTS))
    for name, m in result["methods"].items():
        ms = " ".join(f"{m['ms_per_frame'][k]:.0f}" for k in COMPONENTS) if "ms_per_frame" in m else "-"
        print(f"{name:<20}{100 * m['jf']:7.1f}{100 * m['j']:7.1f}{100 * m['f']:7.1f}{m['fps']:10.2f}  {ms}")
    for name, sizes in result.get("speed", {}).items():
        for res, s in sizes.items():
            ms = " ".join(f"{k} {v:.0f}" for k, v in s["ms_per_frame"].items())
            print(f"speed {name} {res}: {s['fps']:.2f} FPS ({s['fps_after_init']:.2f} after init); ms/frame {ms}")


def plot(result: dict, path: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = list(result["methods"])
    fig, ax = plt.subplots(figsize=(5, 3.5))
    for n in names:
        m = result["methods"][n]
        ax.scatter(m["fps"], 100 * m["jf"], label=n)
    ax.set_xscale("log")
    ax.set_xlabel("frames per second")
    ax.set_ylabel("J&F (%)")
    ax.set_title(result.get("dataset", "FRTM"))
    ax.legend()
    fig.tight_layout()
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120)


def plot_frames(result: dict, path: str) -> None:
    """Per-frame curves of a ``--per-frame`` run: one row per sequence and object, J on the left, predicted areas
    (and the true area, dashed) on the right, one colour per method."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    curves: dict[tuple[str, str], dict[str, dict]] = {}
    for method, m in result["methods"].items():
        for name, objects in m["per_sequence"].items():
            for obj, stats in objects.items():
                curves.setdefault((name, obj), {})[method] = stats["frames"]
    if not curves:
        raise InputError("--plot-frames needs videos to segment (--davis, --synthetic or --lookalike)")
    fig, axes = plt.subplots(len(curves), 2, figsize=(9, 2.4 * len(curves)), squeeze=False)
    for (j_ax, area_ax), ((name, obj), methods) in zip(axes, curves.items(), strict=True):
        for i, (method, frames) in enumerate(methods.items()):
            colour = f"C{i}"
            j_ax.plot(frames["j"], color=colour, label=method)
            area_ax.plot(frames["area"], color=colour)
        area_ax.plot(frames["gt_area"], "k--", label="ground truth")
        j_ax.set_ylim(0, 1.02)
        j_ax.set_ylabel(f"{name} #{obj}\nJ")
        area_ax.set_ylabel("area (frame fraction)")
    axes[0, 0].legend(fontsize="small")
    axes[0, 1].legend(fontsize="small")
    axes[-1, 0].set_xlabel("frame")
    axes[-1, 1].set_xlabel("frame")
    fig.tight_layout()
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=100)
    plt.close(fig)


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--ckpt", help="FRTMSegmentation checkpoint (default: untrained networks)")
    p.add_argument("--davos-ckpt", help="DAVOSSegmentation checkpoint with a distractor channel (methods davos, "
                   "davos_no_wta)")
    p.add_argument("--lwl-ckpt", help="DAVOSSegmentation checkpoint without a distractor channel (method lwl)")
    p.add_argument("--extra", nargs="+", action="extend", metavar="NAME=CKPT",
                   help="more DAVOSSegmentation checkpoints as methods NAME, e.g. davos_hard_loss=CKPT")
    p.add_argument("--davos-tracker", nargs="+", metavar="KEY=JSON",
                   help="tracker settings over the DAVOS-family checkpoints', e.g. update_iters=3 memory_size=16")
    p.add_argument("--davis", help="DAVIS root, e.g. ../shared/data/davis2016")
    p.add_argument("--split", default="val", help="ImageSets split name (default val)")
    p.add_argument("--resolution", default="480p", help="resolution folder (default 480p)")
    p.add_argument("--sequences", help="comma-separated subset of the split's sequences")
    p.add_argument("--composites", choices=sorted(EVAL_SETS),
                   help="with --davis: held-out multi-object composites of the sequences instead of the sequences")
    p.add_argument("--synthetic", action="store_true", help="held-out synthetic videos (the default dataset)")
    p.add_argument("--lookalike", action="store_true",
                   help="held-out synthetic look-alike videos (240x427, 3 labelled look-alikes, 40 frames by default)")
    p.add_argument("--videos", type=int, default=8, help="synthetic videos (default 8)")
    p.add_argument("--height", type=int, help="synthetic frame height (default: checkpoint's data, else 96)")
    p.add_argument("--width", type=int, help="synthetic frame width (default: checkpoint's data, else 160)")
    p.add_argument("--objects", type=int, help="objects per synthetic video (default: checkpoint's data, else 2)")
    p.add_argument("--distractors", type=int, help="distractors per synthetic video (checkpoint's data, else 1)")
    p.add_argument("--object-scale", type=float, nargs=2, metavar=("LOW", "HIGH"),
                   help="object radius range as a fraction of the short side (checkpoint's data, else 0.15 0.3)")
    p.add_argument("--max-frames", type=int, help="cut videos to this many frames")
    p.add_argument("--backbone", default="resnet18", help="backbone of the untrained model (no --ckpt): resnet18 .. "
                   "resnet152, efficientnet_lite0 .. efficientnet_lite2")
    p.add_argument("--weights", help="backbone weights of the untrained model: imagenet, a torchvision name, or "
                   "none (default)")
    p.add_argument("--feature-layer", default="layer3",
                   help="target-model stage(s) of the untrained model: layer3 (default), layer2, layer2+layer3, ...")
    p.add_argument("--feature-norm", default="none", choices=FEATURE_NORMS,
                   help="target-model feature scaling of the untrained model (none)")
    p.add_argument("--feature-scale", type=float, default=1.0,
                   help="with --feature-norm fixed: divide the target-model features by this (default 1)")
    p.add_argument("--tracker", nargs="+", metavar="KEY=JSON",
                   help="tracker settings over the model's, e.g. channels=32 memory_size=20 'update_schedule=[5]'")
    p.add_argument("--methods", help=f"comma-separated subset of {','.join(METHODS)} and the --extra names (default: "
                   "all the given checkpoints allow)")
    p.add_argument("--speed", action="store_true", help="measure FPS at 240p and 480p")
    p.add_argument("--speed-config", nargs="+", action="extend", metavar="YAML",
                   help="with --speed: also time the (untrained) models of these train.py configs, in the same run")
    p.add_argument("--speed-frames", type=int, default=24, help="frames of the --speed video (default 24)")
    p.add_argument("--onnx", nargs="+", action="extend", metavar="BUNDLE",
                   help="also run these VOS or DAVOS bundles in the deployment runtime (methods onnx:<folder>)")
    p.add_argument("--threads", type=int, help="torch intra-op threads (1 is much faster on an oversubscribed CPU)")
    p.add_argument("--per-frame", action="store_true",
                   help="also give each object's per-frame J and predicted / true area (fraction of the frame)")
    p.add_argument("--plot-frames", metavar="PNG",
                   help="write the per-frame J and area curves of every sequence as a PNG (implies --per-frame)")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.add_argument("--plot", help="write a J&F-vs-FPS PNG")
    args = p.parse_args(argv)
    args.per_frame = args.per_frame or bool(args.plot_frames)
    return args


def plot_masks(factories: dict[str, Callable | None], video: tuple[str, torch.Tensor, torch.Tensor],
               path: str | Path, columns: int = 6) -> None:
    """Mask outlines of every method (name -> tracker factory, None for the first mask copied) over ``columns``
    frames of one video (one colour per object), ground truth in the first row."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    name, frames, labels = video
    rows = {"ground truth": labels.clamp(0, 254)}
    for method, make_tracker in factories.items():
        if make_tracker is None:
            rows[method] = labels[:1].expand_as(labels).clamp(0, 254)
        else:
            rows[method] = torch.stack(list(make_tracker().segment(frames, {0: labels[0]})))
    times = torch.linspace(0, frames.shape[0] - 1, columns).round().long().tolist()
    ids = [k for k in labels[0].unique().tolist() if 0 < k < 255]
    outline = ["yellow", "cyan", "magenta", "orange"]
    fig, axes = plt.subplots(len(rows), columns, figsize=(1.9 * columns, 1.3 * len(rows)), squeeze=False)
    for r, (method, masks) in enumerate(rows.items()):
        for c, t in enumerate(times):
            axes[r, c].imshow(frames[t].permute(1, 2, 0).numpy())
            for i, k in enumerate(ids):  # each object's outline in its own colour
                if (masks[t] == k).any():
                    axes[r, c].contour((masks[t] == k).numpy(), levels=[0.5], colors=[outline[i % len(outline)]],
                                       linewidths=1.3)
            axes[r, c].set_xticks([])
            axes[r, c].set_yticks([])
            if c == 0:
                axes[r, c].set_ylabel(method.replace("_", " "), fontsize=7)
            if r == 0:
                axes[r, c].set_title(f"frame {t}", fontsize=7)
    fig.suptitle(f"{name}: masks over the video", fontsize=8)
    fig.tight_layout()
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def demo(report_dir: Path | None = None, quick: bool = False, height: int = 96, width: int = 160) -> list:
    """Small train-and-segment run on synthetic videos, as in the paper: the frozen ImageNet EfficientNet-Lite0
    backbone (the target model on its stride-8 stage), a small decoder trained for 400 steps (50 quick; stopped
    after 300 s on a slow machine) with the target model in the loop (train.py's loop), then the three methods on
    2 held-out videos of ``height`` x ``width`` px; prints the table. With ``report_dir``, writes the masks over
    the frames and J&F against speed there; returns the figures. ``configs/frtm_lite0_davis2016_cpu.yaml`` is the
    real CPU training."""
    import lightning as L

    from data.vos.datamodule import SyntheticVOSDataModule

    steps, limit_s = (50, 60.0) if quick else (400, 300.0)  # fixed steps: the same model on every run
    torch.manual_seed(0)
    model = FRTMSegmentation(backbone="efficientnet_lite0", weights="imagenet", feature_layer="layer2",
                             feature_norm="instance_l2", mdim=16, train_channels=16, train_num_aug=2,
                             train_schedule=(3, 5), loss="bce_iou", amsgrad=False,
                             tracker={"channels": 16, "num_aug": 3, "memory_size": 10, "init_schedule": [3, 5],
                                      "update_schedule": [5], "update_every": 4})
    data = SyntheticVOSDataModule(train_samples=4096, height=height, width=width, batch_size=4, max_gap=4,
                                  n_objects=2, n_distractors=0, object_scale=(0.25, 0.45))
    trainer = L.Trainer(accelerator="cpu", max_steps=steps, max_time={"seconds": limit_s}, logger=False,
                        enable_checkpointing=False, enable_progress_bar=False, enable_model_summary=False,
                        limit_val_batches=0)
    trainer.fit(model, datamodule=data)
    print(f"trained the decoder {trainer.global_step} steps on the frozen ImageNet EfficientNet-Lite0 (batch 4; "
          f"at most {limit_s:.0f} s)")
    args = parse_args(["--videos", "2", "--max-frames", "8" if quick else "12", "--height", str(height), "--width",
                       str(width), "--objects", "2", "--distractors", "0", "--object-scale", "0.25", "0.45"])
    _, videos = load_videos(args)
    model.eval()
    factories = {"frtm": model.make_tracker, "target_model_only": lambda: model.make_tracker(use_decoder=False),
                 "first_frame_copy": None}
    result = {"dataset": f"synthetic:2x{height}x{width}", "checkpoints": dict.fromkeys(factories, "demo (in memory)"),
              "methods": {m: run_method(f, videos) for m, f in factories.items()}}
    print_table(result)
    if report_dir is None:
        return []
    plot_masks(factories, videos[0], report_dir / "vos_masks.png")
    plot(result, str(report_dir / "vos_speed.png"))
    return [("vos_masks.png", "FRTM on a held-out synthetic video: the first-frame mask is given; frtm (target model "
             "+ decoder), the target model alone and the first mask copied, over the frames"),
            ("vos_speed.png", "J&F against frames per second of the three methods (same run)")]


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    if args.threads:
        set_cpu_threads(args.threads)
    try:
        result = run(args)
        if args.plot_frames:
            plot_frames(result, args.plot_frames)
    except InputError as err:
        print(f"bench/vos.py: error: {err}", file=sys.stderr)
        return 2
    if args.plot:
        plot(result, args.plot)
    if args.json:
        print(json.dumps(result, indent=1))
    else:
        print_table(result)
    return 0


if __name__ == "__main__":
    sys.exit(main())
