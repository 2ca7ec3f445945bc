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


def linear_to_srgb(x: np.ndarray) -> np.ndarray:
    """The inverse of ``srgb_to_linear`` (IEC 61966-2-1), clipped to [0, 1] first."""
    x = np.clip(np.asarray(x, dtype=np.float64), 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * x ** (1 / 2.4) - 0.055)


# Linear sRGB (Rec. 709 primaries) to CIE XYZ, and the D65 white the sRGB standard sets.
_RGB_TO_XYZ = np.array([[0.4124564, 0.3575761, 0.1804375],
                        [0.2126729, 0.7151522, 0.0721750],
                        [0.0193339, 0.1191920, 0.9503041]])
_WHITE_D65 = _RGB_TO_XYZ.sum(1)
_EPSILON, _KAPPA = 216 / 24389, 24389 / 27  # CIE's exact constants of the L* curve


def linear_to_lab(rgb: np.ndarray) -> np.ndarray:
    """(..., 3) linear sRGB to CIELAB under D65: the space colour names and CIEDE2000 are judged in."""
    t = (np.asarray(rgb, np.float64) @ _RGB_TO_XYZ.T) / _WHITE_D65
    f = np.where(t > _EPSILON, np.cbrt(t), (_KAPPA * t + 16) / 116)
    return np.stack([116 * f[..., 1] - 16, 500 * (f[..., 0] - f[..., 1]), 200 * (f[..., 1] - f[..., 2])], -1)


def lab_to_linear(lab: np.ndarray) -> np.ndarray:
    """(..., 3) CIELAB under D65 to linear sRGB (not clipped: a Lab colour may lie outside the gamut)."""
    lab = np.asarray(lab, np.float64)
    fy = (lab[..., 0] + 16) / 116
    f = np.stack([fy + lab[..., 1] / 500, fy, fy - lab[..., 2] / 200], -1)
    t = np.where(f ** 3 > _EPSILON, f ** 3, (116 * f - 16) / _KAPPA)
    return (t * _WHITE_D65) @ np.linalg.inv(_RGB_TO_XYZ).T


def ciede2000(lab1: np.ndarray, lab2: np.ndarray) -> np.ndarray:
    """CIEDE2000 colour difference of (..., 3) CIELAB colours, kL = kC = kH = 1, as Sharma, Wu and Dalal
    (2005), "The CIEDE2000 color-difference formula: implementation notes", eqs. (1)-(17) write it."""
    l1, a1, b1 = np.moveaxis(np.asarray(lab1, np.float64), -1, 0)
    l2, a2, b2 = np.moveaxis(np.asarray(lab2, np.float64), -1, 0)
    c_mean = (np.hypot(a1, b1) + np.hypot(a2, b2)) / 2
    g = 0.5 * (1 - np.sqrt(c_mean ** 7 / (c_mean ** 7 + 25.0 ** 7)))
    a1p, a2p = (1 + g) * a1, (1 + g) * a2
    c1p, c2p = np.hypot(a1p, b1), np.hypot(a2p, b2)
    h1p = np.where(c1p == 0, 0.0, np.degrees(np.arctan2(b1, a1p)) % 360)
    h2p = np.where(c2p == 0, 0.0, np.degrees(np.arctan2(b2, a2p)) % 360)
    dl, dc = l2 - l1, c2p - c1p
    dh = h2p - h1p
    half_turn = 180 + 1e-9  # hues exactly opposite (Sharma's pair 14) land a rounding error past 180
    dh = np.where(c1p * c2p == 0, 0.0, np.where(dh > half_turn, dh - 360, np.where(dh < -half_turn, dh + 360, dh)))
    dhh = 2 * np.sqrt(c1p * c2p) * np.sin(np.radians(dh) / 2)
    l_mean, cp_mean = (l1 + l2) / 2, (c1p + c2p) / 2
    h_sum = h1p + h2p
    h_mean = np.where(c1p * c2p == 0, h_sum,
                      np.where(np.abs(h1p - h2p) <= half_turn, h_sum / 2,
                               np.where(h_sum < 360, (h_sum + 360) / 2, (h_sum - 360) / 2)))
    t = (1 - 0.17 * np.cos(np.radians(h_mean - 30)) + 0.24 * np.cos(np.radians(2 * h_mean))
         + 0.32 * np.cos(np.radians(3 * h_mean + 6)) - 0.20 * np.cos(np.radians(4 * h_mean - 63)))
    d_theta = 30 * np.exp(-(((h_mean - 275) / 25) ** 2))
    r_c = 2 * np.sqrt(cp_mean ** 7 / (cp_mean ** 7 + 25.0 ** 7))
    s_l = 1 + 0.015 * (l_mean - 50) ** 2 / np.sqrt(20 + (l_mean - 50) ** 2)
    s_c, s_h = 1 + 0.045 * cp_mean, 1 + 0.015 * cp_mean * t
    r_t = -np.sin(np.radians(2 * d_theta)) * r_c
    return np.sqrt((dl / s_l) ** 2 + (dc / s_c) ** 2 + (dhh / s_h) ** 2 + r_t * (dc / s_c) * (dhh / s_h))
