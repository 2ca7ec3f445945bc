"""On a GPU machine: each type in EEVEE and in Cycles on the GPU, against the Cycles CPU renders.

The cases of support/agreement_cases.py render on the preview ball in every
configuration the machine has (bench/material/native_agreement_cycles.py skips a missing
device): Cycles on the CPU reading the OSL graph (the reference) and the native
graph, Cycles with OptiX reading either, Cycles with CUDA, HIP, Metal or oneAPI
reading the native graph (they have no OSL), and EEVEE (native graph). Each is
compared by LDR-FLIP with the CPU OSL render and with the CPU native render.

EEVEE shows a default grey while a shader compiles or when it fails, so the run
also renders a plain Principled ball, and a case counts as compiled only when
EEVEE's render is closer to the Cycles reference than to that grey.

    python -m bench.material.native_gpu [--per-type N] [--out FILE.json]

Where the GPU machine lacks torch or bpy, split the run: ``--jobs DIR`` writes
DIR/cpu/job.json and DIR/gpu/job.json (paths relative to the repository) and
stops; ``python -m bench.material.native_agreement_cycles DIR/gpu/job.json`` renders the
GPU half there (``tools/bpy_bundle.sh`` carries bpy to a machine without it)
and the CPU half here, from the repository root; then ``--renders DIR``
compares them. Not run on the 2-core CPU machine the other
benches use; see docs/backends.md.
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

from support.agreement_cases import cases
from bench.common import FLIP_CONVENTION, REPO, add_out_argument, pyplot, run_python, save_chart, write_report
from bench.material.native_agreement import DEFAULT_PROBE, TARGET_MEAN, TARGET_WORST, labelled_sheet
from bench.material.native_agreement_cycles import CONTROL, CPU_CONFIGS, FRAMES, read_json
from richmat_addon.core.folder_io import read_exr
from torch_models.render.flip import flip_map
from torch_models.render.tonemap import agx

# EEVEE first and OSL last: a run cut short by a time limit keeps the configurations that matter most.
GPU_CONFIGS = [
    {"label": "eevee", "engine": "BLENDER_EEVEE", "device": "GPU", "graph": "native"},
    *({"label": f"{device.lower()}_native", "engine": "CYCLES", "device": device, "graph": "native"}
      for device in ("CUDA", "OPTIX", "HIP", "METAL", "ONEAPI")),
    {"label": "optix_osl", "engine": "CYCLES", "device": "OPTIX", "graph": "osl"},
]
REFERENCES = ("osl", "native")  # the CPU configurations every other one is compared with


def image(folder: Path, name: str, label: str) -> np.ndarray:
    return agx(read_exr(folder / f"{name}_{label}_{FRAMES:04d}.exr")[..., :3])


def rendered(folder: Path, name: str) -> list[str]:
    """The GPU configurations that rendered case ``name`` into ``folder`` (a run cut short leaves some out)."""
    return [c["label"] for c in GPU_CONFIGS if (folder / f"{name}_{c['label']}_{FRAMES:04d}.exr").exists()]


def summarise(rows: list[dict], label: str) -> dict:
    """Mean and worst FLIP of one configuration against each CPU reference, and its median seconds
    (None where its run stopped before it recorded a case's times)."""
    summary: dict = {"cases": len(rows)}
    for ref in REFERENCES:
        flips = [r["flip"][label][ref] for r in rows]
        summary[f"mean_flip_vs_cpu_{ref}"], summary[f"worst_flip_vs_cpu_{ref}"] = float(np.mean(flips)), max(flips)
    for key in ("frame", "first"):
        seconds = [r["seconds"][label][key][0] for r in rows if label in r["seconds"]]
        summary[f"{key}_wall_s"] = statistics.median(seconds) if seconds else None
    return summary


def write_jobs(folder: Path, all_cases: list, args: argparse.Namespace) -> None:
    """``folder``/cpu/job.json and ``folder``/gpu/job.json: the CPU references and the GPU configurations."""
    for half, configs in (("cpu", CPU_CONFIGS), ("gpu", GPU_CONFIGS)):
        (folder / half).mkdir(parents=True, exist_ok=True)
        (folder / half / "job.json").write_text(json.dumps({
            "cases": [asdict(c) for c in all_cases], "probe": str(relative(DEFAULT_PROBE)),
            "resolution": args.resolution, "samples": args.samples, "seed": args.seed,
            "out": str(relative(folder / half)), "configs": configs, "control": half == "gpu"}))


def relative(path: Path) -> Path:
    """``path`` from the repository root when it lies inside it (the jobs run from there on either machine)."""
    path = path.resolve()
    return path.relative_to(REPO) if path.is_relative_to(REPO) else path


def chart(report: dict, path: Path) -> None:
    plt = pyplot()
    labels = list(report["configs"])
    fig, ax = plt.subplots(figsize=(max(7, 1.1 * len(labels)), 4.5))
    x = np.arange(len(labels))
    for k, ref in enumerate(REFERENCES):
        ax.bar(x + (k - 0.5) * 0.4, [report["configs"][c][f"mean_flip_vs_cpu_{ref}"] for c in labels], 0.4,
               label=f"mean FLIP vs CPU {ref}")
    ax.axhline(TARGET_MEAN, color="gray", ls="--", lw=0.8, label=f"target mean {TARGET_MEAN}")
    ax.set_xticks(x, [f"{c} ({report['configs'][c]['cases']} cases)" for c in labels], rotation=30, ha="right")
    ax.set_ylabel(FLIP_CONVENTION, fontsize=8)
    ax.set_title("GPU renders against the Cycles CPU renders")
    ax.legend(fontsize=8)
    save_chart(fig, path)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--per-type", type=int, default=1, help="drawn materials per type (default: 1)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--resolution", type=int, default=96)
    parser.add_argument("--samples", type=int, default=256)
    parser.add_argument("--jobs", type=Path, help="only write the two halves' jobs into this folder")
    parser.add_argument("--renders", type=Path, help="compare the renders already in this folder's cpu/ and gpu/")
    parser.add_argument("--machine", default="", help="the GPU machine, in words, for the report")
    parser.add_argument("--note", default="", help="how the renders were made, for the report (with --renders)")
    add_out_argument(parser, "native_gpu.json")
    args = parser.parse_args()

    all_cases = cases(args.seed, args.per_type, 1)
    if args.jobs:
        write_jobs(args.jobs, all_cases, args)
        print(f"wrote {args.jobs}/cpu/job.json and {args.jobs}/gpu/job.json")
        return
    start = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="richmat_native_gpu_") as tmp:
        folder = args.renders or Path(tmp)
        if not args.renders:
            write_jobs(folder, all_cases, args)
            for half in ("cpu", "gpu"):
                run_python(["-m", "bench.material.native_agreement_cycles", str(folder / half / "job.json")], folder)
        cpu, gpu = folder / "cpu", folder / "gpu"
        times = json.loads((cpu / "times.json").read_text())
        for name, seconds in read_json(gpu / "times.json").items():
            times.setdefault(name, {}).update(seconds)
        rows, sheet = [], []
        for case in all_cases:
            refs = {ref: image(cpu, case.name, ref) for ref in REFERENCES}
            row = {"name": case.name, "node": case.node, "seconds": times.get(case.name, {}), "flip": {}}
            images = [("CPU OSL", refs["osl"])]
            for label in rendered(gpu, case.name):
                render = image(gpu, case.name, label)
                row["flip"][label] = {ref: flip_map(refs[ref], render)[1] for ref in REFERENCES}
                if label == "eevee":
                    grey = image(gpu, CONTROL, label)
                    row["eevee_compiled"] = flip_map(grey, render)[1] > row["flip"][label]["osl"]
                images.append((f"{label} {row['flip'][label]['osl']:.3f}", render))
            rows.append(row)
            sheet.append((case.name, images))
        devices = read_json(gpu / "devices.json")
    configs = {label: summarise([r for r in rows if label in r["flip"]], label)
               for label in dict.fromkeys(label for r in rows for label in r["flip"])}
    report = {"machine": args.machine, "note": args.note, "devices": devices, "seed": args.seed, "per_type": args.per_type,
              "resolution": args.resolution, "samples": args.samples, "flip_convention": FLIP_CONVENTION,
              "configs": configs, "eevee_compiled": [r["name"] for r in rows if r.get("eevee_compiled")],
              "cases_planned": len(all_cases), "wall_seconds": time.perf_counter() - start, "cases": rows}
    write_report(args.out, report)
    chart(report, args.out.with_suffix(".png"))
    labelled_sheet(sheet, args.out.with_name(args.out.stem + "_sheet.png"))
    for label, summary in configs.items():
        print(f"{label:14s} {summary['cases']} cases: mean FLIP vs CPU OSL {summary['mean_flip_vs_cpu_osl']:.4f}, "
              f"worst {summary['worst_flip_vs_cpu_osl']:.4f}; {summary['frame_wall_s']} s per frame")
    print(f"wrote {args.out}")
    sys.exit(0 if all(s["worst_flip_vs_cpu_osl"] <= TARGET_WORST for s in configs.values()) else 1)


if __name__ == "__main__":
    main()
