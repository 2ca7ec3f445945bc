"""The beauty pass's denoiser prefilter: seconds per frame against accuracy (issue 29, item 2).

The beauty pass is the farm's biggest stage at the real defaults (bench/farm_cost.py),
and OIDN's "accurate" prefilter, which denoises the albedo and normal passes before
using them, costs about half of a 512 px, 16 spp frame on one thread. Here both
prefilters render the same frames of the same prepared assets (enhanced and fitted
once, ``bench.render_speed.prepare``) at the farm's defaults otherwise, both at the
same time so that the shared machine's load hits them alike; each is compared by mean
FLIP (LDR, AgX PNGs) with a reference of the same frames at ``--reference-samples`` spp
(accurate prefilter). Seconds per frame: the beauty stage's CPU seconds (one render
thread) over its frames. The assets are prepared as bench/render_speed.py prepares them
(textures cut to 128 px, 20 fit steps): the denoiser's cost depends on the image, not on
them.

    python -m bench.beauty_denoise [--assets A.glb B.glb] [--frames 4] [--reference-samples 128]
"""
from __future__ import annotations

import argparse
import json
import sys
import tempfile
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np

from batch import options
from batch.options import DEFAULT_DENOISE_PREFILTER, DENOISE_PREFILTERS
from bench.common import add_out_argument, pyplot, save_chart, write_report
from bench.render_speed import beauty_frames, mean_flip, parse, prepare, render_ours

_FARM = options.build_parser()
SAMPLES, THRESHOLD = _FARM.get_default("samples"), _FARM.get_default("adaptive_threshold")  # the farm's defaults


def main(argv: list[str]) -> int:
    extra = argparse.ArgumentParser(add_help=False)
    add_out_argument(extra, "beauty_denoise.json")
    own, rest = extra.parse_known_args(argv)
    args = parse(["--resolution", "512", "--threads", "1", "--reference-samples", "128",
                  "--work", str(Path(tempfile.gettempdir()) / "richmat_beauty_denoise"), *rest])
    assets = [a for a in args.assets if a.is_file()]
    prepared = [prepare(a, args.work, args) for a in assets]
    rows = {p: {"seconds_per_frame": [], "flip": []} for p in DENOISE_PREFILTERS}
    for asset in prepared:
        ref_dir = args.work / "ref" / asset.name
        if (ref_dir / "render.json").is_file():  # a reference this work folder already holds
            reference = beauty_frames(ref_dir)
        else:
            _, _, reference = render_ours(asset, ref_dir, args.reference_samples, 0.001, args, "accurate")

        def render(prefilter: str) -> tuple[float, list[np.ndarray]]:
            out = args.work / prefilter / asset.name
            _, _, frames = render_ours(asset, out, SAMPLES, THRESHOLD, args, prefilter)
            cpu = json.loads((out / "render.json").read_text())["cpu_s"]["beauty"]
            return cpu / args.frames, frames

        with ThreadPoolExecutor(len(DENOISE_PREFILTERS)) as pool:  # at once: the machine's load hits both alike
            results = dict(zip(DENOISE_PREFILTERS, pool.map(render, DENOISE_PREFILTERS)))
        for prefilter, (seconds, frames) in results.items():
            rows[prefilter]["seconds_per_frame"].append(seconds)
            rows[prefilter]["flip"].append(mean_flip(reference, frames))
            print(asset.name, prefilter, seconds, rows[prefilter]["flip"][-1], flush=True)
    summary = {p: {"median_seconds_per_frame": float(np.median(r["seconds_per_frame"])),
                   "mean_flip": float(np.mean(r["flip"])), **r} for p, r in rows.items()}
    report = {"assets": [a.name for a in assets], "resolution": args.resolution, "frames": args.frames,
              "samples": SAMPLES, "adaptive_threshold": THRESHOLD, "threads": args.threads,
              "reference_samples": args.reference_samples, "farm_default": DEFAULT_DENOISE_PREFILTER,
              "prefilters": summary,
              "speedup_fast_over_accurate": summary["accurate"]["median_seconds_per_frame"]
              / summary["fast"]["median_seconds_per_frame"],
              "flip_added_by_fast": summary["fast"]["mean_flip"] - summary["accurate"]["mean_flip"]}
    write_report(own.out, report, [args.decoder])
    chart(report, own.out.with_suffix(".png"))
    print(json.dumps({k: report[k] for k in ("speedup_fast_over_accurate", "flip_added_by_fast")}, indent=1))
    return 0


def chart(report: dict, path: Path) -> None:
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(6.5, 4.2))
    for prefilter, row in report["prefilters"].items():
        ax.plot(row["seconds_per_frame"], row["flip"], "o", ms=8, label=f"prefilter {prefilter}")
        for name, x, y in zip(report["assets"], row["seconds_per_frame"], row["flip"]):
            ax.annotate(Path(name).stem, (x, y), fontsize=7, xytext=(4, 3), textcoords="offset points")
    ax.set_xlabel("beauty CPU seconds per frame (one thread)")
    ax.set_ylabel(f"mean FLIP vs {report['reference_samples']} spp reference")
    ax.set_title(f"{report['resolution']}² beauty, {report['samples']} spp, OIDN: fast prefilter "
                 f"{report['speedup_fast_over_accurate']:.2f}x faster, FLIP {report['flip_added_by_fast']:+.4f}",
                 fontsize=9)
    ax.legend(fontsize=8)
    save_chart(fig, path)


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
