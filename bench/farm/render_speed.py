"""Dataset render speed against accuracy, and throughput against a naive baseline.

1. Sweep: the beauty pass of the dataset renderer (``batch/blender_job.py render``)
   over samples per pixel x adaptive thresholds, denoised with OIDN; per-frame time
   and mean FLIP (LDR, AgX PNGs) against a high-sample reference of the same
   frames. The default is the fastest setting whose FLIP is within ``--flip-slack``
   of the best swept setting.
2. Throughput at that default, side by side in one run on the same prepared
   assets (alternating, so machine load hits both alike): our render stage (beauty
   pass + one cheap SVM intrinsics pass, persistent data) against a naive baseline
   as the surveyed scripts work (one Blender process per asset, the beauty and then
   each intrinsic map as its own full path-traced render of an emission material,
   no persistent data). Both render the beauty with the same settings, so their
   beauty FLIP is equal by construction (and measured).

The fit and prepare stages are run once per asset beforehand and are not timed:
they are the same for both sides. Costs on 2 shared CPU cores forced small
settings (defaults: 128 x 128, 4 frames, 2 assets); the report says which.
Writes docs/reports/render_speed.json and docs/reports/render_speed.png.

    python -m bench.farm.render_speed [--assets A.glb B.glb] [--resolution 128] [--frames 4]
"""
from __future__ import annotations

import argparse
import json
import os
import shutil
import sys
import tempfile
from pathlib import Path

import numpy as np

from batch.options import DEFAULT_DENOISE_PREFILTER, DEFAULT_DENOISE_QUALITY, DEFAULT_GRAPH
from bench.common import REPO, add_out_argument, child_env, pyplot, save_chart, write_report

SHARED_MODELS = REPO.parent / "shared" / "assets" / "models"
DEFAULT_ASSETS = [SHARED_MODELS / "Suzanne.glb", SHARED_MODELS / "WaterBottle.glb"]
SWEEP_SAMPLES = (4, 8, 12, 16, 32, 64)
SWEEP_THRESHOLDS = (0.1, 0.05, 0.01)
INTRINSIC_MAPS = ("Normal", "Position", "basecolor", "latent_a", "latent_b", "coverage")
PREPARED = ("scene.blend", "asset.json", "materials")


def parse(argv: list[str]) -> argparse.Namespace:
    from batch.options import DEFAULT_DECODER, DEFAULT_PROBE

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0],
                                formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    p.add_argument("--assets", type=Path, nargs="+", default=DEFAULT_ASSETS)
    p.add_argument("--resolution", type=int, default=128)
    p.add_argument("--frames", type=int, default=4)
    p.add_argument("--reference-samples", type=int, default=512)
    p.add_argument("--aov-samples", type=int, default=8)
    p.add_argument("--flip-slack", type=float, default=0.005, help="FLIP allowed above the best swept setting")
    p.add_argument("--fit-steps", type=int, default=20)
    p.add_argument("--max-texture", type=int, default=128)
    p.add_argument("--decoder", type=Path, default=DEFAULT_DECODER)
    p.add_argument("--probe", type=Path, default=DEFAULT_PROBE)
    p.add_argument("--threads", type=int, default=os.cpu_count() or 1)
    p.add_argument("--work", type=Path, default=Path(tempfile.gettempdir()) / "richmat_render_speed")
    add_out_argument(p, "render_speed.json")
    return p.parse_args(argv)


def _run(cmd: list[str], log: Path) -> float:
    """Run a child to completion; its wall time. Raise with the log tail on failure."""
    from batch import runner

    out = runner.run(cmd, 3600, log, env=child_env())
    if not out.ok:
        raise RuntimeError(f"{cmd[:4]}... {out.describe()}:\n{out.stderr_tail}")
    return out.seconds


