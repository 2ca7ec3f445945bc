"""Generate a neural material for a mesh from a text prompt (paper sec. 5.2).

Reads every material of the mesh with its UVs and maps (glTF: base colour,
roughness and metalness, factor times texture), uplifts each with the
enhancement rules of the type the prompt's keywords name (the prior), renders
views chosen to see most of the surface (normals, positions, base colour and
prior), samples what the prompt's wording changes (the 6 latent channels'
residual over the prior, in every view) with the trained multi-view diffusion
model (conditioned on the views, the prompt's MiniLM embedding and the type), and
projects the residual into each material's texture space, over its prior. Only
parts without usable UVs are unwrapped with xatlas (OUT/mesh.glb then holds the
whole mesh with the UVs the latents belong to).

Writes one neural folder per material: OUT itself for a mesh with one material,
OUT/materials/<name>/ for each of several (with the run's record in
OUT/generate.json). A neural folder holds latent_0.exr and latent_1.exr (latent
channels 0-2 and 3-5, the layout ``fit`` writes), base_color.exr, and neural.json
(prompt, type, seed, steps, views and their cameras, the share of the texels seen,
inpainted and given the fallback for the material and the whole mesh, warnings,
notes, timings). OUT/preview.png shows the mesh rendered with the generated
materials.

The prompt's words set what the mesh lacks (``--base``): on a material of one colour (or
none: an OBJ without a material) the named colour, on any material without roughness and
metalness the named family's and finish's; its strength words set the prior's worded
settings (``prompt.read_prompt``). ``--material DIR`` takes the base colour from a baked enhanced-material folder
(params.json, as the add-on's Bake writes it) instead of the mesh file, so the
latents belong to the base colour the neural preview will use; its metalness
turns fuzz/scattering prompts on metals into Types 1/3, as the enhancer does. ``--progress
jsonl`` speaks the add-on's protocol (as ``fit`` does): ``{"event": "progress",
"step", "total"}`` per sampling step, then ``{"event": "done", "out", "files",
"type", "warnings"}``; bad input is ``{"event": "error", "message"}``, exit code 2.
"""
from __future__ import annotations

import argparse
import time
from dataclasses import replace
from pathlib import Path
from typing import Any

from .generator import DEFAULT_SAMPLES, DEFAULT_STEPS, DEFAULT_TEXTURE_SIZE, DEFAULT_VIEWS, guidance_by_type

HELP = "generate the latent textures of a neural material for a mesh from a text prompt"
RUN_RECORD = "generate.json"  # the run's record beside the per-material folders of a mesh with several materials
PREVIEW_FRAMES, PREVIEW_SIZE, PREVIEW_SPP = 2, 512, 8  # two framed views a person can judge, in seconds


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("mesh", type=Path, help="a mesh file (GLB, glTF, OBJ, PLY, ...)")
    parser.add_argument("--prompt", required=True, help='what the material looks like ("dusty copper, light dust")')
    parser.add_argument("--out", type=Path, required=True, help="output folder")
    parser.add_argument("--seed", type=int, default=0, help="sampling seed (default: 0)")
    parser.add_argument("--steps", type=int, default=DEFAULT_STEPS,
                        help=f"Heun sampling steps (default: {DEFAULT_STEPS})")
    parser.add_argument("--views", type=int, default=DEFAULT_VIEWS,
                        help=f"views generated, chosen to see most of the surface (default: {DEFAULT_VIEWS})")
    parser.add_argument("--samples", type=int, default=DEFAULT_SAMPLES,
                        help=f"samples drawn and averaged, an estimate of the posterior mean "
                             f"(default: {DEFAULT_SAMPLES}; each costs one more sampling run)")
    parser.add_argument("--guidance", type=float, default=None,
                        help="classifier-free guidance scale (default: per enhancement type, "
                             + ", ".join(f"Type {t}: {g:g}" for t, g in guidance_by_type().items()) + ")")
    parser.add_argument("--texture-size", type=int, default=DEFAULT_TEXTURE_SIZE,
                        help=f"largest side of a material's latent texture in texels; each follows its own "
                             f"maps' size up to this (default: {DEFAULT_TEXTURE_SIZE})")
    parser.add_argument("--checkpoint", type=Path, default=None,
                        help="a train-generator run folder (default: the shipped generator)")
    parser.add_argument("--no-preview", action="store_true", help="skip the preview render")
    parser.add_argument("--no-energy-guard", action="store_true",
                        help="skip the energy guard, which only a decoder not bounded by construction needs (the MLP "
                             "kind, about 40 ms per texel on one thread; the shipped hybrid needs none)")
    parser.add_argument("--material", type=Path, default=None,
                        help="a baked enhanced-material folder whose base colour replaces the mesh file's "
                             "(and whose metalness keeps fuzz/scattering off metals)")
    parser.add_argument("--base", choices=("auto", "mesh", "words"), default="auto",
                        help="the base colour: the mesh's own (mesh), the prompt's colour, material and finish words "
                             "(words), or auto (default): the mesh's where it is a texture, the words' where it is one "
                             "colour or absent; roughness and metalness the file lacks come from the words either way")
    parser.add_argument("--progress", choices=("bar", "jsonl"), default="bar",
                        help="messages for people (default) or JSON lines on stdout (for the Blender add-on)")


