"""Wall and CPU seconds per named stage of one process, for pricing a farm run.

CPU seconds are this process's user + system time over all its threads
(``time.process_time``: Cycles' render threads and torch's are included). On a
shared machine they are the honest measure of what a stage costs: its wall time
also counts the neighbours' turns on the cores.
"""
from __future__ import annotations

import time
from collections.abc import Iterator
from contextlib import contextmanager


class StageClock:
    """Seconds per stage, summed when a stage runs more than once (once per material).

    ``cpu["startup"]`` is what the process spent before the clock was made: the
    interpreter and its imports (Blender's or torch's), part of every stage's price.
    ``cpu["process"]`` is all the process spent until ``record``: startup, stages and
    whatever ran between them.
    """

    def __init__(self) -> None:
        self.wall: dict[str, float] = {}
        self.cpu: dict[str, float] = {"startup": time.process_time()}

    @contextmanager
    def stage(self, name: str) -> Iterator[None]:
        wall, cpu = time.monotonic(), time.process_time()
        try:
            yield
        finally:
            self.wall[name] = self.wall.get(name, 0.0) + time.monotonic() - wall
            self.cpu[name] = self.cpu.get(name, 0.0) + time.process_time() - cpu

    def record(self, whole_process: bool = True) -> dict[str, dict[str, float]]:
        """``{"timings_s": wall, "cpu_s": cpu}``, to the millisecond; without ``startup`` and
        ``process`` when the clock timed only a part of its process (one fit of several)."""
        cpu = {**self.cpu, "process": time.process_time()} if whole_process else \
            {k: v for k, v in self.cpu.items() if k != "startup"}
        return {"timings_s": {k: round(v, 3) for k, v in self.wall.items()},
                "cpu_s": {k: round(v, 3) for k, v in cpu.items()}}
