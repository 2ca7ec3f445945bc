"""Render every procedural mask, tiled 2x2 to show that the seams vanish.

    python -m bench.material.mask_gallery [--out docs/reports/mask_gallery.png] [--size 256] [--seed 0]

The figure is the report: its provenance is in the PNG's text.
"""
from __future__ import annotations

import argparse

import numpy as np

from bench.common import add_out_argument, provenance, pyplot, save_chart
from richmat_addon.core import masks


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_out_argument(parser, "mask_gallery.png")
    parser.add_argument("--size", type=int, default=256)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()

    plt = pyplot()
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
    save_chart(fig, args.out, provenance())


if __name__ == "__main__":
    main()
