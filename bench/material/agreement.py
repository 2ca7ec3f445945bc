"""Cycles (OSL) against the torch renderer: mean FLIP per case on the preview ball.

For each of Types 0-5 and for each lobe alone, constant materials are drawn
from the seed (support/agreement_cases.py), rendered once by Cycles in a child
process with the pip bpy module (bench/material/agreement_cycles.py) and once by
torch_models.render, same ball, same probe, both tone mapped with Blender's AgX,
and compared with LDR-FLIP (sRGB, 67 ppd; see torch_models/render/flip.py).

    python -m bench.material.agreement [--quick] [--seed N] [--out FILE.json]

Target: every case <= 0.03 in the full run, <= 0.05 with --quick (< 10 min on 2 cores).
"""
from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from dataclasses import asdict
from pathlib import Path

import numpy as np
import torch

from support.agreement_cases import Case, cases
from bench.common import FLIP_CONVENTION, REPO, REPORTS, contact_sheet, pyplot, run_python, save_chart, write_report
from richmat_addon.core.folder_io import read_exr
from torch_models.brdf.model import LayeredBsdf
from torch_models.render.ball import render_ball
from torch_models.render.envmap import EnvMap, read_probe
from torch_models.render.flip import flip_map
from torch_models.render.preview_scene import PreviewScene
from torch_models.render.tonemap import agx

DEFAULT_PROBE = REPO / "torch_models" / "data" / "studio_small_03_512.hdr"
# (cases per type, cases per lobe, resolution, Cycles samples, torch spp, FLIP target)
SETTINGS = {"quick": (1, 1, 96, 256, 256, 0.05), "full": (2, 1, 128, 1024, 256, 0.03)}


def render_cycles(all_cases: list[Case], probe: Path, resolution: int, samples: int, seed: int,
                  folder: Path, osl: dict[str, str] | None = None, threads: int = 0) -> dict[str, float]:
    """Render the cases into ``folder`` (bench/material/agreement_cycles.py); the render seconds per case.

    ``osl`` (case name -> OSL file) renders those cases with an outside shader; ``threads`` 0 uses all cores.
    """
    job = folder / "job.json"
    job.write_text(json.dumps({"cases": [asdict(c) for c in all_cases], "probe": str(probe),
                               "resolution": resolution, "samples": samples, "seed": seed,
                               "out": str(folder), "osl": osl or {}, "threads": threads}))
    run_python(["-m", "bench.material.agreement_cycles", str(job)], folder)
    return json.loads((folder / "cycles_times.json").read_text())


def reused_cycles(folder: Path, all_cases: list[Case], probe: Path, resolution: int, samples: int,
                  seed: int) -> dict[str, float] | None:
    """Cycles render times of an earlier run in ``folder`` if it finished rendering these very cases."""
    try:
        job = json.loads((folder / "job.json").read_text())
        times = json.loads((folder / "cycles_times.json").read_text())
    except (OSError, ValueError):
        return None
    same = (job["cases"] == [asdict(c) for c in all_cases] and job["resolution"] == resolution
            and job["samples"] == samples and job["seed"] == seed and Path(job["probe"]) == probe)
    return times if same else None


def torch_bsdf(case: Case) -> LayeredBsdf:
    params = {k: torch.tensor([v], dtype=torch.float32) for k, v in case.params.items()}
    return LayeredBsdf(params, torch.tensor([case.base_color]), node=case.graph_node())


