"""Mean FLIP between two renders, with one stated convention.

Convention used everywhere in richmat: LDR-FLIP (NVIDIA's ``flip-evaluator``)
on display-referred images, i.e. both renders tone mapped with Blender's AgX to
sRGB-encoded values in [0, 1] (``inputsRGB=True``), at 67 pixels per degree
(the package's default: a 0.7 m viewing distance, 3840 px across 0.7 m).
"""
from __future__ import annotations

import numpy as np

PPD = 67.02


def flip_map(reference: np.ndarray, test: np.ndarray, ppd: float = PPD) -> tuple[np.ndarray, float]:
    """Per-pixel FLIP error (H, W) and its mean, for sRGB images in [0, 1] (H, W, 3)."""
    import flip_evaluator

    if reference.shape != test.shape or reference.shape[-1] != 3:
        raise ValueError(f"FLIP needs two RGB images of one size, got {reference.shape} and {test.shape}")
    ref = np.ascontiguousarray(np.clip(reference, 0, 1), np.float32)
    tst = np.ascontiguousarray(np.clip(test, 0, 1), np.float32)
    error, mean, _ = flip_evaluator.evaluate(ref, tst, "LDR", inputsRGB=True, applyMagma=False,
                                             computeMeanError=True, parameters={"ppd": ppd})
    return error[..., 0], float(mean)


def mean_flip(reference: np.ndarray, test: np.ndarray, ppd: float = PPD) -> float:
    return flip_map(reference, test, ppd)[1]
