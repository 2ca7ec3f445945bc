"""Uplift the built-in material to every type and show them beside the original.

The built-in input is procedural (chipped red paint over steel on a UV sphere,
see richmat_addon/core/builtin.py), so the demo needs nothing beside the clone.
Writes OUT/type_<k>/ (parameter maps as EXR, params.json, material.mtlx) for
Types 0-5, and OUT/side_by_side.png: the original PBR material and Types 0-5
rendered on a ball under the shipped probe with the torch renderer. Then each
type is fitted as a neural material with the shipped decoder
(OUT/type_<k>/neural/: two latent EXRs and neural.json) and
OUT/neural_vs_analytic.png shows analytic | neural | FLIP map per type, with
the FLIPs in OUT/neural_vs_analytic.json. Last, the shipped generator makes
neural materials for a held-out procedural mesh from prompts naming different
enhancements (OUT/generated.png: one row of two preview frames per prompt,
OUT/generated.json: the prompts, types, warnings and timings).
"""
from __future__ import annotations

import argparse
from pathlib import Path

HELP = "uplift the built-in material to Types 0-5 and render them side by side"
DEFAULT_PROBE = Path(__file__).resolve().parent / "data" / "studio_small_03_512.hdr"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--out", type=Path, default=Path("demo_out"), help="output folder (default: demo_out)")
    parser.add_argument("--seed", type=int, default=0, help="enhancement seed (default: 0)")
    parser.add_argument("--size", type=int, default=256, help="texture size of the built-in material (default: 256)")
    parser.add_argument("--resolution", type=int, default=160, help="ball image size in pixels (default: 160)")
    parser.add_argument("--spp", type=int, default=64, help="samples per pixel of the ball renders (default: 64)")
    parser.add_argument("--probe", type=Path, default=DEFAULT_PROBE, help="equirectangular HDR probe")
    parser.add_argument("--fit-steps", type=int, default=300, help="neural fit steps per type (default: 300)")
    parser.add_argument("--no-neural", action="store_true", help="skip fitting the neural materials")
    parser.add_argument("--no-generate", action="store_true", help="skip generating materials from prompts")
    parser.add_argument("--generate-size", type=int, default=32,
                        help="latent texture size of the generated materials (default: 32, what the generator's "
                             "32 px views resolve; the energy guard's time grows with the texels)")


def run(args: argparse.Namespace) -> int:
    from tqdm import tqdm

    from richmat_addon.core import material_folder
    from richmat_addon.core.builtin import chipped_paint, sphere_texel_geometry
    from richmat_addon.core.enhance import enhance
    from richmat_addon.core.enhancement_types import TYPES

    from .cli import InputError
    from .demo_render import render_side_by_side

    if args.generate_size < 8:
        raise InputError("--generate-size must be >= 8")
    pbr = chipped_paint(args.size)
    normals, positions = sphere_texel_geometry(args.size, args.size)
    materials = []
    for type_ in tqdm(range(len(TYPES)), desc="enhance", unit="type"):
        mat = enhance(pbr, type_, args.seed, world_normals=normals, world_positions=positions)
        material_folder.write(args.out / f"type_{type_}", mat,
                              {"asset": "built-in chipped_paint", "material": pbr.name, "requested_type": type_})
        materials.append(mat)
    image = render_side_by_side(pbr, materials, args.probe, args.resolution, args.spp, args.seed,
                                args.out / "side_by_side.png")
    print(f"wrote {args.out}/type_0..5 and {image}")
    if not args.no_neural:
        fit_and_compare(args, materials)
    if not args.no_generate:
        generate_from_prompts(args.out, args.seed, args.generate_size)
    return 0


