"""Views chosen to see the surface: batch's orbit, then the views that see what it misses.

The generator samples the residual only where some view sees the surface; the rest
of each texture is inpainted from its neighbours. batch's orbit (elevation 25 +- 10
degrees) never sees tops, bottoms or undersides squarely. So a generation's views are
the orbit the model was trained on (as many views as its corpus had, or fewer), and
the remaining ones are picked greedily among rings of cameras at other elevations and
the views from straight above and below: each adds most to the sum over the chart
texels of every material of the best cos^2 (the weight the projection gives a texel)
between the texel's normal and the direction to a picked camera that sees it.
Candidates are rasterised at 4x the model's resolution, not the projection's 8x:
the picks see about the same shares at a quarter of the cost. The model needs no view
order (its tokens carry world positions, ``dit.py``) and every candidate keeps batch's
lens and framing.

Keeping the orbit costs little coverage and keeps the model on the views it knows
(coverage: docs/generator.md, "Real assets"; the comparison with all views picked
greedily: docs/history.md).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import torch
from torch import Tensor

from .views import Cameras, Mesh, direction, look_at, orbit_cameras, rasterize

RINGS = ((-35.0, 8), (5.0, 8), (50.0, 8), (60.0, 8))  # (elevation in degrees, cameras) the extra views come from


@dataclass
class TextureSpace:
    """One material's latent texture: its (H, W) and the texels its UV charts cover."""

    charts: Tensor  # (H, W) bool

    @property
    def shape(self) -> tuple[int, int]:
        return int(self.charts.shape[0]), int(self.charts.shape[1])


def extra_cameras(resolution: int) -> Cameras:
    """The cameras extra views are picked from: the ``RINGS`` and straight above and below."""
    rings = [direction(2 * math.pi * (i + 0.5) / n, math.radians(el)) for el, n in RINGS for i in range(n)]
    return look_at(np.stack(rings + [direction(0.0, math.pi / 2), direction(0.0, -math.pi / 2)]), resolution)


def texel_weights(mesh: Mesh, cameras: Cameras, spaces: list[TextureSpace]) -> Tensor:
    """(cameras, texels) the best cos^2 each camera sees each chart texel with (0: not seen): the
    texels of every material in turn, row-major; a pixel reaches the four texels around its UV, as
    the projection's bilinear splat does."""
    frags = rasterize(mesh, cameras)
    material = frags.material(mesh.materials)
    uv = frags.interpolate(mesh.uvs, mesh.faces)
    to_camera = cameras.origins.float()[:, None, None, :] - frags.interpolate(mesh.positions, mesh.faces)
    normal = frags.interpolate(mesh.normals, mesh.faces)
    cos = (torch.nn.functional.normalize(normal, dim=-1) * torch.nn.functional.normalize(to_camera, dim=-1)).sum(-1)
    sizes = [s.shape[0] * s.shape[1] for s in spaces]
    total, views = sum(sizes), len(cameras.camera_to_world)
    best = torch.zeros(views * total)
    for index, (space, offset) in enumerate(zip(spaces, np.cumsum([0] + sizes[:-1]))):
        h, w = space.shape
        v, y, x = torch.nonzero(material == index, as_tuple=True)
        weight = cos[v, y, x].clamp(min=0) ** 2
        x0, y0 = (uv[v, y, x, 0] * w - 0.5).floor().long(), (uv[v, y, x, 1] * h - 0.5).floor().long()
        for dx, dy in ((0, 0), (1, 0), (0, 1), (1, 1)):
            texel = ((y0 + dy) % h) * w + (x0 + dx) % w
            best.scatter_reduce_(0, v * total + int(offset) + texel, weight, "amax")
    charts = torch.cat([s.charts.reshape(-1) for s in spaces]).float()
    return best.reshape(views, total) * charts


def greedy(weights: Tensor, count: int, first: int = 0) -> list[int]:
    """The ``first`` rows of ``weights`` (candidates, texels), then rows up to ``count``, each raising
    the sum over texels of the best weight picked so far the most."""
    chosen = list(range(first))
    best = weights[:first].max(0).values if first else torch.zeros(weights.shape[1])
    for _ in range(min(count, len(weights)) - first):
        gain = (torch.maximum(weights, best) - best).sum(1)
        gain[chosen] = -1.0
        pick = int(gain.argmax())
        chosen.append(pick)
        best = torch.maximum(best, weights[pick])
    return chosen


def choose_cameras(mesh: Mesh, spaces: list[TextureSpace], count: int, orbit: int, resolution: int,
                   judge_resolution: int) -> Cameras:
    """``count`` cameras at ``resolution``: batch's orbit of ``min(count, orbit)`` views, then those
    of ``extra_cameras`` that see most of what it misses of the charts of ``spaces`` (judged at
    ``judge_resolution``)."""
    base, extra = orbit_cameras(min(count, orbit), judge_resolution), extra_cameras(judge_resolution)
    candidates = Cameras(judge_resolution, base.focal_px, torch.cat([base.camera_to_world, extra.camera_to_world]))
    picked = greedy(texel_weights(mesh, candidates, spaces), count, first=len(base.camera_to_world))
    return Cameras(resolution, base.focal_px * resolution / judge_resolution, candidates.camera_to_world[picked])
