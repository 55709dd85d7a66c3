"""DAVOS (and LWL) online inference over a video (thesis ch. 6; paper E).

A new object gets its label [target, distractor] (the distractor: every other labelled object of the frame),
its encoding E(y), W(y) and a zero filter trained by ``init_iters`` steepest-descent steps on that one sample,
which starts its memory (no first-frame augmentation). Every frame then: backbone -> target-model features ->
per object scores tau_i * x -> decoder -> target and distractor logits -> soft aggregation of the target
logits over objects -> labels. Each object's memory label is its merged target probability and its
regenerated distractor map (eqs. 6.1-6.5, ``regenerate_distractors``), encoded and inserted with the frame's
features; the filters are re-trained by ``update_iters`` steps every ``update_every`` frames.
"""

from __future__ import annotations

import torch
from torch import nn

from models.vos.davos_net import DAVOSNet
from models.vos.davos_settings import DAVOSSettings
from models.vos.distractors import first_frame_distractors, regenerate_distractors
from models.vos.memory import Memory, memory_init, memory_insert
from models.vos.merge import soft_aggregate
from models.vos.video_loop import VideoLoop

COMPONENTS = ("backbone", "target_model", "decoder", "update", "init")


class DAVOSTracker(nn.Module, VideoLoop):
    """Video object segmentation with a meta-learnt target model and distractor channel, in PyTorch.

    Args:
        net: the trained networks (``DAVOSNet``; one label channel = LWL).
        settings: ``DAVOSSettings`` (default: the paper's inference settings).

    Attributes:
        distractors: (N, H, W) distractor maps regenerated at the last frame (None before the second frame or
            for an LWL network), for overlays.
    """

    def __init__(self, net: DAVOSNet, settings: DAVOSSettings | None = None) -> None:
        nn.Module.__init__(self)
        self.net = net
        self.settings = settings or DAVOSSettings()
        VideoLoop.__init__(self)

    def reset(self) -> None:
        """Forget the current video."""
        super().reset()
        self.tau: torch.Tensor | None = None
        self.memory: Memory | None = None
        self.distractors: torch.Tensor | None = None

    def distractor_maps(self, size: tuple[int, int]) -> torch.Tensor | None:
        """The distractor maps (N, H, W) regenerated at the last frame (zeros at the first), None for LWL."""
        if self.net.label_channels == 1:
            return None
        maps = torch.zeros(len(self.ids), *size)
        if self.distractors is not None:  # objects added at this frame have none yet
            maps[: self.distractors.shape[0]] = self.distractors.cpu()
        return maps

    def _labels(self, target: torch.Tensor, distractor: torch.Tensor) -> torch.Tensor:
        """Label channels (N, L, H, W) of the network from target and distractor maps (N, H, W)."""
        if self.net.label_channels == 1:
            return target[:, None]
        if not self.settings.use_distractors:
            distractor = torch.zeros_like(distractor)
        return torch.stack([target, distractor], 1)

    def _train(self, iters: int) -> None:
        mem = self.memory
        n = int((mem.weights > 0).sum(1).max())
        self.tau, _ = self.net.optimizer(self.tau, mem.features[:, :n], mem.labels[:, :n], mem.pixel_weights[:, :n],
                                         mem.weights[:, :n], iters)

    def add_objects(self, image: torch.Tensor, labels: torch.Tensor, ids: list[int]) -> None:
        """Train filters for new objects ``ids`` (masks ``labels == id``; the other labelled objects of ``labels``
        are their first distractors) and start their memories.

        Args:
            image: (3, H, W) RGB in [0, 1]; labels: (H, W) int label map.
        """
        device = image.device
        start = self._tic(device)
        ids_t = torch.tensor(ids, device=labels.device)
        target = (labels[None] == ids_t[:, None, None]).to(image.dtype)
        feats, x = self.net.features(image[None])
        encodings, weights = self.net.encode(self._labels(target, first_frame_distractors(labels, ids_t)),
                                             x.shape[-2:])
        n = len(ids)
        xs = x.expand(n, -1, -1, -1)[:, None]
        tau0 = self.net.initial_filter(n, x)
        tau, _ = self.net.optimizer(tau0, xs, encodings[:, None], weights[:, None], x.new_ones(n, 1),
                                    self.settings.init_iters)
        memory = memory_init(xs, encodings[:, None], weights[:, None], self.settings.memory_size, first_weight=1.0)
        if self.ids:
            memory = Memory(*(torch.cat([a, b], 0) for a, b in zip(self.memory, memory, strict=True)))
            tau = torch.cat([self.tau, tau])
        self.ids += list(ids)
        self.tau, self.memory = tau, memory
        self._toc("init", start, device)

    def step(self, image: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """Segment one frame (3, H, W): labels (H, W), memory labels (N, L, H, W), features (1, P, h, w)."""
        device = image.device
        start = self._tic(device)
        feats = self.net.stages(image[None])
        self._toc("backbone", start, device)
        start = self._tic(device)
        x = self.net.target_features(feats)
        scores = self.net.frame_scores(self.tau, x)
        self._toc("target_model", start, device)
        start = self._tic(device)
        logits = self.net.decode(scores, feats, tuple(image.shape[-2:]))
        self._toc("decoder", start, device)
        merged = soft_aggregate(logits[:, 0])
        ids = torch.tensor(self.ids, device=device)
        labels = torch.cat([ids.new_zeros(1), ids])[merged.argmax(0)]
        target = merged[1:]
        distractor = torch.zeros_like(target)
        if self.net.label_channels == 2:
            distractor = regenerate_distractors(torch.sigmoid(logits[:, 0]), labels, ids,
                                                self.settings.winner_takes_all)
            self.distractors = distractor
        return labels, self._labels(target, distractor), x

    def update(self, memory_labels: torch.Tensor, features: torch.Tensor) -> None:
        """Encode the memory labels (N, L, H, W), insert them with the frame's features (1, P, h, w), and re-train
        the filters every ``update_every`` frames."""
        device = features.device
        start = self._tic(device)
        s = self.settings
        encodings, weights = self.net.encode(memory_labels, features.shape[-2:])
        n = memory_labels.shape[0]
        valid = torch.ones(n, dtype=torch.bool, device=device)
        self.memory = memory_insert(self.memory, features.expand(n, -1, -1, -1), encodings, weights, valid,
                                    s.learning_rate, s.keep_first)
        if self.frame % s.update_every == 0 and s.update_iters > 0:
            self._train(s.update_iters)
        self._toc("update", start, device)
