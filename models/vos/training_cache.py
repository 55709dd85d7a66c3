"""Memo of a batched computation per sample key: FRTM trains its decoder on a frozen backbone, so a test frame's
features and a reference's fitted target model are the same every time a sample meets them again (the paper
cached its target models on disk; here they stay in memory)."""

from __future__ import annotations

from collections.abc import Callable, Hashable, Sequence

import torch

from core.errors import InputError


class KeyedMemo:
    """Remembers, per key, one row of a batched function's dict of tensors.

    Args:
        store_dtype: floating tensors are kept in this dtype (e.g. ``torch.float16``: half the memory of
            backbone features) and handed back in the dtype they were computed in; None keeps them as they are.

    Attributes:
        hits, misses: keys served from memory and keys computed.
    """

    def __init__(self, store_dtype: torch.dtype | None = None) -> None:
        self.store_dtype = store_dtype
        self._rows: dict[Hashable, dict[str, torch.Tensor]] = {}
        self._dtypes: dict[str, torch.dtype] = {}
        self.hits = 0
        self.misses = 0

    def __len__(self) -> int:
        return len(self._rows)

    def _store(self, value: torch.Tensor) -> torch.Tensor:
        keep = self.store_dtype is not None and value.is_floating_point()
        return (value.to(self.store_dtype) if keep else value).clone()

    def __call__(
        self, keys: Sequence[Hashable], compute: Callable[[list[int]], dict[str, torch.Tensor]]
    ) -> dict[str, torch.Tensor]:
        """Rows of ``keys`` stacked: ``compute(positions)`` is called once, for the positions (indices into
        ``keys``) of the keys not seen before, and must return ``{name: (len(positions), ...)}``.

        Returns:
            ``{name: (len(keys), ...)}``.
        """
        missing = [i for i, k in enumerate(keys) if k not in self._rows]
        first = {}
        for i in missing:
            first.setdefault(keys[i], i)
        if first:
            positions = list(first.values())
            values = compute(positions)
            for name, value in values.items():
                if value.shape[0] != len(positions):
                    raise InputError(f"memoised {name!r} has {value.shape[0]} rows for {len(positions)} keys")
                self._dtypes[name] = value.dtype
            for row, i in enumerate(positions):
                self._rows[keys[i]] = {name: self._store(value[row]) for name, value in values.items()}
        self.misses += len(first)
        self.hits += len(keys) - len(first)
        rows = [self._rows[k] for k in keys]
        return {name: torch.stack([r[name] for r in rows]).to(dtype) for name, dtype in self._dtypes.items()}
