"""Path-traced preview ball (or any G-buffer) under an environment probe, with MIS, and a sun.

The ball is convex and alone, so every path ends after one bounce: a direction
below a point's horizon would hit the ball itself and is already zero in the
BRDF, and everything above it sees the probe. Each sample per pixel takes one
probe sample and one BSDF sample, combined with the power heuristic (Veach),
which is what Cycles does for a world light with MIS. The background is black
(alpha 0), as Cycles' transparent film composited over black. A sun (a delta
directional light, Cycles' Sun lamp at angle 0) adds f cos times its irradiance;
the ball cannot shadow itself where its BRDF is non-zero.
"""
from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Callable, Protocol

import numpy as np
import torch
from torch import Tensor

from .camera import hit_sphere, primary_rays
from .envmap import EnvMap
from .preview_scene import PreviewScene


class Bsdf(Protocol):
    """What the integrator needs from a material (local directions, z = normal)."""

    def eval(self, wi: Tensor, wo: Tensor) -> Tensor: ...  # f * cos(theta_o), (N, 3)
    def pdf(self, wi: Tensor, wo: Tensor) -> Tensor: ...  # solid-angle pdf, (N,)
    def sample(self, wi: Tensor, u: Tensor) -> Tensor: ...  # wo, (N, 3)


BsdfAt = Callable[[Tensor], Bsdf]  # world normals of the shading points -> their BSDF


@dataclass
class RenderResult:
    rgb: np.ndarray  # (H, W, 3) scene-linear, premultiplied over black
    alpha: np.ndarray  # (H, W) coverage
    seconds: float


def shading_basis(n: Tensor) -> tuple[Tensor, Tensor]:
    """Tangent and bitangent of unit normals (Duff et al. 2017, branchless)."""
    sign = torch.where(n[:, 2] >= 0, 1.0, -1.0)
    a = -1.0 / (sign + n[:, 2])
    b = n[:, 0] * n[:, 1] * a
    t = torch.stack([1.0 + sign * n[:, 0] ** 2 * a, sign * b, -sign * n[:, 0]], -1)
    bt = torch.stack([b, sign + n[:, 1] ** 2 * a, -n[:, 1]], -1)
    return t, bt


def _power_heuristic(a: Tensor, b: Tensor) -> Tensor:
    a2, b2 = a * a, b * b
    return torch.where(a2 + b2 > 0, a2 / (a2 + b2).clamp(min=1e-30), torch.zeros_like(a))


def direct_light(bsdf: Bsdf, env: EnvMap, wi: Tensor, frame: tuple[Tensor, Tensor, Tensor],
                 u_light: Tensor, u_bsdf: Tensor) -> Tensor:
    """One MIS estimate of reflected probe radiance per shading point, (N, 3)."""
    t, b, n = frame

    def to_local(w: Tensor) -> Tensor:
        return torch.stack([(w * t).sum(-1), (w * b).sum(-1), (w * n).sum(-1)], -1)

    # Probe sample.
    wl, pdf_l = env.sample(u_light)
    wl_local = to_local(wl)
    f = bsdf.eval(wi, wl_local)
    pdf_b = bsdf.pdf(wi, wl_local)
    weight = _power_heuristic(pdf_l, pdf_b) / pdf_l.clamp(min=1e-30)
    light = env.radiance(wl) * f * weight[:, None]

    # BSDF sample.
    wo_local = bsdf.sample(wi, u_bsdf)
    above = wo_local[:, 2] > 0
    f = bsdf.eval(wi, wo_local)
    pdf_b = bsdf.pdf(wi, wo_local)
    wo = wo_local[:, :1] * t + wo_local[:, 1:2] * b + wo_local[:, 2:3] * n
    pdf_l = env.pdf(wo)
    weight = torch.where(above & (pdf_b > 0), _power_heuristic(pdf_b, pdf_l) / pdf_b.clamp(min=1e-30),
                         torch.zeros_like(pdf_b))
    reflected = env.radiance(wo) * f * weight[:, None]
    return torch.nan_to_num(light + reflected, nan=0.0, posinf=0.0)


@dataclass(frozen=True)
class Sun:
    """A directional light: the unit world direction towards it and its irradiance (Cycles' Strength)."""

    direction: tuple[float, float, float]
    irradiance: float


def sun_light(bsdf: Bsdf, sun: Sun, wi: Tensor, frame: tuple[Tensor, Tensor, Tensor]) -> Tensor:
    """Radiance (N, 3) towards wi from the sun alone."""
    d = torch.tensor(sun.direction, dtype=wi.dtype)
    wo = torch.stack([(frame[i] * d).sum(-1) for i in range(3)], -1)
    return bsdf.eval(wi, wo) * sun.irradiance


