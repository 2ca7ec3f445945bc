"""Reading a fit's error: the grade of the one number per material, and the heat colours of its
per-texel map. The number is computed by the torch fit (``torch_models/neural/fit/error.py``)
and kept by ``neural_folder``; this module is torch- and bpy-free so a stock Blender reads it.

The thresholds come from Table 1's fitted materials beside their ball FLIP
(bench/addon/fit_error_calibration.py; the numbers in docs/addon.md, "Fit error"); ``POOR``
marks the worst eighth of the errors.
"""
from __future__ import annotations

MEASURE = "relative error of log(1 + reflected light)"  # what the number is; written beside it in neural.json
GOOD = 0.05
POOR = 0.08
GRADES = ("good", "visible", "poor")
# Heat map stops (linear RGB) at error 0, GOOD and POOR; beyond POOR the map stays red.
HEAT = ((0.0, (0.0, 0.5, 0.05)), (GOOD, (1.0, 0.85, 0.0)), (POOR, (0.9, 0.02, 0.0)))


def grade(error: float) -> str:
    """The word shown beside a material's fit error: good, visible or poor."""
    if error <= GOOD:
        return GRADES[0]
    return GRADES[1] if error <= POOR else GRADES[2]
