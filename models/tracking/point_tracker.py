"""Batched DCF point tracker (thesis 3.4, paper B): one small gray-pixel correlation filter per point and
pyramid level, searched coarse to fine.

Per frame: build a 3-level pyramid; from the coarsest level down, extract every point's patch at its current
estimate (one ``grid_sample`` call for all points), correlate with that level's filter, find the peak (Newton
on the Fourier series for C-COT, grid peak plus parabola for MOSSE) and add the scaled shift. Points whose
level-0 PSR falls below a threshold or that leave the image are flagged lost and frozen at their last
position. Then the filters of the points still tracked learn, with weight ``eta``, a sample at the new position
(the coarsest level extracts it again; finer levels shift their search samples in the Fourier domain).

Variants: ``ccot`` (continuous filter, exponentially decaying sample weights = a sample memory), ``ccot_ff``
(continuous filter retrained from the newest sample only, ``eta = 1``) and ``mosse``. A level-``l`` pixel
``i`` sits at level-0 coordinate ``2^l (i + 0.5) - 0.5`` (``kornia`` ``pyrdown``). Positions are (x, y)
pixels.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np
import torch
import torch.nn.functional as F
from kornia.geometry.transform import pyrdown
from torch import Tensor, nn
from tqdm import tqdm

from data.errors import InputError
from models.dcf import (
    ccot_filter,
    ccot_sample,
    ccot_update,
    continuous_label,
    dcf_preprocess,
    fourier_series_peak,
    gaussian_label,
    mosse_filter,
    peak_to_sidelobe_ratio,
    response_peak,
    shift_fourier,
)

METHODS = ("ccot", "ccot_ff", "mosse")
DEFAULT_ETA = {"ccot": 0.1, "ccot_ff": 1.0, "mosse": 0.125}


def image_pyramid(frame: Tensor, levels: int) -> list[Tensor]:
    """``levels`` images ``(1, 1, H / 2^l, W / 2^l)`` of a ``(1, 1, H, W)`` frame, finest first."""
    pyramid = [frame]
    for _ in range(levels - 1):
        pyramid.append(pyrdown(pyramid[-1]))
    return pyramid


def extract_patches(image: Tensor, centres: Tensor, size: int) -> Tensor:
    """Bilinear ``size x size`` patches around sub-pixel centres, in FFT order (centre pixel at index 0).

    Args:
        image: ``(1, 1, h, w)``; centres: ``(P, 2)`` (x, y) pixels of that image (border pixels repeat
        outside).
    Returns:
        ``(P, size, size)`` patches.
    """
    h, w = image.shape[-2:]
    off = torch.arange(size, device=centres.device, dtype=centres.dtype)
    off = torch.remainder(off + size // 2, size) - size // 2
    gx = (2 * (centres[:, 0, None, None] + off[None, None, :]) + 1) / w - 1
    gy = (2 * (centres[:, 1, None, None] + off[None, :, None]) + 1) / h - 1
    grid = torch.stack([gx.expand(-1, size, size), gy.expand(-1, size, size)], -1)
    patches = F.grid_sample(
        image, grid.reshape(1, -1, size, 2), mode="bilinear", padding_mode="border", align_corners=False
    )
    return patches.reshape(-1, size, size)


@dataclass
class TrackerState:
    """Tracker state: positions ``(P, 2)``, lost ``(P,)`` bool, last PSR ``(P,)`` and the filters' numerators
    ``A`` ``(L, P, N, N // 2 + 1)`` complex and denominators ``B`` (same shape, real)."""

    positions: Tensor
    lost: Tensor
    psr: Tensor
    A: Tensor
    B: Tensor


class PointTracker(nn.Module):
    """Batched DCF point tracker.

    Args:
        method: ``ccot``, ``ccot_ff`` or ``mosse``.
        levels: pyramid levels (coarse-to-fine search). patch_size: odd patch side per level (px of that
        level).
        sigma: label std in px of each level. eta: learning rate (default per method: 0.1, 1.0, 0.125).
        reg_rel: regulariser relative to the mean sample energy (``beta^2`` / ``eps``).
        newton_iterations: sub-pixel steps for the continuous variants.
        psr_threshold: points whose level-0 PSR falls below this are lost. psr_exclude: PSR exclusion window.
    """

    def __init__(
        self,
        method: str = "ccot",
        levels: int = 3,
        patch_size: int = 33,
        sigma: float = 1.0,
        eta: float | None = None,
        reg_rel: float = 1e-2,
        newton_iterations: int = 5,
        psr_threshold: float = 5.0,
        psr_exclude: int = 7,
    ) -> None:
        super().__init__()
        if method not in METHODS:
            raise InputError(f"unknown tracking method {method!r}; choose one of {', '.join(METHODS)}")
        if patch_size % 2 == 0 or patch_size < psr_exclude + 2:
            raise InputError(f"patch_size must be odd and larger than the PSR window, got {patch_size}")
        self.method, self.levels, self.size = method, levels, patch_size
        self.eta = DEFAULT_ETA[method] if eta is None else eta
        self.reg_rel, self.newton_iterations = reg_rel, newton_iterations
        self.psr_threshold, self.psr_exclude = psr_threshold, psr_exclude
        shape = (patch_size, patch_size)
        if method == "mosse":
            label = torch.fft.rfft2(gaussian_label(shape, sigma)).real
        else:
            label = continuous_label(shape, sigma)
        self.register_buffer("label", label, persistent=False)

    def _spectrum(self, patches: Tensor) -> Tensor:
        """Normalise, window and transform ``(P, N, N)`` patches to ``(P, N, K)`` spectra."""
        x = dcf_preprocess(patches, 2, log=False, normalize=True, window=True)
        return torch.fft.rfft2(x) if self.method == "mosse" else ccot_sample(x, 2)

    def _samples(self, pyramid: list[Tensor], positions: Tensor) -> Tensor:
        """Spectra ``(L, P, N, K)`` of the patches around ``positions`` at every level."""
        spectra = []
        for level, image in enumerate(pyramid):
            centres = (positions + 0.5) / 2**level - 0.5
            spectra.append(self._spectrum(extract_patches(image, centres, self.size)))
        return torch.stack(spectra)

    @staticmethod
    def _frame(frame: Tensor) -> Tensor:
        if frame.dim() == 2:
            frame = frame[None, None]
        if frame.dim() != 4 or frame.shape[:2] != (1, 1):
            raise InputError(f"a frame must be (H, W) or (1, 1, H, W) gray, got shape {tuple(frame.shape)}")
        return frame

    def _inside(self, positions: Tensor, frame: Tensor) -> Tensor:
        h, w = frame.shape[-2:]
        x, y = positions[:, 0], positions[:, 1]
        return torch.isfinite(positions).all(-1) & (x >= 0) & (x <= w - 1) & (y >= 0) & (y <= h - 1)

    def init(self, frame: Tensor, points: Tensor) -> TrackerState:
        """Train every point's filters on ``frame`` ``(H, W)``; points ``(P, 2)`` outside the image start
        lost."""
        frame = self._frame(frame)
        points = torch.as_tensor(points, dtype=frame.dtype, device=frame.device)
        if points.dim() != 2 or points.shape[1] != 2:
            raise InputError(f"points must have shape (P, 2), got {tuple(points.shape)}")
        if points.shape[0] == 0:
            raise InputError("the point set is empty: nothing to track")
        lost = ~self._inside(points, frame)
        positions = torch.where(lost.unsqueeze(-1), torch.zeros_like(points), points)
        Z = self._samples(image_pyramid(frame, self.levels), positions)
        A = Z.conj() * self.label
        B = Z.real.square() + Z.imag.square()
        psr = torch.full_like(points[:, 0], float("inf"))
        return TrackerState(torch.where(lost.unsqueeze(-1), points, positions), lost, psr, A, B)

    def forward(
        self, frame: Tensor, positions: Tensor, lost: Tensor, A: Tensor, B: Tensor
    ) -> tuple[Tensor, Tensor, Tensor, Tensor, Tensor]:
        """One tracking step (exportable: real tensors in and out).

        Args:
            frame: ``(1, 1, H, W)`` gray frame. positions: ``(P, 2)``. lost: ``(P,)`` bool.
            A: ``(L, P, N, K, 2)`` real view of the complex numerators. B: ``(L, P, N, K)`` denominators.
        Returns:
            positions, lost, psr ``(P,)``, A, B after this frame.
        """
        # slicing a complex tensor does not export, so slice the real view first
        A = [torch.view_as_complex(A[level]) for level in range(self.levels)]
        pyramid = image_pyramid(frame, self.levels)
        size = (self.size, self.size)
        start = torch.where(lost.unsqueeze(-1), torch.zeros_like(positions), positions)
        d = torch.zeros_like(positions)
        spectra, centres = [], []
        for level in reversed(range(self.levels)):
            centre = (start + d + 0.5) / 2**level - 0.5
            Z = self._spectrum(extract_patches(pyramid[level], centre, self.size))
            if self.method == "mosse":
                S = mosse_filter(A[level], B[level], 2, eps_rel=self.reg_rel) * Z
                score = torch.fft.irfft2(S, s=size)
                delta, _ = response_peak(score, 2)
            else:
                S = ccot_filter(A[level], B[level], 2, beta2_rel=self.reg_rel) * Z
                score = torch.fft.irfft2(S, s=size)
                delta, _ = fourier_series_peak(S, size, self.newton_iterations, grid=score)
            d = d + 2**level * delta
            spectra.insert(0, Z)
            centres.insert(0, centre)
        psr = peak_to_sidelobe_ratio(score, 2, self.psr_exclude)
        moved = start + d
        lost = lost | ~self._inside(moved, frame) | ~(psr >= self.psr_threshold)
        positions = torch.where(lost.unsqueeze(-1), positions, moved)
        # Training samples at the new positions: the coarsest level moved most and is extracted again; the finer
        # levels moved by at most a few pixels and reuse their search samples, shifted in the Fourier domain (C-COT).
        target = torch.where(lost.unsqueeze(-1), start, moved)
        Z = []
        for level in range(self.levels):
            if level == self.levels - 1:
                coarse = (target + 0.5) / 2**level - 0.5
                Z.append(self._spectrum(extract_patches(pyramid[level], coarse, self.size)))
            else:
                shift = (target + 0.5) / 2**level - 0.5 - centres[level]
                Z.append(shift_fourier(spectra[level], shift, size))
        eta = torch.where(lost, torch.zeros_like(psr), torch.full_like(psr, self.eta)).reshape(1, -1, 1, 1)
        # MOSSE's running update has the same form as the continuous filter's sample weighting.
        updated = [
            ccot_update(A[level], B[level], Z[level], self.label, eta[0]) for level in range(self.levels)
        ]
        A = torch.stack([torch.view_as_real(a) for a, _ in updated])
        return positions, lost, psr, A, torch.stack([b for _, b in updated])

    def step(self, frame: Tensor, state: TrackerState) -> TrackerState:
        """Track all points of ``state`` into ``frame`` ``(H, W)``."""
        frame = self._frame(frame)
        out = self(frame, state.positions, state.lost, torch.view_as_real(state.A), state.B)
        return TrackerState(out[0], out[1], out[2], torch.view_as_complex(out[3]), out[4])

    @torch.no_grad()
    def track(
        self, frames: Iterable[Tensor | np.ndarray], points: Tensor, progress: bool = False
    ) -> tuple[Tensor, Tensor, Tensor]:
        """Track points ``(P, 2)`` given in the first frame through gray frames ``(H, W)`` of equal size.

        Returns:
            tracks ``(T, P, 2)``, lost ``(T, P)`` and PSR ``(T, P)`` (inf in frame 0).
        """
        param = self.label
        tracks, lost, psr, state, shape = [], [], [], None, None
        for t, frame in enumerate(tqdm(frames, desc=f"track {self.method}", disable=not progress)):
            frame = torch.as_tensor(frame, dtype=param.dtype, device=param.device)
            if frame.dim() != 2:
                raise InputError(f"frame {t}: expected a (H, W) gray image, got shape {tuple(frame.shape)}")
            if shape is not None and frame.shape != shape:
                raise InputError(f"frame {t} has size {tuple(frame.shape)}, frame 0 has {tuple(shape)}")
            shape = frame.shape
            state = self.init(frame, points) if state is None else self.step(frame, state)
            tracks.append(state.positions)
            lost.append(state.lost)
            psr.append(state.psr)
        if state is None:
            raise InputError("no frames to track")
        return torch.stack(tracks), torch.stack(lost), torch.stack(psr)