def chart(report: dict, path: Path) -> None:
    plt = pyplot()
    rows = report["cases"]
    names = [r["name"] for r in rows]
    x = np.arange(len(rows))
    fig, (a, b) = plt.subplots(2, 1, figsize=(max(8, 0.42 * len(rows)), 7), sharex=True)
    a.bar(x, [r["flip"] for r in rows], color=["tab:blue" if r["node"] == "surface" else "tab:orange"
                                              for r in rows])
    a.axhline(report["target"], color="red", ls="--", label=f"target {report['target']}")
    a.set_ylabel("mean FLIP (AgX, sRGB, 67 ppd)")
    a.set_title(f"Cycles OSL vs torch renderer, seed {report['seed']} "
                f"({'quick' if report['quick'] else 'full'}; blue: whole material, orange: lobe alone)")
    a.legend()
    b.bar(x - 0.2, [r["cycles_seconds"] for r in rows], 0.4, label=f"Cycles, {report['cycles_samples']} spp")
    b.bar(x + 0.2, [r["torch_seconds"] for r in rows], 0.4, label=f"torch, {report['torch_spp']} spp")
    b.set_ylabel("render time (s)")
    b.legend()
    b.set_xticks(x, names, rotation=70, ha="right", fontsize=8)
    save_chart(fig, path)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer cases and samples (< 10 min)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the drawn materials (default: 0)")
    parser.add_argument("--out", type=Path, default=None,
                        help="report JSON (default: docs/reports/agreement[_quick].json); chart and sheet beside it")
    parser.add_argument("--probe", type=Path, default=DEFAULT_PROBE, help="equirectangular HDR probe")
    parser.add_argument("--cycles-dir", type=Path, default=None, metavar="DIR",
                        help="keep the Cycles renders in DIR; if DIR already holds a finished run of the same "
                             "cases and settings, score against it instead of rendering again "
                             "(default: a temporary folder)")
    args = parser.parse_args()

    mode = "quick" if args.quick else "full"
    per_type, per_lobe, resolution, samples, spp, target = SETTINGS[mode]
    out = args.out or REPORTS / f"agreement{'_quick' if args.quick else ''}.json"
    all_cases = cases(args.seed, per_type, per_lobe)
    env = EnvMap(read_probe(args.probe))
    scene = PreviewScene(resolution=resolution)
    start = time.perf_counter()
    rows, images = [], []
    with tempfile.TemporaryDirectory(prefix="richmat_agreement_") as fresh:
        tmp = args.cycles_dir or Path(fresh)
        tmp.mkdir(parents=True, exist_ok=True)
        cycles_times = reused_cycles(tmp, all_cases, args.probe, resolution, samples, args.seed)
        if cycles_times is None:
            print(f"Cycles: {len(all_cases)} cases at {resolution}px, {samples} spp ...", flush=True)
            cycles_times = render_cycles(all_cases, args.probe, resolution, samples, args.seed, tmp)
        else:
            print(f"Cycles: reusing the finished renders in {tmp}", flush=True)
        for case in all_cases:
            bsdf = torch_bsdf(case)
            result = render_ball(lambda n, b=bsdf: b, env, scene, spp, args.seed)
            cy, to = agx(read_exr(Path(tmp) / f"{case.name}.exr")[..., :3]), agx(result.rgb)
            error, flip = flip_map(cy, to)
            rows.append({"name": case.name, "node": case.node, "flip": flip,
                         "cycles_seconds": cycles_times[case.name], "torch_seconds": result.seconds,
                         "params": case.params, "base_color": case.base_color})
            images.append((case.name, cy, to, error))
            print(f"{case.name:28s} FLIP {flip:.4f}  (Cycles {cycles_times[case.name]:.1f} s, "
                  f"torch {result.seconds:.1f} s)", flush=True)
    worst = max(r["flip"] for r in rows)
    report = {"quick": args.quick, "seed": args.seed, "probe": args.probe.name, "resolution": resolution,
              "cycles_samples": samples, "torch_spp": spp, "target": target,
              "flip_convention": FLIP_CONVENTION,
              "worst_flip": worst, "passed": worst <= target,
              "wall_seconds": time.perf_counter() - start, "cases": rows}
    write_report(out, report)
    chart(report, out.with_suffix(".png"))
    contact_sheet(images, out.with_name(out.stem + "_sheet.png"))
    print(f"worst FLIP {worst:.4f} (target {target}): {'PASS' if report['passed'] else 'FAIL'}; "
          f"{report['wall_seconds'] / 60:.1f} min; wrote {out}")
    sys.exit(0 if report["passed"] else 1)


if __name__ == "__main__":
    main()
