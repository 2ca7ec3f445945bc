"""A report's provenance: the git commit (and whether the tree had uncommitted changes), the command line, the
date, the machine, and the sha256 of each decoder and generator weights file it used, so a number quoted in
the docs can be traced to the code and weights that produced it (tests/test_docs_reports.py holds the cited
reports to it). The benches write their reports with ``write_report``.
"""
from __future__ import annotations

import datetime
import hashlib
import json
import os
import platform
import shlex
import subprocess
import sys
from collections.abc import Iterable
from pathlib import Path

from .paths import REPO


def _git(*args: str) -> str:
    return subprocess.run(["git", *args], cwd=REPO, capture_output=True, text=True).stdout.strip()


def file_sha256(path: Path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def _shown(path: Path) -> str:
    """A path relative to the repository when it is inside it."""
    full = Path(path).resolve()
    return str(full.relative_to(REPO)) if full.is_relative_to(REPO) else str(full)


def _command() -> str:
    """The command line as it was typed: ``python -m bench.NAME ARGS``."""
    spec = sys.modules["__main__"].__spec__
    run = ["-m", spec.name] if spec is not None else [_shown(Path(sys.argv[0]))]
    return shlex.join(["python", *run, *sys.argv[1:]])


def provenance(decoders: Iterable[Path] = (), generator: Path | None = None) -> dict:
    """The report's ``provenance`` block; ``decoders`` and ``generator`` are weights folders."""
    # a bench rewrites its own reports as it goes: only changes outside docs/reports/ make the tree dirty
    dirty = _git("status", "--porcelain", "--untracked-files=no", "--", ".", ":(exclude)docs/reports")
    out = {"git_commit": _git("rev-parse", "HEAD"), "tree_dirty": bool(dirty),
           "command": _command(), "date": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
           "machine": {"platform": platform.platform(), "processor": platform.machine(), "cpus": os.cpu_count()},
           "decoder_sha256": {_shown(d): file_sha256(Path(d) / "weights.safetensors") for d in decoders}}
    if generator is not None:
        out["generator_sha256"] = file_sha256(Path(generator) / "weights.safetensors")
    return out


def write_report(out: Path, report: dict, decoders: Iterable[Path] = (), generator: Path | None = None) -> None:
    """The report as indented JSON with its provenance, its folder made if missing."""
    out.parent.mkdir(parents=True, exist_ok=True)
    text = json.dumps({**report, "provenance": provenance(decoders, generator)}, indent=1, ensure_ascii=False)
    out.write_text(text, encoding="utf-8")
