"""Data-parallel training under ``torchrun``, shared by the decoder and generator trainers.

``torchrun`` sets RANK, WORLD_SIZE and LOCAL_RANK; without them a run is one
process and nothing here does anything. Each rank draws its own batches (its
generator is seeded with the rank), DistributedDataParallel averages the
gradients, and only rank 0 writes checkpoints and shows progress.
"""
from __future__ import annotations

import os
from dataclasses import dataclass

import torch
from torch import nn


@dataclass(frozen=True)
class Placement:
    rank: int
    world: int
    device: torch.device

    @property
    def is_main(self) -> bool:
        return self.rank == 0


def placement(device: str = "cpu") -> Placement:
    """This process's rank, world size and device; joins the process group when WORLD_SIZE > 1."""
    rank, world = int(os.environ.get("RANK", 0)), int(os.environ.get("WORLD_SIZE", 1))
    where = torch.device(f"cuda:{int(os.environ.get('LOCAL_RANK', 0))}" if device == "cuda" and world > 1
                         else device)
    if world > 1:
        import torch.distributed as dist

        if not dist.is_initialized():
            dist.init_process_group("nccl" if where.type == "cuda" else "gloo")
    return Placement(rank, world, where)


def data_parallel(module: nn.Module, where: Placement) -> nn.Module:
    """``module`` wrapped for gradient averaging across ranks, or itself in a single process."""
    if where.world == 1:
        return module
    return nn.parallel.DistributedDataParallel(module, device_ids=[where.device.index]
                                               if where.device.type == "cuda" else None)


def finish(where: Placement) -> None:
    """Waits for every rank (rank 0 may still be writing its last checkpoint), then
    leaves the process group: a rank that exits while its peer still holds the
    connection can abort in gloo's teardown."""
    if where.world == 1:
        return
    import torch.distributed as dist

    if dist.is_initialized():
        dist.barrier()
        dist.destroy_process_group()
