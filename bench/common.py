"""What every bench shares: where its report goes, how it is written, how its charts look.

A report records the git commit (and whether the tree had uncommitted changes), the
command line, the date, the machine, and the sha256 of each decoder and generator
weights file it used, so a number quoted in the docs can be traced to the code and
weights that produced it. A bench whose only output is a figure writes the same
record into the PNG's text.

Benches run from the repository root as modules (``python -m bench.fit_flip``);
a child process they start (a Cycles render with the pip bpy module) goes through
``run_python``, which makes the repository importable there too.
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
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import numpy as np

REPO = Path(__file__).resolve().parents[1]
REPORTS = REPO / "docs" / "reports"
FLIP_CONVENTION = "LDR-FLIP on AgX-tone-mapped sRGB, 67.02 pixels per degree"
TARGET_MEDIAN, TARGET_WORST = 0.05, 0.12  # Table 1's targets: median and worst FLIP per type
CHART_DPI = 110


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


def add_out_argument(parser: argparse.ArgumentParser, name: str) -> None:
    """``--out``, by default ``docs/reports/NAME``; charts and sheets go beside it."""
    parser.add_argument("--out", type=Path, default=REPORTS / name,
                        help=f"report file (default: docs/reports/{name}); charts beside it")


def write_report(out: Path, report: dict, decoders: Iterable[Path] = (), generator: Path | None = None) -> None:
    """The report as indented JSON with its provenance, its folder made if missing."""
    out.parent.mkdir(parents=True, exist_ok=True)
    text = json.dumps({**report, "provenance": provenance(decoders, generator)}, indent=1, ensure_ascii=False)
    out.write_text(text, encoding="utf-8")


def pyplot():  # type: ignore[no-untyped-def]
    """matplotlib.pyplot on the file-only Agg backend (benches run headless)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def save_chart(fig: Any, path: Path, record: dict | None = None) -> None:
    """The figure, laid out tight, as a PNG; ``record`` (a provenance block) goes into its text
    where the figure is the bench's only output."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.tight_layout()
    fig.savefig(path, dpi=CHART_DPI, bbox_inches="tight",  # titles above image panels are not clipped
                metadata={"Comment": json.dumps(record)} if record else None)
    pyplot().close(fig)


def target_lines(ax: Any, labelled: bool = True) -> None:
    """Table 1's targets as horizontal lines: dashed median, dotted worst."""
    ax.axhline(TARGET_MEDIAN, ls="--", color="gray", lw=0.8, label=f"target median {TARGET_MEDIAN}" if labelled else None)
    ax.axhline(TARGET_WORST, ls=":", color="gray", lw=0.8, label=f"target worst {TARGET_WORST}" if labelled else None)


def contact_sheet(rows: list[tuple[str, np.ndarray, np.ndarray, np.ndarray]], path: Path) -> None:
    """Display-referred images side by side, one row per (name, first, second, FLIP map)."""
    from PIL import Image

    def u8(x: np.ndarray) -> np.ndarray:
        return (np.clip(x, 0, 1) * 255 + 0.5).astype(np.uint8)

    sheet = [np.concatenate([u8(a), u8(b), u8(np.repeat(e[..., None], 3, -1))], 1) for _, a, b, e in rows]
    Image.fromarray(np.concatenate(sheet, 0)).save(path)


def child_env(blender_user: Path | None = None) -> dict[str, str]:
    """The environment of a child process: the repository importable (the packages and
    ``python -m bench.NAME``), and Blender's user folder at ``blender_user`` when given."""
    env = dict(os.environ, PYTHONPATH=str(REPO))
    if blender_user is not None:
        env["BLENDER_USER_RESOURCES"] = str(blender_user)
    return env


def run_python(args: list[str], folder: Path) -> None:
    """``python ARGS`` in a child process (the pip bpy module's Blender), Blender's user folder
    inside ``folder``; exits with its output on failure."""
    proc = subprocess.run([sys.executable, *args], env=child_env(folder / "blender_user"), cwd=REPO,
                          capture_output=True, text=True)
    if proc.returncode != 0:
        raise SystemExit(f"python {shlex.join(args)} failed:\n{proc.stdout[-2000:]}\n{proc.stderr[-2000:]}")


def add_weights_argument(parser: argparse.ArgumentParser) -> None:
    """``--weights``, repeatable: the decoders a bench measures side by side on the same inputs."""
    parser.add_argument("--weights", type=Path, action="append",
                        help="a decoder's weights folder; repeat to compare decoders (default: the shipped one)")


def weights_folders(args: argparse.Namespace) -> list[Path]:
    """The folders ``--weights`` named, or the shipped decoder's."""
    from torch_models.neural import weights

    return args.weights or [weights.SHIPPED]
