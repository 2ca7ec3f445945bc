"""On a GPU machine: each type in EEVEE and in Cycles on the GPU, against the Cycles CPU renders.

The cases of bench/agreement_cases.py render on the preview ball in every
configuration the machine has (bench/native_agreement_cycles.py skips a missing
device): Cycles on the CPU reading the OSL graph (the reference) and the native
graph, Cycles with OptiX reading either, Cycles with CUDA, HIP, Metal or oneAPI
reading the native graph (they have no OSL), and EEVEE (native graph). Each is
compared by LDR-FLIP with the CPU OSL render and with the CPU native render.

EEVEE shows a default grey while a shader compiles or when it fails, so the run
also renders a plain Principled ball, and a case counts as compiled only when
EEVEE's render is closer to the Cycles reference than to that grey.

    python -m bench.native_gpu [--per-type N] [--out FILE.json]

Not run on the 2-core CPU machine the other benches use; see docs/backends.md.
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

from bench.agreement_cases import cases
from bench.common import FLIP_CONVENTION, add_out_argument, pyplot, run_python, save_chart, write_report
from bench.native_agreement import DEFAULT_PROBE, TARGET_MEAN, TARGET_WORST, labelled_sheet
from bench.native_agreement_cycles import CONTROL, CPU_CONFIGS, FRAMES
from richmat_addon.core.folder_io import read_exr
from torch_models.render.flip import flip_map
from torch_models.render.tonemap import agx

GPU_CONFIGS = [
    {"label": "optix_osl", "engine": "CYCLES", "device": "OPTIX", "graph": "osl"},
    *({"label": f"{device.lower()}_native", "engine": "CYCLES", "device": device, "graph": "native"}
      for device in ("OPTIX", "CUDA", "HIP", "METAL", "ONEAPI")),
    {"label": "eevee", "engine": "BLENDER_EEVEE", "device": "GPU", "graph": "native"},
]
REFERENCES = ("osl", "native")  # the CPU configurations every other one is compared with


def image(folder: Path, name: str, label: str) -> np.ndarray:
    return agx(read_exr(folder / f"{name}_{label}_{FRAMES:04d}.exr")[..., :3])


def chart(report: dict, path: Path) -> None:
    plt = pyplot()
    labels = list(report["configs"])
    fig, ax = plt.subplots(figsize=(max(7, 1.1 * len(labels)), 4.5))
    x = np.arange(len(labels))
    for k, ref in enumerate(REFERENCES):
        ax.bar(x + (k - 0.5) * 0.4, [report["configs"][c][f"mean_flip_vs_cpu_{ref}"] for c in labels], 0.4,
               label=f"mean FLIP vs CPU {ref}")
    ax.axhline(TARGET_MEAN, color="gray", ls="--", lw=0.8, label=f"target mean {TARGET_MEAN}")
    ax.set_xticks(x, labels, rotation=30, ha="right")
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
    add_out_argument(parser, "native_gpu.json")
    args = parser.parse_args()

    all_cases = cases(args.seed, args.per_type, 1)
    start = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="richmat_native_gpu_") as tmp:
        folder = Path(tmp)
        job = folder / "job.json"
        job.write_text(json.dumps({"cases": [asdict(c) for c in all_cases], "probe": str(DEFAULT_PROBE),
                                   "resolution": args.resolution, "samples": args.samples, "seed": args.seed,
                                   "out": str(folder), "configs": CPU_CONFIGS + GPU_CONFIGS, "control": True}))
        run_python(["-m", "bench.native_agreement_cycles", str(job)], folder)
        times = json.loads((folder / "times.json").read_text())
        present = [c["label"] for c in CPU_CONFIGS + GPU_CONFIGS if c["label"] in times[all_cases[0].name]]
        rows, sheet = [], []
        for case in all_cases:
            refs = {ref: image(folder, case.name, ref) for ref in REFERENCES}
            row = {"name": case.name, "node": case.node, "seconds": times[case.name], "flip": {}}
            images = [("CPU OSL", refs["osl"])]
            for label in present[len(REFERENCES):]:
                render = image(folder, case.name, label)
                row["flip"][label] = {ref: flip_map(refs[ref], render)[1] for ref in REFERENCES}
                if label == "eevee":
                    grey = image(folder, CONTROL, label)
                    row["eevee_compiled"] = flip_map(grey, render)[1] > row["flip"][label]["osl"]
                images.append((f"{label} {row['flip'][label]['osl']:.3f}", render))
            rows.append(row)
            sheet.append((case.name, images))
    configs = {}
    for label in present[len(REFERENCES):]:
        summary = {f"mean_flip_vs_cpu_{ref}": float(np.mean([r["flip"][label][ref] for r in rows]))
                   for ref in REFERENCES}
        summary.update({f"worst_flip_vs_cpu_{ref}": max(r["flip"][label][ref] for r in rows) for ref in REFERENCES})
        summary["frame_wall_s"] = statistics.median(r["seconds"][label]["frame"][0] for r in rows)
        summary["first_wall_s"] = statistics.median(r["seconds"][label]["first"][0] for r in rows)
        configs[label] = summary
    report = {"seed": args.seed, "per_type": args.per_type, "resolution": args.resolution, "samples": args.samples,
              "flip_convention": FLIP_CONVENTION, "configs_present": present, "configs": configs,
              "eevee_compiled": [r["name"] for r in rows if r.get("eevee_compiled")],
              "wall_seconds": time.perf_counter() - start, "cases": rows}
    write_report(args.out, report)
    chart(report, args.out.with_suffix(".png"))
    labelled_sheet(sheet, args.out.with_name(args.out.stem + "_sheet.png"))
    for label, summary in configs.items():
        print(f"{label:14s} mean FLIP vs CPU OSL {summary['mean_flip_vs_cpu_osl']:.4f}, worst "
              f"{summary['worst_flip_vs_cpu_osl']:.4f}; {summary['frame_wall_s']:.2f} s per frame")
    print(f"wrote {args.out}")
    sys.exit(0 if all(s["worst_flip_vs_cpu_osl"] <= TARGET_WORST for s in configs.values()) else 1)


if __name__ == "__main__":
    main()
