"""Which cores each worker's children run on: their own share of the run's, as their affinity mask.

A child sees every core of its run unless told otherwise. One that renders with fewer
threads than the cores it sees leaves the pip ``bpy`` module's TBB a spare worker, which
spins in ``sched_yield`` beside the render (a Blender binary's ``-t`` caps TBB; the module
has no such switch). With its affinity limited to its own share, TBB starts no spare
worker. One worker keeps every core, so nothing changes for it; with more workers than
cores they all share every core.
"""
from __future__ import annotations

import os
import queue
from collections.abc import Iterator
from contextlib import contextmanager

Cores = frozenset[int] | None  # None: every core of the run


def allowed_cores() -> list[int]:
    """The cores this process may run on: a SLURM task's ``--cpus-per-task``, not every core of the node."""
    if hasattr(os, "sched_getaffinity"):
        return sorted(os.sched_getaffinity(0))
    return list(range(os.cpu_count() or 1))


class CoreShares:
    """One disjoint share of ``cores`` per worker, lent to the worker for as long as it runs one asset."""

    def __init__(self, workers: int, cores: list[int] | None = None) -> None:
        cores = allowed_cores() if cores is None else cores
        per = len(cores) // workers
        self._free: queue.SimpleQueue[Cores] = queue.SimpleQueue()
        for i in range(workers):
            self._free.put(frozenset(cores[i * per:(i + 1) * per]) if workers > 1 and per else None)

    @contextmanager
    def lend(self) -> Iterator[Cores]:
        share = self._free.get()
        try:
            yield share
        finally:
            self._free.put(share)
