"""The native graph in EEVEE against Cycles, on the CPU: FLIP per type, per lobe alone and on a real asset.

The cases of support/agreement_cases.py (Types 0-5 and each lobe alone) and a few
drawn from one uplifted sample asset (support/real_cases.py) render on the
preview ball in one Blender child process (bench/material/native_agreement_cycles.py):
EEVEE reading the native graph, which needs no GPU here (Mesa's llvmpipe through
EGL; docs/backends.md section 3.6), and Cycles on the CPU reading the same graph.
The same graph in both isolates what the engines do differently; Cycles' native
render agrees with the exact OSL graph to FLIP 0.0025 (bench/material/native_agreement.py).
Both are tone mapped with AgX and compared with LDR-FLIP.

Noise floors, per case: Cycles at the next seed against Cycles (a second child
process), and EEVEE's two frames against each other (EEVEE has no seed: its sample
pattern is fixed, so the two agree exactly unless it is not deterministic). A plain
Principled ball (Blender's default material) renders in both engines too: its FLIP is
what EEVEE's lighting costs a material that is no richmat graph at all. (A final render
waits for EEVEE's shaders to compile, so the grey fallback bench/material/native_gpu.py guards
against in an interactive session does not arise here.) Where EEVEE reads a form of
the native graph of its own (``Family.eevee``: the sheen), a third child renders EEVEE
reading Cycles' form too, side by side. The brightness ratio (EEVEE over Cycles, mean
displayed luminance over the ball) says which way a lobe misses.

The asset itself renders too: the farm's prepare stage uplifts it (bench/farm/render_speed.py's
``farm_prepare``), and EEVEE and Cycles (two seeds) draw its textured meshes with the farm's
materials (native graph) from the farm's first camera under the same probe; its FLIP is the
mean over the asset's pixels. Last, EEVEE's settings that govern the world's light and
reflections (``SETTINGS``) each render the Principled ball and the first Type 0 draw, against
the same Cycles renders: whether any of them brings EEVEE closer than the preview's settings.

    python -m bench.material.native_eevee [--per-type N] [--asset NAME] [--eevee-samples N] [--out FILE.json]

Target (issue 52): mean FLIP <= 0.05 and worst <= 0.10 per type, or the reason per lobe.
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

from bench.common import FLIP_CONVENTION, add_out_argument, pyplot, run_python, save_chart, write_report
from bench.material.native_agreement import DEFAULT_PROBE, group_of, labelled_sheet
from bench.material.native_agreement_cycles import CONTROL, CPU_CONFIGS, read_json
from bench.material.native_gpu import GPU_CONFIGS
from bench.farm.render_speed import farm_prepare
from richmat_addon.core.colour import LUMINANCE
from richmat_addon.core.folder_io import read_exr
from support.agreement_cases import Case, cases
from support.paths import SHARED_ASSETS
from support.real_cases import real_cases
from torch_models.render.flip import flip_map
from torch_models.render.tonemap import agx

TARGET_MEAN, TARGET_WORST = 0.05, 0.10
FRAMES = 2  # EEVEE's second frame checks that it is deterministic; the first one also pays for compiling
CYCLES = CPU_CONFIGS[1]  # Cycles on the CPU, native graph (SVM)
CYCLES_FORM = "eevee_cycles_form"  # EEVEE reading the native graph's form for Cycles, where EEVEE has its own
REFERENCE = "Principled BSDF"  # the control ball's group: Blender's default material in both engines
ASSET = "asset"  # the renders folder of the textured asset
SWEEP = "settings"  # the renders folder of the settings sweep
PREVIEW = "preview scene (sun_threshold 0, Blender's defaults otherwise)"  # the sweep's baseline
# EEVEE's settings tried against the preview scene's (support/blender_preview_scene.py), each alone:
# scene properties by dotted path. Screen-space rays reach the diffuse only up to trace_max_roughness.
SETTINGS = {
    "clamp_surface_indirect 0 (no clamp; default 10)": {"eevee.clamp_surface_indirect": 0.0},
    "sun_threshold 10 (Blender's default)": {"world.sun_threshold": 10.0},
    "use_raytracing (screen space)": {"eevee.use_raytracing": True},
    "use_raytracing, trace_max_roughness 1": {"eevee.use_raytracing": True,
                                              "eevee.ray_tracing_options.trace_max_roughness": 1.0},
    "world probe_resolution 4096 (default 1024)": {"world.probe_resolution": "4096"},
}


def frame(folder: Path, name: str, label: str, number: int = FRAMES) -> np.ndarray:
    """The linear RGBA render of case ``name`` by configuration ``label``."""
    return read_exr(folder / f"{name}_{label}_{number:04d}.exr")


def brightness_ratio(eevee: np.ndarray, cycles: np.ndarray) -> float:
    """EEVEE's mean displayed (AgX) luminance over Cycles' on the ball, where both are opaque: how much
    brighter it looks; a linear mean would weigh little more than the probe's brightest reflection."""
    ball = (eevee[..., 3] > 0.5) & (cycles[..., 3] > 0.5)
    return float((agx(eevee[..., :3])[ball] @ LUMINANCE).mean() / (agx(cycles[..., :3])[ball] @ LUMINANCE).mean())


