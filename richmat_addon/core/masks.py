"""Procedural masks that tile seamlessly, in numpy only (runs inside Blender).

Every mask is built on a torus: noise is white noise low-pass filtered in the
Fourier domain (periodic by construction) and shapes are placed with
wrap-around distances, so the left edge continues into the right edge and the
top into the bottom. Values are in [0, 1]; damage masks are binary.
"""
from __future__ import annotations

from typing import Callable

import numpy as np

Rng = np.random.Generator


def periodic_noise(size: int, feature: float, rng: Rng, aniso: float = 1.0,
                   angle: float = 0.0) -> np.ndarray:
    """Smooth tileable noise in [0, 1]; ``feature`` is the blob size as a fraction of the tile."""
    white = rng.standard_normal((size, size))
    f = np.fft.fftfreq(size)
    fy, fx = np.meshgrid(f, f, indexing="ij")
    c, s = np.cos(angle), np.sin(angle)
    u, v = c * fx + s * fy, -s * fx + c * fy
    sigma = 1.0 / (2.0 * np.pi * feature * size)
    spectrum = np.exp(-0.5 * ((u / sigma) ** 2 + (v * aniso / sigma) ** 2))
    field = np.real(np.fft.ifft2(np.fft.fft2(white) * spectrum))
    return _normalise(field)


def _normalise(x: np.ndarray) -> np.ndarray:
    lo, hi = float(x.min()), float(x.max())
    return ((x - lo) / (hi - lo)).astype(np.float32) if hi > lo else np.zeros_like(x, np.float32)


def _grid(size: int) -> tuple[np.ndarray, np.ndarray]:
    t = (np.arange(size) + 0.5) / size
    return np.meshgrid(t, t, indexing="ij")  # (y, x) in [0, 1)


def _wrap(d: np.ndarray) -> np.ndarray:
    """Shortest signed distance on the unit torus."""
    return d - np.round(d)


def fingerprints(size: int, rng: Rng, count: int = 6) -> np.ndarray:
    """Whorls of ridge lines inside soft elliptical patches."""
    y, x = _grid(size)
    out = np.zeros((size, size), np.float32)
    for _ in range(count):
        cy, cx = rng.random(2)
        dy, dx = _wrap(y - cy), _wrap(x - cx)
        a = rng.uniform(0, np.pi)
        u, v = np.cos(a) * dx + np.sin(a) * dy, -np.sin(a) * dx + np.cos(a) * dy
        r = np.sqrt((u / 0.06) ** 2 + (v / 0.045) ** 2)
        ridges = 0.5 + 0.5 * np.sin(2 * np.pi * 9.0 * r + rng.uniform(0, 2 * np.pi))
        out = np.maximum(out, ridges * np.clip(1.5 - r, 0.0, 1.0) ** 0.5 * (r < 1.5))
    return out


def wipes(size: int, rng: Rng) -> np.ndarray:
    """Smeared streaks: strongly anisotropic noise, soft-thresholded."""
    n = periodic_noise(size, 0.025, rng, aniso=6.0, angle=rng.uniform(0, np.pi))
    return np.clip((n - 0.45) / 0.25, 0.0, 1.0).astype(np.float32)


def ripples(size: int, rng: Rng, count: int = 3) -> np.ndarray:
    """Interfering rings, as dust left by dried droplets or a swirled cloth."""
    y, x = _grid(size)
    waves = np.zeros((size, size))
    for _ in range(count):
        cy, cx = rng.random(2)
        r = np.hypot(_wrap(y - cy), _wrap(x - cx))
        waves += np.sin(2 * np.pi * rng.uniform(8, 14) * r) * np.exp(-r / 0.3)
    return _normalise(waves)


def scratches(size: int, rng: Rng, count: int = 40) -> np.ndarray:
    """Thin straight scratches (binary), wrapping around the tile."""
    y, x = _grid(size)
    out = np.zeros((size, size), bool)
    for _ in range(count):
        cy, cx = rng.random(2)
        a = rng.uniform(0, np.pi)
        half, width = rng.uniform(0.03, 0.2), rng.uniform(0.6, 1.5) / size
        dy, dx = _wrap(y - cy), _wrap(x - cx)
        along = np.cos(a) * dx + np.sin(a) * dy
        across = -np.sin(a) * dx + np.cos(a) * dy
        out |= (np.abs(across) < width) & (np.abs(along) < half)
    return out.astype(np.float32)


def dents(size: int, rng: Rng) -> np.ndarray:
    """Small round dents (binary): the peaks of fine noise."""
    n = periodic_noise(size, 0.012, rng)
    return (n > 0.78).astype(np.float32)


DUST_MASKS: dict[str, Callable[[int, Rng], np.ndarray]] = {
    "fingerprints": fingerprints, "wipes": wipes, "ripples": ripples}
DAMAGE_MASKS: dict[str, Callable[[int, Rng], np.ndarray]] = {"scratches": scratches, "dents": dents}


def triplanar(mask: np.ndarray, positions: np.ndarray, normals: np.ndarray,
              scale: float = 1.0, sharpness: float = 4.0) -> np.ndarray:
    """Sample a tiling mask by world position, blending the three axis projections.

    Weights are |n|^sharpness normalised to sum to 1, so a face sees the
    projection it is most aligned with and seams are blended.
    """
    w = np.abs(normals) ** sharpness
    w = w / np.maximum(w.sum(-1, keepdims=True), 1e-12)
    size = mask.shape[0]

    def lookup(a: np.ndarray, b: np.ndarray) -> np.ndarray:
        i = np.floor(a * scale * size).astype(np.int64) % size
        j = np.floor(b * scale * size).astype(np.int64) % size
        return mask[i, j]

    p = positions
    return (w[..., 0] * lookup(p[..., 1], p[..., 2]) + w[..., 1] * lookup(p[..., 0], p[..., 2])
            + w[..., 2] * lookup(p[..., 0], p[..., 1])).astype(np.float32)
