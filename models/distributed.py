"""Evaluation results gathered over the processes of a distributed (DDP) run, so that metrics computed from them
equal a single process's: every rank contributes its own results, duplicates (a distributed sampler pads the
last batch with repeated samples) are dropped by their key."""

from __future__ import annotations

import os

import torch
import torch.distributed as dist


def is_primary_process() -> bool:
    """Whether this is the first process of a (possibly distributed) run: rank 0 on node 0, from the environment
    Lightning and torchrun set for the other processes (so it is known before the process group exists)."""
    return int(os.environ.get("LOCAL_RANK", 0)) == 0 and int(os.environ.get("NODE_RANK", 0)) == 0


def barrier() -> None:
    """Wait for every process of the distributed run (nothing outside one)."""
    if world_size() > 1:
        dist.barrier()


def world_size() -> int:
    """Processes in the current distributed run (1 outside one)."""
    return dist.get_world_size() if dist.is_available() and dist.is_initialized() else 1


def end_process_group() -> None:
    """Destroy this process's process group, if it has one (nothing outside a distributed run). Each process of a
    DDP run calls it when its work is done: a gloo group left to the interpreter's teardown can abort the process
    (SIGABRT, "terminate called without an active exception") after a run that finished, since its worker threads
    outlive the interpreter state they need."""
    if dist.is_available() and dist.is_initialized():
        dist.destroy_process_group()


def gather_objects(obj: object) -> list[object]:
    """``obj`` of every rank, in rank order (``[obj]`` outside a distributed run)."""
    if world_size() == 1:
        return [obj]
    out: list[object] = [None] * world_size()
    dist.all_gather_object(out, obj)
    return out


def gather_dicts(results: dict) -> dict:
    """The union of every rank's ``{key: result}`` dict (a key seen on several ranks is kept once), sorted by key."""
    merged: dict = {}
    for part in gather_objects(results):
        for key, value in part.items():
            merged.setdefault(key, value)
    return dict(sorted(merged.items()))


def gather_rows(rows: dict[str, torch.Tensor], key: str = "index") -> dict[str, torch.Tensor]:
    """Per-sample tensors ``{name: (N, ...)}`` of every rank, one row per distinct ``rows[key]`` (the sample
    index), ordered by it: what one process evaluating the whole set would have."""
    parts = [{k: v.cpu() for k, v in p.items()} for p in gather_objects({k: v.detach().cpu() for k, v in
                                                                       rows.items()})]
    joined = {k: torch.cat([p[k] for p in parts]) for k in rows}
    order = joined[key].argsort(stable=True)
    sorted_keys = joined[key][order]
    first = torch.ones_like(sorted_keys, dtype=torch.bool)
    first[1:] = sorted_keys[1:] != sorted_keys[:-1]
    keep = order[first]
    return {k: v[keep] for k, v in joined.items()}
