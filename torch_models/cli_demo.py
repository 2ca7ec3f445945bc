"""Uplift the built-in material to every type and show them beside the original.

The built-in input is procedural (chipped red paint over steel on a UV sphere,
see richmat_addon/core/builtin.py), so the demo needs nothing beside the clone.
Writes OUT/type_<k>/ (parameter maps as EXR, params.json, material.mtlx) for
Types 0-5, and OUT/side_by_side.png: the original PBR material and Types 0-5
rendered on a ball under the shipped probe with the torch renderer.
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


def run(args: argparse.Namespace) -> int:
    from tqdm import tqdm

    from richmat_addon.core.builtin import chipped_paint, sphere_texel_geometry
    from richmat_addon.core.enhance import enhance

    from .cli_enhance import write_material
    from .demo_render import render_side_by_side

    pbr = chipped_paint(args.size)
    normals, positions = sphere_texel_geometry(args.size, args.size)
    materials = []
    for type_ in tqdm(range(6), desc="enhance", unit="type"):
        mat = enhance(pbr, type_, args.seed, world_normals=normals, world_positions=positions)
        write_material(args.out / f"type_{type_}", mat,
                       {"asset": "built-in chipped_paint", "material": pbr.name, "requested_type": type_})
        materials.append(mat)
    image = render_side_by_side(pbr, materials, args.probe, args.resolution, args.spp, args.seed,
                                args.out / "side_by_side.png")
    print(f"wrote {args.out}/type_0..5 and {image}")
    return 0