def farm_prepare(asset: Path, folder: Path, max_texture: int) -> None:
    """The farm's prepare stage on ``asset`` into ``folder``: the scene normalised, every material uplifted
    at the farm's type for the asset (seed 0) into ``folder``/materials, ``scene.blend`` and ``asset.json``."""
    from batch.assets import asset_id
    from batch.pipeline import default_commands
    from torch_models.assets.enhancement_plan import asset_type

    aid = asset_id(asset.name)
    _run(default_commands(None, None).blender_job(
        ["prepare", "--asset", str(asset), "--work", str(folder), "--asset-id", aid, "--type",
         str(asset_type(aid, 0)), "--seed", "0", "--max-texture", str(max_texture)]), folder / "logs" / "prepare")


def prepare(asset: Path, work: Path, args: argparse.Namespace) -> Path:
    """Prepare and fit one asset once (not timed): the input of every render below."""
    from batch.assets import asset_id
    from batch.options import DEFAULT_CLUSTER_STEP
    from batch.pipeline import default_commands

    commands = default_commands(None, None)
    folder = work / "prepared" / asset_id(asset.name)
    if (folder / "fit.json").is_file():
        return folder
    shutil.rmtree(folder, ignore_errors=True)
    folder.mkdir(parents=True)
    farm_prepare(asset, folder, args.max_texture)
    _run(commands.fit_job(["--work", str(folder), "--decoder", str(args.decoder), "--steps",
                           str(args.fit_steps), "--cluster-step", repr(DEFAULT_CLUSTER_STEP),
                           "--threads", str(args.threads)]), folder / "logs" / "fit")
    return folder


def _copy_prepared(prepared: Path, out: Path) -> None:
    shutil.rmtree(out, ignore_errors=True)
    out.mkdir(parents=True)
    for name in PREPARED:
        src = prepared / name
        (shutil.copytree if src.is_dir() else shutil.copy2)(src, out / name)


def beauty_frames(folder: Path) -> list[np.ndarray]:
    from PIL import Image

    return [np.asarray(Image.open(p), np.float32)[..., :3] / 255.0 for p in sorted((folder / "rgb").glob("*.png"))]


def render_ours(prepared: Path, out: Path, samples: int, threshold: float, args: argparse.Namespace,
                prefilter: str = DEFAULT_DENOISE_PREFILTER, quality: str = DEFAULT_DENOISE_QUALITY
                ) -> tuple[float, dict, list[np.ndarray]]:
    """Our render stage: (wall seconds, render.json timings, beauty frames); ``prefilter`` and ``quality``
    are OIDN's."""
    from batch.pipeline import default_commands

    _copy_prepared(prepared, out)
    cmd = default_commands(None, None).blender_job(
        ["render", "--work", str(out), "--asset-id", prepared.name, "--frames", str(args.frames),
         "--resolution", str(args.resolution), "--samples", str(samples), "--adaptive-threshold", str(threshold),
         "--denoise-prefilter", prefilter, "--denoise-quality", quality, "--aov-samples", str(args.aov_samples),
         "--probe", str(args.probe), "--seed", "0", "--threads", str(args.threads)])
    seconds = _run(cmd, out / "logs" / "render")
    timings = json.loads((out / "render.json").read_text())["timings_s"]
    return seconds, timings, beauty_frames(out)


def render_naive(prepared: Path, out: Path, samples: int, threshold: float, args: argparse.Namespace
                 ) -> tuple[float, list[np.ndarray]]:
    """The baseline: one process, beauty then one full render per intrinsic map."""
    _copy_prepared(prepared, out)
    cmd = [sys.executable, "-m", "bench.farm.render_speed", "--naive-job", str(out), prepared.name,
           str(args.frames), str(args.resolution), str(samples), str(threshold), str(args.probe),
           str(args.threads)]
    seconds = _run(cmd, out / "logs" / "naive")
    return seconds, beauty_frames(out)


