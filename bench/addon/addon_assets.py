"""The add-on end to end on real assets: Uplift -> Bake -> Fit -> Preview -> Export.

Builds the extension exactly as the tests do (``make extension``), copies the
zip aside (other runs of ``make extension`` rewrite dist/ meanwhile, and every
asset must get the same add-on), installs it into the pip bpy module with a temporary BLENDER_USER_RESOURCES and, per
asset in its own Blender process, imports the glTF and runs every operator on
every mesh (every material slot), recording per step: ok or the error messages,
wall seconds, the files written and a Cycles render of the asset lit by the
preview probe (the world the neural preview's lobe sees), with OSL on: the
enhanced material is then Cycles' exact OSL shader, and the neural preview runs
only there. The fit step's render
shows latent texture 0 on the asset (0.5 + 0.25 z as colour); Export changes
nothing visible and has no render.

The neural preview is judged against the Bake render, the analytic material it
compresses, under the same camera and light: the report holds their mean FLIP
over the asset's pixels and its noise floor (the Bake render against itself at the
next seed), and the step sheet shows one row per asset with Bake
and Preview side by side and the FLIP map beside them.

    python -m bench.addon.addon_assets [--assets WaterBottle ...] [--steps 100] [--size 320] [--samples 32]
        [--texture-size 128] [--upscale] [--out docs/reports/addon_assets.json] [--sheet docs/reports/addon_steps.png]

The asset's images are scaled down to ``--texture-size`` texels first (default
128; 0 keeps them): Bake writes maps at the input textures' resolution and the
fit's cost grows with the distinct texel vectors; at 256 texels FlightHelmet's
first material alone took 53 minutes on the shared 2-core machine. Every step still runs on the real meshes,
materials and texture content. The report is rewritten after each asset.
"""
from __future__ import annotations

import argparse
import hashlib
import os
import shutil
import tempfile
import time
import zipfile
from pathlib import Path

import numpy as np

from bench.common import REPORTS, add_out_argument, pyplot, save_chart, write_report
from support.blender_child import run_blender
from support.extension import build_extension, script
from support.paths import SHARED_ASSETS
from richmat_addon.core.texel_vectors import FIT_BUDGET
from torch_models.neural import trained
from torch_models.neural.evaluate import DEFAULT_PROBE
from torch_models.render.flip import flip_map

ASSETS = ("WaterBottle", "CesiumMilkTruck", "FlightHelmet")
# The step sheet's columns: a step's render (or "flip", the Bake vs Preview map) and its title.
# Preview sits beside Bake, its reference; the latents, which only show where the fit varies, go last.
SHEET_COLUMNS = (("original", "as imported"), ("uplift", "1 Uplift"), ("bake", "2 Bake: analytic"),
                 ("preview", "4 Preview: neural"), ("flip", "FLIP Bake vs Preview"), ("fit", "3 Fit: latent 0"))

# What every add-on bench run in Blender shares: the asset imported, framed, rendered.
SCENE = r'''
import math
from mathutils import Vector
from bl_ext.user_default.richmat.blender import uplift
from bl_ext.user_default.richmat.blender.cycles_builder import enable_osl
from bl_ext.user_default.richmat.core import neural_folder
# The preview scene's setup is not part of the extension (no operator uses it): from support/.
from support import blender_preview_scene
from torch_models.render.preview_scene import PreviewScene

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
    blender_preview_scene.setup(scene, PreviewScene(resolution=SIZE), Path(PROBE), None, SAMPLES, with_ball=False)
    enable_osl(scene)  # before Uplift, so the enhanced materials render with their OSL graph
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


def render_with_floor(name):
    """The render, then the same at the next seed (``NAME_floor``): the noise floor of a FLIP against it."""
    result = render_png(name)
    scene.cycles.seed += 1
    try:
        render_png(f"{name}_floor")
    finally:
        scene.cycles.seed -= 1
    return result


def render_mask():
    """The asset's pixels as the alpha of a one-sample render on a transparent film."""
    cycles = scene.cycles
    saved = scene.render.film_transparent, cycles.samples, cycles.use_denoising
    scene.render.film_transparent, cycles.samples, cycles.use_denoising = True, 1, False
    scene.render.image_settings.file_format = "PNG"
    scene.render.image_settings.color_mode = "RGBA"
    scene.render.filepath = str(RENDERS / "mask.png")
    bpy.ops.render.render(write_still=True)
    scene.render.film_transparent, cycles.samples, cycles.use_denoising = saved
    return scene.render.filepath


def import_asset():
    """The glTF, its images scaled down to TEXTURE_SIZE texels at most (bake and fit cost grow with texels),
    or, with UPSCALE, up to it: a 4k copy of a 1k scan has a 4k scan's distinct vectors, not its detail."""
    bpy.ops.import_scene.gltf(filepath=ASSET)
    sizes = {}
    for image in bpy.data.images:
        w, h = image.size
        k = max(w, h) / TEXTURE_SIZE if TEXTURE_SIZE else 0
        if k > 1 or (UPSCALE and 0 < k < 1):
            image.scale(max(1, round(w / k)), max(1, round(h / k)))
        sizes[image.name] = [w, h, *image.size]
    return [], {"images": sizes}
'''

