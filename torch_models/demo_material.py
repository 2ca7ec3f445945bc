"""The built-in default input: a procedural PBR material on a UV sphere.

`make demo` must work in a fresh clone with no assets beside it, so the demo
material is generated: chipped red paint over brushed steel, with roughness
that varies with wear. Mostly dielectric (paint), so all six types apply. The
sphere's equirectangular UV layout gives exact world normals and positions per
texel, which the dust rule needs.
"""
from __future__ import annotations

import numpy as np

from richmat_addon.core.maps import ParamMap, PbrInputs
from richmat_addon.core.masks import periodic_noise


def chipped_paint(size: int = 256, seed: int = 0) -> PbrInputs:
    rng = np.random.default_rng(seed)
    chips = periodic_noise(size, 0.03, rng) > 0.8  # bare metal where the paint chipped off
    wear = periodic_noise(size, 0.1, rng)
    grain = periodic_noise(size, 0.004, rng)
    paint = np.array([0.55, 0.06, 0.04], np.float32) * (0.85 + 0.3 * wear[..., None])
    steel = np.array([0.62, 0.62, 0.64], np.float32) * (0.9 + 0.2 * grain[..., None])
    base = np.where(chips[..., None], steel, paint)
    rough = np.where(chips, 0.25 + 0.1 * grain, 0.35 + 0.3 * wear)[..., None]
    return PbrInputs("chipped_paint", ParamMap(base.astype(np.float32)),
                     ParamMap(rough.astype(np.float32)),
                     ParamMap(chips[..., None].astype(np.float32)))


def sphere_texel_geometry(height: int, width: int) -> tuple[ParamMap, ParamMap]:
    """World normals and positions of a unit UV sphere at texel centres.

    u runs around +z (longitude), v from the south pole (row H-1) to the north
    pole (row 0), so up-facing texels are at the top of the image.
    """
    v = 1.0 - (np.arange(height) + 0.5) / height
    u = (np.arange(width) + 0.5) / width
    theta = np.pi * (v - 0.5)  # latitude
    phi = 2.0 * np.pi * u
    lat, lon = np.meshgrid(theta, phi, indexing="ij")
    n = np.stack([np.cos(lat) * np.cos(lon), np.cos(lat) * np.sin(lon), np.sin(lat)], -1)
    return ParamMap(n.astype(np.float32)), ParamMap(n.astype(np.float32))


def sphere_uv(normals: np.ndarray) -> np.ndarray:
    """(u, v) of world normals on the same layout, for texture lookups on a ball."""
    u = (np.arctan2(normals[..., 1], normals[..., 0]) / (2 * np.pi)) % 1.0
    v = np.arcsin(np.clip(normals[..., 2], -1, 1)) / np.pi + 0.5
    return np.stack([u, v], -1)
