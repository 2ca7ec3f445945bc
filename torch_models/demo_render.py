"""The demo's pictures: materials on the preview ball, and sheets of panels each under its caption."""
from __future__ import annotations

from pathlib import Path
from typing import Callable

import numpy as np
import torch

from richmat_addon.core.maps import EnhancedMaterial, ParamMap

from .brdf.model import LayeredBsdf
from .demo_material import sphere_uv
from .neural.bsdf import NeuralBsdf
from .neural.model import NeuralModel
from .render.ball import BsdfAt
from .render.preview_scene import PreviewScene

CAPTION_FONT_SIZE = 14  # px: readable on a 160 px panel, where a Type's name wraps to two lines
CAPTION_PAD = 4


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


def analytic_at(mat: EnhancedMaterial) -> BsdfAt:
    """The ball's BSDF lookup of an analytic material (torch normals in, as ``render_ball`` passes them)."""
    return lambda n: material_bsdf(mat, n.numpy())


def render_balls(materials: list[BsdfAt], probe: Path, resolution: int, spp: int, seed: int,
                 done: Callable[[], None]) -> list[np.ndarray]:
    """Display-referred (AgX sRGB) renders of each material on the preview ball; ``done()`` after each."""
    from .render.ball import render_ball
    from .render.envmap import EnvMap
    from .render.tonemap import agx

    env = EnvMap.load(probe)
    scene = PreviewScene(resolution=resolution)
    images = []
    for bsdf_at in materials:
        images.append(agx(render_ball(bsdf_at, env, scene, spp, seed).rgb))
        done()
    return images


def to_u8(display: np.ndarray) -> np.ndarray:
    """Display-referred float RGB in [0, 1] as 8-bit."""
    return (np.clip(display, 0.0, 1.0) * 255.0 + 0.5).astype(np.uint8)


def _wrap(text: str, font, width: float) -> list[str]:  # type: ignore[no-untyped-def]
    """``text`` broken at spaces into lines no wider than ``width`` px (a longer word keeps its own line)."""
    lines: list[str] = []
    for word in text.split():
        if lines and font.getlength(f"{lines[-1]} {word}") <= width:
            lines[-1] += f" {word}"
        else:
            lines.append(word)
    return lines


def captioned_row(panels: list[np.ndarray], captions: list[str]) -> np.ndarray:
    """Panels (uint8, equal heights) side by side, each under its caption wrapped to the panel's width
    on a dark strip: the caption never covers what the panel shows."""
    from PIL import Image, ImageDraw, ImageFont

    font = ImageFont.load_default(size=CAPTION_FONT_SIZE)
    wrapped = [_wrap(c, font, p.shape[1] - 2 * CAPTION_PAD) for p, c in zip(panels, captions)]
    line_height = CAPTION_FONT_SIZE + CAPTION_PAD
    strip = max(len(lines) for lines in wrapped) * line_height + CAPTION_PAD
    out = []
    for panel, lines in zip(panels, wrapped):
        image = Image.new("RGB", (panel.shape[1], strip + panel.shape[0]), (40, 40, 40))
        image.paste(Image.fromarray(panel), (0, strip))
        ImageDraw.Draw(image).multiline_text((CAPTION_PAD, CAPTION_PAD), "\n".join(lines), font=font,
                                             fill=(255, 255, 255), spacing=CAPTION_PAD)
        out.append(np.asarray(image))
    return np.concatenate(out, 1)


def save_sheet(rows: list[np.ndarray], out_png: Path) -> Path:
    """Rows of equal width, stacked, written as a PNG (atomically)."""
    from PIL import Image

    from .cli import atomic_path

    with atomic_path(out_png) as tmp:
        Image.fromarray(np.concatenate(rows, 0)).save(tmp)
    return out_png
