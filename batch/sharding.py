"""Which assets a farm task owns: ``--shard I/N``, SLURM array variables, stable hash split.

The split hashes the asset id, not its position in the list, so adding assets
to the input never moves an existing asset to another shard (a contiguous
split would reshuffle everything and re-render finished work elsewhere).
"""
from __future__ import annotations

import hashlib
import os
from dataclasses import dataclass
from typing import Mapping


@dataclass(frozen=True)
class Shard:
    index: int
    count: int

    def __post_init__(self) -> None:
        if self.count < 1 or not 0 <= self.index < self.count:
            raise ValueError(f"shard {self.index}/{self.count}: need 0 <= I < N")

    def owns(self, asset_id: str) -> bool:
        return shard_of(asset_id, self.count) == self.index

    @property
    def label(self) -> str:
        return f"{self.index:04d}-of-{self.count:04d}"


def shard_of(asset_id: str, count: int) -> int:
    digest = hashlib.sha256(asset_id.encode("utf-8")).digest()
    return int.from_bytes(digest[:8], "big") % count


def parse_shard(text: str) -> Shard:
    """``I/N`` with 0 <= I < N."""
    try:
        index, count = (int(part) for part in text.split("/"))
    except ValueError:
        raise ValueError(f"--shard {text!r}: expected I/N, e.g. 0/8") from None
    return Shard(index, count)


def shard_from_environment(env: Mapping[str, str] = os.environ) -> Shard | None:
    """A SLURM array task's shard; task ids may start at any offset (``--array=1-8``)."""
    if "SLURM_ARRAY_TASK_ID" not in env or "SLURM_ARRAY_TASK_COUNT" not in env:
        return None
    task, count = int(env["SLURM_ARRAY_TASK_ID"]), int(env["SLURM_ARRAY_TASK_COUNT"])
    first = int(env.get("SLURM_ARRAY_TASK_MIN", "0"))
    return Shard(task - first, count)