def naive_job(argv: list[str]) -> None:
    """Blender side of the baseline (runs with the bpy module)."""
    work, asset, frames, res, samples, threshold, probe, threads = argv
    from richmat_addon.blender.osl_env import prefer_blender_bundled_modules

    prefer_blender_bundled_modules()
    import bpy

    from batch import bl_render, dataset_material

    work_dir = Path(work)
    bpy.ops.wm.open_mainfile(filepath=str(work_dir / "scene.blend"), load_ui=False, use_scripts=False)
    scene = bpy.context.scene
    prepared = json.loads((work_dir / "asset.json").read_text())
    built = {m["name"]: dataset_material.build(work_dir / "materials" / m["folder"], DEFAULT_GRAPH)
             for m in prepared["materials"]}
    slots = [s for o in scene.objects for s in getattr(o, "material_slots", []) if s.material and s.material.name in built]
    names = [s.material.name for s in slots]
    bl_render.configure_cycles(scene, int(res), int(samples), float(threshold), int(threads), DEFAULT_GRAPH)
    scene.render.use_persistent_data = False  # Blender's default, as in the surveyed scripts
    scene.world = bl_render.probe_world(Path(probe))
    bl_render.orbit(scene, int(frames), bl_render.start_azimuth(asset, 0))
    for slot, name in zip(slots, names):
        slot.material = built[name][0]
    bl_render.beauty_output(scene, work_dir / "rgb")
    bpy.ops.render.render(animation=True, scene=scene.name)
    scene.cycles.shading_system = False
    scene.render.image_settings.file_format = "OPEN_EXR"
    scene.render.image_settings.color_mode = "RGB"
    scene.render.image_settings.color_depth = "16"
    for map_name in INTRINSIC_MAPS:
        emissive = {name: _emission(built[name][1], map_name) for name in set(names)}
        for slot, name in zip(slots, names):
            slot.material = emissive[name]
        scene.render.filepath = str(work_dir / "naive" / map_name) + "/"
        bpy.ops.render.render(animation=True, scene=scene.name)


def _emission(aov_material, map_name: str):  # type: ignore[no-untyped-def]
    """A copy of the AOV material that shows one map as emission (normals/positions from geometry)."""
    material = aov_material.copy()
    tree = material.node_tree
    out = next(n for n in tree.nodes if n.bl_idname == "ShaderNodeOutputMaterial")
    emit = tree.nodes.new("ShaderNodeEmission")
    if map_name in ("Normal", "Position"):
        source = tree.nodes.new("ShaderNodeNewGeometry").outputs[map_name]
    else:
        aov = tree.nodes[f"aov_{map_name}"]
        socket = aov.inputs["Value" if map_name == "coverage" else "Color"]
        source = socket.links[0].from_socket if socket.is_linked else None
        if source is None:
            emit.inputs["Color"].default_value = (*[socket.default_value] * 3, 1.0) if map_name == "coverage" \
                else socket.default_value
    if source is not None:
        tree.links.new(source, emit.inputs["Color"])
    tree.links.new(emit.outputs["Emission"], out.inputs["Surface"])
    return material


def mean_flip(reference: list[np.ndarray], test: list[np.ndarray]) -> float:
    from torch_models.render.flip import mean_flip as flip

    return float(np.mean([flip(r, t) for r, t in zip(reference, test)]))


def chart(report: dict, path: Path) -> None:
    plt = pyplot()
    fig, (ax, bx) = plt.subplots(1, 2, figsize=(12, 4.8))
    for threshold in SWEEP_THRESHOLDS:
        rows = [r for r in report["sweep"] if r["adaptive_threshold"] == threshold]
        ax.plot([r["seconds_per_frame"] for r in rows], [r["mean_flip"] for r in rows], "o-",
                label=f"adaptive threshold {threshold}")
        for r in rows:
            ax.annotate(str(r["samples"]), (r["seconds_per_frame"], r["mean_flip"]), fontsize=7,
                        xytext=(3, 3), textcoords="offset points")
    d = report["default"]
    ax.plot([d["seconds_per_frame"]], [d["mean_flip"]], "k*", ms=14, label="chosen default")
    ax.set_xlabel("beauty seconds per frame (median, 2 shared CPU cores)")
    ax.set_ylabel(f"mean FLIP vs {report['setup']['reference_samples']} spp reference")
    ax.set_title(f"{report['setup']['resolution']}² beauty, OIDN, 3 bounces (labels: spp)")
    ax.legend(fontsize=8)
    t = report["throughput"]
    bars = bx.bar(["ours: beauty + 1 SVM\nintrinsics pass", "naive: beauty + 6 full\nrenders, 1 per map"],
                  [t["ours_assets_per_hour"], t["naive_assets_per_hour"]], color=["tab:green", "tab:grey"])
    bx.bar_label(bars, fmt="%.0f")
    bx.set_ylabel("assets per hour (render stage)")
    bx.set_title(f"throughput at the default: {t['speedup']:.2f}x "
                 f"(beauty FLIP {t['ours_beauty_flip']:.4f} vs {t['naive_beauty_flip']:.4f})")
    save_chart(fig, path)


