"""Run one child process in its own process group, with a wall-clock limit.

A timeout kills the whole group (Blender and anything it started), not just the
direct child; on Linux the child also gets SIGKILL if the orchestrator dies, so
a killed farm task leaves no orphan writing into its folders. Output goes to
log files, of which the tail of stderr is kept for the ledger.
"""
from __future__ import annotations

import ctypes
import os
import signal
import subprocess
import sys
import threading
import time
from dataclasses import dataclass
from functools import partial
from pathlib import Path
from typing import Sequence

from .cores import Cores

STDERR_TAIL_BYTES = 2000
_PR_SET_PDEATHSIG = 1

STOPPING = threading.Event()  # set by kill_all: no new child may start
_live: dict[int, subprocess.Popen] = {}  # pid -> process, for kill_all on shutdown
_live_lock = threading.Lock()


@dataclass
class Outcome:
    exit_code: int | None  # None when killed by a signal
    signal: str | None  # e.g. "SIGSEGV", "SIGKILL"
    timed_out: bool
    seconds: float
    stderr_tail: str

    @property
    def ok(self) -> bool:
        return self.exit_code == 0 and not self.timed_out

    def describe(self) -> str:
        if self.timed_out:
            return f"timed out after {self.seconds:.0f} s (process group killed)"
        if self.signal:
            return f"killed by {self.signal}"
        return f"exit code {self.exit_code}"


def _child_setup(cores: Cores) -> None:
    """In the child before it starts: die with this process; run on ``cores`` only."""
    if sys.platform.startswith("linux"):
        ctypes.CDLL(None, use_errno=True).prctl(_PR_SET_PDEATHSIG, signal.SIGKILL)
    if cores is not None:
        os.sched_setaffinity(0, cores)


def _kill_group(proc: subprocess.Popen) -> None:
    try:
        os.killpg(proc.pid, signal.SIGKILL)
    except ProcessLookupError:
        pass


def _tail(path: Path, limit: int = STDERR_TAIL_BYTES) -> str:
    if not path.is_file():
        return ""
    with path.open("rb") as f:
        f.seek(max(0, path.stat().st_size - limit))
        return f.read().decode("utf-8", "replace")


def run(cmd: Sequence[str], timeout: float, log_stem: Path, env: dict[str, str] | None = None,
        cwd: Path | None = None, cores: Cores = None) -> Outcome:
    """Run ``cmd`` on ``cores`` (None: wherever this process may run); stdout/stderr go to ``<log_stem>.out`` /
    ``.err``."""
    if STOPPING.is_set():
        raise RuntimeError("shutting down: no new child processes")
    log_stem.parent.mkdir(parents=True, exist_ok=True)
    err_path = log_stem.with_suffix(".err")
    start = time.monotonic()
    with open(log_stem.with_suffix(".out"), "wb") as out, open(err_path, "wb") as err:
        proc = subprocess.Popen(list(cmd), stdout=out, stderr=err, stdin=subprocess.DEVNULL, env=env,
                                cwd=cwd, start_new_session=True, preexec_fn=partial(_child_setup, cores))
        with _live_lock:
            _live[proc.pid] = proc
            if STOPPING.is_set():  # kill_all ran while this child was starting
                _kill_group(proc)
        timed_out = False
        try:
            proc.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            timed_out = True
        finally:
            _kill_group(proc)  # also reaps anything the child left running in its group
            proc.wait()
            with _live_lock:
                _live.pop(proc.pid, None)
    code = proc.returncode
    sig = signal.Signals(-code).name if code < 0 else None
    return Outcome(None if code < 0 else code, sig, timed_out, time.monotonic() - start, _tail(err_path))


def kill_all() -> None:
    """Kill every running child group and refuse new ones (on SIGINT/SIGTERM of the orchestrator)."""
    STOPPING.set()
    with _live_lock:
        procs = list(_live.values())
    for proc in procs:
        _kill_group(proc)