def render(all_cases: list[Case], args: argparse.Namespace, folder: Path) -> None:
    """Into ``folder``: seed/, EEVEE and Cycles at ``args.seed``; floor/, Cycles at the next seed; cycles_form/,
    EEVEE reading the form of the native graph Cycles reads, for the cases where EEVEE has its own; settings/,
    EEVEE under each of ``SETTINGS``; asset/, the prepared asset and its renders, a folder per seed."""
    eevee = dict(GPU_CONFIGS[0], samples=args.eevee_samples)
    cycles_form = dict(eevee, label=CYCLES_FORM, eevee_form=False)
    for half, configs, seed, frames in (("seed", [eevee, CYCLES], args.seed, FRAMES),
                                        ("floor", [CYCLES], args.seed + 1, 1),
                                        (CYCLES_FORM, [cycles_form], args.seed, 1)):
        job(folder / half, all_cases, configs, seed, args.resolution, frames, half != CYCLES_FORM, args)
    swept = [dict(eevee, label=label_of(name), settings=settings) for name, settings in SETTINGS.items()]
    job(folder / SWEEP, [swept_case(all_cases)], swept, args.seed, args.resolution, 1, True, args)
    print(f"asset: the farm prepares {args.asset} ...", flush=True)
    prepared = folder / ASSET / "prepared"
    prepared.mkdir(parents=True, exist_ok=True)
    farm_prepare(SHARED_ASSETS / "models" / f"{args.asset}.glb", prepared, args.texture_size)
    for seed, configs in ((args.seed, [eevee, CYCLES]), (args.seed + 1, [CYCLES])):
        job(folder / ASSET / str(seed), [], configs, seed, args.asset_resolution, 1, False, args, asset=prepared)


def label_of(setting: str) -> str:
    """A file-name label for one of ``SETTINGS``."""
    return "eevee_" + "".join(ch if ch.isalnum() else "_" for ch in setting.split(" (")[0])


def swept_case(all_cases: list[Case]) -> Case:
    """The settings sweep's richmat case: the first whole material drawn of Type 0."""
    return next(c for c in all_cases if c.node == "surface" and c.name.startswith("type0"))