def render_ball(bsdf_at: BsdfAt, env: EnvMap | None, scene: PreviewScene = PreviewScene(),
                spp: int = 64, seed: int = 0, max_rays: int = 1 << 18, sun: Sun | None = None) -> RenderResult:
    """Render the preview ball lit by the probe (``env``, or none: a black world) and ``sun``;
    deterministic for a given seed.

    Samples are traced in batches of whole sample passes (up to ``max_rays``
    camera rays at once): torch's per-call overhead, not arithmetic, dominates
    small batches.
    """
    start = time.perf_counter()
    npix = scene.resolution ** 2
    # Scrambled Sobol points, shifted per pixel (Cranley-Patterson): stratified
    # in all nine dimensions, so noise falls much faster than with random numbers.
    points = torch.quasirandom.SobolEngine(9, scramble=True, seed=seed).draw(spp)
    shift = torch.rand(npix, 9, generator=torch.Generator().manual_seed(seed))
    per_batch = max(1, max_rays // npix)
    total = torch.zeros(npix, 3)
    coverage = torch.zeros(npix)
    with torch.no_grad():
        for s0 in range(0, spp, per_batch):
            k = min(per_batch, spp - s0)
            u = ((points[s0:s0 + k, None, :] + shift[None]) % 1.0).reshape(-1, 9)
            pixels = torch.arange(npix).repeat(k)
            origin, d = primary_rays(scene, u[:, :2], pixels)
            hit, p = hit_sphere(origin, d, scene.radius)
            idx = hit.nonzero(as_tuple=True)[0]
            if not idx.numel():
                continue
            coverage.index_add_(0, pixels[idx], torch.ones(len(idx)))
            n = p[idx] / scene.radius
            t, b = shading_basis(n)
            view = -d[idx]
            wi = torch.stack([(view * t).sum(-1), (view * b).sum(-1), (view * n).sum(-1)], -1)
            bsdf = bsdf_at(n)
            radiance = torch.zeros(len(idx), 3)
            if env is not None:
                radiance += direct_light(bsdf, env, wi, (t, b, n), u[idx, 2:6], u[idx, 6:9])
            if sun is not None:
                radiance += sun_light(bsdf, sun, wi, (t, b, n))
            total.index_add_(0, pixels[idx], radiance)
    shape = (scene.resolution, scene.resolution)
    rgb = (total / spp).reshape(*shape, 3).numpy()
    return RenderResult(rgb, (coverage / spp).reshape(shape).numpy(), time.perf_counter() - start)


def shade_gbuffer(bsdf_at: BsdfAt, env: EnvMap, normals: np.ndarray, views: np.ndarray,
                  mask: np.ndarray, spp: int = 64, seed: int = 0, sun: Sun | None = None) -> np.ndarray:
    """Probe lighting (and ``sun``) of a G-buffer: per covered pixel, its world normal and the unit
    direction towards the camera, (H, W, 3) each; returns scene-linear RGB (H, W, 3).

    A G-buffer carries no geometry beyond the pixel, so nothing is shadowed: exact
    for a convex object (the ball), an approximation for anything else.
    """
    rows = torch.from_numpy(np.flatnonzero(mask))
    n = torch.from_numpy(normals.reshape(-1, 3)[rows.numpy()]).float()
    view = torch.from_numpy(views.reshape(-1, 3)[rows.numpy()]).float()
    t, b = shading_basis(n)
    wi = torch.stack([(view * t).sum(-1), (view * b).sum(-1), (view * n).sum(-1)], -1)
    bsdf = bsdf_at(n)
    points = torch.quasirandom.SobolEngine(7, scramble=True, seed=seed).draw(spp)
    shift = torch.rand(len(rows), 7, generator=torch.Generator().manual_seed(seed))
    total = torch.zeros(len(rows), 3)
    with torch.no_grad():
        for s in range(spp):
            u = (points[s] + shift) % 1.0
            total += direct_light(bsdf, env, wi, (t, b, n), u[:, :4], u[:, 4:7])
        if sun is not None:  # unshadowed, as the probe is
            total += spp * sun_light(bsdf, sun, wi, (t, b, n))
    out = np.zeros((mask.size, 3), np.float32)
    out[rows.numpy()] = (total / spp).numpy()
    return out.reshape(*mask.shape, 3)
