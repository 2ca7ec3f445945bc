"""Does the generator follow the prompt visibly? Prompt sensitivity and a gallery (issue 30, item 4).

On held-out procedural dielectrics (as bench/generator/generate_eval.py picks them), or with
``--real`` on the real sample assets the corpus holds out (support/held_out_assets.py,
each read as ``generate`` reads it), metals left out since fuzz and scattering fall back
to dust on a metal: every material is enhanced with each of Types 0, 1, 2 and 4 (its
own draws), captioned as the corpus captions it, and the object generated from that
caption. For each pair of prompts, the mean FLIP between the two generated materials'
renders over the mean FLIP between their references' (the encoder's latents of the two
enhanced materials): 1 when the generations differ as much as the references do, 0 when
the wording changes nothing. The issue's target is 0.7. Each generation's PSNR against
its own reference is reported beside it.

Writes docs/reports/generate_prompts[_real].json with its chart (.png: the ratio per pair
of prompts) and docs/reports/generate_prompts[_real]_gallery.png (per object a reference
row and a generated row, one labelled column per prompt).

    python -m bench.generator.generate_prompts [--real] [--objects N] [--seed S] [--checkpoint DIR]
"""
from __future__ import annotations

import argparse
import itertools
import json
import textwrap
from pathlib import Path

import numpy as np
import torch

from bench.common import REPORTS, provenance, pyplot, save_chart, write_report
from bench.generator.generate_eval import held_out_indices, latents_of, psnr, render, views_flip
from support.held_out_assets import RealHeldOut, real_held_out
from richmat_addon.core.enhance import enhance, is_metallic
from richmat_addon.core.enhancement_types import TYPES
from richmat_addon.core.maps import ParamMap
from torch_models.generator import (DEFAULT_SAMPLES, DEFAULT_STEPS, DEFAULT_VIEWS, guidance_by_type, corpus,
                                    procedural)
from torch_models.generator import generate as gen
from torch_models.generator.mesh_input import MeshInput
from torch_models.neural import trained

PROMPT_TYPES = (0, 1, 2, 4)  # haze, dust, clearcoat, inner scattering: what a dielectric can be asked for
TARGET = 0.7


def dielectric_prompts(count: int, size: int, seed: int) -> list[tuple[str, MeshInput, list[dict]]]:
    """The first ``count`` held-out procedural objects whose material is not a metal, each with, per
    prompt type, its enhanced material's caption and reference latents."""
    picked = []
    for index in held_out_indices(10 * count, seed):
        asset = procedural.make_asset(index, size, seed)
        if is_metallic(asset.pbr):
            continue
        rows = []
        for type_ in PROMPT_TYPES:
            material = enhance(asset.pbr, type_, corpus.enhancement_seed(seed, index),
                               ParamMap(asset.world_normals), ParamMap(asset.world_positions))
            rows.append({"type": type_, "prompt": corpus.caption_for(asset.shape, material, False),
                         "reference": latents_of(material, size)})
        picked.append((asset.asset_id, MeshInput.from_pbr(asset.mesh, asset.pbr), rows))
        if len(picked) == count:
            break
    return picked


def real_prompts(objects: list[RealHeldOut], size: int) -> list[tuple[str, MeshInput, list[dict]]]:
    """The held-out sample assets (``real_held_out``) that are not all metal, each with, per prompt
    type, every material uplifted with its own draws, batch's caption for that uplift and its
    latents at ``size``."""
    picked = []
    for obj in objects:
        if obj.inp.metallic:
            continue
        rows = []
        for type_ in PROMPT_TYPES:
            latents, prompt = obj.uplifted(type_, size)
            rows.append({"type": type_, "prompt": prompt, "reference": latents})
        picked.append((obj.asset_id, obj.inp, rows))
    return picked


def prompt_pairs(references: list[np.ndarray], generated: list[np.ndarray]) -> dict[str, dict[str, float]]:
    """One object's FLIP between the renders of every pair of prompts (``PROMPT_TYPES`` order),
    for the references and for the generations."""
    return {f"{a}-{b}": {"references": views_flip(references[i], references[j]),
                         "generated": views_flip(generated[i], generated[j])}
            for (i, a), (j, b) in itertools.combinations(enumerate(PROMPT_TYPES), 2)}


def sensitivity(objects: list[dict[str, dict[str, float]]]) -> tuple[dict, float]:
    """Per pair of prompts and overall, the mean generated FLIP over the mean reference FLIP
    across objects (each ``prompt_pairs``' output)."""
    per_pair = {}
    for key in objects[0]:
        ref = float(np.mean([o[key]["references"] for o in objects]))
        out = float(np.mean([o[key]["generated"] for o in objects]))
        per_pair[key] = {"references_flip": ref, "generated_flip": out, "ratio": out / ref}
    overall = float(np.mean([p["generated_flip"] for p in per_pair.values()])
                    / np.mean([p["references_flip"] for p in per_pair.values()]))
    return per_pair, overall


