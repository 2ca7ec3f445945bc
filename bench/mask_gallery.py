"""Render every procedural mask, tiled 2x2 to show that the seams vanish.

    python bench/mask_gallery.py [--out docs/reports/mask_gallery.png] [--size 256] [--seed 0]
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from richmat_addon.core import masks  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("docs/reports/mask_gallery.png"))
    parser.add_argument("--size", type=int, default=256)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()

    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    every = {**{f"dust: {k}": f for k, f in masks.DUST_MASKS.items()},
             **{f"coat damage: {k}": f for k, f in masks.DAMAGE_MASKS.items()}}
    fig, axes = plt.subplots(1, len(every), figsize=(3.2 * len(every), 3.5))
    for ax, (title, fn) in zip(axes, every.items()):
        tile = fn(args.size, np.random.default_rng(args.seed))
        ax.imshow(np.tile(tile, (2, 2)), cmap="gray", vmin=0, vmax=1)
        ax.axhline(args.size - 0.5, color="r", lw=0.5, ls=":")
        ax.axvline(args.size - 0.5, color="r", lw=0.5, ls=":")
        ax.set_title(title, fontsize=9)
        ax.axis("off")
    fig.suptitle("procedural masks, each tiled 2x2 (red dots: tile seams)", fontsize=10)
    fig.tight_layout()
    fig.savefig(args.out, dpi=100)


if __name__ == "__main__":
    main()
