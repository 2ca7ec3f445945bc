"""Colour-space transfer curves and luminance weights, in one place so every reader decodes texels the same way.

The add-on's Principled BSDF reader, the farm and the glTF reader all linearise
sRGB-tagged textures with the exact curve, as Cycles does before shading. The generator's
corpus keeps a plain 2.2 power instead (``gamma_to_linear``, ``linear_to_gamma``): the
shipped generator was trained on colours and captions made with it.
"""
from __future__ import annotations

import numpy as np

LUMINANCE = (0.2126, 0.7152, 0.0722)  # Rec. 709 weights of linear RGB: Blender's scene-linear primaries
CORPUS_GAMMA = 2.2  # the corpus's stand-in for the sRGB curve, at most 0.0085 from it


def srgb_to_linear(x: np.ndarray) -> np.ndarray:
    """The sRGB electro-optical transfer function (IEC 61966-2-1), float in, float32 out."""
    x = np.asarray(x, dtype=np.float32)
    return np.where(x <= 0.04045, x / 12.92, ((x + 0.055) / 1.055) ** 2.4).astype(np.float32)


def gamma_to_linear(x: np.ndarray) -> np.ndarray:
    """Linear values of 2.2-gamma-encoded ones: how the procedural corpus decodes its drawn colours."""
    return np.asarray(x) ** CORPUS_GAMMA


def linear_to_gamma(x: float) -> float:
    """A linear value clipped to [0, 1] and encoded with a 1/2.2 power: how captions read a base colour."""
    return max(0.0, min(1.0, x)) ** (1 / CORPUS_GAMMA)
