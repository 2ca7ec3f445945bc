"""Render enhanced materials on the preview ball for the demo's side-by-side image."""
from __future__ import annotations

from pathlib import Path
from typing import Callable

import numpy as np
import torch

from richmat_addon.core.builtin import sphere_uv
from richmat_addon.core.enhance import baseline
from richmat_addon.core.maps import EnhancedMaterial, ParamMap, PbrInputs
from richmat_addon.core.preview import PreviewScene

from .brdf.model import LayeredBsdf
from .neural.bsdf import NeuralBsdf
from .neural.weights import NeuralModel


NeuralBsdfFactory = Callable[[np.ndarray], NeuralBsdf]  # world normals of ball points -> their BSDF


def sample_map(pmap: ParamMap, uv: np.ndarray) -> torch.Tensor:
    """Per-point values of a map at (u, v) (nearest texel, v up); constants broadcast as (1, C)."""
    if pmap.is_constant:
        return torch.from_numpy(pmap.value[None].astype(np.float32))
    h, w = pmap.shape
    col = np.clip((uv[:, 0] * w).astype(int), 0, w - 1)
    row = np.clip(((1.0 - uv[:, 1]) * h).astype(int), 0, h - 1)
    return torch.from_numpy(pmap.value[row, col].astype(np.float32))


def material_bsdf(mat: EnhancedMaterial, world_normals: np.ndarray) -> LayeredBsdf:
    """The layered BSDF of a textured material at the given ball points."""
    uv = sphere_uv(world_normals)
    params = {name: sample_map(m, uv) for name, m in mat.params.items()}
    return LayeredBsdf(params, sample_map(mat.base_color, uv))


def neural_bsdf(model: NeuralModel, latents: ParamMap, energy_scale: ParamMap, base_color: ParamMap,
                world_normals: np.ndarray) -> NeuralBsdf:
    """The fitted neural material (latent texture, energy scale) at the given ball points."""
    uv = sphere_uv(world_normals)
    return NeuralBsdf(model, sample_map(latents, uv), sample_map(base_color, uv), sample_map(energy_scale, uv))


def render_side_by_side(pbr: PbrInputs, materials: list[EnhancedMaterial], probe: Path, resolution: int,
                        spp: int, seed: int, out_png: Path) -> Path:
    """One labelled row: the original PBR material, then each enhanced material, on the ball."""
    from PIL import Image, ImageDraw

    from .cli import atomic_path
    from .render.ball import render_ball
    from .render.envmap import EnvMap
    from .render.tonemap import agx

    env = EnvMap.load(probe)
    scene = PreviewScene(resolution=resolution)
    labels = ["original PBR"] + [f"Type {m.type}" for m in materials]
    tiles = []
    for mat in [baseline(pbr)] + materials:
        result = render_ball(lambda n, m=mat: material_bsdf(m, n.numpy()), env, scene, spp, seed)
        tiles.append((agx(result.rgb) * 255 + 0.5).astype(np.uint8))
    sheet = Image.fromarray(np.concatenate(tiles, 1))
    draw = ImageDraw.Draw(sheet)
    for k, label in enumerate(labels):
        draw.text((k * resolution + 4, 4), label, fill=(255, 255, 255))
    with atomic_path(out_png) as tmp:
        sheet.save(tmp)
    return out_png


def render_neural_rows(rows: list[tuple[str, EnhancedMaterial, NeuralBsdfFactory]], probe: Path, resolution: int,
                       spp: int, seed: int, out_png: Path) -> list[float]:
    """Per material a row analytic | neural | FLIP map, labelled; returns the mean FLIPs."""
    from PIL import Image, ImageDraw

    from .cli import atomic_path
    from .neural.evaluate import compare, side_by_side
    from .render.ball import render_ball
    from .render.envmap import EnvMap
    from .render.tonemap import agx

    env = EnvMap.load(probe)
    scene = PreviewScene(resolution=resolution)
    results = []
    for _, mat, make_neural in rows:
        ref = render_ball(lambda n, m=mat: material_bsdf(m, n.numpy()), env, scene, spp, seed)
        with torch.no_grad():
            neu = render_ball(lambda n: make_neural(n.numpy()), env, scene, spp, seed)
        results.append(compare(agx(ref.rgb), agx(neu.rgb)))
    sheet = Image.fromarray(side_by_side(results))
    draw = ImageDraw.Draw(sheet)
    for k, ((label, _, _), result) in enumerate(zip(rows, results)):
        y = k * resolution + 4
        draw.text((4, y), f"{label} analytic", fill=(255, 255, 255))
        draw.text((resolution + 4, y), "neural", fill=(255, 255, 255))
        draw.text((2 * resolution + 4, y), f"FLIP {result.flip:.3f}", fill=(255, 255, 255))
    with atomic_path(out_png) as tmp:
        sheet.save(tmp)
    return [r.flip for r in results]