def fit_and_compare(args: argparse.Namespace, materials: list) -> None:  # type: ignore[type-arg]
    """Fit every type with the shipped decoder, write its latents, render analytic vs neural."""
    import json

    from tqdm import tqdm

    from richmat_addon.core.maps import ParamMap

    from .demo_render import neural_bsdf, render_neural_rows
    from .neural import energy, fitting, material_vectors, weights

    model = weights.load()
    rows = []
    for mat in tqdm(materials, desc="fit neural", unit="type"):
        folder = args.out / f"type_{mat.type}"
        vectors = material_vectors.read_vectors(folder)
        z = fitting.fit_latents(model, vectors.unique, args.fit_steps, seed=args.seed)
        bounded = energy.fit_bounded(model, vectors.unique, z, seed=args.seed)
        z, check = bounded.z, bounded.check
        material_vectors.write_fit(folder / "neural", vectors, bounded, model.digest, {})
        latents = ParamMap(vectors.texels(z))
        scales = ParamMap(vectors.texels(check.energy_scale()))
        rows.append((f"Type {mat.type}", mat, lambda n, m=mat, lt=latents, sc=scales:
                     neural_bsdf(model, lt, sc, m.base_color, n)))
    png = args.out / "neural_vs_analytic.png"
    flips = render_neural_rows(rows, args.probe, args.resolution, args.spp, args.seed, png)
    (args.out / "neural_vs_analytic.json").write_text(json.dumps(
        {"flip_convention": "LDR-FLIP on AgX sRGB, 67.02 ppd", "fit_steps": args.fit_steps,
         "flip": {f"type_{m.type}": f for m, f in zip(materials, flips)}}, indent=1))
    print("neural vs analytic FLIP: " + ", ".join(f"Type {m.type} {f:.3f}" for m, f in zip(materials, flips))
          + f"; wrote {png}")


DEMO_PROMPT_ENDINGS = ("heavy haze, heavy dust", "light haze, glossy clearcoat",
                       "moderate haze, heavy fuzz, light subsurface scattering")


def generate_from_prompts(out: Path, seed: int, texture_size: int = 32) -> None:
    """The paper's Fig. 8 on a mesh training never saw: one object, prompts naming different enhancements.

    Two small preview frames per prompt and a ``texture_size`` texture keep this step to a few minutes
    on 2 cores; the energy guard, which measures every distinct texel, takes most of it."""
    import json

    import numpy as np
    import torch

    from .generator import corpus, procedural
    from .generator import generate as gen
    from .generator.mesh_input import MeshInput
    from .render.tonemap import agx, to_png

    torch.set_num_threads(1)  # small tensors: a second thread costs more in synchronisation than it saves
    model, cfg = gen.load_generator()
    index = next(i for i in range(1000) if corpus.is_held_out(f"proc-{cfg.corpus.seed}-{i:05d}"))
    asset = procedural.make_asset(index, cfg.corpus.texture_size, cfg.corpus.seed)
    inp = MeshInput.from_pbr(asset.mesh, asset.pbr)
    subject = f"a {asset.shape}: {asset.pbr.name} {'metal' if asset.family == 'metal' else 'material'}"
    rows, records = [], []
    for ending in DEMO_PROMPT_ENDINGS:
        result = gen.generate(inp, f"{subject} with {ending}", model, cfg, seed, texture_size=texture_size)
        frames = gen.preview(inp, result.latents, frames=2, resolution=96, spp=8,
                             energy_scale=result.energy_scale)
        rows.append(np.concatenate(list(agx(frames.reshape(-1, *frames.shape[2:])).reshape(frames.shape)), 1))
        records.append({"prompt": f"{subject} with {ending}", "type": result.type, "warnings": result.warnings,
                        "seconds": result.seconds})
    out.mkdir(parents=True, exist_ok=True)
    to_png(np.concatenate(rows, 0), out / "generated.png")
    (out / "generated.json").write_text(json.dumps({"asset": asset.asset_id, "held_out": True, "seed": seed,
                                                     "rows": records}, indent=1))
    print(f"generated {len(rows)} materials for {asset.asset_id} (held out); wrote {out / 'generated.png'}")