PIPELINE = SCENE + r'''
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
                "texels", "exact_unique_vectors", "merged_vectors", "fitted_vectors", "budget", "encoder_only", "steps",
                "refit_steps", "final_loss", "furnace", "decoder_sha256", "timings_s", "cpu_s")})
            details[enhanced.name]["fit_error"] = (record.get("fit_error") or {}).get("mean")
    return errors, details


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
        record["mask"] = render_mask()
    if render is not None:
        record["render"], record["render_seconds"] = render(name)
    records.append(record)
    print(f"{name}: {'ok' if record['ok'] else errors} in {seconds:.1f} s", flush=True)


scene.richmat.output_dir = str(OUT / "baked")
scene.richmat.fit_steps = FIT_STEPS
scene.richmat.fit_budget = FIT_BUDGET
step("original", import_asset)
step("uplift", lambda: each_object("uplift_material"))
step("bake", lambda: each_object("bake_parameters"), render_with_floor)
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
                f"TEXTURE_SIZE = {args.texture_size}\nUPSCALE = {args.upscale}\nFIT_BUDGET = {args.fit_budget}\n")
    start = time.perf_counter()
    result = run_blender(script(settings + PIPELINE, zip_path), folder, timeout=4 * 3600)
    result.update(asset=name, wall_seconds=time.perf_counter() - start)
    return result


def read_png(path: Path) -> np.ndarray:
    """An 8-bit PNG as floats in [0, 1] (H, W, channels)."""
    from PIL import Image

    return np.asarray(Image.open(path), np.float32) / 255


def step_images(record: dict, renders: Path) -> dict[str, np.ndarray]:
    """The renders of an asset by step, plus ``flip``, the per-pixel FLIP of Preview against Bake
    (the analytic material the neural one compresses), zero off the asset."""
    images = {r["step"]: read_png(renders / Path(r["render"]).name) for r in record["records"] if "render" in r}
    mask = read_png(renders / "mask.png")[..., 3] > 0.5
    if "bake" in images and "preview" in images:
        error, _ = flip_map(images["bake"], images["preview"])
        images["flip"] = np.where(mask, error, 0.0)
        record["preview_flip_vs_bake"] = float(error[mask].mean())
        floor, _ = flip_map(images["bake"], read_png(renders / "bake_floor.png"))
        record["bake_noise_floor"] = float(floor[mask].mean())  # the Bake render against itself at the next seed
        record["asset_pixels"] = int(mask.sum())
    return images


def step_sheet(rows: dict[str, tuple[dict, dict[str, np.ndarray]]], path: Path) -> None:
    """One row per asset, one labelled column per step (SHEET_COLUMNS), seconds in each title."""
    plt = pyplot()
    fig, axes = plt.subplots(len(rows), len(SHEET_COLUMNS), figsize=(3.4 * len(SHEET_COLUMNS), 3.8 * len(rows)),
                             squeeze=False)
    for row, (asset, (record, images)) in zip(axes, rows.items()):
        steps = {r["step"]: r for r in record["records"]}
        for ax, (key, title) in zip(row, SHEET_COLUMNS):
            ax.set_xticks([]), ax.set_yticks([])
            if key == "flip":
                if "flip" in images:
                    ax.imshow(images["flip"], cmap="magma", vmin=0, vmax=1)
                    title = (f"{title}\nmean {record['preview_flip_vs_bake']:.3f} on the asset "
                             f"(floor {record['bake_noise_floor']:.3f})")
                ax.set_title(title, fontsize=10)
                continue
            step = steps.get(key)
            if key in images:
                ax.imshow(images[key])
            if step is not None and not step["ok"]:
                ax.set_title(f"{asset}: {title}\nERROR", fontsize=10, color="red")
            elif step is not None:
                ax.set_title(f"{asset}: {title}\n{step['seconds']:.1f} s", fontsize=10)
        row[0].set_ylabel(asset, fontsize=12)
    save_chart(fig, path)


def bundled_decoder_sha256(zip_path: Path) -> str:
    """The sha256 of the decoder the built extension ships (and so encodes, fits and previews with)."""
    with zipfile.ZipFile(zip_path) as z:
        return hashlib.sha256(z.read("decoder/weights.safetensors")).hexdigest()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--assets", nargs="+", default=list(ASSETS))
    parser.add_argument("--steps", type=int, default=100, help="fit steps (the operator's Fit Steps)")
    parser.add_argument("--fit-budget", type=int, default=FIT_BUDGET,
                        help="the operator's Fit Budget (0: every vector, the fit before the budget)")
    parser.add_argument("--size", type=int, default=320, help="render size in pixels")
    parser.add_argument("--samples", type=int, default=32, help="Cycles samples per pixel of the renders")
    parser.add_argument("--texture-size", type=int, default=128,
                        help="scale the asset's images down to this many texels at most (0: as stored)")
    parser.add_argument("--upscale", action="store_true",
                        help="scale smaller images up to --texture-size too (the fit's cost at a larger scan)")
    add_out_argument(parser, "addon_assets.json")
    parser.add_argument("--sheet", type=Path, default=REPORTS / "addon_steps.png", help="the step sheet (PNG)")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(prefix="richmat_extension_") as pinned:
        run(args, Path(shutil.copy2(build_extension(), pinned)))


def run(args: argparse.Namespace, zip_path: Path) -> None:
    """Every asset with the extension ``zip_path``; the report and the sheet rewritten after each."""
    bundled = bundled_decoder_sha256(zip_path)
    if bundled != trained.digest():
        raise SystemExit(f"the extension ships decoder {bundled[:8]}, not the shipped {trained.digest()[:8]}")
    report = dict(probe=DEFAULT_PROBE.name, extension=zip_path.name,
                  extension_sha256=hashlib.sha256(zip_path.read_bytes()).hexdigest(),
                  settings=dict(fit_steps=args.steps, fit_budget=args.fit_budget, texture_size=args.texture_size, upscale=args.upscale, render_size=args.size,
                                render_samples=args.samples, torch_threads=os.environ.get("OMP_NUM_THREADS", "all")),
                  assets={})
    rows = {}
    for name in args.assets:
        with tempfile.TemporaryDirectory(prefix=f"richmat_{name}_") as tmp:
            record = run_asset(name, zip_path, Path(tmp), args)
            images = step_images(record, Path(tmp) / "renders")
        for r in record["records"]:
            r["render"] = Path(r["render"]).name if "render" in r else None
            r.pop("mask", None)
        record["load_average_after"] = os.getloadavg()
        report["assets"][name] = record
        report["all_ok"] = all(r["ok"] for a in report["assets"].values() for r in a["records"])
        write_report(args.out, report, decoders=[trained.SHIPPED])
        rows[name] = (record, images)
        step_sheet(rows, args.sheet)
        print(name, {r["step"]: (r["ok"], round(r["seconds"], 1)) for r in record["records"]},
              f"FLIP preview vs bake {record.get('preview_flip_vs_bake', float('nan')):.3f} "
              f"(floor {record.get('bake_noise_floor', float('nan')):.3f})", flush=True)


if __name__ == "__main__":
    main()
