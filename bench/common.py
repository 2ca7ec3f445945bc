"""What every bench shares: where its report goes, how its charts look, its child processes.

A report is written with ``write_report`` (``support.reports``: the provenance that traces a
number quoted in the docs to the code and weights that produced it). A bench whose only output
is a figure writes the same record (``provenance``) into the PNG's text.

Benches run from the repository root as modules (``python -m bench.neural.fit_flip``);
a child process they start (a Cycles render with the pip bpy module) goes through
``run_python``, which makes the repository importable there too.
"""
from __future__ import annotations

import argparse
import json
import os
import shlex
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np

from support.paths import REPO
from support.reports import file_sha256, provenance, write_report  # noqa: F401  (the benches' report writer)

REPORTS = REPO / "docs" / "reports"
FLIP_CONVENTION = "LDR-FLIP on AgX-tone-mapped sRGB, 67.02 pixels per degree"
TARGET_MEDIAN, TARGET_WORST = 0.05, 0.12  # Table 1's targets: median and worst FLIP per type
CHART_DPI = 110


def add_out_argument(parser: argparse.ArgumentParser, name: str) -> None:
    """``--out``, by default ``docs/reports/NAME``; charts and sheets go beside it."""
    parser.add_argument("--out", type=Path, default=REPORTS / name,
                        help=f"report file (default: docs/reports/{name}); charts beside it")


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
    from torch_models.neural import trained

    return args.weights or [trained.SHIPPED]