def job(out: Path, job_cases: list[Case], configs: list[dict], seed: int, resolution: int, frames: int,
        control: bool, args: argparse.Namespace, asset: Path | None = None) -> None:
    """One child rendering ``configs`` into ``out``: ``job_cases`` (and the Principled ball where
    ``control``) on the preview ball, or the prepared ``asset``."""
    out.mkdir(parents=True, exist_ok=True)
    spec = {"cases": [asdict(c) for c in job_cases], "probe": str(args.probe), "resolution": resolution,
            "samples": args.samples, "seed": seed, "out": str(out), "configs": configs, "frames": frames,
            "control": control, **({"asset": str(asset), "name": args.asset} if asset else {})}
    (out / "job.json").write_text(json.dumps(spec))
    print(f"{out.name}: {[c['label'] for c in configs]} at seed {seed}, {len(job_cases)} cases ...", flush=True)
    run_python(["-m", "bench.material.native_agreement_cycles", str(out / "job.json")], out)


def compare(name: str, folder: Path, times: dict) -> tuple[dict, list[tuple[str, np.ndarray]]]:
    """One case's row of the report and its row of the sheet."""
    eevee_rgba, cycles_rgba = frame(folder / "seed", name, "eevee"), frame(folder / "seed", name, "native")
    eevee, cycles = agx(eevee_rgba[..., :3]), agx(cycles_rgba[..., :3])
    other_seed = agx(frame(folder / "floor", name, "native", 1)[..., :3])
    error, flip = flip_map(cycles, eevee)
    floor_map, floor = flip_map(cycles, other_seed)
    repeat = flip_map(agx(frame(folder / "seed", name, "eevee", 1)[..., :3]), eevee)[1]
    row = {"name": name, "flip": flip, "cycles_floor": floor, "eevee_repeat": repeat,
           "brightness_ratio": brightness_ratio(eevee_rgba, cycles_rgba), "seconds": times.get(name, {})}
    images = [("EEVEE", eevee), ("Cycles", cycles), (f"FLIP {flip:.3f}", error),
              (f"Cycles seed+1: {floor:.3f}", floor_map)]
    if (folder / CYCLES_FORM / f"{name}_{CYCLES_FORM}_0001.exr").exists():
        other_form = frame(folder / CYCLES_FORM, name, CYCLES_FORM, 1)
        row["cycles_form"] = {"flip": flip_map(cycles, agx(other_form[..., :3]))[1],
                              "brightness_ratio": brightness_ratio(other_form, cycles_rgba)}
        images.append((f"EEVEE, Cycles' form: {row['cycles_form']['flip']:.3f}", agx(other_form[..., :3])))
    return row, images


def compare_asset(folder: Path, args: argparse.Namespace) -> tuple[dict, list[tuple[str, np.ndarray]]]:
    """The textured asset's summary row (its mean FLIP over the pixels both engines cover) and sheet row."""
    seed, other = folder / ASSET / str(args.seed), folder / ASSET / str(args.seed + 1)
    eevee_rgba, cycles_rgba = frame(seed, args.asset, "eevee", 1), frame(seed, args.asset, "native", 1)
    eevee, cycles = agx(eevee_rgba[..., :3]), agx(cycles_rgba[..., :3])
    on_asset = (eevee_rgba[..., 3] > 0.5) & (cycles_rgba[..., 3] > 0.5)
    error = np.where(on_asset, flip_map(cycles, eevee)[0], 0.0)
    floor_map = np.where(on_asset, flip_map(cycles, agx(frame(other, args.asset, "native", 1)[..., :3]))[0], 0.0)
    flip, floor, ratio = float(error[on_asset].mean()), float(floor_map[on_asset].mean()), \
        brightness_ratio(eevee_rgba, cycles_rgba)
    times = read_json(seed / "times.json")[args.asset]["eevee"]
    prepared = read_json(folder / ASSET / "prepared" / "asset.json")
    row = {"cases": 1, "mean_flip": flip, "worst_flip": flip, "mean_cycles_floor": floor,
           "brightness_ratio": [ratio, ratio], "passed": flip <= TARGET_MEAN, "pixels": int(on_asset.sum()),
           "resolution": args.asset_resolution, "texture_size": args.texture_size,
           "material_types": {m["name"]: m["type"] for m in prepared["materials"]},
           "eevee_first_wall_s": times["first"][0], "eevee_frame_wall_s": times["frame"][0]}
    window = around(on_asset)
    images = [("EEVEE", eevee[window]), ("Cycles", cycles[window]), (f"FLIP {flip:.3f} on the asset", error[window]),
              (f"Cycles seed+1: {floor:.3f}", floor_map[window])]
    return row, images


