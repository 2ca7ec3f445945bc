"""The table of named colours a prompt's colour words are read against.

Two lists a maintained package carries, as matplotlib ships them (``matplotlib._color_data``):
the XKCD colour survey's 949 names (what people called each colour they were shown, so "red",
"dark red", "pale blue", "off white" are what people mean by them) and, where the survey lacks a
name, the 148 CSS4 names ("crimson", "navy"). Stored as ``data/named_colours.json`` because a
stock Blender has no matplotlib; ``python -m richmat_addon.core.named_colours`` rewrites the file
from the installed matplotlib (``tests/test_prompt_reading.py`` checks that they agree).
"""
from __future__ import annotations

import json
from functools import cache
from pathlib import Path

import numpy as np

from .colour import srgb_to_linear

TABLE = Path(__file__).resolve().parent / "data" / "named_colours.json"
SOURCE = "matplotlib._color_data: XKCD_COLORS (xkcd colour survey), then CSS4_COLORS names the survey lacks"


def normalised(name: str) -> str:
    """How names are compared: lower case, hyphens as spaces ("Off-White" -> "off white")."""
    return " ".join(name.lower().replace("-", " ").split())


@cache
def table() -> dict[str, np.ndarray]:
    """Name -> linear sRGB colour (the sRGB hex decoded with the exact curve)."""
    hexes = json.loads(TABLE.read_text())["colours"]
    return {name: srgb_to_linear(np.array([int(h[i:i + 2], 16) for i in (1, 3, 5)]) / 255.0)
            for name, h in hexes.items()}


def from_matplotlib() -> dict[str, str]:
    """The table as the installed matplotlib holds it: name -> "#rrggbb"."""
    from matplotlib import _color_data

    colours = {normalised(k.removeprefix("xkcd:")): v.lower() for k, v in _color_data.XKCD_COLORS.items()}
    for k, v in _color_data.CSS4_COLORS.items():
        colours.setdefault(normalised(k), v.lower())
    return dict(sorted(colours.items()))


if __name__ == "__main__":
    TABLE.write_text(json.dumps({"source": SOURCE, "colours": from_matplotlib()}, indent=0) + "\n")
    print(f"wrote {TABLE}")
