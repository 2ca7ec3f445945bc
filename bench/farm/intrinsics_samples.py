"""What the intrinsics pass's samples per pixel (``--aov-samples``) buy: error per layer against CPU seconds.

One sample asset is prepared and fitted once (``bench.farm.render_speed.prepare``); then the farm's own
intrinsics pass (``batch/blender_job.py``'s ``render_intrinsics`` on the farm's orbit and Cycles settings,
512 px, every ``STRIDE``-th frame of the 16-frame orbit) renders it at each of ``SAMPLES`` and at
``REFERENCE`` samples, each in its own process, CPU-timed around the pass. Per EXR layer and sample count:
the mean absolute error against the reference over the object's pixels (either image's coverage above 0)
and the share of those pixels where some channel differs by more than ``DIFFER``. The pass is seeded (the
Cycles seed is fixed), so the noise floor is the reference rendered at another seed against itself, and the
spread of the default's error shows in ``DEFAULT`` samples at that other seed.

The rule: the fewest samples whose every layer's error (mean and share) is at most the default's plus the
floor. Writes docs/reports/intrinsics_samples.json and .png.

    python -m bench.farm.intrinsics_samples [--asset WaterBottle] [--work DIR]
"""
from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from batch import options
from batch.options import DEFAULT_GRAPH, cpu_threads
from bench.common import REPO, add_out_argument, pyplot, run_python, save_chart, write_report

MODELS = REPO.parent / "shared" / "assets" / "models"
SAMPLES = (1, 2, 4, 6, 8)
REFERENCE = 64
DEFAULT = options.build_parser().get_default("aov_samples")
RESOLUTION = options.build_parser().get_default("resolution")
FRAMES = options.build_parser().get_default("frames")
STRIDE = 4  # frames 0, 4, 8, 12 of the orbit
OTHER_SEED = 1
DIFFER = 1 / 255  # a pixel differs where some channel is further apart than an 8-bit step


def job(prepared: Path, out: Path, samples: int, seed: int, threads: int) -> None:
    """Blender side: the farm's intrinsics pass over ``prepared``'s orbit at ``samples`` and Cycles seed
    ``seed``, into ``out/passes``; its CPU seconds into ``out/cpu.json``."""
    import bpy

    from batch import bl_render, blender_job

    bpy.ops.wm.open_mainfile(filepath=str(prepared / "scene.blend"), load_ui=False, use_scripts=False)
    scene = bpy.context.scene
    slots = blender_job.enhanced_slots(scene, json.loads((prepared / "asset.json").read_text(encoding="utf-8")),
                                       prepared, DEFAULT_GRAPH)
    bl_render.configure_cycles(scene, RESOLUTION, 1, 0.01, threads, DEFAULT_GRAPH)
    scene.cycles.seed = seed  # the intrinsics scene copies it
    bl_render.orbit(scene, FRAMES, bl_render.start_azimuth(prepared.name, 0))
    for slot, (_, unlit) in slots:
        slot.material = unlit
    start = time.process_time()
    blender_job.render_intrinsics(scene, samples, out, STRIDE)
    (out / "cpu.json").write_text(json.dumps({"cpu_s": time.process_time() - start}))


def read_layers(folder: Path) -> dict[str, np.ndarray]:
    """Every layer of every frame's EXR, frames stacked: {layer: (F, H, W, C)} without alpha channels."""
    import OpenImageIO as oiio

    frames: dict[str, list[np.ndarray]] = {}
    for path in sorted((folder / "passes").glob("*.exr")):
        for part in range(oiio.ImageBuf(str(path)).nsubimages):
            buf = oiio.ImageBuf(str(path), part, 0)
            names = buf.spec().channelnames
            keep = [i for i, n in enumerate(names) if not n.endswith(".A")]
            frames.setdefault(names[0].split(".")[0], []).append(buf.get_pixels(oiio.FLOAT)[..., keep])
    return {layer: np.stack(v) for layer, v in frames.items()}


def errors(test: dict[str, np.ndarray], reference: dict[str, np.ndarray]) -> dict[str, dict[str, float]]:
    """Per layer: mean absolute error over the object's pixels, and the share of them that differ."""
    mask = (test["coverage"][..., 0] > 0) | (reference["coverage"][..., 0] > 0)
    out = {}
    for layer, ref in reference.items():
        gap = np.abs(test[layer] - ref)[mask]
        out[layer] = {"mae": float(gap.mean()), "differ": float((gap.max(-1) > DIFFER).mean())}
    return out


