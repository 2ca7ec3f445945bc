"""The add-on end to end on real assets: Uplift -> Bake -> Fit -> Preview -> Export.

Builds the extension exactly as the tests do (``make extension``), installs the
zip into the pip bpy module with a temporary BLENDER_USER_RESOURCES and, per
asset in its own Blender process, imports the glTF and runs every operator on
every mesh (every material slot), recording per step: ok or the error messages,
wall seconds, the files written and a small Cycles render of the asset lit by
the preview probe (the world the neural preview's lobe sees). The fit step's
render shows latent texture 0 on the asset (0.5 + 0.25 z as colour); Export
changes nothing visible and has no render.

    python bench/addon_assets.py [--assets WaterBottle ...] [--steps 100] [--size 192] [--samples 16]
        [--texture-size 256]
        [--out docs/reports/addon_assets.json] [--sheet-asset WaterBottle] [--sheet docs/reports/addon_steps.png]

The asset's images are scaled down to ``--texture-size`` texels first (default
256; 0 keeps them): Bake writes maps at the input textures' resolution and the
fit's cost grows with them, and the full 1K-2K maps take tens of minutes per
material on a shared 2-core machine. Every step still runs on the real meshes,
materials and texture content.

The report is rewritten after each asset, and a run with ``--merge`` keeps the
assets it does not run, so assets can run in separate (also concurrent) runs;
each asset records its settings.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(REPO)]

from tests.conftest import SHARED_ASSETS, run_blender  # noqa: E402
from tests.test_addon_extension import build_extension, script  # noqa: E402
from torch_models.neural.evaluate import DEFAULT_PROBE  # noqa: E402

ASSETS = ("WaterBottle", "CesiumMilkTruck", "FlightHelmet")
STEPS = ("original", "uplift", "bake", "fit", "preview", "export")

PIPELINE = r'''
import math
from mathutils import Vector
from bl_ext.user_default.richmat.blender import preview_scene, uplift
from bl_ext.user_default.richmat.core import neural_folder
from bl_ext.user_default.richmat.core.preview import PreviewScene

OUT, RENDERS = Path(OUT), Path(RENDERS)
RENDERS.mkdir(parents=True, exist_ok=True)
records = []


def meshes():
    return [o for o in scene.objects if o.type == "MESH" and any(s.material for s in o.material_slots)]


def enhanced_of(material):
    if material is None:
        return None
    return material if uplift.is_enhanced(material) else uplift.original_of(material).richmat.enhanced


def frame_camera():
    """The probe world and a camera seeing the whole asset from the front right, above.

    The preview scene's settings are unbiased and noisy at few samples; these
    renders only show each step, so they are denoised (OpenImageDenoise).
    """
    preview_scene.setup(scene, PreviewScene(resolution=SIZE), Path(PROBE), None, SAMPLES, with_ball=False)
    scene.cycles.use_denoising, scene.cycles.denoiser = True, "OPENIMAGEDENOISE"
    corners = [o.matrix_world @ Vector(c) for o in meshes() for c in o.bound_box]
    lo = Vector([min(c[i] for c in corners) for i in range(3)])
    hi = Vector([max(c[i] for c in corners) for i in range(3)])
    centre, radius = (lo + hi) / 2, (hi - lo).length / 2
    cam = scene.camera
    distance = 1.08 * radius / math.sin(cam.data.angle / 2)
    cam.location = centre + distance * Vector((0.55, -0.75, 0.37)).normalized()
    cam.rotation_euler = (centre - cam.location).to_track_quat("-Z", "Y").to_euler()
    cam.data.clip_start, cam.data.clip_end = distance / 100, distance * 10


def render_png(name):
    t = time.perf_counter()
    scene.render.image_settings.file_format = "PNG"
    scene.render.image_settings.color_mode = "RGB"
    scene.render.image_settings.color_depth = "8"
    scene.render.filepath = str(RENDERS / f"{name}.png")
    bpy.ops.render.render(write_still=True)
    return scene.render.filepath, time.perf_counter() - t


def latent_view(enhanced):
    """An emission material showing latent 0 of a fitted material (0.5 + 0.25 z)."""
    neural = neural_folder.read(Path(enhanced.richmat.neural_dir))
    mat = bpy.data.materials.new(enhanced.name + " latent view")
    tree = mat.node_tree
    tree.nodes.clear()
    emission = tree.nodes.new("ShaderNodeEmission")
    tree.links.new(emission.outputs["Emission"], tree.nodes.new("ShaderNodeOutputMaterial").inputs["Surface"])
    if neural.latent is not None:
        emission.inputs["Color"].default_value = (*[0.5 + 0.25 * z for z in neural.latent[:3]], 1.0)
        return mat
    image = tree.nodes.new("ShaderNodeTexImage")
    image.image = enhanced.node_tree.nodes["neural_latent_0"].image
    affine = tree.nodes.new("ShaderNodeVectorMath")
    affine.operation = "MULTIPLY_ADD"
    affine.inputs[1].default_value = (0.25, 0.25, 0.25)
    affine.inputs[2].default_value = (0.5, 0.5, 0.5)
    tree.links.new(image.outputs["Color"], affine.inputs[0])
    tree.links.new(affine.outputs["Vector"], emission.inputs["Color"])
    return mat


def render_latents(name):
    views, swaps = {}, []
    for obj in meshes():
        for slot in obj.material_slots:
            enhanced = enhanced_of(slot.material)
            if enhanced is not None and enhanced.richmat.neural_dir:
                if enhanced.name not in views:
                    views[enhanced.name] = latent_view(enhanced)
                swaps.append((slot, slot.material))
                slot.material = views[enhanced.name]
    try:
        return render_png(name)
    finally:
        for slot, material in swaps:
            slot.material = material


def each_object(op, **kw):
    errors = []
    for obj in meshes():
        bpy.context.view_layer.objects.active = obj
        res, err = run_op(op, **kw)
        if res != {"FINISHED"}:
            errors.append(f"{obj.name}: {err or sorted(res)}")
    return errors, {}


def fit_all():
    """Fit each enhanced material once (the operator fits the active slot's material)."""
    errors, details = [], {}
    for obj in meshes():
        bpy.context.view_layer.objects.active = obj
        for index, slot in enumerate(obj.material_slots):
            enhanced = enhanced_of(slot.material)
            if enhanced is None or enhanced.name in details:
                continue
            obj.active_material_index = index
            t = time.perf_counter()
            res, err = run_op("fit_neural")
            details[enhanced.name] = {"seconds": time.perf_counter() - t}
            if res != {"FINISHED"}:
                errors.append(f"{obj.name} / {enhanced.name}: {err or sorted(res)}")
                continue
            record = neural_folder.read(Path(enhanced.richmat.neural_dir)).record
            details[enhanced.name].update({k: record.get(k) for k in (
                "texels", "exact_unique_vectors", "fitted_vectors", "final_loss", "furnace")})
    return errors, details


def import_asset():
    """The glTF, its images scaled down to TEXTURE_SIZE texels at most (bake and fit cost grow with texels)."""
    bpy.ops.import_scene.gltf(filepath=ASSET)
    sizes = {}
    for image in bpy.data.images:
        w, h = image.size
        k = max(w, h) / TEXTURE_SIZE if TEXTURE_SIZE else 0
        if k > 1:
            image.scale(max(1, round(w / k)), max(1, round(h / k)))
        sizes[image.name] = [w, h, *image.size]
    return [], {"images": sizes}


def files_under(root):
    return {str(p.relative_to(root)): p.stat().st_mtime_ns for p in root.rglob("*") if p.is_file()}


def step(name, action, render=render_png):
    before = files_under(OUT) if OUT.is_dir() else {}
    t = time.perf_counter()
    try:
        errors, details = action()
    except Exception as exc:  # a crash is a result too: record it and go on with the next step
        errors, details = [f"{type(exc).__name__}: {exc}"], {}
    seconds = time.perf_counter() - t
    after = files_under(OUT) if OUT.is_dir() else {}
    written = sorted(k for k, v in after.items() if before.get(k) != v)
    record = dict(step=name, ok=not errors, errors=errors, seconds=seconds, files=written,
                  bytes=sum((OUT / f).stat().st_size for f in written), details=details)
    if name == "original":
        frame_camera()
    if render is not None:
        record["render"], record["render_seconds"] = render(name)
    records.append(record)
    print(f"{name}: {'ok' if record['ok'] else errors} in {seconds:.1f} s", flush=True)


scene.richmat.output_dir = str(OUT / "baked")
scene.richmat.fit_steps = FIT_STEPS
step("original", import_asset)
step("uplift", lambda: each_object("uplift_material"))
step("bake", lambda: each_object("bake_parameters"))
step("fit", fit_all, render_latents)
step("preview", lambda: each_object("preview_neural"))
step("export", lambda: each_object("export_materialx", directory=str(OUT / "mtlx")), None)
materials = sorted({s.material.name for o in meshes() for s in o.material_slots if s.material})
print("RESULT " + json.dumps(dict(records=records, materials=materials,
                                  mtlx=sorted(str(p.relative_to(OUT)) for p in (OUT / "mtlx").glob("*/*.mtlx")))))
'''


def run_asset(name: str, zip_path: Path, folder: Path, args: argparse.Namespace) -> dict:
    """One asset through every step in a fresh Blender process; its record."""
    settings = (f"ASSET = {str(SHARED_ASSETS / 'models' / f'{name}.glb')!r}\nOUT = {str(folder / 'out')!r}\n"
                f"RENDERS = {str(folder / 'renders')!r}\nPROBE = {str(DEFAULT_PROBE)!r}\n"
                f"FIT_STEPS = {args.steps}\nSIZE = {args.size}\nSAMPLES = {args.samples}\n"
                f"TEXTURE_SIZE = {args.texture_size}\n")
    start = time.perf_counter()
    result = run_blender(script(settings + PIPELINE, zip_path), folder, timeout=4 * 3600)
    result.update(asset=name, wall_seconds=time.perf_counter() - start)
    return result


def contact_sheet(record: dict, renders: Path, path: Path) -> None:
    """One row of the step renders of an asset, each labelled with its step and seconds."""
    from PIL import Image, ImageDraw

    tiles = []
    for r in record["records"]:
        if "render" not in r:
            continue
        tile = Image.open(renders / Path(r["render"]).name).convert("RGB")
        label = f"{r['step']} ({r['seconds']:.0f} s)" if r["ok"] else f"{r['step']}: ERROR"
        draw = ImageDraw.Draw(tile)
        draw.rectangle((0, 0, tile.width, 14), fill=(0, 0, 0))
        draw.text((4, 2), label, fill=(255, 255, 255))
        tiles.append(np.asarray(tile))
    path.parent.mkdir(parents=True, exist_ok=True)
    Image.fromarray(np.concatenate(tiles, 1)).save(path)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--assets", nargs="+", default=list(ASSETS))
    parser.add_argument("--steps", type=int, default=100, help="fit steps (the operator's Fit Steps)")
    parser.add_argument("--size", type=int, default=192, help="render size in pixels")
    parser.add_argument("--samples", type=int, default=16, help="Cycles samples per pixel of the renders")
    parser.add_argument("--texture-size", type=int, default=256,
                        help="scale the asset's images down to this many texels at most (0: as stored)")
    parser.add_argument("--out", type=Path, default=REPO / "docs" / "reports" / "addon_assets.json")
    parser.add_argument("--sheet-asset", default="WaterBottle")
    parser.add_argument("--sheet", type=Path, default=REPO / "docs" / "reports" / "addon_steps.png")
    parser.add_argument("--merge", action="store_true", help="keep the other assets of an existing report")
    args = parser.parse_args()

    zip_path = build_extension()
    settings = dict(fit_steps=args.steps, texture_size=args.texture_size, render_size=args.size,
                    render_samples=args.samples, torch_threads=os.environ.get("OMP_NUM_THREADS", "all"))
    assets = {}
    for name in args.assets:
        with tempfile.TemporaryDirectory(prefix=f"richmat_{name}_") as tmp:
            record = run_asset(name, zip_path, Path(tmp), args)
            if name == args.sheet_asset:
                contact_sheet(record, Path(tmp) / "renders", args.sheet)
        for r in record["records"]:
            r["render"] = Path(r["render"]).name if "render" in r else None
        assets[name] = dict(record, settings=settings)
        # Read again before writing: runs of other assets with --merge may have written meanwhile.
        report = json.loads(args.out.read_text()) if args.merge and args.out.is_file() else {}
        report.update(probe=DEFAULT_PROBE.name, extension=zip_path.name)
        report.setdefault("assets", {}).update(assets)
        report["all_ok"] = all(r["ok"] for a in report["assets"].values() for r in a["records"])
        args.out.write_text(json.dumps(report, indent=1))
        print(name, {r["step"]: (r["ok"], round(r["seconds"], 1)) for r in record["records"]}, flush=True)


if __name__ == "__main__":
    main()
