"""The beauty pass's denoiser, OIDN's prefilter and network: seconds per frame against accuracy
(issue 29, item 2; issue 40, item 3).

The beauty pass is the farm's biggest stage after the fit (bench/farm/farm_cost.py), and OIDN a
large part of it: its "accurate" prefilter denoises the albedo and normal passes before using
them, and its "high" network is Cycles' default. Here every variant (``VARIANTS``) renders the
same frames of the same prepared assets (enhanced and fitted once,
``bench.farm.render_speed.prepare``) at the farm's defaults otherwise, ``--repeats`` times, one render
per core at a time in an order rotated each repeat, so that the shared machine's load hits them
alike (the median of the repeats is quoted); each is compared by mean FLIP (LDR, AgX PNGs) with a
reference of the same frames at ``--reference-samples`` spp (accurate prefilter, high network).
Seconds per frame: the beauty stage's CPU seconds (one render thread) over its frames. The
assets are prepared as bench/farm/render_speed.py prepares them (textures cut to 128 px, 20 fit
steps): the denoiser's cost depends on the image, not on them.

    python -m bench.farm.beauty_denoise [--assets A.glb B.glb] [--frames 4] [--reference-samples 128] [--repeats 3]
"""
from __future__ import annotations

import argparse
import json
import shutil
import sys
import tempfile
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np

from batch import options
from batch.cores import allowed_cores
from batch.options import DEFAULT_DENOISE_PREFILTER, DEFAULT_DENOISE_QUALITY
from bench.common import add_out_argument, pyplot, save_chart, write_report
from bench.farm.render_speed import beauty_frames, mean_flip, parse, prepare, render_ours

_FARM = options.build_parser()
SAMPLES, THRESHOLD = _FARM.get_default("samples"), _FARM.get_default("adaptive_threshold")  # the farm's defaults
VARIANTS = (("accurate", "high"), ("fast", "high"), ("fast", "balanced"), ("fast", "fast"))  # (prefilter, network)
FARM_DEFAULT = (DEFAULT_DENOISE_PREFILTER, DEFAULT_DENOISE_QUALITY)


def label(variant: tuple[str, str]) -> str:
    return f"{variant[0]} prefilter, {variant[1]} network"


def main(argv: list[str]) -> int:
    extra = argparse.ArgumentParser(add_help=False)
    add_out_argument(extra, "beauty_denoise.json")
    extra.add_argument("--repeats", type=int, default=3, help="renders of each variant (median CPU seconds)")
    own, rest = extra.parse_known_args(argv)
    args = parse(["--resolution", "512", "--threads", "1", "--reference-samples", "128",
                  "--work", str(Path(tempfile.gettempdir()) / "richmat_beauty_denoise"), *rest])
    assets = [a for a in args.assets if a.is_file()]
    prepared = [prepare(a, args.work, args) for a in assets]
    rows = {label(v): {"seconds_per_frame": [], "flip": []} for v in VARIANTS}
    for asset in prepared:
        ref_dir = args.work / "ref" / asset.name
        if (ref_dir / "render.json").is_file():  # a reference this work folder already holds
            reference = beauty_frames(ref_dir)
        else:
            _, _, reference = render_ours(asset, ref_dir, args.reference_samples, 0.001, args, "accurate", "high")

        def folder(variant: tuple[str, str]) -> Path:
            return args.work / "_".join(variant) / asset.name

        def render(variant: tuple[str, str]) -> float:
            out = folder(variant)
            shutil.rmtree(out, ignore_errors=True)
            render_ours(asset, out, SAMPLES, THRESHOLD, args, *variant)
            return json.loads((out / "render.json").read_text())["cpu_s"]["beauty"] / args.frames

        seconds: dict[tuple[str, str], list[float]] = {v: [] for v in VARIANTS}
        with ThreadPoolExecutor(len(allowed_cores())) as pool:
            for repeat in range(own.repeats):
                order = VARIANTS[repeat % len(VARIANTS):] + VARIANTS[:repeat % len(VARIANTS)]
                for variant, cpu in zip(order, pool.map(render, order)):
                    seconds[variant].append(cpu)
        for variant in VARIANTS:  # the frames are the same at every repeat (seeded): FLIP of the last
            row = rows[label(variant)]
            row["seconds_per_frame"].append(float(np.median(seconds[variant])))
            row["flip"].append(mean_flip(reference, beauty_frames(folder(variant))))
            print(asset.name, label(variant), seconds[variant], row["flip"][-1], flush=True)
    summary = {name: {"median_seconds_per_frame": float(np.median(r["seconds_per_frame"])),
                      "mean_flip": float(np.mean(r["flip"])), **r} for name, r in rows.items()}
    default = summary[label(FARM_DEFAULT)]
    report = {"assets": [a.name for a in assets], "resolution": args.resolution, "frames": args.frames,
              "samples": SAMPLES, "adaptive_threshold": THRESHOLD, "threads": args.threads, "repeats": own.repeats,
              "reference_samples": args.reference_samples, "farm_default": label(FARM_DEFAULT),
              "variants": summary,
              "time_over_farm_default": {name: r["median_seconds_per_frame"] / default["median_seconds_per_frame"]
                                         for name, r in summary.items()},
              "flip_over_farm_default": {name: r["mean_flip"] - default["mean_flip"] for name, r in summary.items()}}
    write_report(own.out, report, [args.decoder])
    chart(report, own.out.with_suffix(".png"))
    print(json.dumps({k: report[k] for k in ("time_over_farm_default", "flip_over_farm_default")}, indent=1))
    return 0


def chart(report: dict, path: Path) -> None:
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(6.5, 4.2))
    for name, row in report["variants"].items():
        ax.plot(row["seconds_per_frame"], row["flip"], "o", ms=8, label=name)
        for asset, x, y in zip(report["assets"], row["seconds_per_frame"], row["flip"]):
            ax.annotate(Path(asset).stem, (x, y), fontsize=7, xytext=(4, 3), textcoords="offset points")
    ax.set_xlabel("beauty CPU seconds per frame (one thread)")
    ax.set_ylabel(f"mean FLIP vs {report['reference_samples']} spp reference")
    ax.set_title(f"{report['resolution']}² beauty, {report['samples']} spp: OIDN's prefilter and network "
                 f"(farm default: {report['farm_default']})", fontsize=9)
    ax.legend(fontsize=8)
    save_chart(fig, path)


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