def main(argv: list[str]) -> int:
    if argv and argv[0] == "--naive-job":
        naive_job(argv[1:])
        return 0
    args = parse(argv)
    assets = [a for a in args.assets if a.is_file()]
    if not assets:
        raise SystemExit(f"none of the bench assets exist: {args.assets}")
    prepared = [prepare(a, args.work, args) for a in assets]
    reference = {}
    for p in prepared:
        _, _, reference[p.name] = render_ours(p, args.work / "ref" / p.name, args.reference_samples, 0.001, args)
    sweep = []
    for samples in SWEEP_SAMPLES:
        for threshold in SWEEP_THRESHOLDS:
            per_frame, flips = [], []
            for p in prepared:
                _, timings, frames = render_ours(p, args.work / "sweep" / p.name, samples, threshold, args)
                per_frame.append(float(np.median(timings["beauty_frames"][1:] or timings["beauty_frames"])))
                flips.append(mean_flip(reference[p.name], frames))
            sweep.append({"samples": samples, "adaptive_threshold": threshold,
                          "seconds_per_frame": float(np.mean(per_frame)),
                          "timing": "median over frames after the first (which also pays scene sync and OSL setup)", "mean_flip": float(np.mean(flips))})
            print(sweep[-1], flush=True)
    best = min(r["mean_flip"] for r in sweep)
    default = min((r for r in sweep if r["mean_flip"] <= best + args.flip_slack),
                  key=lambda r: r["seconds_per_frame"])
    ours_s, naive_s, ours_flip, naive_flip = [], [], [], []
    for p in prepared:  # alternate, so load changes hit both sides
        seconds, _, frames = render_ours(p, args.work / "ours" / p.name, default["samples"],
                                         default["adaptive_threshold"], args)
        ours_s.append(seconds)
        ours_flip.append(mean_flip(reference[p.name], frames))
        seconds, frames = render_naive(p, args.work / "naive" / p.name, default["samples"],
                                       default["adaptive_threshold"], args)
        naive_s.append(seconds)
        naive_flip.append(mean_flip(reference[p.name], frames))
    throughput = {"ours_seconds_per_asset": ours_s, "naive_seconds_per_asset": naive_s,
                  "ours_assets_per_hour": 3600 * len(ours_s) / sum(ours_s),
                  "naive_assets_per_hour": 3600 * len(naive_s) / sum(naive_s),
                  "ours_beauty_flip": float(np.mean(ours_flip)), "naive_beauty_flip": float(np.mean(naive_flip))}
    throughput["speedup"] = throughput["ours_assets_per_hour"] / throughput["naive_assets_per_hour"]
    report = {"setup": {"assets": [a.name for a in assets], "resolution": args.resolution, "frames": args.frames,
                        "reference_samples": args.reference_samples, "reference_threshold": 0.001,
                        "aov_samples": args.aov_samples, "threads": args.threads,
                        "timing": "wall seconds on this machine (provenance): noisy where it is shared"},
              "rule": f"fastest swept setting with mean FLIP <= best swept FLIP + {args.flip_slack}",
              "sweep": sweep, "default": default, "throughput": throughput}
    write_report(args.out, report, [args.decoder])
    chart(report, args.out.with_suffix(".png"))
    print(json.dumps({"default": default, "throughput": throughput}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
