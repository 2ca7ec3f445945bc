"""Camera rays of the preview scene, with Cycles' pixel filter.

Cycles importance-samples its pixel filter: each camera ray is offset from the
pixel centre by a distance drawn, per axis, from the filter's profile. Its
default is a Blackman-Harris "width" of 1.5 px, and the window it samples spans
twice that (docs/renderer.md measures the ball's edge coverage both ways).
Doing the same here makes the two renderers antialias edges identically.
"""
from __future__ import annotations

import math

import torch
from torch import Tensor

from .preview_scene import PreviewScene

FILTER_WIDTH = 3.0  # span of the window Cycles samples for its default width of 1.5 px
_TABLE_SIZE = 1024


def blackman_harris(x: Tensor, width: float = FILTER_WIDTH) -> Tensor:
    """The window over [-width/2, width/2] (Cycles' filter_func_blackman_harris)."""
    t = 2.0 * math.pi * (x / width + 0.5)
    return 0.35875 - 0.48829 * t.cos() + 0.14128 * (2 * t).cos() - 0.01168 * (3 * t).cos()


def _inverse_filter_cdf(width: float) -> Tensor:
    x = torch.linspace(-0.5 * width, 0.5 * width, _TABLE_SIZE, dtype=torch.float64)
    density = blackman_harris(x, width).clamp(min=0.0)
    cdf = torch.cat([torch.zeros(1, dtype=torch.float64),
                     torch.cumsum(0.5 * (density[1:] + density[:-1]), 0)])
    return x, cdf / cdf[-1]


def filter_offsets(u: Tensor, width: float = FILTER_WIDTH) -> Tensor:
    """Offsets from the pixel centre, in pixels, distributed as the filter (same shape as u)."""
    x, cdf = _inverse_filter_cdf(width)
    idx = torch.searchsorted(cdf, u.double().contiguous()).clamp(1, _TABLE_SIZE - 1)
    lo, hi = cdf[idx - 1], cdf[idx]
    t = (u.double() - lo) / (hi - lo).clamp(min=1e-30)
    return (x[idx - 1] + t * (x[idx] - x[idx - 1])).float()


def primary_rays(scene: PreviewScene, u: Tensor, pixels: Tensor | None = None) -> tuple[Tensor, Tensor]:
    """Origins and unit directions (N, 3) of camera rays through ``pixels``.

    ``pixels`` are flat indices (row-major, rows top to bottom), all H*W pixels
    once when omitted; ``u`` is (N, 2) in [0,1): the filter offsets. The camera
    sits at (0, -distance, 0) looking along +y with +z up; the field of view
    spans the (square) image's width, as Blender's sensor fit Auto does.
    """
    n = scene.resolution
    if pixels is None:
        pixels = torch.arange(n * n)
    offset = filter_offsets(u)
    px = (pixels % n) + 0.5 + offset[:, 0]
    py = torch.div(pixels, n, rounding_mode="floor") + 0.5 + offset[:, 1]
    half = math.tan(0.5 * math.radians(scene.fov_deg))
    x = (2.0 * px / n - 1.0) * half
    z = (1.0 - 2.0 * py / n) * half
    d = torch.stack([x, torch.ones_like(x), z], -1)
    d = d / d.norm(dim=-1, keepdim=True)
    origin = torch.tensor([0.0, -scene.distance, 0.0]).expand_as(d)
    return origin, d


def hit_sphere(origin: Tensor, d: Tensor, radius: float) -> tuple[Tensor, Tensor]:
    """(hit mask (N,), hit points (N, 3)) of rays against the sphere at the origin."""
    b = (origin * d).sum(-1)
    c = (origin * origin).sum(-1) - radius * radius
    disc = b * b - c
    hit = disc > 0
    t = -b - disc.clamp(min=0).sqrt()
    return hit & (t > 0), origin + t[:, None] * d
