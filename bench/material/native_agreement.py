"""The native node graph against the exact OSL graph, both in Cycles on the CPU: FLIP and time per case.

For each of Types 0-5 (several drawn materials) and each lobe alone, the cases of
support/agreement_cases.py are rendered on the preview ball by one Blender child
process (bench/material/native_agreement_cycles.py), once with Cycles reading the OSL
Script node (OSL shading) and once reading the native group (SVM), same scene,
same samples, one thread. Both are tone mapped with AgX and compared with
LDR-FLIP. Each graph renders a few frames: the first pays for the sync and the
shader compilation, the fastest of the others is the per-frame cost.

    python -m bench.material.native_agreement [--per-type N] [--seed N] [--out FILE.json]

Targets (issue 28): mean FLIP <= 0.03 and worst <= 0.06 over the cases.
"""
from __future__ import annotations

import argparse
import json
import statistics
import sys
import tempfile
import time
from dataclasses import asdict
from pathlib import Path

import numpy as np

from support.agreement_cases import Case, cases
from bench.common import FLIP_CONVENTION, REPO, add_out_argument, pyplot, run_python, save_chart, write_report
from bench.material.native_agreement_cycles import CPU_CONFIGS, FRAMES
from richmat_addon.core.folder_io import read_exr
from torch_models.render.flip import flip_map
from torch_models.render.tonemap import agx

TARGET_MEAN, TARGET_WORST = 0.03, 0.06
DEFAULT_PROBE = REPO / "torch_models" / "data" / "studio_small_03_512.hdr"
GRAPHS = tuple(c["label"] for c in CPU_CONFIGS)


def render(all_cases: list[Case], args: argparse.Namespace, folder: Path) -> dict:
    job = folder / "job.json"
    job.write_text(json.dumps({"cases": [asdict(c) for c in all_cases], "probe": str(args.probe),
                               "resolution": args.resolution, "samples": args.samples, "seed": args.seed,
                               "out": str(folder)}))
    run_python(["-m", "bench.material.native_agreement_cycles", str(job)], folder)
    return json.loads((folder / "times.json").read_text())


def group_of(case: Case) -> str:
    """``type3`` for a drawn material, ``lobe coat`` for a lobe alone."""
    return case.name.split("_")[0] if case.node == "surface" else f"lobe {case.node}"


def summary(rows: list[dict]) -> dict:
    """Mean and worst FLIP and the median per-frame CPU seconds of each graph, per group and overall."""
    groups: dict[str, list[dict]] = {}
    for row in rows:
        groups.setdefault(row["group"], []).append(row)
    groups["all"] = rows

    def stats(members: list[dict]) -> dict:
        flips = [r["flip"] for r in members]
        out = {"cases": len(members), "mean_flip": float(np.mean(flips)), "worst_flip": max(flips)}
        for which in GRAPHS:
            out[f"{which}_frame_cpu_s"] = statistics.median(r["seconds"][which]["frame"][1] for r in members)
            out[f"{which}_first_cpu_s"] = statistics.median(r["seconds"][which]["first"][1] for r in members)
        out["native_speedup"] = out["osl_frame_cpu_s"] / out["native_frame_cpu_s"]
        return out

    return {name: stats(members) for name, members in groups.items()}


def chart(report: dict, path: Path) -> None:
    """Speed against accuracy: each case's FLIP over its native/OSL per-frame time, and the times."""
    plt = pyplot()
    rows = report["cases"]
    fig, (a, b) = plt.subplots(1, 2, figsize=(13, 5))
    ratio = [r["seconds"]["native"]["frame"][1] / r["seconds"]["osl"]["frame"][1] for r in rows]
    lobe = [r["node"] != "surface" for r in rows]
    for alone, colour, label in ((False, "tab:blue", "whole material"), (True, "tab:orange", "lobe alone")):
        pick = [i for i, x in enumerate(lobe) if x == alone]
        a.scatter([ratio[i] for i in pick], [rows[i]["flip"] for i in pick], c=colour, label=label)
    for r, x in zip(rows, ratio):
        a.annotate(r["name"], (x, r["flip"]), fontsize=6, alpha=0.7)
    a.axhline(TARGET_MEAN, color="gray", ls="--", lw=0.8, label=f"target mean {TARGET_MEAN}")
    a.axhline(TARGET_WORST, color="gray", ls=":", lw=0.8, label=f"target worst {TARGET_WORST}")
    a.axvline(1.0, color="black", lw=0.5)
    a.set_xlabel("native / OSL CPU seconds per frame (< 1: native faster)")
    a.set_ylabel(f"FLIP native vs OSL ({FLIP_CONVENTION})", fontsize=8)
    a.set_title(f"mean FLIP {report['summary']['all']['mean_flip']:.4f}, "
                f"worst {report['summary']['all']['worst_flip']:.4f}")
    a.legend(fontsize=8)
    groups = [g for g in report["summary"] if g != "all"]
    x = np.arange(len(groups))
    for k, (which, kind) in enumerate((("osl", "frame"), ("native", "frame"), ("osl", "first"),
                                       ("native", "first"))):
        b.bar(x + (k - 1.5) * 0.2, [report["summary"][g][f"{which}_{kind}_cpu_s"] for g in groups], 0.2,
              label=f"{which}, {'per frame' if kind == 'frame' else 'first frame (sync, compile)'}",
              color=["tab:red", "tab:green", "salmon", "lightgreen"][k])
    b.set_xticks(x, groups, rotation=60, ha="right", fontsize=8)
    b.set_ylabel("median CPU seconds (one thread)")
    b.set_title(f"{report['resolution']} px, {report['samples']} samples per frame")
    b.legend(fontsize=8)
    save_chart(fig, path)