def measure(args: argparse.Namespace) -> tuple[dict, list]:
    model, cfg = gen.load_generator(args.checkpoint)
    size = cfg.corpus.texture_size
    objects, cells = [], []
    picked = real_prompts(real_held_out(cfg), size) if args.real else dielectric_prompts(args.objects, size, cfg.corpus.seed)
    for asset_id, inp, prompts in picked:
        renders, row_cells = [], []
        for p in prompts:
            result = gen.generate(inp, p["prompt"], model, cfg, args.seed, DEFAULT_STEPS, DEFAULT_VIEWS,
                                  args.guidance, size, samples=DEFAULT_SAMPLES)
            ref = render(inp, p["reference"], args.eval_views, args.resolution, args.spp)
            latents, scales = [m.latents for m in result.materials], [m.energy_scale for m in result.materials]
            out = render(inp, latents, args.eval_views, args.resolution, args.spp, scales)
            renders.append((ref, out))
            p.update(generated_type=result.type, guidance=result.guidance, psnr=psnr(ref, out, ref.sum(-1) > 0))
            row_cells.append((p, [render(inp, lat, 1, args.gallery_size, 32, scale)[0]
                                  for lat, scale in ((p["reference"], None), (latents, scales))]))
        pairs = prompt_pairs([r for r, _ in renders], [g for _, g in renders])
        objects.append({"asset_id": asset_id, "pairs": pairs,
                        "prompts": [{k: v for k, v in p.items() if k != "reference"} for p in prompts]})
        cells.append((asset_id, row_cells))
        print(f"{asset_id}: " + ", ".join(f"{k} {v['generated'] / v['references']:.2f}" for k, v in pairs.items()),
              flush=True)
    per_pair, overall = sensitivity([o["pairs"] for o in objects])
    report = {"kind": "real" if args.real else "procedural", "seed": args.seed, "checkpoint": str(args.checkpoint), "prompt_types": list(PROMPT_TYPES),
              "eval_views": args.eval_views, "resolution": args.resolution, "spp": args.spp,
              "steps": DEFAULT_STEPS, "views": DEFAULT_VIEWS, "samples": DEFAULT_SAMPLES,
              "guidance": guidance_by_type() if args.guidance is None else args.guidance,
              "ratio": overall, "target": TARGET, "passed": overall >= TARGET, "per_pair": per_pair,
              "median_psnr": float(np.median([p["psnr"] for o in objects for p in o["prompts"]])),
              "objects": objects}
    return report, cells


def chart(report: dict, path: Path) -> None:
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(6.5, 3.2))
    keys = list(report["per_pair"])
    ax.bar(range(len(keys)), [report["per_pair"][k]["ratio"] for k in keys], color="tab:blue")
    ax.axhline(report["target"], color="tab:red", ls="--", lw=1, label=f"target {report['target']}")
    ax.set_xticks(range(len(keys)), [" vs ".join(f"T{t}" for t in k.split("-")) for k in keys])
    ax.set_ylabel("FLIP(generated) / FLIP(references)")
    ax.set_title(f"prompt sensitivity, {len(report['objects'])} held-out {report['kind']} objects, seed {report['seed']}: "
                 f"overall {report['ratio']:.2f}", fontsize=9)
    ax.legend(fontsize=8)
    save_chart(fig, path)


def gallery(cells: list, path: Path, record: dict) -> None:
    """Per object two rows (reference, generated), one column per prompt, each titled with its wording."""
    plt = pyplot()
    cols = len(PROMPT_TYPES)
    fig, axes = plt.subplots(2 * len(cells), cols, figsize=(2.7 * cols, 2.9 * 2 * len(cells)), squeeze=False)
    for k, (asset_id, row_cells) in enumerate(cells):
        mask = row_cells[0][1][0].sum(-1) > 0
        ys, xs = np.nonzero(mask)
        crop = (slice(max(ys.min() - 4, 0), ys.max() + 5), slice(max(xs.min() - 4, 0), xs.max() + 5))
        for c, (p, (ref, out)) in enumerate(row_cells):
            wording = p["prompt"].split(" with ", 1)[-1].split(";")[0]  # the first material's
            for r, (image, kind) in enumerate(((ref, "reference"), (out, "generated"))):
                ax = axes[2 * k + r][c]
                ax.imshow(image[crop])
                if r == 0:
                    title = (textwrap.fill(f"Type {p['type']} {TYPES[p['type']].label}", 34) + "\n"
                             + textwrap.fill(f'"{wording}"', 38) + "\nreference")
                else:
                    title = f"generated, {p['psnr']:.1f} dB against the reference"
                ax.set_title(title, fontsize=6.5)
                ax.axis("off")
        axes[2 * k][0].text(-0.06, 0.0, asset_id, transform=axes[2 * k][0].transAxes, rotation=90,
                            fontsize=7, ha="right", va="center")
    save_chart(fig, path, record)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--objects", type=int, default=4, help="held-out dielectric objects")
    ap.add_argument("--seed", type=int, default=0, help="sampling seed")
    ap.add_argument("--checkpoint", type=Path, default=gen.SHIPPED)
    ap.add_argument("--eval-views", type=int, default=8, help="views rendered for the FLIPs")
    ap.add_argument("--resolution", type=int, default=64)
    ap.add_argument("--spp", type=int, default=16)
    ap.add_argument("--guidance", type=float, default=None,
                    help="classifier-free guidance scale (default: per enhancement type)")
    ap.add_argument("--real", action="store_true",
                    help="the real sample assets the corpus holds out (corpus.held_out) instead, but the metal ones")
    ap.add_argument("--gallery-size", type=int, default=None,
                    help="gallery render size in pixels (default: 192, 256 with --real)")
    ap.add_argument("--out", type=Path, default=None,
                    help="report JSON (default: docs/reports/generate_prompts[_real].json)")
    args = ap.parse_args()
    args.gallery_size = args.gallery_size or (256 if args.real else 192)
    args.out = args.out or REPORTS / ("generate_prompts_real.json" if args.real else "generate_prompts.json")
    torch.set_num_threads(1)
    report, cells = measure(args)
    write_report(args.out, report, [trained.SHIPPED], args.checkpoint)
    chart(report, args.out.with_suffix(".png"))
    gallery(cells, args.out.with_name(args.out.stem + "_gallery.png"), provenance([trained.SHIPPED], args.checkpoint))
    print(json.dumps({k: report[k] for k in ("ratio", "passed", "per_pair", "median_psnr")}, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
