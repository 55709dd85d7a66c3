"""Mask parity of a deployment bundle: its runtime tracker against the PyTorch tracker it was exported from."""

from __future__ import annotations

import torch

from models.vos.video_loop import VideoLoop
from runtime.video_loop import NumpyVideoLoop


def mask_parity(tracker: VideoLoop, runtime: NumpyVideoLoop, videos: list[tuple[str, torch.Tensor, torch.Tensor]]
                ) -> list[float]:
    """Per frame and object IoU between the PyTorch tracker's and the runtime's masks on videos (name, frames
    uint8, labels), each run closed loop (own memory and filter updates) from the first-frame labels; frames where
    neither segments the object are skipped (IoU undefined)."""
    ious = []
    for _, frames, labels in videos:
        ids = [i for i in labels[0].unique().tolist() if i not in (0, 255)]
        ref = [a.numpy() for a in tracker.segment(frames, {0: labels[0]})]
        got = list(runtime.segment(frames.numpy(), {0: labels[0].numpy()}))
        for a, b in zip(ref, got, strict=True):
            for k in ids:
                union = int(((a == k) | (b == k)).sum())
                if union:
                    ious.append(int(((a == k) & (b == k)).sum()) / union)
    return ious
