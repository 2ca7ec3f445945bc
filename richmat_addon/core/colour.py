"""Colour-space transfer curves and luminance weights, in one place so every reader decodes texels the same way.

The add-on's Principled BSDF reader, the farm and the glTF reader all linearise
sRGB-tagged textures with this curve, as Cycles does before shading.
"""
from __future__ import annotations

import numpy as np

LUMINANCE = (0.2126, 0.7152, 0.0722)  # Rec. 709 weights of linear RGB: Blender's scene-linear primaries


def srgb_to_linear(x: np.ndarray) -> np.ndarray:
    """The sRGB electro-optical transfer function (IEC 61966-2-1), float in, float32 out."""
    x = np.asarray(x, dtype=np.float32)
    return np.where(x <= 0.04045, x / 12.92, ((x + 0.055) / 1.055) ** 2.4).astype(np.float32)
