"""On-disk storage of a horizon filter bank: chunked, memory-mappable, tied to its DEM.

The directory layout and its reader are ``core.bank_reader`` (torch-free, shared with the deployment runtime); here
the writer and ``FilterBank``, the reader with tensor blocks and the DEM check. A bank is a directory::

    bank.json                 settings, grid, DEM fingerprint, chunk list, ``complete`` flag
    chunks/filters_NNNNN.npy  (L_i, 2K) float16 (or float32): H* of L_i locations, (re, im) per frequency
    chunks/cells_NNNNN.npy    (L_i, 2) int32 grid (row, col) of those locations

Each chunk holds the sea locations of one tile of grid rows; chunks are opened with ``np.load(mmap_mode="r")``,
so a bank of any size is matched chunk by chunk without loading it. A build interrupted part-way resumes:
chunks already written are kept when the settings and the DEM are the same (``bank.json`` of an unfinished build
names them; its chunk list is written last).
The DEM fingerprint (SHA-256 of the flooded heights and the geotransform) catches a bank used with another DEM.
"""

from __future__ import annotations

import json
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import torch

from core.bank_reader import BANK_FORMAT, BANK_VERSION, STORAGE_DTYPES, BankReader
from core.errors import InputError
from core.files import atomic_path, writable_folder, write_text
from data.world.dem import Dem, dem_fingerprint


class BankWriter:
    """Writes a bank directory chunk by chunk; ``meta`` holds everything but the chunk list.

    Chunks are files written atomically, each complete once both of its files exist, so several processes can
    write chunks of one bank at once (a distributed build) and a killed build keeps what it finished. The
    manifest is written at the start without chunks (``complete: false``, it identifies the build) and again by
    ``finish`` with the chunk list, last.
    """

    def __init__(self, path: str | Path, meta: dict, overwrite: bool = False, primary: bool = True) -> None:
        self.path = Path(path)
        if meta.get("storage_dtype") not in STORAGE_DTYPES:
            raise InputError(f"storage dtype must be one of {STORAGE_DTYPES}, got {meta.get('storage_dtype')!r}")
        self.meta = {"format": BANK_FORMAT, "version": BANK_VERSION, **meta, "chunks": [], "complete": False}
        if not primary:  # another process of a distributed build: the primary one prepared the folder
            return
        old = self._read_existing()
        same = old is not None and all(old.get(k) == v for k, v in self.meta.items() if k not in ("chunks", "complete"))
        if old is not None and not same and not overwrite:
            raise InputError(f"{self.path} holds another filter bank (other DEM or settings); "
                             "choose another --out or pass --overwrite")
        chunks = writable_folder(self.path / "chunks")
        if not same:  # a new build: chunks of another one must not be taken for this one's
            for stale in chunks.glob("*.npy"):
                stale.unlink()
        self._save_meta()

    def _read_existing(self) -> dict | None:
        meta = self.path / "bank.json"
        if not meta.is_file():
            return None
        try:
            return json.loads(meta.read_text())
        except json.JSONDecodeError:
            return {}

    def _chunk_files(self, index: int) -> tuple[Path, Path]:
        return tuple(self.path / "chunks" / f"{kind}_{index:05d}.npy" for kind in ("filters", "cells"))

    def has_chunk(self, index: int) -> bool:
        """Whether chunk ``index`` is complete on disk (both files, each written atomically)."""
        return all(f.is_file() for f in self._chunk_files(index))

    def _save_meta(self) -> None:
        write_text(self.path / "bank.json", json.dumps(self.meta, indent=1))

    def write_chunk(self, index: int, filters: np.ndarray, cells: np.ndarray) -> None:
        """Store chunk ``index``: filters (L, 2K) (cast to the storage dtype) and grid cells (L, 2)."""
        k2 = 2 * self.meta["settings"]["half_spectrum"]
        if filters.ndim != 2 or filters.shape[1] != k2 or cells.shape != (filters.shape[0], 2):
            raise InputError(f"chunk {index}: filters must be (L, {k2}) and cells (L, 2), got "
                             f"{filters.shape}, {cells.shape}")
        arrays = (filters.astype(self.meta["storage_dtype"]), cells.astype(np.int32))
        for final, array in zip(self._chunk_files(index), arrays, strict=True):
            with atomic_path(final) as tmp:
                np.save(tmp, array)

    def finish(self, chunks: int) -> Path:
        """List chunks ``0 .. chunks - 1`` (all must be complete) in the manifest, mark the bank complete and return
        its path. The manifest holds no timings, so a resumed build writes the same bytes as an uninterrupted one."""
        missing = [i for i in range(chunks) if not self.has_chunk(i)]
        if missing:
            raise InputError(f"filter bank {self.path}: chunks {missing[:5]} were not written")
        counts = [int(np.load(self._chunk_files(i)[1], mmap_mode="r").shape[0]) for i in range(chunks)]
        self.meta.update(chunks=[{"index": i, "count": n} for i, n in enumerate(counts)], complete=True)
        self._save_meta()
        return self.path


class FilterBank(BankReader):
    """A stored bank opened for matching (``core.bank_reader.BankReader``) with its blocks as tensors."""

    def chunks(self, size: int = 2**16, dtype: torch.dtype = torch.float32, device=None) -> Iterator[torch.Tensor]:
        """Filters (L_c, 2K) of up to ``size`` locations at a time, in bank order, as tensors of ``dtype``."""
        for _, _, filters in self.arrays(size):
            yield torch.from_numpy(filters).to(device=device, dtype=dtype)

    def blocks(
        self, size: int = 8192, dtype: torch.dtype = torch.float32, device=None, rows: tuple[int, int] | None = None
    ) -> Iterator[tuple[int, np.ndarray, torch.Tensor]]:
        """``(offset, cells (L_c, 2), filters (L_c, 2K))`` blocks in bank order; with ``rows = (lo, hi)`` only the
        blocks holding a grid row in ``[lo, hi]`` are read (a search window)."""
        for offset, cells, filters in self.arrays(size, rows):
            yield offset, cells, torch.from_numpy(filters).to(device=device, dtype=dtype)

    def check_dem(self, dem: Dem, name: str = "DEM") -> None:
        """Raise ``InputError`` unless the bank was built for ``dem`` (same flooded heights and geotransform)."""
        if dem_fingerprint(dem) != self.meta["dem"]["fingerprint"]:
            raise InputError(f"filter bank {self.path} was built for another DEM ({self.meta['dem'].get('source')}, "
                             f"sea level {self.meta['dem'].get('sea_level')} m), not for this {name}")
