"""The MaterialX export rendered by an outside generator against the add-on's own OSL, both in Cycles.

For the plain grey control (core.enhance.baseline of a grey PBR material) and
drawn materials of Types 0-5 (bench/agreement_cases.py), the add-on writes its
MaterialX document (core/mtlx.py), MaterialX's own OSL generator from the
``materialx`` wheel turns the file into OSL (bench/mtlx_osl.py), and Cycles renders
that shader on the preview ball. The reference is the add-on's OSL shader
(core/osl.py) in the same scene. All renders run in Cycles on the CPU, one
thread, through bench/agreement_cycles.py.

The reference renders at ``--seed``; the MaterialX shader renders at the next seed,
and so does the add-on's shader a second time: that pair's FLIP is the noise
floor, the difference two seeds of one shader make, so a FLIP near it means the
two shaders agree to within the noise.

    python -m bench.mtlx_osl_agreement [--per-type N] [--seed N] [--out FILE.json]

Target (issue 38): mean FLIP <= 0.03 over the cases.
"""
from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from pathlib import Path

import MaterialX as mx
import numpy as np

from bench.agreement import DEFAULT_PROBE, render_cycles
from bench.agreement_cases import Case, cases
from bench.common import FLIP_CONVENTION, add_out_argument, pyplot, save_chart, write_report
from bench.mtlx_osl import cycles_source
from bench.native_agreement import labelled_sheet
from richmat_addon.core import mtlx
from richmat_addon.core.enhance import baseline
from richmat_addon.core.folder_io import read_exr
from richmat_addon.core.maps import ParamMap, PbrInputs
from torch_models.render.flip import flip_map
from torch_models.render.tonemap import agx

TARGET_MEAN = 0.03
CONTROL = "plain_grey"
RENDERS = ("addon", "floor", "mtlx")  # reference seed, next seed, next seed with the MaterialX shader


def control_case() -> Case:
    """The un-enhanced grey material (mid grey, roughness 0.5, dielectric) as the add-on models it."""
    grey = PbrInputs(CONTROL, ParamMap.constant(0.5, 0.5, 0.5), ParamMap.constant(0.5), ParamMap.constant(0.0))
    mat = baseline(grey)
    return Case(CONTROL, "surface", {k: [float(x) for x in m.mean()] for k, m in mat.params.items()},
                [float(x) for x in mat.base_color.mean()])


def group_of(case: Case) -> str:
    return case.name.split("_")[0] if case.name != CONTROL else "control"


def export_and_generate(case: Case, folder: Path) -> Path:
    """Write the case's MaterialX file as the add-on exports it, read it back, and write genosl's shader."""
    document = mtlx.write_materialx(case.material(), {}, folder / f"{case.name}.mtlx")
    problems = mtlx.validate_document(mtlx.to_materialx(case.material(), {}))
    if problems:
        raise SystemExit(f"{case.name}: the exported document is not valid MaterialX: {problems}")
    doc = mx.createDocument()
    mx.readFromXmlFile(doc, str(document))
    shader = folder / f"{case.name}.osl"
    shader.write_text(cycles_source(doc))
    return shader


def summary(rows: list[dict]) -> dict:
    groups: dict[str, list[dict]] = {}
    for row in rows:
        groups.setdefault(row["group"], []).append(row)
    groups["all"] = rows
    return {name: {"cases": len(members), "mean_flip": float(np.mean([r["flip"] for r in members])),
                   "worst_flip": max(r["flip"] for r in members),
                   "mean_noise_floor": float(np.mean([r["noise_floor"] for r in members])),
                   "addon_render_s": statistics.median(r["seconds"]["addon"] for r in members),
                   "mtlx_render_s": statistics.median(r["seconds"]["mtlx"] for r in members)}
            for name, members in groups.items()}


