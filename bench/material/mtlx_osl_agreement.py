"""The MaterialX export rendered by an outside generator against the add-on's own OSL, both in Cycles.

For the plain grey control (core.enhance.baseline of a grey PBR material) and
drawn materials of Types 0-5 (support/agreement_cases.py), the add-on writes its
MaterialX document (core/mtlx.py), MaterialX's own OSL generator from the
``materialx`` wheel turns the file into OSL (support/mtlx_osl.py), and Cycles renders
that shader on the preview ball. The reference is the add-on's OSL shader
(core/osl.py) in the same scene. All renders run in Cycles on the CPU, one
thread, through bench/material/agreement_cycles.py.

The MaterialX shader renders twice: as generated, and with its ``*_distribution``
inputs set to Cycles' energy-compensated GGX (``"multi_ggx"``; genosl passes
MaterialX's ``"ggx"``, which Cycles renders single-scatter, see
support/mtlx_osl.with_distribution).

The reference renders at ``--seed``; the MaterialX shaders render at the next
seed, and so does the add-on's shader a second time: that pair's FLIP is the
noise floor, the difference two seeds of one shader make, so a FLIP near it means
the two shaders agree to within the noise. The MaterialX renders are also compared
with that second add-on render, same seed: there the noise cancels where the two
shaders sample the same closures.

    python -m bench.material.mtlx_osl_agreement [--per-type N] [--seed N] [--renders DIR] [--out FILE.json]

Target (issue 38): mean FLIP <= 0.03 over the cases.
"""
from __future__ import annotations

import argparse
import json
import statistics
import sys
import tempfile
import time
from pathlib import Path

import MaterialX as mx
import numpy as np

from bench.material.agreement import DEFAULT_PROBE, render_cycles, reused_cycles
from bench.common import FLIP_CONVENTION, add_out_argument, pyplot, save_chart, write_report
from bench.material.native_agreement import labelled_sheet
from support.agreement_cases import Case, cases
from support.mtlx_osl import cycles_source, with_distribution
from richmat_addon.core import mtlx
from richmat_addon.core.enhance import baseline
from richmat_addon.core.folder_io import read_exr
from richmat_addon.core.maps import ParamMap, PbrInputs
from torch_models.render.flip import flip_map
from torch_models.render.tonemap import agx

TARGET_MEAN = 0.03
CONTROL = "plain_grey"
# Reference at the seed; at the next seed: the add-on's shader again, genosl's as generated, genosl's with multi_ggx.
RENDERS = ("addon", "floor", "mtlx", "mtlx_multi_ggx")
COMPENSATED = "multi_ggx"


def control_case() -> Case:
    """The un-enhanced grey material (mid grey, roughness 0.5, dielectric) as the add-on models it."""
    grey = PbrInputs(CONTROL, ParamMap.constant(0.5, 0.5, 0.5), ParamMap.constant(0.5), ParamMap.constant(0.0))
    mat = baseline(grey)
    return Case(CONTROL, "surface", {k: [float(x) for x in m.mean()] for k, m in mat.params.items()},
                [float(x) for x in mat.base_color.mean()])


def group_of(case: Case) -> str:
    return case.name.split("_")[0] if case.name != CONTROL else "control"


def export_and_generate(case: Case, folder: Path) -> tuple[Path, Path]:
    """Write the case's MaterialX file as the add-on exports it, read it back, and write genosl's shader
    as generated and with the energy-compensated distribution."""
    document = mtlx.write_materialx(case.material(), {}, folder / f"{case.name}.mtlx")
    problems = mtlx.validate_document(mtlx.to_materialx(case.material(), {}))
    if problems:
        raise SystemExit(f"{case.name}: the exported document is not valid MaterialX: {problems}")
    doc = mx.createDocument()
    mx.readFromXmlFile(doc, str(document))
    source = cycles_source(doc)
    shader, compensated = folder / f"{case.name}.osl", folder / f"{case.name}_{COMPENSATED}.osl"
    shader.write_text(source)
    compensated.write_text(with_distribution(source, COMPENSATED))
    return shader, compensated