def around(mask: np.ndarray, margin: int = 4) -> tuple[slice, slice]:
    """The square window about ``mask``'s pixels, ``margin`` pixels wider: the asset fills its tile of the sheet."""
    ys, xs = np.nonzero(mask)
    half = max(np.ptp(ys), np.ptp(xs)) // 2 + margin
    y, x = (ys.min() + ys.max()) // 2, (xs.min() + xs.max()) // 2
    return slice(max(y - half, 0), y + half + 1), slice(max(x - half, 0), x + half + 1)


def sweep(folder: Path, case: str) -> list[dict]:
    """Each of ``SETTINGS`` after the preview scene's own, on ``case`` and the Principled ball: FLIP against
    Cycles and the brightness ratio."""
    out = []
    cycles_of = {ball: frame(folder / "seed", ball, "native") for ball in (CONTROL, case)}  # read once
    for name, settings in {PREVIEW: None, **SETTINGS}.items():
        row: dict = {"setting": name, "settings": settings or {}, "flip": {}, "brightness_ratio": {}}
        for ball, cycles in cycles_of.items():
            eevee = frame(folder / "seed", ball, "eevee") if settings is None else \
                frame(folder / SWEEP, ball, label_of(name), 1)
            row["flip"][ball] = flip_map(agx(cycles[..., :3]), agx(eevee[..., :3]))[1]
            row["brightness_ratio"][ball] = brightness_ratio(eevee, cycles)
        print(f"{name:58s} " + "  ".join(f"{k} {v:.4f}" for k, v in row["flip"].items()), flush=True)
        out.append(row)
    return out


def summary(rows: list[dict]) -> dict:
    """Per group and overall: mean and worst FLIP, the mean noise floor, the brightness ratio's range,
    and EEVEE's median first-frame and per-frame wall seconds."""
    groups: dict[str, list[dict]] = {}
    for row in rows:
        groups.setdefault(row["group"], []).append(row)
    groups["all"] = [r for r in rows if r["group"] != REFERENCE]

    def stats(members: list[dict]) -> dict:
        flips = [r["flip"] for r in members]
        ratios = [r["brightness_ratio"] for r in members]
        return {"cases": len(members), "mean_flip": float(np.mean(flips)), "worst_flip": max(flips),
                "mean_cycles_floor": float(np.mean([r["cycles_floor"] for r in members])),
                "worst_eevee_repeat": max(r["eevee_repeat"] for r in members),
                "brightness_ratio": [min(ratios), max(ratios)],
                "passed": float(np.mean(flips)) <= TARGET_MEAN and max(flips) <= TARGET_WORST,
                **{f"eevee_{key}_wall_s": float(np.median([r["seconds"]["eevee"][key][0] for r in members]))
                   for key in ("first", "frame")}}

    return {name: stats(members) for name, members in groups.items()}


def own_form(rows: list[dict]) -> dict:
    """EEVEE's own form of the graph against the form Cycles reads, over the whole materials that have one:
    the median FLIP of each and how many cases each draws closer to Cycles."""
    both = [r for r in rows if "cycles_form" in r and r["node"] == "surface"]
    if not both:
        return {"cases": 0}
    return {"cases": len(both), "median_flip": float(np.median([r["flip"] for r in both])),
            "median_flip_cycles_form": float(np.median([r["cycles_form"]["flip"] for r in both])),
            "closer": sum(r["flip"] < r["cycles_form"]["flip"] for r in both)}


