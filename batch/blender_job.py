"""The per-asset Blender job (run by the orchestrator, one process per asset and stage).

``prepare``: import, check, unwrap, normalise, enhance every material into
``materials/<name>/``, save ``scene.blend`` and ``asset.json``.
``render``: open ``scene.blend`` (scripts off), give every material its
enhanced shader (``--graph``: the OSL one or the native node graph), render
the orbit's beauty (PNG), then the intrinsics pass (multilayer EXR per frame,
see ``bl_render``), encode the MP4, write ``cameras.json`` and ``render.json``.
``device``: only check that ``--device`` renders here.
A bad asset, or a device that is not there, ends in ``error.json`` and exit
code 3; anything else that goes wrong is a crash the orchestrator records with
its stderr.

Run as ``python batch/blender_job.py STAGE ...`` (pip bpy) or
``blender -b -Y --factory-startup -P batch/blender_job.py -- STAGE ...``.
"""
from __future__ import annotations

import argparse
import json
import shutil
import sys
from pathlib import Path
from typing import Callable, TypeVar

REPO = Path(__file__).resolve().parents[1]
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

import bpy  # noqa: E402

from batch import bl_render  # noqa: E402
from batch.bl_scene import BadAsset  # noqa: E402
from batch.options import (  # noqa: E402
    DEFAULT_DENOISE_PREFILTER, DEFAULT_DENOISE_QUALITY, DEFAULT_GRAPH, DEFAULT_MAX_TRIANGLES, DENOISE_PREFILTERS,
    DENOISE_QUALITIES, DEVICES, GRAPHS)
from torch_models.stage_clock import StageClock  # noqa: E402

Built = TypeVar("Built")
BAD_INPUT_EXIT = 3  # batch.pipeline.BAD_INPUT_EXIT (not imported: the orchestrator side stays bpy-free)


def prepare(args: argparse.Namespace) -> None:
    from richmat_addon.blender import mesh_maps
    from richmat_addon.core import material_folder
    from richmat_addon.core.enhance import enhance, is_metallic
    from torch_models.assets.enhancement_plan import material_type
    from richmat_addon.core.enhancement_types import DUST_TYPES

    from batch import bl_materials, bl_scene

    clock = StageClock()
    with clock.stage("import"):
        bl_scene.empty_scene()
        loaded, import_notes = bl_scene.import_asset(args.asset, args.max_triangles)
        removed, removal_notes = bl_scene.remove_drivers_and_extras()
        geometry = bl_scene.check_geometry(args.max_triangles)
        notes = import_notes + removal_notes + bl_materials.unwrap_missing_uvs()
        bl_materials.ensure_materials()
        norm = bl_scene.normalise()
        sources = [bl_materials.read_pbr(mat, args.max_texture) for mat in bl_materials.used_materials()]
        notes += bl_materials.render_uv_maps(sources)
    materials, taken = [], set()
    for source in sources:
        mat = source.material
        metallic = is_metallic(source.pbr)
        type_, type_note = material_type(args.type, metallic)
        normals = positions = None
        world_note = None
        with clock.stage("bake"):  # mesh data rasterised into the material's texture space
            bl_materials.bake_vertex_colours(source, args.max_texture)
            if type_ in DUST_TYPES:
                size = bl_materials.map_size(source.pbr, args.max_texture)
                normals, positions, world_note = mesh_maps.world_maps(bl_materials.material_surfaces(mat), size)
        with clock.stage("enhance"):
            enhanced = enhance(source.pbr, type_, args.seed, world_normals=normals, world_positions=positions)
            folder = args.work / "materials" / material_folder.safe_name(mat.name, taken)
            material_folder.write(folder, enhanced,
                                  {"asset": args.asset.name, "material": mat.name, "type_note": type_note})
        materials.append({"name": mat.name, "folder": folder.name, "type": type_, "type_note": type_note,
                          "metallic": metallic, "mean_base_color": source.pbr.base_color.mean().tolist(),
                          "settings": enhanced.settings,
                          "world_maps": "rasterised" if normals is not None else world_note, "notes": source.notes})
    with clock.stage("save"):
        bpy.ops.wm.save_as_mainfile(filepath=str(args.work / "scene.blend"), copy=True, compress=False)
    record = {"asset_id": args.asset_id, "type": args.type, "blender_version": bpy.app.version_string,
              **loaded, "removed": removed, "geometry": geometry, "normalisation": norm,
              "notes": notes + [n for m in materials for n in m["notes"]], "materials": materials, **clock.record()}
    (args.work / "asset.json").write_text(json.dumps(record, indent=1, ensure_ascii=False, default=str))


def enhanced_slots(scene: bpy.types.Scene, prepared: dict, work: Path, graph: str,
                   build: Callable[[Path, str], Built] | None = None) -> list[tuple[bpy.types.MaterialSlot, Built]]:
    """Every material slot of ``scene`` that holds a prepared material, with what ``build`` makes of that
    material's folder in ``work/materials``: by default its (beauty, intrinsics) pair (the intrinsics need
    the fit's latents; ``dataset_material.beauty`` alone does not)."""
    from batch import dataset_material

    built = {m["name"]: (build or dataset_material.build)(work / "materials" / m["folder"], graph)
             for m in prepared["materials"]}
    return [(s, built[s.material.name]) for o in scene.objects for s in getattr(o, "material_slots", [])
            if s.material is not None and s.material.name in built]


