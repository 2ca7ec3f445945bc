"""Progress of a run: a tqdm bar where tqdm is installed, else one plain line per finished asset.

A stock Blender's Python has no tqdm, and a farm's log file is read line by line
anyway, so the plain form says what the bar would: how many of how many, which
asset, how it ended, and the estimated time left.
"""
from __future__ import annotations

import sys
import time
from typing import Protocol, TextIO


class Progress(Protocol):
    def step(self, status: str, asset_id: str) -> None: ...

    def close(self) -> None: ...


class _Bar:
    def __init__(self, total: int, label: str) -> None:
        from tqdm import tqdm

        self._bar = tqdm(total=total, unit="asset", desc=label, dynamic_ncols=True)

    def step(self, status: str, asset_id: str) -> None:
        self._bar.update(1)
        self._bar.set_postfix_str(f"{status}: {asset_id}")

    def close(self) -> None:
        self._bar.close()


class Lines:
    """``shard 0000-of-0001 [3/10] done chair-3f2a9c01b2 (ETA 0:05:12)`` per finished asset."""

    def __init__(self, total: int, label: str, stream: TextIO | None = None) -> None:
        self.total, self.label, self.done = total, label, 0
        self.stream = stream if stream is not None else sys.stderr
        self.start = time.monotonic()

    def step(self, status: str, asset_id: str) -> None:
        self.done += 1
        left = (time.monotonic() - self.start) / self.done * (self.total - self.done)
        eta = time.strftime("%H:%M:%S", time.gmtime(left)) if left < 86400 else f"{left / 3600:.0f} h"
        print(f"{self.label} [{self.done}/{self.total}] {status} {asset_id} (ETA {eta})", file=self.stream,
              flush=True)

    def close(self) -> None:
        pass


def progress(total: int, label: str) -> Progress:
    try:
        return _Bar(total, label)
    except ImportError:
        return Lines(total, label)