def labelled_sheet(rows: list[tuple[str, list[tuple[str, np.ndarray]]]], path: Path) -> None:
    """One row per case, its label on the left; one titled column per image (an (H, W) one is a FLIP map)."""
    plt = pyplot()
    columns = max(len(images) for _, images in rows)
    fig, axes = plt.subplots(len(rows), columns, figsize=(2 * columns, 2.1 * len(rows)), squeeze=False)
    for row, (label, images) in zip(axes, rows):
        for ax in row:
            ax.set_axis_off()
        for ax, (title, image) in zip(row, images):
            ax.set_axis_on()
            ax.imshow(np.clip(image, 0, 1), cmap="magma" if image.ndim == 2 else None, vmin=0, vmax=1)
            ax.set_xticks([])
            ax.set_yticks([])
            ax.set_title(title, fontsize=8)
        row[0].set_ylabel(label, fontsize=7)
    save_chart(fig, path)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--per-type", type=int, default=2, help="drawn materials per type (default: 2)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the drawn materials (default: 0)")
    parser.add_argument("--resolution", type=int, default=96, help="preview ball size in pixels (default: 96)")
    parser.add_argument("--samples", type=int, default=256, help="Cycles samples per frame (default: 256)")
    parser.add_argument("--probe", type=Path, default=DEFAULT_PROBE, help="equirectangular HDR probe")
    parser.add_argument("--renders", type=Path, default=None, metavar="DIR",
                        help="keep the renders in DIR (default: a temporary folder)")
    add_out_argument(parser, "native_agreement.json")
    args = parser.parse_args()

    all_cases = cases(args.seed, args.per_type, 1)
    start = time.perf_counter()
    rows, images = [], []
    with tempfile.TemporaryDirectory(prefix="richmat_native_") as fresh:
        folder = args.renders or Path(fresh)
        folder.mkdir(parents=True, exist_ok=True)
        print(f"Cycles: {len(all_cases)} cases x {GRAPHS} at {args.resolution} px, {args.samples} spp ...", flush=True)
        times = render(all_cases, args, folder)
        for case in all_cases:
            osl, native = (agx(read_exr(folder / f"{case.name}_{g}_{FRAMES:04d}.exr")[..., :3]) for g in GRAPHS)
            error, flip = flip_map(osl, native)
            rows.append({"name": case.name, "node": case.node, "group": group_of(case), "flip": flip,
                         "seconds": times[case.name], "params": case.params, "base_color": case.base_color})
            images.append((f"{case.name}\nFLIP {flip:.4f}", [("OSL", osl), ("native", native), ("FLIP", error)]))
            print(f"{case.name:28s} FLIP {flip:.4f}  CPU s per frame: OSL {times[case.name]['osl']['frame'][1]:.2f}, "
                  f"native {times[case.name]['native']['frame'][1]:.2f}", flush=True)
    overall = summary(rows)
    mean, worst = overall["all"]["mean_flip"], overall["all"]["worst_flip"]
    report = {"seed": args.seed, "per_type": args.per_type, "probe": args.probe.name, "resolution": args.resolution,
              "samples": args.samples, "threads": 1, "flip_convention": FLIP_CONVENTION,
              "target_mean": TARGET_MEAN, "target_worst": TARGET_WORST,
              "passed": mean <= TARGET_MEAN and worst <= TARGET_WORST,
              "missed_by": {"mean": max(0.0, mean - TARGET_MEAN), "worst": max(0.0, worst - TARGET_WORST)},
              "time_columns": "seconds[graph][first|frame] = [wall, cpu]",
              "wall_seconds": time.perf_counter() - start, "summary": overall, "cases": rows}
    write_report(args.out, report)
    chart(report, args.out.with_suffix(".png"))
    labelled_sheet(images, args.out.with_name(args.out.stem + "_sheet.png"))
    print(f"mean FLIP {mean:.4f} (target {TARGET_MEAN}), worst {worst:.4f} (target {TARGET_WORST}): "
          f"{'PASS' if report['passed'] else 'FAIL'}; native {overall['all']['native_speedup']:.2f}x the OSL speed "
          f"per frame; {report['wall_seconds'] / 60:.1f} min; wrote {args.out}")
    sys.exit(0 if report["passed"] else 1)


if __name__ == "__main__":
    main()
