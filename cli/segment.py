"""``infer.py segment``: video object segmentation (FRTM, thesis ch. 5; LWL/DAVOS, ch. 6) of a folder of frames or a
DAVIS split."""

from __future__ import annotations

import argparse
from pathlib import Path

from core.errors import InputError

NAME = "segment"
HELP = "Segment objects through a video from a first-frame mask (FRTM or DAVOS), or a DAVIS split with J&F."


def add_arguments(p: argparse.ArgumentParser) -> None:
    src = p.add_argument_group("input: one video folder or a whole DAVIS split")
    src.add_argument("--video", help="folder of frames (sorted by name)")
    src.add_argument("--mask", help="first-frame mask PNG (palette ids, any of 1..254, or binary gray = object 1)")
    src.add_argument("--annotations", help="with --video: folder of later masks named after frames (00040.png); "
                     "objects with a new id start at their first one")
    src.add_argument("--davis", help="DAVIS root; segments and scores every sequence of --split (a rerun into the "
                     "same --out resumes after the last finished sequence)")
    src.add_argument("--split", default="val", help="DAVIS ImageSets split (default val)")
    src.add_argument("--resolution", default="480p", help="DAVIS resolution folder (default 480p)")
    src.add_argument("--max-frames", type=int, help="cut the video, or each DAVIS sequence, to this many frames")
    model = p.add_argument_group("model: exactly one")
    model.add_argument("--ckpt", help="FRTMSegmentation or DAVOSSegmentation checkpoint from train.py (DAVOS overlays "
                       "show the regenerated distractor maps beside the masks)")
    model.add_argument("--onnx", help="a VOS bundle (python -m export.vos_onnx or export.davos_onnx), run by the "
                       "torch-free runtime (runtime.vos, runtime.davos)")
    p.add_argument("--out", required=True, help="output folder for palette PNG masks")
    p.add_argument("--overlay", help="also write an overlay video (e.g. out.mp4)")


def run(args: argparse.Namespace) -> int:
    import json

    from models.builders import vos_tracker
    from models.vos.inference import check_first_frame, segment_davis, segment_folder

    if args.davis is None and (args.video is None or args.mask is None):
        raise InputError("give --video DIR --mask FIRST.png, or --davis ROOT --split NAME")
    if (args.ckpt is None) == (args.onnx is None):
        raise InputError("give exactly one of --ckpt CKPT or --onnx DIR")
    if args.onnx and (args.overlay or args.annotations):
        raise InputError("--overlay and --annotations need --ckpt (the runtime tracks the first mask's objects)")
    if args.max_frames is not None and args.max_frames < 1:
        raise InputError(f"--max-frames must be at least 1, got {args.max_frames}")
    if args.davis is None:
        if args.onnx:
            from runtime.segmentation import segmentation_tracker
            from runtime.video_loop import segment_folder as runtime_segment_folder

            n, seconds = runtime_segment_folder(segmentation_tracker(args.onnx), args.video, args.mask, args.out,
                                                progress=True, max_frames=args.max_frames)
            print(f"segmented {n} frames in {seconds:.1f} s ({n / seconds:.2f} FPS, onnxruntime); masks in {args.out}")
            return 0
        from data.vos.io import list_frames

        check_first_frame(list_frames(args.video), args.mask)  # bad input fails before the model loads
        tracker = vos_tracker(args.ckpt)
        n, seconds = segment_folder(tracker, args.video, args.mask, args.out, args.overlay,
                                    annotations=args.annotations, max_frames=args.max_frames)
        print(f"segmented {n} frames in {seconds:.1f} s ({n / seconds:.2f} FPS); masks in {args.out}")
        return 0
    if args.onnx:
        from runtime.segmentation import segmentation_tracker

        tracker = segmentation_tracker(args.onnx)
    else:
        tracker = vos_tracker(args.ckpt)
    job = {"model": str(Path(args.ckpt or args.onnx).resolve())}
    result, fps = segment_davis(tracker, args.davis, args.split, args.resolution, args.out, args.max_frames, job)
    print(json.dumps({"J&F": result["J&F-Mean"], "J": result["J-Mean"], "F": result["F-Mean"], "FPS": fps}))
    return 0


