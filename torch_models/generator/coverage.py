"""Views chosen to see the surface: a greedy pick among orbit, high, low, top and bottom cameras.

The generator samples the residual only where some view sees the surface; the rest
of each texture is inpainted from its neighbours. batch's orbit (elevation 25 +- 10
degrees) never sees tops, bottoms or the insides of real assets squarely, so the
views are picked per mesh: every candidate camera is rasterised at the projection's
resolution, each texel of every material's UV charts keeps the best cos^2 between
its surface normal and the direction to a camera that sees it (the weight the
projection gives it), and the pick adds, one view at a time, the candidate that
raises the sum of those best weights most. The model needs no view order (its
tokens carry world positions, ``dit.py``) and the candidates keep batch's lens and
framing, so it sees views as it was trained on, from more directions.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import torch
from torch import Tensor

from .views import Cameras, Mesh, direction, look_at, orbit_cameras, rasterize

ORBIT = 12  # candidates on batch's orbit (more when more views are asked for)
RINGS = ((-35.0, 8), (60.0, 8))  # (elevation in degrees, cameras) besides the orbit; plus straight up and down


@dataclass
class TextureSpace:
    """One material's latent texture: its (H, W) and the texels its UV charts cover."""

    charts: Tensor  # (H, W) bool

    @property
    def shape(self) -> tuple[int, int]:
        return int(self.charts.shape[0]), int(self.charts.shape[1])


def candidate_cameras(orbit: int, resolution: int) -> Cameras:
    """batch's orbit of ``orbit`` views, a low and a high ring, and the views from straight above and below."""
    rings = [direction(2 * math.pi * (i + 0.5) / n, math.radians(el)) for el, n in RINGS for i in range(n)]
    poles = [direction(0.0, math.pi / 2), direction(0.0, -math.pi / 2)]
    extra = look_at(np.stack(rings + poles), resolution)
    base = orbit_cameras(orbit, resolution)
    return Cameras(resolution, base.focal_px, torch.cat([base.camera_to_world, extra.camera_to_world]))


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


def greedy(weights: Tensor, count: int) -> list[int]:
    """``count`` rows of ``weights`` (candidates, texels), each raising the sum over texels of the
    best weight picked so far the most."""
    best, chosen = torch.zeros(weights.shape[1]), []
    for _ in range(min(count, len(weights))):
        gain = (torch.maximum(weights, best) - best).sum(1)
        gain[chosen] = -1.0
        pick = int(gain.argmax())
        chosen.append(pick)
        best = torch.maximum(best, weights[pick])
    return chosen


def choose_cameras(mesh: Mesh, spaces: list[TextureSpace], count: int, resolution: int,
                   fine_resolution: int) -> Cameras:
    """``count`` cameras at ``resolution`` that see the charts of ``spaces`` best, judged at
    ``fine_resolution`` (the projection's)."""
    candidates = candidate_cameras(max(count, ORBIT), fine_resolution)
    picked = greedy(texel_weights(mesh, candidates, spaces), count)
    return Cameras(resolution, candidates.focal_px * resolution / fine_resolution, candidates.camera_to_world[picked])
