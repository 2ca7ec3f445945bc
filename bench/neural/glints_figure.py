"""Haze with and without glints (paper sec. 5.4, Fig. "Haze + Glint"), rendered neurally.

A metallic haze material (Type 0, low roughness) is fitted against the frozen
decoder and rendered on the preview ball twice with the same samples: plain,
and with f_neu multiplied by a ``GlintPattern`` at every shading point (on the
unit ball the position is the normal the renderer hands to ``bsdf_at``). The
bottom row zooms into the highlight.

    python -m bench.neural.glints_figure [--weights RUN] [--resolution 256] [--spp 64]

Writes docs/reports/glints.png; the figure is the report: its provenance is in the PNG's text.
"""
from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import torch

from bench.common import add_out_argument, provenance, pyplot, save_chart
from bench.neural.neural_failure_modes import enhanced_vector, view_cosines
from richmat_addon.core.schema import CHANNEL_SLICES
from torch_models.neural import trained
from torch_models.neural.bsdf import NeuralBsdf
from torch_models.neural.furnace import furnace
from torch_models.neural.evaluate import BallSetup
from torch_models.neural.fit.latents import fit_latents
from torch_models.neural.glints import GlintPattern, Glints
from torch_models.render.ball import render_ball
from torch_models.render.preview_scene import PreviewScene
from torch_models.render.tonemap import agx

BASE_COLOR = np.array([0.95, 0.72, 0.45], np.float32)  # a warm metal (copper-gold)
ROUGHNESS, ENHANCE_SEED = 0.25, 7


def render(setup: BallSetup, bsdf_at) -> np.ndarray:  # type: ignore[no-untyped-def]
    with torch.no_grad():
        return agx(render_ball(bsdf_at, setup.env, setup.scene, setup.spp, setup.seed).rgb)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--weights", type=Path, default=trained.SHIPPED)
    parser.add_argument("--resolution", type=int, default=256)
    parser.add_argument("--spp", type=int, default=64)
    parser.add_argument("--scale", type=float, default=20.0, help="glint cells per unit length (ball radius 1)")
    parser.add_argument("--strength", type=float, default=0.7)
    add_out_argument(parser, "glints.png")
    args = parser.parse_args()

    model = trained.load(args.weights)
    vector = enhanced_vector(BASE_COLOR, ROUGHNESS, 1.0, ENHANCE_SEED)
    z = fit_latents(model, vector[None], 100, batch=4096)
    scale = float(furnace(model, z).energy_scale()[0])
    base = torch.from_numpy(BASE_COLOR)[None]
    pattern = GlintPattern(scale=args.scale, strength=args.strength)
    setup = BallSetup.default(args.resolution, args.spp)

    def bsdf_at(glints: GlintPattern | None):  # type: ignore[no-untyped-def]
        # Unit ball: the shading point's position is its normal n.
        return lambda n: NeuralBsdf(model, z, base, scale, None if glints is None else Glints(glints, n))

    plain, glinty = render(setup, bsdf_at(None)), render(setup, bsdf_at(pattern))
    figure(plain, glinty, vector, pattern, args.out, provenance([args.weights]))


def zoom_window(image: np.ndarray, level: float = 0.45) -> tuple[int, int, int]:
    """(row, col, size) of a window inside the ball, away from the rim (n.v > 0.6), whose mean
    display value is closest to ``level``: mid-tones show sparkle, a saturated highlight clips it."""
    res = image.shape[0]
    size, stride = res // 5, max(1, res // 40)
    inside = np.nan_to_num(view_cosines(PreviewScene(resolution=res)), nan=0.0) > 0.6
    lum = image.mean(-1)
    corners = [(r, c) for r in range(0, res - size + 1, stride) for c in range(0, res - size + 1, stride)
               if inside[r:r + size, c:c + size].all()]
    return (*min(corners, key=lambda rc: abs(lum[rc[0]:rc[0] + size, rc[1]:rc[1] + size].mean() - level)), size)


def figure(plain: np.ndarray, glinty: np.ndarray, vector: np.ndarray, pattern: GlintPattern, path: Path,
           record: dict) -> None:
    plt = pyplot()
    from matplotlib.patches import Rectangle

    r0, c0, size = zoom_window(plain)
    fig, axes = plt.subplots(2, 2, figsize=(8, 8.4))
    lo, hi = pattern.range
    for k, (image, title) in enumerate(((plain, "(a) haze"), (glinty, "(b) haze + glints"))):
        axes[0, k].imshow(np.clip(image, 0, 1))
        axes[0, k].add_patch(Rectangle((c0 - 0.5, r0 - 0.5), size, size, fill=False, color="orange", lw=1.5))
        axes[0, k].set_title(title)
        axes[1, k].imshow(np.clip(image[r0:r0 + size, c0:c0 + size], 0, 1), interpolation="nearest")
        axes[1, k].set_title("zoom", fontsize=9)
    for ax in axes.ravel():
        ax.set_axis_off()
    alpha = vector[CHANNEL_SLICES["alpha_core"]][0]
    fig.suptitle(f"Neural haze material (Type 0, metal, PBR roughness {ROUGHNESS}, alpha_core {alpha:.3g})\n"
                 f"glints: scale {pattern.scale:g}, strength {pattern.strength:g}, "
                 f"multiplier in [{lo:.2f}, {hi:.1f}] with mean 1", fontsize=10)
    save_chart(fig, path, record)


if __name__ == "__main__":
    main()
