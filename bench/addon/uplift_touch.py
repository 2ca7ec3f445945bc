"""Uplift on the sample assets, per material: the type Auto draws and how light the result is.

Per asset, in a fresh Blender process with the built extension installed (as
``bench.addon.addon_assets`` does): the glTF imported with its images scaled to the
uplift's own preview size (512 texels, so the maps are those the Uplift button
makes), then every material uplifted twice with Auto's types and seed 0: once
with the rules as drawn (amount 1, no touch) and once as Auto now does (lighter on
dark texels, ``core.enhance.auto_touch``). Per material the report holds the type,
the base colour's luminance and the mean albedo (``torch_models.material_albedo``:
the white furnace's, averaged over the texels the material's faces cover) of the
PBR material, the rules' uplift and Auto's; the sheet shows the asset as imported
and after each uplift, rendered by Cycles (OSL) under the preview probe.

    python -m bench.addon.uplift_touch [--assets CesiumMilkTruck ...] [--size 512] [--samples 32]
"""
from __future__ import annotations

import argparse
import shutil
import tempfile
from pathlib import Path

from bench.addon.addon_assets import SCENE, read_png
from bench.common import REPORTS, add_out_argument, write_report
from support.blender_child import run_blender
from support.paths import SHARED_ASSETS
from support.extension import build_extension, script
from torch_models.demo_render import captioned_row, save_sheet, to_u8
from torch_models.neural.evaluate import DEFAULT_PROBE

ASSETS = ("CesiumMilkTruck", "FlightHelmet", "WaterBottle")
UPLIFT_SIZE = 512  # the add-on's preview size (blender/uplift.py PREVIEW_SIZE)
VARIANTS = (("rules", False, "Uplift: the rules as drawn"), ("auto", True, "Uplift: Auto, lighter on dark texels"))

MEASURE = r'''
from bl_ext.user_default.richmat.blender import mesh_maps, pbr_source
from bl_ext.user_default.richmat.core.enhance import baseline, resolve_type
from torch_models.demo_render import sample_map
from torch_models.material_albedo import luminance, mean_albedo, texel_uvs

import_asset()
frame_camera()
render_png("original")
users = {}  # original material name -> (a slot plan, every (object, slot) using it)
for obj in meshes():
    for p in uplift.plan(obj, True):
        users.setdefault(p.original.name, (p, []))[1].append((obj, [p.slot_index]))
materials = {}
for name, (p, surfaces) in sorted(users.items()):
    pbr = pbr_source.load_pbr(p.sources, UPLIFT_SIZE)
    shapes = [m.shape for m in (pbr.base_color, pbr.roughness, pbr.metalness) if m.shape]
    covered = mesh_maps.coverage(surfaces, max(shapes, key=lambda s: s[0] * s[1])) if shapes else None
    uv = texel_uvs(covered) if covered is not None and covered.any() else np.full((1, 2), 0.5)
    base = sample_map(pbr.base_color, uv).numpy().mean(0)
    record = dict(type=resolve_type(pbr, "auto", SEED)[0], texels=len(uv), base_luminance=luminance(base),
                  albedo={"pbr": mean_albedo(baseline(pbr), uv).tolist()})
    for variant, touch in VARIANTS:
        mat = uplift.enhance_slot(p, "AUTO", SEED, UPLIFT_SIZE, touch=touch)
        record["albedo"][variant] = mean_albedo(mat, uv).tolist()
    record["luminance"] = {k: luminance(v) for k, v in record["albedo"].items()}
    materials[name] = record
for variant, touch in VARIANTS:
    for obj in meshes():
        uplift.uplift(obj, True, "AUTO", SEED, "osl", max_size=UPLIFT_SIZE, touch=touch)
    render_png(variant)
print("RESULT " + json.dumps(dict(materials=materials)))
'''


def run_asset(name: str, zip_path: Path, folder: Path, args: argparse.Namespace) -> dict:
    settings = (f"ASSET = {str(SHARED_ASSETS / 'models' / f'{name}.glb')!r}\nOUT = {str(folder / 'out')!r}\n"
                f"RENDERS = {str(folder / 'renders')!r}\nPROBE = {str(DEFAULT_PROBE)!r}\nSIZE = {args.size}\n"
                f"SAMPLES = {args.samples}\nTEXTURE_SIZE = {UPLIFT_SIZE}\nUPLIFT_SIZE = {UPLIFT_SIZE}\n"
                f"SEED = {args.seed}\nVARIANTS = {[(v, t) for v, t, _ in VARIANTS]!r}\n")
    return run_blender(script(settings + SCENE + MEASURE, zip_path), folder, timeout=3600)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--assets", nargs="+", default=list(ASSETS))
    parser.add_argument("--size", type=int, default=512, help="render size in pixels")
    parser.add_argument("--samples", type=int, default=32, help="Cycles samples per pixel (denoised)")
    parser.add_argument("--seed", type=int, default=0, help="the panel's Seed")
    add_out_argument(parser, "uplift_touch.json")
    parser.add_argument("--sheet", type=Path, default=REPORTS / "uplift_touch.png")
    args = parser.parse_args()
    report = dict(settings=dict(render_size=args.size, render_samples=args.samples, seed=args.seed,
                                texture_size=UPLIFT_SIZE, probe=DEFAULT_PROBE.name), assets={})
    rows = []
    with tempfile.TemporaryDirectory(prefix="richmat_extension_") as pinned:
        zip_path = Path(shutil.copy2(build_extension(), pinned))
        for name in args.assets:
            with tempfile.TemporaryDirectory(prefix=f"richmat_{name}_") as tmp:
                report["assets"][name] = run_asset(name, zip_path, Path(tmp), args)["materials"]
                renders = Path(tmp) / "renders"
                panels = [to_u8(read_png(renders / f"{k}.png")[..., :3]) for k in ("original", "rules", "auto")]
            rows.append(captioned_row(panels, [f"{name}: as imported", *(title for _, _, title in VARIANTS)]))
            write_report(args.out, report)
            save_sheet(rows, args.sheet)
            for material, r in report["assets"][name].items():
                print(f"{name}/{material}: type {r['type']}, base {r['base_luminance']:.3f}, albedo "
                      + ", ".join(f"{k} {v:.3f}" for k, v in r["luminance"].items()), flush=True)


if __name__ == "__main__":
    main()
