"""Reading a horizon filter bank directory, torch-free (the localiser and the deployment runtime share it; the
bank is written by ``data.horizon.bank_io.BankWriter``).

A bank is a directory::

    bank.json                 settings, grid, DEM fingerprint, chunk list, ``complete`` flag
    chunks/filters_NNNNN.npy  (L_i, 2K) float16 (or float32): H* of L_i locations, (re, im) per frequency
    chunks/cells_NNNNN.npy    (L_i, 2) int32 grid (row, col) of those locations

Each chunk holds the sea locations of one tile of grid rows; chunks are opened with ``np.load(mmap_mode="r")``,
so a bank of any size is matched chunk by chunk without loading it. ``subgrid_refine`` refines a best location on
the bank's grid.
"""

from __future__ import annotations

import json
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from core.errors import InputError

BANK_FORMAT = "dcfvision-horizon-filter-bank"
BANK_VERSION = 1
STORAGE_DTYPES = ("float16", "float32")


@dataclass
class BankChunk:
    """One chunk: ``filters`` (L, 2K) storage-dtype array (memory-mapped) and ``cells`` (L, 2) int32."""

    filters: np.ndarray
    cells: np.ndarray


class BankReader:
    """A stored bank opened for matching (see the module docstring for the layout).

    Attributes:
        meta: the parsed ``bank.json``; ``settings``, ``grid`` and ``dem`` entries describe the bank.
    """

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        meta_path = self.path / "bank.json"
        if not meta_path.is_file():
            raise InputError(f"filter bank not found: {meta_path} (build one with `infer.py build-bank`)")
        try:
            meta = json.loads(meta_path.read_text())
        except json.JSONDecodeError as err:
            raise InputError(f"filter bank {meta_path} is not valid JSON: {err}") from err
        if meta.get("format") != BANK_FORMAT or meta.get("version") != BANK_VERSION:
            raise InputError(f"{meta_path} is not a version {BANK_VERSION} {BANK_FORMAT}")
        if not meta.get("complete"):
            raise InputError(f"filter bank {self.path} is incomplete (its build was interrupted; run build-bank "
                             "again with the same arguments to resume)")
        self.meta = meta
        self._chunks: list[BankChunk] = []
        for chunk in meta["chunks"]:
            files = [self.path / "chunks" / f"{kind}_{chunk['index']:05d}.npy" for kind in ("filters", "cells")]
            try:
                filters, cells = (np.load(f, mmap_mode="r") for f in files)
            except (OSError, ValueError) as err:
                message = f"filter bank {self.path}: chunk {chunk['index']} is missing or corrupt: {err}"
                raise InputError(message) from err
            if filters.shape != (chunk["count"], 2 * self.half_spectrum) or cells.shape != (chunk["count"], 2):
                raise InputError(f"filter bank {self.path}: chunk {chunk['index']} has shapes {filters.shape}, "
                                 f"{cells.shape}, expected ({chunk['count']}, {2 * self.half_spectrum}), "
                                 f"({chunk['count']}, 2)")
            self._chunks.append(BankChunk(filters, cells))

    @property
    def settings(self) -> dict:
        return self.meta["settings"]

    @property
    def bins(self) -> int:
        return int(self.settings["bins"])

    @property
    def half_spectrum(self) -> int:
        return int(self.settings["half_spectrum"])

    @property
    def grid(self) -> dict:
        """``x0, y0, spacing, rows, cols`` of the location grid."""
        return self.meta["grid"]

    def __len__(self) -> int:
        return sum(len(c.cells) for c in self._chunks)

    @property
    def nbytes(self) -> int:
        """Bytes of the stored filters and cells."""
        return sum(c.filters.nbytes + c.cells.nbytes for c in self._chunks)

    def cells(self) -> np.ndarray:
        """(L, 2) int grid (row, col) of all locations, in bank order."""
        if not self._chunks:
            return np.zeros((0, 2), dtype=np.int32)
        return np.concatenate([np.asarray(c.cells) for c in self._chunks])

    def locations(self) -> np.ndarray:
        """(L, 2) map coordinates (x, y) of all locations, metres."""
        cells = self.cells().astype(np.float64)
        g = self.grid
        return np.stack([g["x0"] + cells[:, 1] * g["spacing"], g["y0"] - cells[:, 0] * g["spacing"]], -1)

    def arrays(
        self, size: int = 8192, rows: tuple[int, int] | None = None
    ) -> Iterator[tuple[int, np.ndarray, np.ndarray]]:
        """``(offset, cells (L_c, 2), filters (L_c, 2K) float32)`` blocks of up to ``size`` locations in bank order;
        with ``rows = (lo, hi)`` only the blocks holding a grid row in ``[lo, hi]`` are read (a search window)."""
        offset = 0
        for chunk in self._chunks:
            for start in range(0, len(chunk.cells), size):
                cells = np.asarray(chunk.cells[start : start + size])
                if rows is None or (cells[:, 0].max() >= rows[0] and cells[:, 0].min() <= rows[1]):
                    yield offset + start, cells, np.array(chunk.filters[start : start + size], dtype=np.float32)
            offset += len(chunk.cells)


def subgrid_refine(scores: np.ndarray, cells: np.ndarray, rows: int, cols: int, best: np.ndarray) -> np.ndarray:
    """Fractional (row, col) of the best locations from a parabola through their grid neighbours' scores.

    Args:
        scores: (B, L) location scores (-inf = not a candidate); cells: (L, 2) grid (row, col) of the locations.
        rows, cols: grid size; best: (B,) index of each query's best location.
    Returns:
        (B, 2) fractional cells (offsets within +-0.5; none along an axis missing a neighbour or not concave).
    """
    lookup = np.full((rows + 2, cols + 2), -1, dtype=np.int64)
    lookup[cells[:, 0] + 1, cells[:, 1] + 1] = np.arange(len(cells))
    centre = cells[best].astype(np.float64)
    queries = np.arange(len(best))
    s0 = scores[queries, best]
    out = centre.copy()
    for axis in (0, 1):
        step = np.zeros(2, dtype=np.int64)
        step[axis] = 1
        lo = lookup[cells[best, 0] + 1 - step[0], cells[best, 1] + 1 - step[1]]
        hi = lookup[cells[best, 0] + 1 + step[0], cells[best, 1] + 1 + step[1]]
        s_lo, s_hi = scores[queries, lo.clip(0)], scores[queries, hi.clip(0)]
        ok = (lo >= 0) & (hi >= 0) & np.isfinite(s_lo) & np.isfinite(s_hi)  # outside a search window: -inf
        s_lo, s_hi = np.where(ok, s_lo, s0), np.where(ok, s_hi, s0)
        curvature = s_lo - 2 * s0 + s_hi
        concave = ok & (curvature < 0)
        delta = np.where(concave, 0.5 * (s_lo - s_hi) / np.where(concave, curvature, -1.0), 0.0)
        out[:, axis] += delta.clip(-0.5, 0.5)
    return out