def run(args: argparse.Namespace) -> int:
    from .cli import InputError, emit, emit_done
    from .generator import generate as gen
    from richmat_addon.core.prompt import read_prompt

    from .generator.colour_words import with_colour_word
    from .generator.mesh_input import load_mesh, put_words_base, use_baked_material
    from .neural import trained

    jsonl = args.progress == "jsonl"
    try:
        if not args.mesh.is_file():
            raise InputError(f"{args.mesh}: no such file")
        if min(args.steps, args.views, args.samples) < 1 or args.texture_size < 8:
            raise InputError("--steps, --views and --samples must be >= 1 and --texture-size >= 8")
        model, cfg = gen.load_generator(args.checkpoint or gen.SHIPPED)
        inp = load_mesh(args.mesh)
        if args.material is not None:
            use_baked_material(inp, args.material)
        reading = with_colour_word(read_prompt(args.prompt))
        put_words_base(inp, reading, args.base)
        decoder = trained.load()
    except (InputError, FileNotFoundError, ValueError, KeyError) as exc:
        if jsonl:
            emit("error", message=str(exc))
        raise InputError(str(exc)) from None

    def progress(step: int, total: int) -> None:
        emit("progress", step=step, total=total)

    result = gen.generate(inp, args.prompt, model, cfg, args.seed, args.steps, args.views, args.guidance,
                          args.texture_size, progress if jsonl else None, not args.no_energy_guard, args.samples)
    mismatch = gen.encoder_mismatch(args.checkpoint or gen.SHIPPED, trained.encoder_digest())
    if mismatch:
        result.warnings.append(mismatch)
    args.out.mkdir(parents=True, exist_ok=True)
    if inp.unwrapped:
        _write_unwrapped(inp, args.out / "mesh.glb")
    fields = {"prompt": args.prompt, "type": result.type, "seed": args.seed, "steps": args.steps,
              "views": args.views, "samples": args.samples, "guidance": result.guidance,
              "reading": {**reading.record(), "type": result.type}, "base": args.base,
              "texture_size": args.texture_size, "coverage": result.coverage(),
              "cameras": result.cameras.camera_to_world.tolist(), "warnings": result.warnings,
              "notes": inp.notes, "seconds": result.seconds, "checkpoint": str(args.checkpoint or gen.SHIPPED),
              "material": str(args.material) if args.material is not None else None}
    if not args.no_preview:
        start = time.perf_counter()
        _write_preview(inp, result, args.out / "preview.png")
        result.seconds["preview"] = time.perf_counter() - start
    records = _write_materials(args.out, inp, result, fields, decoder.digest)
    if jsonl:
        emit_done(args.out, type=result.type, warnings=result.warnings)
        return 0
    print("read: " + "; ".join(replace(reading, type=result.type).lines()))
    for w in result.warnings:
        print(f"warning: {w}")
    for record in records:
        share = record["projection"]
        print(f"{record['material_name']}: {share['seen']:.0%} of the texels seen, {share['inpainted']:.0%} "
              f"inpainted, {share['fallback']:.0%} fallback")
    print(f"type {result.type}; {result.coverage()['seen']:.0%} of the texels seen; wrote {args.out}")
    return 0


def _write_materials(out: Path, inp, result, fields: dict[str, Any], decoder_sha256: str) -> list[dict[str, Any]]:
    """One neural folder per material: ``out`` itself for a one-material mesh (the add-on's case),
    else ``out/materials/<name>/`` with the run's record in ``out/generate.json``. Returns the
    materials' records."""
    from richmat_addon.core import material_folder, neural_folder
    from richmat_addon.core.folder_io import write_record

    several = len(inp.materials) > 1
    taken: set[str] = set()
    records = []
    for material, generated in zip(inp.materials, result.materials):
        folder = out / "materials" / material_folder.safe_name(material.name, taken) if several else out
        own = {"material_name": material.name, **material.record, "unwrapped": material.unwrapped,
               "texture_shape": list(generated.latents.shape[:2]), "projection": generated.stats(),
               "texels_darkened_by_guard": float((generated.energy_scale < 1).mean())}
        neural_folder.write(folder, generated.latents, generated.energy_scale, decoder_sha256, {**fields, **own},
                            {"base_color": material.base_color})
        records.append({**own, "folder": str(folder.relative_to(out))})
    if several:
        write_record(out / RUN_RECORD, {**fields, "materials": records}, indent=1, sort_keys=True)
    return records


def _write_preview(inp, result, path: Path) -> None:
    """``PREVIEW_FRAMES`` framed views side by side, ``PREVIEW_SIZE`` px each, AgX tone-mapped."""
    import numpy as np

    from .generator import generate as gen
    from .render.tonemap import agx, to_png

    frames = gen.preview(inp, [m.latents for m in result.materials], PREVIEW_FRAMES, PREVIEW_SIZE, PREVIEW_SPP,
                         [m.energy_scale for m in result.materials])
    to_png(np.concatenate(list(agx(frames)), 1), path)


def _write_unwrapped(inp, path: Path) -> None:  # inp: MeshInput
    """The mesh with the UVs the latent textures belong to, one part per material (Y up again, as glTF
    wants), for meshes where some part was unwrapped; the UVs already hold any texture transform."""
    import numpy as np
    import trimesh

    def y_up(a: np.ndarray) -> np.ndarray:
        return np.stack([a[:, 0], a[:, 2], -a[:, 1]], 1)

    mesh = inp.mesh
    scene = trimesh.Scene()
    for index, material in enumerate(inp.materials):
        faces = mesh.faces[mesh.materials == index]
        used, local = np.unique(faces, return_inverse=True)
        uv = mesh.uvs[used].copy()
        uv[:, 1] = 1.0 - uv[:, 1]
        scene.add_geometry(trimesh.Trimesh(y_up(mesh.positions[used]), local.reshape(-1, 3),
                                           vertex_normals=y_up(mesh.normals[used]),
                                           visual=trimesh.visual.TextureVisuals(uv=uv), process=False),
                           geom_name=material.name)
    scene.export(str(path))