def summary(rows: list[dict]) -> dict:
    groups: dict[str, list[dict]] = {}
    for row in rows:
        groups.setdefault(row["group"], []).append(row)
    groups["all"] = rows
    def mean(key: str, members: list[dict]) -> float:
        return float(np.mean([r[key] for r in members]))

    return {name: {"cases": len(members), "mean_flip": mean("flip", members),
                   "worst_flip": max(r["flip"] for r in members),
                   "mean_flip_multi_ggx": mean("flip_multi_ggx", members),
                   "worst_flip_multi_ggx": max(r["flip_multi_ggx"] for r in members),
                   "mean_noise_floor": mean("noise_floor", members),
                   "worst_flip_same_seed": max(r["flip_same_seed"] for r in members),
                   "worst_flip_multi_ggx_same_seed": max(r["flip_multi_ggx_same_seed"] for r in members),
                   **{f"{which}_render_cpu_s": statistics.median(r["seconds"][which]["cpu"] for r in members)
                      for which in ("addon", "mtlx", "mtlx_multi_ggx")}}
            for name, members in groups.items()}


def chart(report: dict, path: Path) -> None:
    """FLIP of the MaterialX render and the noise floor per case; render seconds per case."""
    plt = pyplot()
    rows = report["cases"]
    x = np.arange(len(rows))
    fig, (a, b) = plt.subplots(1, 2, figsize=(13, 4.8))
    a.bar(x - 0.27, [r["flip"] for r in rows], 0.27, color="tab:blue", label="genosl as generated (\"ggx\")")
    a.bar(x, [r["flip_multi_ggx"] for r in rows], 0.27, color="tab:green",
          label=f"genosl, distribution inputs \"{COMPENSATED}\"")
    a.bar(x + 0.27, [r["noise_floor"] for r in rows], 0.27, color="tab:gray", label="noise floor (add-on, two seeds)")
    a.axhline(TARGET_MEAN, color="black", ls="--", lw=0.8, label=f"target mean {TARGET_MEAN}")
    a.set_xticks(x, [r["name"] for r in rows], rotation=60, ha="right", fontsize=8)
    a.set_ylabel(f"mean FLIP ({FLIP_CONVENTION})", fontsize=8)
    overall = report["summary"]["all"]
    a.set_title(f"FLIP against the add-on's OSL, mean {overall['mean_flip']:.4f} as generated, "
                f"{overall['mean_flip_multi_ggx']:.4f} with {COMPENSATED} (floor {overall['mean_noise_floor']:.4f})",
                fontsize=9)
    a.legend(fontsize=8)
    for k, (which, colour, label) in enumerate((("addon", "tab:red", "add-on OSL"),
                                                ("mtlx", "tab:blue", "genosl as generated"),
                                                ("mtlx_multi_ggx", "tab:green", f"genosl, {COMPENSATED}"))):
        b.bar(x + (k - 1) * 0.27, [r["seconds"][which]["cpu"] for r in rows], 0.27, color=colour, label=label)
    b.set_xticks(x, [r["name"] for r in rows], rotation=60, ha="right", fontsize=8)
    b.set_ylabel("render CPU seconds (one thread)")
    b.set_title(f"{report['resolution']} px, {report['samples']} samples, Cycles CPU OSL")
    b.legend(fontsize=8)
    save_chart(fig, path)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--per-type", type=int, default=2,
                        help="drawn materials per type; the second is a metal where the type allows (default: 2)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the drawn materials and the reference (default: 0)")
    parser.add_argument("--resolution", type=int, default=128, help="preview ball size in pixels (default: 128)")
    parser.add_argument("--samples", type=int, default=256, help="Cycles samples (default: 256)")
    parser.add_argument("--probe", type=Path, default=DEFAULT_PROBE, help="equirectangular HDR probe")
    parser.add_argument("--renders", type=Path, default=None, metavar="DIR",
                        help="keep the documents, shaders and renders in DIR; a render set DIR already holds "
                             "for the same cases and settings is reused (default: a temporary folder)")
    add_out_argument(parser, "mtlx_osl_agreement.json")
    args = parser.parse_args()

    all_cases = [control_case(), *cases(args.seed, args.per_type, 0)]
    start = time.perf_counter()
    rows, images = [], []
    with tempfile.TemporaryDirectory(prefix="richmat_mtlx_osl_") as fresh:
        folder = args.renders or Path(fresh)
        for which in RENDERS:
            (folder / which).mkdir(parents=True, exist_ok=True)
        shaders = {c.name: export_and_generate(c, folder / "documents") for c in all_cases}
        seconds = {}
        for which, seed, osl in (("addon", args.seed, None), ("floor", args.seed + 1, None),
                                 ("mtlx", args.seed + 1, {n: str(s[0]) for n, s in shaders.items()}),
                                 ("mtlx_multi_ggx", args.seed + 1, {n: str(s[1]) for n, s in shaders.items()})):
            (folder / which).mkdir(parents=True, exist_ok=True)
            reused = reused_cycles(folder / which, all_cases, args.probe, args.resolution, args.samples, seed)
            print(f"Cycles ({which}, seed {seed}): {len(all_cases)} cases at {args.resolution} px, "
                  f"{args.samples} spp{', reused' if reused else ' ...'}", flush=True)
            wall = reused or render_cycles(all_cases, args.probe, args.resolution, args.samples, seed,
                                           folder / which, osl, threads=1)
            cpu = json.loads((folder / which / "cycles_cpu_times.json").read_text())
            seconds[which] = {name: {"wall": wall[name], "cpu": cpu[name]} for name in wall}
        for case in all_cases:
            ref, floor, ours, compensated = (agx(read_exr(folder / which / f"{case.name}.exr")[..., :3])
                                             for which in RENDERS)
            error, flip = flip_map(ref, ours)
            compensated_error, compensated_flip = flip_map(ref, compensated)
            floor_error, floor_flip = flip_map(ref, floor)
            rows.append({"name": case.name, "group": group_of(case), "flip": flip,
                         "flip_multi_ggx": compensated_flip, "noise_floor": floor_flip,
                         "flip_same_seed": flip_map(floor, ours)[1],
                         "flip_multi_ggx_same_seed": flip_map(floor, compensated)[1],
                         "seconds": {which: seconds[which][case.name] for which in RENDERS},
                         "params": case.params, "base_color": case.base_color})
            images.append((f"{case.name}\nFLIP {flip:.4f}\n{COMPENSATED} {compensated_flip:.4f}\nfloor {floor_flip:.4f}",
                           [("add-on OSL", ref), ("genosl as generated", ours), ("FLIP", error),
                            (f"genosl, {COMPENSATED}", compensated), ("FLIP", compensated_error),
                            ("add-on OSL, next seed", floor), ("FLIP (noise floor)", floor_error)]))
            print(f"{case.name:18s} FLIP {flip:.4f}, with {COMPENSATED} {compensated_flip:.4f}, "
                  f"noise floor {floor_flip:.4f}", flush=True)
    overall = summary(rows)
    report = {"seed": args.seed, "per_type": args.per_type, "probe": args.probe.name,
              "resolution": args.resolution, "samples": args.samples, "threads": 1,
              "materialx_version": mx.getVersionString(), "generator": "MaterialX OslShaderGenerator (genosl)",
              "flip_convention": FLIP_CONVENTION, "target_mean": TARGET_MEAN,
              "passed": {"as_generated": overall["all"]["mean_flip"] <= TARGET_MEAN,
                         COMPENSATED: overall["all"]["mean_flip_multi_ggx"] <= TARGET_MEAN},
              "wall_seconds": time.perf_counter() - start, "summary": overall, "cases": rows}
    write_report(args.out, report)
    chart(report, args.out.with_suffix(".png"))
    labelled_sheet(images, args.out.with_name(args.out.stem + "_sheet.png"))
    print(f"mean FLIP (target {TARGET_MEAN}): as generated {overall['all']['mean_flip']:.4f}, with {COMPENSATED} "
          f"{overall['all']['mean_flip_multi_ggx']:.4f}, noise floor {overall['all']['mean_noise_floor']:.4f}; "
          f"{report['wall_seconds'] / 60:.1f} min; wrote {args.out}")
    sys.exit(0 if report["passed"][COMPENSATED] else 1)


if __name__ == "__main__":
    main()
