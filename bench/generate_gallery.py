"""Gallery of generated materials (issue 6, the paper's Fig. 8): docs/reports/generate_gallery.png.

Rows: held-out objects (as bench/generate_eval.py picks them). Columns: the PBR
input, the reference, the generation from the object's own caption, then the same
object generated from prompts naming other enhancements. Each generation is what
``generate`` writes (energy guard included), rendered from one view. The figure is
the report: its provenance is in the PNG's text.

    python -m bench.generate_gallery [--objects N] [--seed S] [--out PNG]
"""
from __future__ import annotations

import argparse
import textwrap
from pathlib import Path

import numpy as np
import torch

from bench.common import add_out_argument, provenance, pyplot, save_chart
from bench.generate_eval import HeldOut, held_out, held_out_indices, latents_of, render
from richmat_addon.core.enhance import baseline
from torch_models.generator import DEFAULT_STEPS, DEFAULT_VIEWS
from torch_models.generator import generate as gen
from torch_models.generator.dit import LatentGenerator
from torch_models.generator.train import GeneratorTrainConfig
from torch_models.neural import weights

# Other enhancements, in the captions' own words (Type 0, 1, 2, 4).
GALLERY_ENDINGS = ("light haze", "heavy haze, heavy dust", "light haze, glossy clearcoat",
                   "moderate haze, heavy fuzz, light subsurface scattering")


def gallery(objects: list[HeldOut], model: LatentGenerator, cfg: GeneratorTrainConfig, seed: int,
            path: Path, record: dict) -> None:
    """Rows: objects; columns: PBR input, reference, generated from the caption, generated from other prompts."""
    plt = pyplot()
    size, res, spp = cfg.corpus.texture_size, 160, 32  # one view per cell: afford a clean render
    fig, axes = plt.subplots(len(objects), 3 + len(GALLERY_ENDINGS),
                             figsize=(2.0 * (3 + len(GALLERY_ENDINGS)), 2.25 * len(objects)), squeeze=False)
    for row, obj in zip(axes, objects):
        subject = obj.prompt.split(" with ")[0]
        generated = [(obj.prompt.split(" with ")[-1], obj.prompt)]
        generated += [(ending, f"{subject} with {ending}") for ending in GALLERY_ENDINGS]
        cells = [("PBR input", latents_of(baseline(obj.asset.pbr), size), None),
                 ("reference", latents_of(obj.material, size), None)]
        for ending, prompt in generated:
            result = gen.generate(obj.inp, prompt, model, cfg, seed, DEFAULT_STEPS, DEFAULT_VIEWS, 2.0, size)
            cells.append(("generated:\n" + ending, result.latents, result.energy_scale))
        images = [render(obj.inp, lat, 1, res, spp, scale)[0] for _, lat, scale in cells]
        ys, xs = np.nonzero(images[1].sum(-1) > 0)  # crop every cell to the object in the reference
        crop = (slice(max(ys.min() - 4, 0), ys.max() + 5), slice(max(xs.min() - 4, 0), xs.max() + 5))
        for ax, (title, _, _), image in zip(row, cells, images):
            ax.imshow(image[crop])
            ax.set_title("\n".join(textwrap.fill(line, 30) for line in title.split("\n")), fontsize=6.5)
            ax.axis("off")
        row[0].text(-0.05, 0.5, subject.replace(": ", ":\n"), transform=row[0].transAxes, fontsize=7,
                    ha="right", va="center")
    save_chart(fig, path, record)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--objects", type=int, default=3)
    ap.add_argument("--seed", type=int, default=0, help="sampling seed")
    ap.add_argument("--checkpoint", type=Path, default=gen.SHIPPED)
    add_out_argument(ap, "generate_gallery.png")
    args = ap.parse_args()
    torch.set_num_threads(1)
    model, cfg = gen.load_generator(args.checkpoint)
    objects = [held_out(i, cfg) for i in held_out_indices(args.objects, cfg.corpus.seed)]
    gallery(objects, model, cfg, args.seed, args.out, provenance([weights.SHIPPED], args.checkpoint))
    print(args.out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
