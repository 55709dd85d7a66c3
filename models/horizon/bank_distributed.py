"""A filter-bank build spread over processes with Lightning (thesis ch. 4.4; a coastline's bank is millions of
locations): the tiles are the samples of a ``predict`` loop under DDP, and a prediction writer stores each tile's
chunk as it comes, so every process writes its own chunks and a killed build resumes at the tiles not written."""

from __future__ import annotations

import lightning as L
import torch
from lightning.pytorch.callbacks import BasePredictionWriter
from torch.utils.data import DataLoader, Dataset

from data.horizon.bank_io import BankWriter
from models.horizon.filter_bank import BankTiles


class TileIndices(Dataset):
    """The tile indices still to build."""

    def __init__(self, indices: list[int]) -> None:
        self.indices = indices

    def __len__(self) -> int:
        return len(self.indices)

    def __getitem__(self, item: int) -> int:
        return self.indices[item]


class BankTileModule(L.LightningModule):
    """``predict_step``: a batch of tile indices -> [(index, filters, cells)] (``BankTiles``; no weights)."""

    def __init__(self, tiles: BankTiles) -> None:
        super().__init__()
        self.tiles = tiles

    def predict_step(self, batch: list[int], batch_idx: int) -> list[tuple[int, object, object]]:
        if self.tiles.heights.device != self.device:
            self.tiles.heights = self.tiles.heights.to(self.device)
        return [(index, *self.tiles(index)) for index in batch]


class ChunkWriter(BasePredictionWriter):
    """Writes each predicted tile as its bank chunk, at once (nothing is kept in memory)."""

    def __init__(self, writer: BankWriter) -> None:
        super().__init__(write_interval="batch")
        self.writer = writer

    def write_on_batch_end(self, trainer, pl_module, prediction, batch_indices, batch, batch_idx,
                           dataloader_idx) -> None:
        for index, filters, cells in prediction:
            self.writer.write_chunk(index, filters, cells)


def build_distributed(tiles: BankTiles, writer: BankWriter, devices: int, accelerator: str = "cpu",
                      progress: bool = True) -> bool:
    """Build the tiles not yet written on ``devices`` processes (DDP; gloo on CPUs); returns whether this is the
    first process (the one that writes the manifest). Every process returns after all tiles are written."""
    todo = [i for i in range(len(tiles)) if not writer.has_chunk(i)]
    if not todo:  # a finished build resumed: nothing to spread over processes
        return True
    trainer = L.Trainer(accelerator=accelerator, devices=devices, strategy="ddp", logger=False,
                        enable_checkpointing=False, enable_model_summary=False, enable_progress_bar=progress,
                        callbacks=[ChunkWriter(writer)], use_distributed_sampler=True)
    loader = DataLoader(TileIndices(todo), batch_size=1, collate_fn=list)
    with torch.no_grad():
        trainer.predict(BankTileModule(tiles), loader, return_predictions=False)
    trainer.strategy.barrier()
    return trainer.global_rank == 0
