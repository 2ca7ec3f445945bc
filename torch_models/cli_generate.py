"""Generate a neural material for a mesh from a text prompt (paper sec. 5.2).

Uplifts the mesh's PBR material with the enhancement rules of the type the
prompt's keywords name (the prior), renders V orbit views of the mesh's normals,
positions, base colour and prior, samples what the prompt's wording changes (the
6 latent channels' residual over the prior, in every view) with the trained
multi-view diffusion model (conditioned on the views, the prompt's MiniLM
embedding and the type), and projects the residual into the mesh's texture space,
over the prior. A mesh without UVs is unwrapped with xatlas (OUT/mesh.glb then
holds the new UVs).

Writes OUT/latent_0.exr and OUT/latent_1.exr (latent channels 0-2 and 3-5, the
layout ``fit`` writes), OUT/base_color.exr, OUT/neural.json (prompt, type, seed,
steps, views, coverage of the projection, warnings, timings) and
OUT/preview.png (the mesh rendered with the generated material).

``--material DIR`` takes the base colour from a baked enhanced-material folder
(params.json, as the add-on's Bake writes it) instead of the mesh file, so the
latents belong to the base colour the neural preview will use; its metalness
turns fuzz/scattering prompts on metals into Types 1/3, as the enhancer does. ``--progress
jsonl`` speaks the add-on's protocol (as ``fit`` does): ``{"event": "progress",
"step", "total"}`` per sampling step, then ``{"event": "done", "out", "files",
"type", "warnings"}``; bad input is ``{"event": "error", "message"}``, exit code 2.
"""
from __future__ import annotations

import argparse
from pathlib import Path

from .generator import DEFAULT_SAMPLES, DEFAULT_STEPS, DEFAULT_TEXTURE_SIZE, DEFAULT_VIEWS

HELP = "generate the latent textures of a neural material for a mesh from a text prompt"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("mesh", type=Path, help="a mesh file (GLB, glTF, OBJ, PLY, ...)")
    parser.add_argument("--prompt", required=True, help='what the material looks like ("dusty copper, light dust")')
    parser.add_argument("--out", type=Path, required=True, help="output folder")
    parser.add_argument("--seed", type=int, default=0, help="sampling seed (default: 0)")
    parser.add_argument("--steps", type=int, default=DEFAULT_STEPS,
                        help=f"Heun sampling steps (default: {DEFAULT_STEPS})")
    parser.add_argument("--views", type=int, default=DEFAULT_VIEWS,
                        help=f"orbit views generated (default: {DEFAULT_VIEWS})")
    parser.add_argument("--samples", type=int, default=DEFAULT_SAMPLES,
                        help=f"samples drawn and averaged, an estimate of the posterior mean "
                             f"(default: {DEFAULT_SAMPLES}; each costs one more sampling run)")
    parser.add_argument("--guidance", type=float, default=2.0, help="classifier-free guidance scale (default: 2)")
    parser.add_argument("--texture-size", type=int, default=None,
                        help=f"latent texture size in texels (default: the base colour texture's size, at most "
                             f"{DEFAULT_TEXTURE_SIZE}: the energy guard's cost grows with the texels)")
    parser.add_argument("--checkpoint", type=Path, default=None,
                        help="a train-generator run folder (default: the shipped generator)")
    parser.add_argument("--no-preview", action="store_true", help="skip the preview render")
    parser.add_argument("--no-energy-guard", action="store_true",
                        help="skip the energy guard (about 40 ms per texel on one thread); texels may then gain energy")
    parser.add_argument("--material", type=Path, default=None,
                        help="a baked enhanced-material folder whose base colour replaces the mesh file's "
                             "(and whose metalness keeps fuzz/scattering off metals)")
    parser.add_argument("--progress", choices=("bar", "jsonl"), default="bar",
                        help="messages for people (default) or JSON lines on stdout (for the Blender add-on)")


def run(args: argparse.Namespace) -> int:
    import numpy as np

    from richmat_addon.core import neural_folder

    from .cli import InputError, emit, emit_done
    from .generator import generate as gen
    from .generator.mesh_input import load_mesh, use_baked_material
    from .neural import weights

    jsonl = args.progress == "jsonl"
    try:
        if not args.mesh.is_file():
            raise InputError(f"{args.mesh}: no such file")
        if min(args.steps, args.views, args.samples) < 1 or (args.texture_size is not None and args.texture_size < 8):
            raise InputError("--steps, --views and --samples must be >= 1 and --texture-size >= 8")
        model, cfg = gen.load_generator(args.checkpoint or gen.SHIPPED)
        inp = load_mesh(args.mesh)
        if args.material is not None:
            use_baked_material(inp, args.material)
        decoder = weights.load()
        if args.texture_size is None:
            args.texture_size = gen.default_texture_size(inp)
    except (InputError, FileNotFoundError, ValueError, KeyError) as exc:
        if jsonl:
            emit("error", message=str(exc))
        raise InputError(str(exc)) from None

    def progress(step: int, total: int) -> None:
        emit("progress", step=step, total=total)

    result = gen.generate(inp, args.prompt, model, cfg, args.seed, args.steps, args.views, args.guidance,
                          args.texture_size, progress if jsonl else None, not args.no_energy_guard, args.samples)
    mismatch = gen.encoder_mismatch(args.checkpoint or gen.SHIPPED, weights.encoder_digest())
    if mismatch:
        result.warnings.append(mismatch)
    args.out.mkdir(parents=True, exist_ok=True)
    darkened = float((result.energy_scale < 1).mean())
    if not inp.had_uvs:
        _write_unwrapped(inp, args.out / "mesh.glb")
    fields = {"prompt": args.prompt, "type": result.type, "seed": args.seed, "steps": args.steps,
              "views": args.views, "samples": args.samples, "guidance": args.guidance,
              "texture_size": args.texture_size,
              "projection": result.projection.stats(result.charts), "warnings": result.warnings,
              "notes": inp.notes, "seconds": result.seconds, "texels_darkened_by_guard": darkened,
              "checkpoint": str(args.checkpoint or gen.SHIPPED),
              "material": str(args.material) if args.material is not None else None}
    if not args.no_preview:
        from .render.tonemap import agx, to_png

        frames = gen.preview(inp, result.latents, energy_scale=result.energy_scale)
        to_png(np.concatenate(list(agx(frames)), 1), args.out / "preview.png")
    record = neural_folder.write(args.out, result.latents, result.energy_scale, decoder.digest, fields,
                                 {"base_color": inp.base_color})
    if jsonl:
        emit_done(args.out, type=result.type, warnings=result.warnings)
        return 0
    for w in result.warnings:
        print(f"warning: {w}")
    print(f"type {result.type}; {record['projection']['seen']:.0%} of the texels seen, "
          f"{record['projection']['inpainted']:.0%} inpainted, {record['projection']['fallback']:.0%} fallback; "
          f"wrote {args.out}")
    return 0


def _write_unwrapped(inp, path: Path) -> None:  # inp: MeshInput
    """The unwrapped mesh (Y up again, as glTF wants), so the latent textures have the UVs they belong to."""
    import numpy as np
    import trimesh

    def y_up(a: np.ndarray) -> np.ndarray:
        return np.stack([a[:, 0], a[:, 2], -a[:, 1]], 1)

    uv = inp.mesh.uvs.copy()
    uv[:, 1] = 1.0 - uv[:, 1]
    trimesh.Trimesh(y_up(inp.mesh.positions), inp.mesh.faces, vertex_normals=y_up(inp.mesh.normals),
                    visual=trimesh.visual.TextureVisuals(uv=uv), process=False).export(str(path))
