"""Reading a fit's error: the grade of the one number per material, and the heat colours of its
per-texel map. The number is computed by the torch fit (``torch_models/neural/fit_error.py``)
and kept by ``neural_folder``; this module is torch- and bpy-free so a stock Blender reads it.

The thresholds are calibrated against ball FLIP (docs/addon.md, "Fit error"): below ``GOOD``
the fitted material's ball renders at FLIP <= 0.05 (Table 1's medians) in most cases, above
``POOR`` at FLIP >= 0.10 (Table 1's worst target).
"""
from __future__ import annotations

MEASURE = "relative error of log(1 + reflected light)"  # what the number is; written beside it in neural.json
GOOD = 0.10
POOR = 0.25
GRADES = ("good", "visible", "poor")
# Heat map stops (linear RGB) at error 0, GOOD and POOR; beyond POOR the map stays red.
HEAT = ((0.0, (0.0, 0.5, 0.05)), (GOOD, (1.0, 0.85, 0.0)), (POOR, (0.9, 0.02, 0.0)))


def grade(error: float) -> str:
    """The word shown beside a material's fit error: good, visible or poor."""
    if error <= GOOD:
        return GRADES[0]
    return GRADES[1] if error <= POOR else GRADES[2]
