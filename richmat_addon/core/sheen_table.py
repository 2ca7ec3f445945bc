"""Cycles' microfiber sheen as a table: the LTC's A and B and the albedo R over (roughness, mu).

Measured from Cycles by bench/material/calibrate_sheen.py and kept here, the lowest floor, because
both the torch lobes (``torch_models/brdf/tables.py``) and the neural preview's shader
(``neural_osl_hybrid``, which divides the sheen closure by R) read it.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

SHEEN_TABLE_FILE = Path(__file__).with_name("data") / "sheen_ltc.npy"


def sheen_table() -> np.ndarray:
    """[A, B, R][roughness 32][mu 32], float64, nodes at i / 31 on both axes."""
    return np.load(SHEEN_TABLE_FILE)
