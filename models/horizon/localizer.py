"""Position and heading from horizon profiles or panoramas, by the filter bank (thesis ch. 4.4).

panorama -> HorizonFinder (pitch, roll) -> levelling warp -> HorizonSegmenter -> horizon profile -> resampled to
the bank's azimuth bins -> band PSR of every bank location (``models.horizon.matching``, chunk by chunk) ->
best location, refined to sub-grid precision by a parabola through the scores of its four grid neighbours,
and the heading of its band peak. Profiles can also come straight from a file or the classical extractor
(``models.horizon.classical_profile``).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
import torch
from torch import Tensor

from core.bank_reader import subgrid_refine
from core.cylinder import column_azimuths, interp_profile, warp_panorama
from core.errors import InputError
from data.horizon.bank_io import FilterBank
from data.horizon.datamodule import resize_panorama
from models.horizon.finder import sincos_to_angles
from models.horizon.matching import band_psr, check_query


@dataclass
class Localization:
    """Result for B queries.

    Attributes:
        xy: (B, 2) estimated map position (x east, y north), metres.
        heading_deg: (B,) estimated heading of profile column 0, degrees in [0, 360).
        psr: (B,) score of the best location.
        index: (B,) bank index of the best location.
        cell: (B, 2) fractional grid (row, col) after sub-grid refinement.
        scores: (B, L) PSR of every bank location, when asked for.
    """

    xy: np.ndarray
    heading_deg: np.ndarray
    psr: np.ndarray
    index: np.ndarray
    cell: np.ndarray
    scores: np.ndarray | None = None


def resample_profile(profile: Tensor, bins: int) -> Tensor:
    """Circular linear resampling of (B, W) profiles (column u at azimuth 2 pi u / W) to (B, bins)."""
    if profile.shape[-1] == bins:
        return profile
    psi = column_azimuths(bins, profile.dtype, profile.device)[None].expand(profile.shape[0], bins)
    return interp_profile(profile, psi)


def locate(
    bank: FilterBank,
    profile: Tensor,
    heading_deg: Tensor,
    band_deg: float = 4.0,
    exclude: int = 11,
    chunk: int = 8192,
    keep_scores: bool = False,
    device: torch.device | str | None = None,
    matcher: Callable[[Tensor, Tensor, Tensor], tuple[Tensor, Tensor]] | None = None,
    prior_xy: np.ndarray | None = None,
    radius: float = 500.0,
    drop_harmonics: int = 0,
) -> Localization:
    """Best bank location and heading for each observed profile.

    Args:
        bank: the filter bank.
        profile: (B, N) tan elevation profiles with N = the bank's bins, column 0 at the camera heading.
        heading_deg: (B,) compass headings in [0, 360) degrees.
        band_deg: peak search band around the compass heading, degrees; exclude: PSR window, bins.
        chunk: locations matched per batched product.
        keep_scores: also return the (B, L) PSR of all locations.
        device: where to match (default: the profile's device).
        matcher: replaces :func:`band_psr` (e.g. an onnxruntime session of the exported ``BandPsr``):
            (filters (L, 2K), profile (B, N), heading_deg (B,)) -> psr (B, L), heading (B, L).
        prior_xy: (B, 2) map positions (e.g. the previous fixes): only locations within ``radius`` metres of
            a query's prior are candidates for it, and only the bank blocks near the priors are read.
        drop_harmonics: ignore the profiles' harmonics 1 .. this (see :func:`band_psr`; 1 for image profiles).
    """
    heading_deg = torch.as_tensor(heading_deg, dtype=profile.dtype if isinstance(profile, Tensor) else None)
    check_query(profile, heading_deg, bank.bins)
    if len(bank) == 0:
        raise InputError(f"filter bank {bank.path} has no sea locations")
    device = device or profile.device
    profile, heading_deg = profile.to(device), heading_deg.to(device=device, dtype=profile.dtype)
    threshold = float(bank.settings["norm_threshold_deg"])
    grid = bank.grid
    total = len(bank)
    scores = np.full((profile.shape[0], total), -np.inf, dtype=np.float32)
    headings = np.zeros((profile.shape[0], total), dtype=np.float32)
    rows = None
    if prior_xy is not None:
        prior_xy = np.asarray(prior_xy, dtype=np.float64).reshape(-1, 2)
        if prior_xy.shape[0] != profile.shape[0] or not radius > 0:
            raise InputError(f"prior_xy must be (B, 2) = ({profile.shape[0]}, 2) and radius > 0, got "
                             f"{prior_xy.shape}, {radius}")
        prior_rows = (grid["y0"] - prior_xy[:, 1]) / grid["spacing"]
        reach = radius / grid["spacing"]
        rows = (int(np.floor(prior_rows.min() - reach)), int(np.ceil(prior_rows.max() + reach)))
    with torch.no_grad():
        for offset, cells, filters in bank.blocks(chunk, dtype=profile.dtype, device=device, rows=rows):
            if matcher is None:
                p, h = band_psr(filters, profile, heading_deg, band_deg, exclude, threshold, drop_harmonics)
            else:
                p, h = matcher(filters, profile, heading_deg)
            p = p.cpu().numpy()
            if prior_xy is not None:
                spacing = grid["spacing"]
                xy = np.stack([grid["x0"] + cells[:, 1] * spacing, grid["y0"] - cells[:, 0] * spacing], -1)
                far = np.linalg.norm(xy[None] - prior_xy[:, None], axis=-1) > radius
                p = np.where(far, -np.inf, p)
            scores[:, offset : offset + len(cells)] = p
            headings[:, offset : offset + len(cells)] = h.cpu().numpy()
    if not np.isfinite(scores.max(1)).all():
        raise InputError(f"no bank location lies within {radius} m of a prior position")
    best = scores.argmax(1)
    cells = bank.cells()
    cell = subgrid_refine(scores, cells, grid["rows"], grid["cols"], best)
    xy = np.stack([grid["x0"] + cell[:, 1] * grid["spacing"], grid["y0"] - cell[:, 0] * grid["spacing"]], -1)
    queries = np.arange(len(best))
    return Localization(xy, headings[queries, best], scores[queries, best], best, cell,
                        scores if keep_scores else None)


def panorama_profiles(
    image: Tensor,
    finder: Callable[[Tensor], Tensor],
    segmenter: Callable[[Tensor], Tensor],
    input_width: int = 512,
) -> tuple[Tensor, Tensor, Tensor]:
    """The network chain of thesis ch. 4.3 on tilted panoramas: HorizonFinder -> levelling -> HorizonSegmenter.

    Args:
        image: (B, 3, H, W) tilted 360-degree panoramas in [0, 1], column 0 forward.
        finder: image (B, 3, h, w) -> (B, 4) (sin, cos) of pitch and roll (a network).
        segmenter: levelled image (B, 3, h, w) -> (B, 2, w) tan elevation of horizon and water line.
        input_width: network input width in px (the panorama is resized, keeping its aspect).
    Returns:
        profiles (B, 2, W) tan elevation of the horizon and the water line at the panorama's own width, pitch (B,)
        and roll (B,) rad.
    """
    if input_width < 64 or input_width % 32:
        raise InputError(f"the network input width must be a multiple of 32 and >= 64, got {input_width}")
    with torch.no_grad():
        pitch, roll = sincos_to_angles(finder(resize_panorama(image, input_width)))
        level = warp_panorama(image, pitch.to(image.dtype), roll.to(image.dtype))
        profiles = segmenter(resize_panorama(level, input_width)).to(image.dtype)
    if profiles.shape[-1] != image.shape[-1]:
        profiles = torch.stack([resample_profile(profiles[:, i], image.shape[-1]) for i in range(2)], 1)
    return profiles, pitch, roll


def network_profiles(
    image: Tensor,
    finder: Callable[[Tensor], Tensor],
    segmenter: Callable[[Tensor], Tensor],
    bins: int,
    input_width: int = 512,
) -> tuple[Tensor, Tensor, Tensor]:
    """Horizon profiles (B, bins) of tilted panoramas (B, 3, H, W) for matching, with pitch and roll (B,) rad
    (``panorama_profiles``; its horizon resampled to the bank's ``bins``)."""
    profiles, pitch, roll = panorama_profiles(image, finder, segmenter, input_width)
    return resample_profile(profiles[:, 0], bins), pitch, roll


class HorizonLocalizer:
    """End to end (thesis ch. 4.4): panoramas (via the networks) or profiles -> positions and headings.

    Args:
        bank: the filter bank.
        finder, segmenter: callables as in :func:`panorama_profiles` (needed for :meth:`from_images` only).
        matcher: replaces the PyTorch band PSR (``locate``), e.g. the exported graph.
        input_width: network input width; band_deg, exclude, drop_harmonics: as in :func:`locate`.
        batch: panoramas through the networks at a time.
    """

    def __init__(
        self,
        bank: FilterBank,
        finder: Callable[[Tensor], Tensor] | None = None,
        segmenter: Callable[[Tensor], Tensor] | None = None,
        matcher: Callable[[Tensor, Tensor, Tensor], tuple[Tensor, Tensor]] | None = None,
        input_width: int = 512,
        band_deg: float = 4.0,
        exclude: int = 11,
        drop_harmonics: int = 0,
        batch: int = 8,
    ) -> None:
        if drop_harmonics and matcher is not None:
            raise InputError("dropping harmonics needs the PyTorch matcher (export the matcher with "
                             "--drop-harmonics instead)")
        self.bank, self.finder, self.segmenter, self.matcher = bank, finder, segmenter, matcher
        self.input_width, self.band_deg, self.exclude = input_width, band_deg, exclude
        self.drop_harmonics, self.batch = drop_harmonics, batch

    def image_profiles(self, images: Sequence[Tensor]) -> Tensor:
        """(B, bins) horizon profiles of B tilted panoramas (each (3, H, W), or (1, 3, H, W)), ``batch`` at a time."""
        if self.finder is None or self.segmenter is None:
            raise InputError("localising panoramas needs the HorizonFinder and HorizonSegmenter models")
        chunks = []
        for start in range(0, len(images), self.batch):
            image = torch.cat([im.reshape(-1, *im.shape[-3:]) for im in images[start : start + self.batch]])
            chunks.append(network_profiles(image, self.finder, self.segmenter, self.bank.bins, self.input_width)[0])
        return torch.cat(chunks).float()

    def from_profiles(self, profile: Tensor, heading_deg: Tensor, keep_scores: bool = False) -> Localization:
        """Localise (B, bins) tan-elevation profiles with compass headings (B,) degrees."""
        return locate(self.bank, profile, heading_deg, self.band_deg, self.exclude, keep_scores=keep_scores,
                      matcher=self.matcher, drop_harmonics=self.drop_harmonics)

    def from_images(self, images: Sequence[Tensor], heading_deg: Tensor, keep_scores: bool = False) -> Localization:
        """Localise tilted panoramas (``image_profiles``) with compass headings (B,) degrees."""
        return self.from_profiles(self.image_profiles(images), heading_deg, keep_scores)


def heading_error_deg(estimate: np.ndarray, truth: np.ndarray) -> np.ndarray:
    """Absolute circular difference of headings in degrees."""
    d = np.remainder(np.asarray(estimate) - np.asarray(truth) + 180.0, 360.0) - 180.0
    return np.abs(d)

