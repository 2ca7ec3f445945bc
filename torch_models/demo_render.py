"""Render enhanced materials on the preview ball for the demo's side-by-side image."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import torch

from richmat_addon.core.builtin import sphere_uv
from richmat_addon.core.enhance import baseline
from richmat_addon.core.maps import EnhancedMaterial, ParamMap, PbrInputs
from richmat_addon.core.preview import PreviewScene

from .brdf.model import LayeredBsdf


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
