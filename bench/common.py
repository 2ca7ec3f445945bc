"""What every bench report shares: its provenance, how it is written, how its charts start.

A report records the git commit (and whether the tree had uncommitted changes), the
command line, the date, the machine, and the sha256 of each decoder and generator
weights file it used, so a number quoted in the docs can be traced to the code and
weights that produced it.
"""
from __future__ import annotations

import argparse
import datetime
import hashlib
import json
import os
import platform
import shlex
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def _git(*args: str) -> str:
    return subprocess.run(["git", *args], cwd=REPO, capture_output=True, text=True).stdout.strip()


def file_sha256(path: Path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def _shown(path: Path) -> str:
    """A path relative to the repository when it is inside it."""
    full = Path(path).resolve()
    return str(full.relative_to(REPO)) if full.is_relative_to(REPO) else str(full)


def provenance(decoders: list[Path] = (), generator: Path | None = None) -> dict:
    """The report's ``provenance`` block; ``decoders`` are weights folders, ``generator`` a checkpoint file."""
    out = {"git_commit": _git("rev-parse", "HEAD"), "tree_dirty": bool(_git("status", "--porcelain", "--untracked-files=no")),
           "command": shlex.join(["python", os.path.relpath(sys.argv[0], REPO), *sys.argv[1:]]),
           "date": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
           "machine": {"platform": platform.platform(), "processor": platform.machine(), "cpus": os.cpu_count()},
           "decoder_sha256": {_shown(d): file_sha256(Path(d) / "weights.safetensors") for d in decoders}}
    if generator is not None:
        out["generator_sha256"] = file_sha256(generator)
    return out


def write_report(out: Path, report: dict) -> None:
    """The report as indented JSON, its folder made if missing."""
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(report, indent=1))


def pyplot():  # type: ignore[no-untyped-def]
    """matplotlib.pyplot on the file-only Agg backend (benches run headless)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def add_weights_argument(parser: argparse.ArgumentParser) -> None:
    """``--weights``, repeatable: the decoders a bench measures side by side on the same inputs."""
    parser.add_argument("--weights", type=Path, action="append",
                        help="a decoder's weights folder; repeat to compare decoders (default: the shipped one)")


def weights_folders(args: argparse.Namespace) -> list[Path]:
    """The folders ``--weights`` named, or the shipped decoder's."""
    from torch_models.neural import weights

    return args.weights or [weights.SHIPPED]