def render(args: argparse.Namespace) -> None:
    from richmat_addon.blender.osl_env import prefer_blender_bundled_modules

    prefer_blender_bundled_modules()  # before anything imports OpenImageIO: OSL needs Blender's copy
    clock = StageClock()
    with clock.stage("open"):
        bpy.ops.wm.open_mainfile(filepath=str(args.work / "scene.blend"), load_ui=False, use_scripts=False)
        prepared = json.loads((args.work / "asset.json").read_text(encoding="utf-8"))
        scene = bpy.context.scene
    with clock.stage("materials"):
        slots = enhanced_slots(scene, prepared, args.work, args.graph)

    with clock.stage("beauty"):
        bl_render.configure_cycles(scene, args.resolution, args.samples, args.adaptive_threshold, args.threads,
                                   args.graph, args.denoise_prefilter, args.denoise_quality, args.device)
        cycles = bl_render.cycles_record(scene)
        scene.world = bl_render.probe_world(args.probe)
        cam = bl_render.orbit(scene, args.frames, bl_render.start_azimuth(args.asset_id, args.seed))
        for slot, (beauty, _) in slots:
            slot.material = beauty
        bl_render.beauty_output(scene, args.work / "rgb")
        with bl_render.frame_clock() as frame_seconds:
            bpy.ops.render.render(animation=True, scene=scene.name)

    with clock.stage("intrinsics"):
        for slot, (_, unlit) in slots:
            slot.material = unlit
        render_intrinsics(scene, args.aov_samples, args.work)
    with clock.stage("video"):
        cameras = bl_render.camera_record(scene, cam, args.frames)
        (args.work / "cameras.json").write_text(json.dumps(cameras, indent=1))
        bl_render.encode_video(args.work / "rgb", args.frames, fps=8, out=args.work / "orbit.mp4",
                               size=(scene.render.resolution_x, scene.render.resolution_y))
    frames = [{"frame": i, "beauty": f"rgb/{i:04d}.png", "intrinsics": f"passes/{i:04d}.exr"}
              for i in range(args.frames)]
    record = clock.record()
    record["timings_s"]["beauty_frames"] = frame_seconds
    (args.work / "render.json").write_text(json.dumps({"frames": frames, "cycles": cycles, **record}, indent=1))


def render_intrinsics(scene: bpy.types.Scene, samples: int, work: Path, frame_step: int = 1) -> None:
    """The intrinsics pass over ``scene``'s orbit (its objects already wear their SVM materials) into
    ``work/passes``; ``frame_step`` > 1 renders every so many frames (``bench/farm/intrinsics_samples.py``)."""
    intrinsics = bl_render.intrinsics_scene(scene, samples)
    intrinsics.frame_step = frame_step
    bl_render.add_aovs(intrinsics.view_layers[0])
    bl_render.compositor_outputs(intrinsics, work / "passes")
    scratch = work / "scratch"
    bl_render.scratch_output(intrinsics, scratch)
    bpy.ops.render.render(animation=True, scene=intrinsics.name)
    shutil.rmtree(scratch)


def device(args: argparse.Namespace) -> None:
    """Only check that ``--device`` renders here (the orchestrator asks before any asset starts)."""
    bl_render.use_device(bpy.context.scene, args.device)


def parse(argv: list[str]) -> argparse.Namespace:
    parser = argparse.ArgumentParser(prog="blender_job.py", description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="stage", required=True)
    p = sub.add_parser("prepare")
    p.add_argument("--asset", type=Path, required=True)
    p.add_argument("--type", type=int, required=True)
    p.add_argument("--max-texture", type=int, required=True)
    p.add_argument("--max-triangles", type=int, default=DEFAULT_MAX_TRIANGLES)
    r = sub.add_parser("render")
    r.add_argument("--frames", type=int, required=True)
    r.add_argument("--resolution", type=int, required=True)
    r.add_argument("--samples", type=int, required=True)
    r.add_argument("--adaptive-threshold", type=float, required=True)
    r.add_argument("--denoise-prefilter", choices=DENOISE_PREFILTERS, default=DEFAULT_DENOISE_PREFILTER)
    r.add_argument("--denoise-quality", choices=DENOISE_QUALITIES, default=DEFAULT_DENOISE_QUALITY)
    r.add_argument("--probe", type=Path, required=True)
    r.add_argument("--aov-samples", type=int, required=True)
    r.add_argument("--graph", choices=GRAPHS, default=DEFAULT_GRAPH)
    r.add_argument("--threads", type=int, default=1)
    d = sub.add_parser("device")
    d.add_argument("--work", type=Path, required=True)
    for stage in (r, d):
        stage.add_argument("--device", choices=DEVICES, default="CPU")
    for stage in (p, r):
        stage.add_argument("--work", type=Path, required=True)
        stage.add_argument("--asset-id", required=True)
        stage.add_argument("--seed", type=int, required=True)
    return parser.parse_args(argv)


def main(argv: list[str]) -> int:
    args = parse(argv)
    try:
        {"prepare": prepare, "render": render, "device": device}[args.stage](args)
    except (BadAsset, bl_render.DeviceMissing) as exc:
        (args.work / "error.json").write_text(json.dumps({"stage": args.stage, "reason": str(exc)}))
        print(f"refused: {exc}", file=sys.stderr)
        return BAD_INPUT_EXIT
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else sys.argv[1:]))