def chosen(rows: dict[int, dict], floor: dict[str, dict[str, float]]) -> int:
    """The fewest samples whose every layer's error and share are at most the default's plus the floor."""
    default = rows[DEFAULT]["layers"]
    return min(n for n, row in rows.items()
               if all(row["layers"][layer][k] <= default[layer][k] + floor[layer][k]
                      for layer in floor for k in ("mae", "differ")))


def chart(report: dict, path: Path) -> None:
    """CPU seconds of the pass against each layer's error, the floor dashed."""
    plt = pyplot()
    fig, axes = plt.subplots(1, 2, figsize=(12, 4.8))
    rows = report["samples"]
    counts = sorted(rows, key=int)
    cpu = [rows[n]["cpu_s"] for n in counts]
    for layer, colour in zip(report["floor"], plt.cm.tab10.colors):
        if not any(rows[n]["layers"][layer]["mae"] for n in counts):
            axes[0].plot([], [], "o-", color=colour, label=f"{layer}: 0 at every count")
            continue
        for ax, key in zip(axes, ("mae", "differ")):
            ax.plot(cpu, [rows[n]["layers"][layer][key] for n in counts], "o-", color=colour, label=layer)
            ax.axhline(report["floor"][layer][key], ls="--", lw=0.8, color=colour)
    for n, x in zip(counts, cpu):
        axes[0].annotate(str(n), (x, rows[n]["layers"]["basecolor"]["mae"]), textcoords="offset points",
                         xytext=(3, 4), fontsize=7)
    for ax, title in zip(axes, ("mean absolute error against the reference", "share of pixels off by > 1/255")):
        ax.set_xlabel(f"CPU s of the intrinsics pass ({len(report['frames'])} frames, {RESOLUTION} px)")
        ax.set_yscale("log")
        ax.set_title(f"{title} ({REFERENCE} spp); dashed: reference vs reference at another seed", fontsize=8)
        ax.legend(fontsize=7)
    save_chart(fig, path)


def main(argv: list[str]) -> int:
    if argv[:1] == ["--job"]:
        job(Path(argv[1]), Path(argv[2]), *map(int, argv[3:6]))
        return 0
    from bench.farm.render_speed import prepare
    from batch.options import DEFAULT_DECODER

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--asset", default="WaterBottle", help="a name in ../shared/assets/models")
    parser.add_argument("--work", type=Path, default=Path(tempfile.gettempdir()) / "richmat_intrinsics_samples")
    parser.add_argument("--fit-steps", type=int, default=20, help="the latents' fit (its accuracy is not measured)")
    add_out_argument(parser, "intrinsics_samples.json")
    args = parser.parse_args(argv)
    threads = cpu_threads(1)
    setup = argparse.Namespace(max_texture=8192, fit_steps=args.fit_steps, decoder=DEFAULT_DECODER, threads=threads)
    prepared = prepare(MODELS / f"{args.asset}.glb", args.work, setup)

    def render(samples: int, seed: int) -> tuple[float, dict[str, np.ndarray]]:
        out = args.work / f"s{samples}_seed{seed}"
        run_python(["-m", "bench.farm.intrinsics_samples", "--job", str(prepared), str(out), str(samples), str(seed),
                    str(threads)], out)
        print(f"{samples} samples, seed {seed}", flush=True)
        return json.loads((out / "cpu.json").read_text())["cpu_s"], read_layers(out)

    _, reference = render(REFERENCE, 0)
    _, other = render(REFERENCE, OTHER_SEED)
    rows = {}
    for n in SAMPLES:
        cpu, layers = render(n, 0)
        rows[n] = {"cpu_s": cpu, "layers": errors(layers, reference)}
    _, default_other = render(DEFAULT, OTHER_SEED)
    floor = errors(other, reference)
    report = {"asset": args.asset, "resolution": RESOLUTION, "frames": list(range(0, FRAMES, STRIDE)),
              "threads": threads, "reference_samples": REFERENCE, "differ_threshold": DIFFER,
              "cpu_measure": "time.process_time of the Blender process around the pass (scene copy, sync, "
                             "render, EXR writes); one run each on a shared machine",
              "error_measure": "over the object's pixels (either image's coverage > 0), alpha channels left out",
              "samples": rows, "floor": floor,
              f"default_{DEFAULT}_at_seed_{OTHER_SEED}": errors(default_other, reference),
              "rule": f"fewest samples with every layer's mae and differ share <= those of {DEFAULT} samples "
                      f"+ the floor", "chosen": chosen(rows, floor)}
    write_report(args.out, report, [DEFAULT_DECODER])
    chart(report, args.out.with_suffix(".png"))
    print(json.dumps({k: report[k] for k in ("samples", "floor", "chosen")}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
