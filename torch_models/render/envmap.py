"""An equirectangular light probe, looked up and importance-sampled as Cycles does.

Blender's convention (checked against a Cycles render in tests/test_render.py):
world +z is up, the image's top row looks up, and u runs clockwise seen from
above, with the image centre facing +x:

    u = 0.5 - atan2(y, x) / (2 pi),    v = 0.5 + elevation / pi   (v = 1: top row)

Radiance is bilinear between pixel centres (the Environment Texture node's
``Linear``); directions are sampled per pixel in proportion to luminance times
the pixel's solid angle (the
brightest neighbour's luminance, to cover the bilinear spread), so the pdf is piecewise constant over pixels.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import torch
from torch import Tensor

from ..brdf.model import luminance


def read_probe(path: Path) -> np.ndarray:
    """Scene-linear RGB (H, W, 3) float32 of an HDR/EXR probe; clear errors for bad files."""
    import OpenImageIO as oiio

    buf = oiio.ImageBuf(str(path))
    if buf.has_error:
        raise ValueError(f"{path}: cannot read the light probe ({buf.geterror().strip()})")
    pixels = buf.get_pixels(oiio.FLOAT)
    if pixels is None or pixels.ndim != 3 or pixels.shape[2] < 3:
        raise ValueError(f"{path}: a light probe needs RGB pixels")
    rgb = np.ascontiguousarray(pixels[..., :3], np.float32)
    h, w = rgb.shape[:2]
    if w != 2 * h:
        raise ValueError(f"{path}: an equirectangular probe is twice as wide as high, got {w}x{h}")
    if not np.isfinite(rgb).all() or (rgb < 0).any():
        raise ValueError(f"{path}: the light probe has negative or non-finite pixels")
    return rgb


def direction_to_uv(d: Tensor) -> Tensor:
    """(u, v) in [0, 1]^2 of unit world directions (..., 3)."""
    u = (0.5 - torch.atan2(d[..., 1], d[..., 0]) / (2.0 * math.pi)) % 1.0
    elevation = torch.atan2(d[..., 2], torch.hypot(d[..., 0], d[..., 1]))
    return torch.stack([u, 0.5 + elevation / math.pi], -1)


def uv_to_direction(uv: Tensor) -> Tensor:
    phi = (0.5 - uv[..., 0]) * 2.0 * math.pi
    elevation = (uv[..., 1] - 0.5) * math.pi
    c = elevation.cos()
    return torch.stack([c * phi.cos(), c * phi.sin(), elevation.sin()], -1)


class EnvMap:
    """A probe rotated by ``rotation_deg`` about +z, with its sampling tables."""

    def __init__(self, rgb: np.ndarray, rotation_deg: float = 0.0) -> None:
        self.rgb = torch.from_numpy(rgb)
        self.height, self.width = rgb.shape[:2]
        self.rotation = math.radians(rotation_deg)
        rows = torch.arange(self.height, dtype=torch.float64)
        elevation = (0.5 - (rows + 0.5) / self.height) * math.pi
        # Pixel solid angles, exact for each row band.
        band = (torch.sin(elevation + 0.5 * math.pi / self.height)
                - torch.sin(elevation - 0.5 * math.pi / self.height)) * 2.0 * math.pi / self.width
        # Bilinear lookup spreads a texel's radiance into its neighbours, so each
        # pixel is sampled by the brightest texel it touches: no fireflies where a
        # BSDF sample meets radiance that the light pdf never expected.
        lum = luminance(self.rgb.double()).squeeze(-1)
        wrapped = torch.cat([lum[:, -1:], lum, lum[:, :1]], 1)[None, None]
        lum = torch.nn.functional.max_pool2d(wrapped, 3, stride=1, padding=(1, 0))[0, 0]
        weight = lum * band[:, None]
        weight = weight + 1e-6 * weight.mean() + 1e-30  # every direction stays reachable
        self.pixel_prob = (weight / weight.sum()).float()  # (H, W)
        self.pixel_solid_angle = band.float()  # (H,)
        self.row_cdf = torch.cumsum(self.pixel_prob.sum(1).double(), 0).float()
        self.col_cdf = torch.cumsum(self.pixel_prob.double(), 1)
        self.col_cdf = (self.col_cdf / self.col_cdf[:, -1:]).float()

    @classmethod
    def load(cls, path: Path, rotation_deg: float = 0.0) -> "EnvMap":
        return cls(read_probe(path), rotation_deg)

    def _to_probe(self, d: Tensor, sign: float = 1.0) -> Tensor:
        """Rotate world directions into the probe's frame (sign -1: back).

        Like a Mapping node (type Point) rotating the lookup vector about +z.
        """
        a = sign * self.rotation
        c, s = math.cos(a), math.sin(a)
        return torch.stack([c * d[..., 0] - s * d[..., 1], s * d[..., 0] + c * d[..., 1], d[..., 2]], -1)

    def radiance(self, d: Tensor) -> Tensor:
        """Bilinear radiance (..., 3) seen along world directions d (..., 3)."""
        uv = direction_to_uv(self._to_probe(d))
        x = uv[..., 0] * self.width - 0.5
        y = (1.0 - uv[..., 1]) * self.height - 0.5
        x0, y0 = x.floor(), y.floor()
        fx, fy = (x - x0)[..., None], (y - y0)[..., None]
        x0, y0 = x0.long(), y0.long()

        def texel(yy: Tensor, xx: Tensor) -> Tensor:
            return self.rgb[yy.clamp(0, self.height - 1), xx % self.width]

        top = texel(y0, x0) * (1 - fx) + texel(y0, x0 + 1) * fx
        bottom = texel(y0 + 1, x0) * (1 - fx) + texel(y0 + 1, x0 + 1) * fx
        return top * (1 - fy) + bottom * fy

    def _pixel_of(self, d: Tensor) -> tuple[Tensor, Tensor]:
        uv = direction_to_uv(self._to_probe(d))
        col = (uv[..., 0] * self.width).long().clamp(0, self.width - 1)
        row = ((1.0 - uv[..., 1]) * self.height).long().clamp(0, self.height - 1)
        return row, col

    def pdf(self, d: Tensor) -> Tensor:
        """Solid-angle density of ``sample`` at world directions d, (...,)."""
        row, col = self._pixel_of(d)
        return self.pixel_prob[row, col] / self.pixel_solid_angle[row]

    def sample(self, u: Tensor) -> tuple[Tensor, Tensor]:
        """World directions for u in [0,1)^(N, 4) (row, column, position in the pixel) and their pdf."""
        row = torch.searchsorted(self.row_cdf, u[:, 0].contiguous(), right=True).clamp(max=self.height - 1)
        col = torch.searchsorted(self.col_cdf[row], u[:, 1:2].contiguous(), right=True).squeeze(1)
        col = col.clamp(max=self.width - 1)
        # Uniform in solid angle inside the pixel: uniform in u, uniform in sin(elevation).
        s_hi = math.pi * (0.5 - row.float() / self.height)
        s_lo = math.pi * (0.5 - (row.float() + 1) / self.height)
        sin_e = torch.sin(s_lo) + u[:, 3] * (torch.sin(s_hi) - torch.sin(s_lo))
        elevation = torch.asin(sin_e.clamp(-1.0, 1.0))
        uu = (col.float() + u[:, 2]) / self.width
        uv = torch.stack([uu, 0.5 + elevation / math.pi], -1)
        d = self._to_probe(uv_to_direction(uv), sign=-1.0)
        return d, self.pixel_prob[row, col] / self.pixel_solid_angle[row]