def chart(report: dict, path: Path) -> None:
    """Mean and worst FLIP per group beside the Cycles noise floor; EEVEE's brightness over Cycles' per case;
    the settings sweep's FLIP per setting."""
    plt = pyplot()
    groups = [g for g in report["summary"] if g != "all"]
    fig, (a, b, c) = plt.subplots(1, 3, figsize=(21, 5.5), gridspec_kw={"width_ratios": [3, 2, 2]})
    x = np.arange(len(groups))
    for k, (key, label, colour) in enumerate((("mean_flip", "mean FLIP", "tab:blue"),
                                              ("worst_flip", "worst FLIP", "tab:red"),
                                              ("mean_cycles_floor", "Cycles noise floor (next seed)", "gray"))):
        a.bar(x + (k - 1) * 0.27, [report["summary"][g][key] for g in groups], 0.27, label=label, color=colour)
    a.axhline(TARGET_MEAN, color="tab:blue", ls="--", lw=0.8, label=f"target mean {TARGET_MEAN}")
    a.axhline(TARGET_WORST, color="tab:red", ls=":", lw=0.8, label=f"target worst {TARGET_WORST}")
    a.set_xticks(x, groups, rotation=60, ha="right", fontsize=8)
    a.set_ylabel(f"EEVEE vs Cycles, native graph ({FLIP_CONVENTION})", fontsize=8)
    a.set_title(f"EEVEE ({report['eevee_samples']} samples, {report['eevee_renderer']}) against Cycles "
                f"({report['samples']} spp), {report['resolution']} px", fontsize=9)
    a.legend(fontsize=8)
    rows = report["cases"]
    y = np.arange(len(rows))
    b.barh(y, [r["brightness_ratio"] - 1 for r in rows], left=1,
           color=["tab:orange" if r["node"] != "surface" else "tab:blue" for r in rows])
    b.axvline(1, color="black", lw=0.6)
    b.set_yticks(y, [REFERENCE if r["group"] == REFERENCE else r["name"] for r in rows], fontsize=7)
    b.invert_yaxis()
    b.set_xlabel("EEVEE / Cycles mean luminance on the ball (orange: a lobe alone)")
    sweep_rows = report["settings_sweep"]
    balls = list(sweep_rows[0]["flip"])
    y = np.arange(len(sweep_rows))
    for k, ball in enumerate(balls):
        c.barh(y + (k - 0.5) * 0.4, [r["flip"][ball] for r in sweep_rows], 0.4,
               label=REFERENCE if ball == CONTROL else ball)
    c.set_yticks(y, [r["setting"] for r in sweep_rows], fontsize=7)
    c.invert_yaxis()
    c.set_xlabel("EEVEE vs Cycles, FLIP as on the left")
    c.set_title("EEVEE's settings, one changed at a time", fontsize=9)
    c.set_xlim(0, 1.4 * max(f for r in sweep_rows for f in r["flip"].values()))  # room for the legend
    c.legend(fontsize=8, loc="lower right")
    save_chart(fig, path)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--per-type", type=int, default=2, help="drawn materials per type (default: 2)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the drawn materials and of Cycles (default: 0)")
    parser.add_argument("--asset", default="WaterBottle", help="the sample asset: uplifted vectors of it on the ball, and its textured mesh (default: WaterBottle)")
    parser.add_argument("--per-asset", type=int, default=2, help="cases drawn from the asset (default: 2)")
    parser.add_argument("--resolution", type=int, default=96, help="preview ball size in pixels (default: 96)")
    parser.add_argument("--samples", type=int, default=256, help="Cycles samples per frame (default: 256)")
    parser.add_argument("--eevee-samples", type=int, default=16,
                        help="EEVEE samples per frame (default: 16; about 0.6 s each at 96 px on llvmpipe)")
    parser.add_argument("--asset-resolution", type=int, default=128,
                        help="size of the textured asset's renders in pixels (default: 128)")
    parser.add_argument("--texture-size", type=int, default=128,
                        help="the farm's --max-texture for the asset's maps (default: 128)")
    parser.add_argument("--probe", type=Path, default=DEFAULT_PROBE, help="equirectangular HDR probe")
    parser.add_argument("--renders", type=Path, default=None, metavar="DIR",
                        help="keep the renders in DIR, or compare those already there (the report's \"rendered\" "
                             "says which; default: a temporary folder)")
    add_out_argument(parser, "native_eevee.json")
    args = parser.parse_args()

    all_cases = cases(args.seed, args.per_type, 1) + real_cases([args.asset], args.per_asset)
    start = time.perf_counter()
    rows, sheet = [], []
    with tempfile.TemporaryDirectory(prefix="richmat_native_eevee_") as fresh:
        folder = args.renders or Path(fresh)
        rendered = not (folder / ASSET / str(args.seed + 1) / "times.json").exists()
        if rendered:
            render(all_cases, args, folder)
        times = read_json(folder / "seed" / "times.json")
        renderer = read_json(folder / "seed" / "devices.json")["eevee"][0]
        for case in [*all_cases, None]:
            row, images = compare(case.name if case else CONTROL, folder, times)
            row.update({"node": case.node, "group": group_of(case), "params": case.params,
                        "base_color": case.base_color} if case else {"node": "surface", "group": REFERENCE})
            rows.append(row)
            sheet.append((f"{row['name']}\nFLIP {row['flip']:.3f} (floor {row['cycles_floor']:.3f})\n"
                          f"EEVEE/Cycles {row['brightness_ratio']:.2f}", images))
            print(f"{row['name']:28s} FLIP {row['flip']:.4f} (Cycles floor {row['cycles_floor']:.4f}, EEVEE repeat "
                  f"{row['eevee_repeat']:.4f}), brightness {row['brightness_ratio']:.3f}"
                  + (f"; Cycles' form {row['cycles_form']['flip']:.4f}" if "cycles_form" in row else ""), flush=True)
        asset_row, images = compare_asset(folder, args)
        sheet.append((f"{args.asset}, textured mesh\nFLIP {asset_row['mean_flip']:.3f} "
                      f"(floor {asset_row['mean_cycles_floor']:.3f})\n"
                      f"EEVEE/Cycles {asset_row['brightness_ratio'][0]:.2f}", images))
        settings = sweep(folder, swept_case(all_cases).name)
    overall = {**summary(rows), f"{args.asset} mesh": asset_row}
    types = [g for g in overall if g.startswith("type")]
    report = {"seed": args.seed, "per_type": args.per_type, "asset": args.asset, "per_asset": args.per_asset,
              "asset_resolution": args.asset_resolution, "texture_size": args.texture_size,
              "probe": args.probe.name, "resolution": args.resolution, "samples": args.samples,
              "eevee_samples": args.eevee_samples, "eevee_renderer": renderer, "reference": "Cycles CPU, native graph",
              "flip_convention": FLIP_CONVENTION, "target_mean": TARGET_MEAN, "target_worst": TARGET_WORST,
              "types_passed": [g for g in types if overall[g]["passed"]], "eevee_form": own_form(rows),
              "settings_sweep": settings,
              "time_columns": "seconds[config][first|frame] = [wall, cpu]",
              "rendered": rendered, "wall_seconds": time.perf_counter() - start, "summary": overall, "cases": rows}
    write_report(args.out, report)
    chart(report, args.out.with_suffix(".png"))
    labelled_sheet(sheet, args.out.with_name(args.out.stem + "_sheet.png"))
    for group, s in overall.items():
        print(f"{group:24s} mean FLIP {s['mean_flip']:.4f} worst {s['worst_flip']:.4f} (floor {s['mean_cycles_floor']:.4f})"
              f" brightness {s['brightness_ratio'][0]:.2f}-{s['brightness_ratio'][1]:.2f}")
    print(f"{len(report['types_passed'])} of {len(types)} types meet the target; {renderer}; "
          f"{report['wall_seconds'] / 60:.1f} min; wrote {args.out}")
    sys.exit(0 if len(report["types_passed"]) == len(types) else 1)


if __name__ == "__main__":
    main()
