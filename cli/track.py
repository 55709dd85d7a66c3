"""``infer.py track``: many points through a gray video with correlation filters or KLT (thesis ch. 3)."""

from __future__ import annotations

import argparse
from pathlib import Path

NAME = "track"
HELP = "Track points through gray frames with correlation filters (or KLT) and save the tracks."


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--frames", required=True,
                   help="folder of frames (sorted by name), a glob like 'clip/*.png' or a video file "
                   "like clip.mp4 (decoded by OpenCV)")
    start = p.add_mutually_exclusive_group(required=True)
    start.add_argument("--points", help="start points in the first frame: .npy/.npz (P, 2) or text 'x y' lines")
    start.add_argument("--detect", type=int, help="detect this many good features to track in the first frame "
                       "(OpenCV's Shi-Tomasi corners, quality 0.01, 5 px apart; the same with --onnx)")
    p.add_argument("--method", default="ccot", choices=("ccot", "ccot_ff", "mosse", "klt"),
                   help="DCF variant, or klt = OpenCV pyramidal Lucas-Kanade (default: ccot)")
    p.add_argument("--onnx", metavar="DIR", help="track with this tracking bundle in the torch-free runtime "
                   "(runtime.tracking; its method, the same --detect points) instead of PyTorch")
    p.add_argument("--out", required=True, help="output .npz with tracks (T, P, 2), lost (T, P), psr (T, P)")
    p.add_argument("--video", help="also write an overlay video (.mp4)")
    p.add_argument("--device", default="cpu", help="torch device for the DCF methods (default: cpu)")
    p.add_argument("--threads", type=int, default=1,
                   help="CPU threads for torch and OpenCV (default 1: fastest for many small filters)")
    p.add_argument("--compile", action="store_true",
                   help="run the DCF step through torch.compile: faster per frame, about a minute to compile")


def run(args: argparse.Namespace) -> int:
    import time

    import numpy as np

    from core.allocator import retain_freed_memory
    from core.files import writable_folder, write_npz
    from core.frames import read_frames, read_points
    from core.threads import cpu_threads
    from models.tracking.overlay import write_overlay_video
    from models.tracking.run import track_points

    if args.onnx:
        from runtime.tracking import track_files

        message, result = track_files(args.onnx, args.frames, args.out, args.points, args.detect, args.threads,
                                      progress=True)
        if args.video:
            write_overlay_video(args.video, read_frames(args.frames)[0], result["tracks"], result["lost"])
        print(message + (f" and {args.video}" if args.video else ""))
        return 0
    frames, paths = read_frames(args.frames)
    points = read_points(args.points) if args.points else None
    writable_folder(Path(args.out).parent)  # an unwritable output fails before the tracking, not after it
    retain_freed_memory()  # the step's large temporaries are reused, not faulted in again every frame
    start = time.perf_counter()
    with cpu_threads(args.threads):
        result = track_points(frames, points, args.detect, args.method, args.device, progress=True,
                              compile=args.compile)
    seconds = time.perf_counter() - start
    done = result.pop("frame_seconds")  # timings are printed, not stored: the tracks file stays deterministic
    write_npz(args.out, compress=False, method=np.array(args.method), frames=np.array([str(p) for p in paths]),
              **result)
    if args.video:
        write_overlay_video(args.video, frames, result["tracks"], result["lost"])
    n_frames, n_points = result["lost"].shape
    lost = int(result["lost"][-1].sum())
    timing = ""
    if n_frames > 2 and np.isfinite(done).all():  # first call (construction, filters, first step), then steady
        timing = (f"; first frame pair {done[1]:.2f} s, then {n_points * (n_frames - 2) / (done[-1] - done[1]):.0f}"
                  " point-frames/s")
    print(f"{args.method}: {n_points} points through {n_frames} frames in {seconds:.1f} s "
          f"({n_points * max(n_frames - 1, 1) / seconds:.0f} point-frames/s{timing}), {lost} lost at the end; "
          f"wrote {args.out}" + (f" and {args.video}" if args.video else ""))
    return 0