def chart(report: dict, path: Path) -> None:
    """FLIP of the MaterialX render and the noise floor per case; render seconds per case."""
    plt = pyplot()
    rows = report["cases"]
    x = np.arange(len(rows))
    fig, (a, b) = plt.subplots(1, 2, figsize=(13, 4.8))
    a.bar(x - 0.2, [r["flip"] for r in rows], 0.4, color="tab:blue", label="MaterialX genosl vs add-on OSL")
    a.bar(x + 0.2, [r["noise_floor"] for r in rows], 0.4, color="tab:gray", label="noise floor (add-on, two seeds)")
    a.axhline(TARGET_MEAN, color="black", ls="--", lw=0.8, label=f"target mean {TARGET_MEAN}")
    a.set_xticks(x, [r["name"] for r in rows], rotation=60, ha="right", fontsize=8)
    a.set_ylabel(f"mean FLIP ({FLIP_CONVENTION})", fontsize=8)
    overall = report["summary"]["all"]
    a.set_title(f"mean FLIP {overall['mean_flip']:.4f} (noise floor {overall['mean_noise_floor']:.4f})")
    a.legend(fontsize=8)
    for k, (which, colour) in enumerate((("addon", "tab:red"), ("mtlx", "tab:blue"))):
        b.bar(x + (k - 0.5) * 0.4, [r["seconds"][which] for r in rows], 0.4, color=colour,
              label="add-on OSL" if which == "addon" else "MaterialX genosl")
    b.set_xticks(x, [r["name"] for r in rows], rotation=60, ha="right", fontsize=8)
    b.set_ylabel("render seconds (one thread)")
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
                        help="keep the documents, shaders and renders in DIR (default: a temporary folder)")
    add_out_argument(parser, "mtlx_osl_agreement.json")
    args = parser.parse_args()

    all_cases = [control_case(), *cases(args.seed, args.per_type, 0)]
    start = time.perf_counter()
    rows, images = [], []
    with tempfile.TemporaryDirectory(prefix="richmat_mtlx_osl_") as fresh:
        folder = args.renders or Path(fresh)
        for which in RENDERS:
            (folder / which).mkdir(parents=True, exist_ok=True)
        shaders = {c.name: str(export_and_generate(c, folder / "mtlx")) for c in all_cases}
        seconds = {}
        for which, seed, osl in (("addon", args.seed, None), ("floor", args.seed + 1, None),
                                 ("mtlx", args.seed + 1, shaders)):
            print(f"Cycles ({which}, seed {seed}): {len(all_cases)} cases at {args.resolution} px, "
                  f"{args.samples} spp ...", flush=True)
            seconds[which] = render_cycles(all_cases, args.probe, args.resolution, args.samples, seed,
                                           folder / which, osl, threads=1)
        for case in all_cases:
            ref, floor, ours = (agx(read_exr(folder / which / f"{case.name}.exr")[..., :3]) for which in RENDERS)
            error, flip = flip_map(ref, ours)
            floor_error, floor_flip = flip_map(ref, floor)
            rows.append({"name": case.name, "group": group_of(case), "flip": flip, "noise_floor": floor_flip,
                         "seconds": {which: seconds[which][case.name] for which in RENDERS},
                         "params": case.params, "base_color": case.base_color})
            images.append((f"{case.name}\nFLIP {flip:.4f}\nfloor {floor_flip:.4f}",
                           [("add-on OSL", ref), ("MaterialX genosl", ours), ("FLIP", error),
                            ("add-on OSL, next seed", floor), ("FLIP (noise floor)", floor_error)]))
            print(f"{case.name:18s} FLIP {flip:.4f}  noise floor {floor_flip:.4f}", flush=True)
    overall = summary(rows)
    report = {"seed": args.seed, "per_type": args.per_type, "probe": args.probe.name,
              "resolution": args.resolution, "samples": args.samples, "threads": 1,
              "materialx_version": mx.getVersionString(), "generator": "MaterialX OslShaderGenerator (genosl)",
              "flip_convention": FLIP_CONVENTION, "target_mean": TARGET_MEAN,
              "passed": overall["all"]["mean_flip"] <= TARGET_MEAN,
              "wall_seconds": time.perf_counter() - start, "summary": overall, "cases": rows}
    write_report(args.out, report)
    chart(report, args.out.with_suffix(".png"))
    labelled_sheet(images, args.out.with_name(args.out.stem + "_sheet.png"))
    print(f"mean FLIP {overall['all']['mean_flip']:.4f} (target {TARGET_MEAN}), noise floor "
          f"{overall['all']['mean_noise_floor']:.4f}: {'PASS' if report['passed'] else 'FAIL'}; "
          f"{report['wall_seconds'] / 60:.1f} min; wrote {args.out}")
    sys.exit(0 if report["passed"] else 1)


if __name__ == "__main__":
    main()
