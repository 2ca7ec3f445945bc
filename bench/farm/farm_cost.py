"""What one asset costs the farm at the real defaults, stage by stage: today's farm against a cheaper one.

1. The farm. Each asset goes through ``batch/render_dataset.py`` on its own at the
   defaults (512 px, 16 frames, 12 spp, 300 fit steps, the shipped decoder), with
   ``--max-texture`` above every texture (checked: no "downscaled" note) and one
   worker, so every child renders or fits with all of the machine's cores
   (``threads_per_child`` in the report: 2 here). Per stage, CPU seconds from the manifest (each child times its
   own stages with ``time.process_time``); the run's whole CPU comes from ``wait4``,
   and what no child claims is the orchestrator's ("overhead"). "before" is the farm
   of ``--baseline`` (a commit, checked out with ``git archive``: today's code and
   defaults), "after" this checkout with ``AFTER``'s arguments; both at the same time,
   so that the machine's load hits them alike.
2. Same outputs: a third run at the same time, this checkout with the exact OSL graph at
   ``REFERENCE_SAMPLES`` spp on every ``REFERENCE_STRIDE``-th frame of the orbit (the
   orbit is the same: frame i of 4 is frame 4i of 16), is the reference of both sides'
   beauty frames (mean LDR-FLIP over those frames); the intrinsics EXRs of the two
   sides are compared value by value, layer by layer: the render's own layers must be
   identical, the latent layers no further apart than the two sides' fitted latents (the
   fit is not held equal: it is not part of the target).
3. The fit at each cluster step of ``--sweep`` (none: skipped), on the farm's own
   enhanced material folders, as ``batch/fit_job.py`` runs it (read and merge, fit),
   CPU-timed here, and its accuracy: per textured material, the 32 x 32 texel crop with
   the most distinct vectors (where merging has the most to lose), as a flat patch seen
   from 45 degrees under the probe (``bench/neural/dedupe.py``), analytic against neural,
   LDR-FLIP. Past a few thousand vectors the fit gives each its own samples, so merging
   changes its cost (``bench/neural/fit_budget.py`` measures the budget itself).

The cost model prices 10 000 assets and the paper's 10 640-asset dataset on 16-core
nodes from the CPU seconds per asset, before and after, in a stated mix of the two kinds of
asset measured (``--scan-share``: the share of photo-scanned assets, whose textures hold a
distinct vector in most texels, against sample assets like WaterBottle, whose do not); per
asset the report says whether its fit costs no more than its render stages.

    python -m bench.farm.farm_cost [--assets WaterBottle ...] [--work DIR] [--baseline REV] [--sweep [256 128 ...]]
        [--scan-share 0.5]
"""
from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np
import torch

from batch import options
from batch.options import DEFAULT_CLUSTER_STEP, cpu_threads
from bench.common import (FLIP_CONVENTION, REPO, add_out_argument, child_env, provenance, pyplot, save_chart,
                          write_report)
from bench.neural.dedupe import CROP, crop_rows, flat_patch, texel_colours
from bench.farm.render_speed import beauty_frames, mean_flip
from richmat_addon.core.texel_vectors import QUANT, read_vectors, texel_matrix
from torch_models.brdf.model import LayeredBsdf, params_from_vectors
from torch_models.neural import trained
from torch_models.neural.model import NeuralModel
from torch_models.neural.bsdf import NeuralBsdf
from torch_models.neural.evaluate import DEFAULT_PROBE, compare
from torch_models.neural.fit.latents import fit_latents
from torch_models.render.envmap import EnvMap
from torch_models.stage_clock import StageClock

MODELS = REPO.parent / "shared" / "assets" / "models"
ASSETS = ("WaterBottle", "CesiumMilkTruck", "FlightHelmet")
SCANNED = ("wooden_table_02_1k",)  # photo-scanned: 40 % of its 1k texels hold a distinct vector
RENDER_STAGES = ("beauty", "intrinsics", "encode")
STAGES = ("import", "enhance", "bake", "fit", "beauty", "intrinsics", "encode")
MAX_TEXTURE = 8192  # above every sample texture (2048 at most): nothing downscaled
FIT_STEPS = options.build_parser().get_default("fit_steps")  # the farm's own default
BASELINE = "2098d77d78db40bb5f2419d2dd632198adbe9de2"  # main before the cheaper render stage: the farm until then
AFTER = ["--graph", "native"]  # the after side's farm arguments besides the defaults
SIDES = ("before", "after")
REFERENCE_SAMPLES, REFERENCE_STRIDE = 128, 4
# The beauty does not read the fitted latents (only the intrinsics pass does), so the reference fits one step.
REFERENCE = ["--graph", "osl", "--samples", str(REFERENCE_SAMPLES), "--adaptive-threshold", "0.001",
             "--frames", str(options.build_parser().get_default("frames") // REFERENCE_STRIDE), "--fit-steps", "1"]
FLIP_TARGET = 0.005  # the after side's beauty may be at most this much further from the reference
NOT_FIT_TARGET = 0.5  # the target: everything but the fit at most this share of the before side's CPU
# The intrinsics layers that show the fitted latents: they move with the fit (not this bench's to hold equal).
LATENT_LAYERS = ("latent_a", "latent_b")
HALF_STEP = 2.0 ** -10  # half float's rounding step near 1, where the latents lie: the EXRs store them as half
PAPER = {"assets": 10_640, "gpus": 80, "hours": 22.0}  # the paper's dataset and what rendering it took
NODE_CORES = 16


def run_farm(asset: Path, work: Path, extra: list[str], tree: Path, commit: str) -> dict:
    """One farm run of one asset with the checkout ``tree`` (at ``commit``) at its defaults but ``extra``
    arguments: its manifest, wall seconds and CPU seconds of everything (``wait4``'s usage of the run and
    every descendant it waited for). OpenMP threads sleep while they wait (``OMP_WAIT_POLICY``), as on a node
    that is not oversubscribed: with three runs on a shared machine, spinning would bill waiting as work."""
    listing, out = work / "list.txt", work / "out"
    listing.write_text(f"{asset}\n")
    shutil.rmtree(out, ignore_errors=True)  # measured afresh: the farm skips what a run here published before
    start = time.monotonic()
    child = subprocess.Popen([sys.executable, str(tree / "batch" / "render_dataset.py"), "--input", str(listing),
                              "--output", str(out), "--max-texture", str(MAX_TEXTURE), "--workers", "1",
                              "--timeout", "86400", "--retries", "0", *extra],
                             env=dict(child_env(), PYTHONPATH=str(tree), OMP_WAIT_POLICY="PASSIVE"), cwd=tree)
    _, status, usage = os.wait4(child.pid, 0)
    child.returncode = os.waitstatus_to_exitcode(status)
    if child.returncode:
        raise SystemExit(f"{asset.name}: the farm run {extra} failed ({child.returncode})")
    wall, cpu = time.monotonic() - start, usage.ru_utime + usage.ru_stime
    record = farm_record(asset.stem, next(p.parent for p in out.glob("*/manifest.json")), wall, cpu)
    return {**record, "arguments": extra, "git_commit": commit}


def checkout(rev: str, folder: Path) -> str:
    """``rev`` of this repository exported into ``folder`` (once per commit); its full commit hash."""
    commit = subprocess.run(["git", "rev-parse", "--verify", f"{rev}^{{commit}}"], cwd=REPO, check=True,
                            capture_output=True, text=True).stdout.strip()
    stamp = folder / ".commit"
    if not stamp.is_file() or stamp.read_text() != commit:
        shutil.rmtree(folder, ignore_errors=True)
        folder.mkdir(parents=True)
        archive = subprocess.run(["git", "archive", commit], cwd=REPO, check=True, capture_output=True).stdout
        subprocess.run(["tar", "-x", "-C", str(folder)], input=archive, check=True)
        stamp.write_text(commit)
    return commit


def farm_record(asset: str, folder: Path, wall: float, cpu: float) -> dict:
    """What the bench keeps of one published asset folder: stage times, the materials' vector counts."""
    manifest = json.loads((folder / "manifest.json").read_text())
    if any("downscaled" in note for note in manifest["notes"]):
        raise SystemExit(f"{asset}: a texture was downscaled: {manifest['notes']}")
    materials = {}
    for record in sorted(folder.glob("materials/*/neural/neural.json")):
        neural = json.loads(record.read_text())
        materials[record.parent.parent.name] = {k: neural.get(k) for k in (
            "texels", "exact_unique_vectors", "fitted_vectors", "cpu_s")}
    return {"asset": asset, "folder": str(folder), "enhancement_type": manifest["enhancement_type"],
            "settings": manifest["settings"], "wall_total": wall, "cpu_total": cpu,
            "timings_s": manifest["timings_s"], "cpu_s": manifest["cpu_s"], "materials": materials}


def stage_table(farm: dict) -> dict[str, float]:
    """CPU seconds of the issue's stages from the children's records: a child's time no sub-stage
    claims (its start, Blender's or torch's import, opening the scene) goes to the stage it opens."""
    cpu = farm["cpu_s"]
    get = lambda key: float(cpu.get(key, 0.0))  # noqa: E731
    whole = {k: get(f"{k}_process") for k in ("prepare", "fit", "render")}
    row = {"enhance": get("prepare_enhance"), "bake": get("prepare_bake"), "fit": whole["fit"],
           "intrinsics": get("render_intrinsics"), "encode": get("render_video")}
    row["import"] = whole["prepare"] - row["enhance"] - row["bake"]
    row["beauty"] = whole["render"] - row["intrinsics"] - row["encode"]
    row["overhead"] = farm["cpu_total"] - sum(whole.values())
    return row


def varied_crop(vectors: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """Texel indices of the CROP x CROP crop, among an 8 x 8 grid of places, with the most distinct vectors."""
    h, w = shape
    places = [(r0, c0) for r0 in range(0, h - CROP + 1, max(1, (h - CROP) // 7))
              for c0 in range(0, w - CROP + 1, max(1, (w - CROP) // 7))]

    return crop_rows(w, *max(places, key=lambda place: len(np.unique(vectors[crop_rows(w, *place)], axis=0))))


class Accuracy:
    """One material's analytic crop, rendered once, against which each step's fit is compared."""

    def __init__(self, folder: Path, env: EnvMap) -> None:
        shape, vectors = texel_matrix(folder)
        self.env = env
        self.rows = varied_crop(vectors, shape) if shape and min(shape) >= CROP else None
        if self.rows is not None:
            self.colours = torch.from_numpy(texel_colours(folder, shape, self.rows))
            analytic = LayeredBsdf(params_from_vectors(torch.from_numpy(vectors[self.rows])), self.colours)
            self.reference = flat_patch(lambda n: analytic, env, CROP, 0)

    def flip(self, model: NeuralModel, z: torch.Tensor) -> float:
        """FLIP of the neural crop, ``z`` per texel of ``rows``."""
        neural = NeuralBsdf(model, z, self.colours)
        with torch.no_grad():
            return compare(self.reference, flat_patch(lambda n: neural, self.env, CROP, 0)).flip


def fit_at_step(model: NeuralModel, folder: Path, step: float, accuracy: Accuracy) -> dict:
    """The fit stage of one material at ``step``, CPU-timed; the crop's FLIP when it has one."""
    clock = StageClock()
    with clock.stage("read"):
        mv = read_vectors(folder, step)
    with clock.stage("fit"):
        z = fit_latents(model, mv.unique, FIT_STEPS)
    cpu = clock.record(whole_process=False)["cpu_s"]
    row = {"step": step, "vectors": len(z), "exact_unique": mv.exact_unique, "read_cpu": cpu["read"],
           "fit_cpu": cpu["fit"], "total_cpu": cpu["read"] + cpu["fit"]}
    if accuracy.rows is not None:
        row["flip"] = accuracy.flip(model, z[torch.from_numpy(mv.inverse[accuracy.rows])])
    return row


def sweep(farm: dict, steps: list[float], model: NeuralModel, env: EnvMap) -> list[dict]:
    """``fit_at_step`` for every material of the farm's asset and every step."""
    rows = []
    for folder in sorted(Path(farm["folder"]).glob("materials/*/params.json")):
        accuracy = Accuracy(folder.parent, env)
        for step in steps:
            row = fit_at_step(model, folder.parent, step, accuracy)
            rows.append({"asset": farm["asset"], "material": folder.parent.name, **row})
            print(f"  {farm['asset']}/{folder.parent.name} step 1/{round(1 / step)}: {row['vectors']} vectors, "
                  f"fit {row['total_cpu']:.1f} CPU s" + (f", FLIP {row['flip']:.4f}" if "flip" in row else ""),
                  flush=True)
    return rows


def all_runs(asset: Path, work: Path, baseline: tuple[Path, str]) -> dict[str, dict]:
    """The asset's farm runs before (``baseline``: a checkout and its commit) and after, and the reference,
    all at once, so that the machine's load hits both sides alike."""
    here = provenance()["git_commit"]
    plans = {"before": (*baseline, []), "after": (REPO, here, AFTER), "reference": (REPO, here, REFERENCE)}

    def side(name: str) -> dict:
        tree, commit, extra = plans[name]
        folder = work / name
        folder.mkdir(parents=True, exist_ok=True)
        return cached(folder / "farm.json", {"commit": commit, "arguments": extra},
                      partial(run_farm, asset, folder, extra, tree, commit))

    with ThreadPoolExecutor(len(plans)) as pool:
        runs = dict(zip(plans, pool.map(side, plans)))
    for name, run in runs.items():
        print(f"{asset.stem} {name}: {run['cpu_total']:.0f} CPU s, {run['wall_total']:.0f} s wall", flush=True)
    return runs


def beauty_flip(run: dict, reference: dict) -> float:
    """Mean FLIP of ``run``'s beauty frames against the reference's, on the frames the reference has."""
    return mean_flip(beauty_frames(Path(reference["folder"])), beauty_frames(Path(run["folder"]))[::REFERENCE_STRIDE])


def intrinsics_difference(a: dict, b: dict) -> dict[str, float]:
    """The largest absolute difference between two runs' intrinsics EXRs per layer, over every frame and channel."""
    import OpenImageIO as oiio

    worst: dict[str, float] = {}
    for path in sorted(Path(a["folder"]).glob("passes/*.exr")):
        other = Path(b["folder"]) / "passes" / path.name
        for part in range(oiio.ImageBuf(str(path)).nsubimages):
            x, y = (oiio.ImageBuf(str(p), part, 0) for p in (path, other))
            layer = x.spec().channelnames[0].split(".")[0]
            difference = float(np.abs(x.get_pixels(oiio.FLOAT) - y.get_pixels(oiio.FLOAT)).max())
            worst[layer] = max(worst.get(layer, 0.0), difference)
    return worst


def latent_difference(a: dict, b: dict) -> float:
    """The largest absolute difference between two runs' fitted latents (textures or constants): the most their
    intrinsics' latent layers may differ by, each pixel there being a weighted mean of latent texels."""
    import OpenImageIO as oiio

    worst = 0.0
    for record in sorted(Path(a["folder"]).glob("materials/*/neural/neural.json")):
        other = Path(b["folder"]) / record.relative_to(a["folder"])
        pairs = [(np.asarray(json.loads(p.read_text()).get("latent") or [0.0])) for p in (record, other)]
        for texture in sorted(record.parent.glob("latent_*.exr")):
            pairs += [oiio.ImageBuf(str(p)).get_pixels(oiio.FLOAT) for p in (texture, other.parent / texture.name)]
        worst = max([worst] + [float(np.abs(x - y).max()) for x, y in zip(pairs[::2], pairs[1::2])])
    return worst


def intrinsics_hold(layers: dict[str, float], latents: float) -> bool:
    """The render's own layers identical; the latent layers no further apart than the fitted latents are."""
    return all(difference <= (latents + HALF_STEP if layer in LATENT_LAYERS else 0.0)
               for layer, difference in layers.items())


def mixed(cpu: dict[str, float], scan_share: float) -> float:
    """CPU seconds per asset of a farm whose assets are photo-scanned in ``scan_share`` of cases: the mean
    over the scanned assets measured and over the others, weighed by the share (the plain mean when
    only one kind was measured)."""
    scans = [v for a, v in cpu.items() if a in SCANNED]
    others = [v for a, v in cpu.items() if a not in SCANNED]
    if not scans or not others:
        return float(np.mean(list(cpu.values())))
    return scan_share * float(np.mean(scans)) + (1 - scan_share) * float(np.mean(others))


def cost_model(cpu_per_asset: float) -> dict:
    """CPU-hours per 10 000 assets, and the paper's dataset on N 16-core nodes (one asset per core)."""
    total_hours = PAPER["assets"] * cpu_per_asset / 3600
    return {"cpu_seconds_per_asset": cpu_per_asset, "cpu_hours_per_10000_assets": 10_000 * cpu_per_asset / 3600,
            "paper_dataset_cpu_hours": total_hours,
            "paper_dataset_hours_on_nodes": {str(n): total_hours / (NODE_CORES * n) for n in (1, 10, 40, 80, 160)},
            "nodes_to_match_paper_22_hours": total_hours / (NODE_CORES * PAPER["hours"]),
            "paper_gpu_hours": PAPER["gpus"] * PAPER["hours"]}


def cached(path: Path, key: dict, measure: Callable[[], Any]) -> Any:
    """``measure()``, or what a run with the same ``key`` left in ``path`` (a long bench resumes)."""
    if path.is_file():
        saved = json.loads(path.read_text())
        if saved["key"] == key:
            return saved["value"]
    value = measure()
    path.write_text(json.dumps({"key": key, "value": value}, indent=1))
    return value


def chart(report: dict, path: Path) -> None:
    """CPU seconds per stage per asset, before and after; the beauty's FLIP against the reference; with a
    sweep, fit CPU against crop FLIP per cluster step."""
    plt = pyplot()
    fits = report["fits"]
    fig, axes = plt.subplots(1, 3 if fits else 2, figsize=(18 if fits else 13, 5.2),
                             gridspec_kw={"width_ratios": [3, 1.2, 2.4][:3 if fits else 2]})
    a, f = axes[0], axes[1]
    table = report["before_after"]
    bars = [(r["asset"], side, r[side]) for r in table for side in SIDES]
    lefts = np.zeros(len(bars))
    for stage, colour in zip((*STAGES, "overhead"), plt.cm.tab10.colors):
        values = np.array([row[stage] for _, _, row in bars])
        a.barh(range(len(bars)), values, left=lefts, color=colour, label=stage)
        lefts += values
    a.set_yticks(range(len(bars)), [f"{asset}\n{side}" for asset, side, _ in bars], fontsize=8)
    a.invert_yaxis()
    a.set_xlabel(f"CPU seconds per asset ({report['threads_per_child']} thread(s) per child)")
    a.set_title(f"Farm at 512 px x 16 frames, full-size textures: {report['baseline'][:7]} (before) "
                f"and {' '.join(AFTER) or 'defaults'} (after)", fontsize=9)
    a.legend(fontsize=8)
    same = report["same_outputs"]["beauty_flip"]
    x = np.arange(len(same))
    for k, side in enumerate(SIDES):
        f.bar(x + 0.4 * k - 0.2, [same[asset][side] for asset in same], 0.4, label=side)
    f.set_xticks(x, list(same), fontsize=8)
    f.set_ylabel(f"mean FLIP vs OSL at {REFERENCE_SAMPLES} spp")
    f.set_title(f"Beauty against the reference (after may add {FLIP_TARGET})", fontsize=9)
    f.legend(fontsize=8)
    if fits:
        b = axes[2]
        for asset in dict.fromkeys(r["asset"] for r in fits):
            rows = [r for r in fits if r["asset"] == asset]
            steps = sorted({r["step"] for r in rows})
            cpu = [sum(r["total_cpu"] for r in rows if r["step"] == s) for s in steps]
            flips = [np.mean([r["flip"] for r in rows if r["step"] == s and "flip" in r]) for s in steps]
            line, = b.plot(cpu, flips, "o-", label=asset)
            for s, px, py in zip(steps, cpu, flips):
                b.annotate(f"1/{round(1 / s)}", (px, py), textcoords="offset points", xytext=(4, 4), fontsize=7,
                           color=line.get_color())
        b.set_xscale("log")
        b.set_xlabel("fit CPU seconds per asset (all its materials)")
        b.set_ylabel("FLIP neural vs analytic, mean over the materials' crops")
        b.set_title("Cluster step: fit cost against accuracy", fontsize=9)
        b.legend(fontsize=8)
    save_chart(fig, path)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--assets", nargs="+", default=list(ASSETS), help="names in ../shared/assets/models")
    parser.add_argument("--work", type=Path, default=None,
                        help="keep the farm's output here; an asset already measured there is not run again")
    parser.add_argument("--baseline", default=BASELINE, help="the commit whose farm is the before side")
    parser.add_argument("--sweep", type=int, nargs="*", default=[256, 128, 64, 32],
                        help="cluster steps 1/N of the fit sweep (none: no sweep)")
    parser.add_argument("--scan-share", type=float, default=0.5,
                        help="share of photo-scanned assets in the cost model's farm (default 0.5)")
    add_out_argument(parser, "farm_cost.json")
    args = parser.parse_args()
    torch.set_num_threads(1)
    model, env = trained.load(trained.SHIPPED), EnvMap.load(DEFAULT_PROBE)
    steps = sorted({1 / n for n in args.sweep} | {QUANT}, reverse=True) if args.sweep else []
    table, farms, fits, same = [], [], [], {}
    with tempfile.TemporaryDirectory(prefix="richmat_farm_cost_") as tmp:
        work = args.work or Path(tmp)
        baseline = work / "baseline"
        baseline_commit = checkout(args.baseline, baseline)
        for name in args.assets:
            runs = all_runs(MODELS / f"{name}.glb", work / name, (baseline, baseline_commit))
            if steps:
                fits += cached(work / name / "sweep.json", {"steps": steps},
                               partial(sweep, runs["after"], steps, model, env))
            farms += [{"side": side, **runs[side]} for side in SIDES]
            table.append({"asset": name, **{side: stage_table(runs[side]) for side in SIDES}})
            flips = {side: beauty_flip(runs[side], runs["reference"]) for side in SIDES}
            layers = intrinsics_difference(runs["before"], runs["after"])
            latents = latent_difference(runs["before"], runs["after"])
            same[name] = {"beauty_flip": {**flips, "after_minus_before": flips["after"] - flips["before"]},
                          "intrinsics_max_abs_difference": layers, "fitted_latents_max_abs_difference": latents,
                          "render_layers_max_abs_difference": max(v for k, v in layers.items()
                                                                  if k not in LATENT_LAYERS),
                          "intrinsics_hold": intrinsics_hold(layers, latents)}
            print(f"{name}: beauty FLIP before {flips['before']:.4f}, after {flips['after']:.4f}; intrinsics "
                  f"differ by at most {layers} (the fitted latents by {latents:.3g})", flush=True)
    total = {side: mixed({r["asset"]: sum(r[side].values()) for r in table}, args.scan_share) for side in SIDES}
    not_fit = {side: float(np.mean([sum(r[side].values()) - r[side]["fit"] for r in table])) for side in SIDES}
    report = {"settings": {side: next(f["settings"] for f in farms if f["side"] == side) for side in SIDES},
              "assets": args.assets, "threads_per_child": cpu_threads(1), "baseline": baseline_commit,
              "sides": {"before": f"the farm at {baseline_commit} at its defaults",
                        "after": f"this checkout, defaults and {' '.join(AFTER) or 'nothing else'}"},
              "cpu_measure": "time.process_time per child stage (user + system); the run's total by wait4; "
                             "both sides and the reference of an asset run at once, OMP_WAIT_POLICY=PASSIVE",
              "flip_convention": FLIP_CONVENTION,
              "same_outputs": {"reference": f"this checkout, {' '.join(REFERENCE)}: frame i is frame "
                                            f"{REFERENCE_STRIDE}i of the sides' orbit", "flip_target": FLIP_TARGET,
                               "beauty_flip": {a: v["beauty_flip"] for a, v in same.items()},
                               **{key: {a: v[key] for a, v in same.items()} for key in (
                                   "intrinsics_max_abs_difference", "fitted_latents_max_abs_difference",
                                   "render_layers_max_abs_difference", "intrinsics_hold")},
                               "holds": all(v["beauty_flip"]["after_minus_before"] <= FLIP_TARGET
                                            and v["intrinsics_hold"] for v in same.values())},
              "not_fit_cpu_per_asset": not_fit, "not_fit_after_over_before": not_fit["after"] / not_fit["before"],
              "not_fit_target": NOT_FIT_TARGET,
              "crop": CROP, "farm_default_step": DEFAULT_CLUSTER_STEP,
              "sweep_mean_crop_flip": {f"1/{round(1 / s)}": float(np.mean([r["flip"] for r in fits
                                                                           if r["step"] == s and "flip" in r]))
                                       for s in steps},
              "sweep_fit_cpu_all_assets": {f"1/{round(1 / s)}": float(sum(r["total_cpu"] for r in fits
                                                                          if r["step"] == s)) for s in steps},
              "farm": farms, "fits": fits, "before_after": table,
              "stage_totals": {side: {s: sum(r[side][s] for r in table) for s in (*STAGES, "overhead")}
                               for side in SIDES},
              "biggest_stage": {side: max(STAGES, key=lambda s: sum(r[side][s] for r in table)) for side in SIDES},
              "fit_within_render": {r["asset"]: {side: {"fit": r[side]["fit"],
                                                        "render": sum(r[side][s] for s in RENDER_STAGES),
                                                        "holds": r[side]["fit"] <= sum(r[side][s] for s in RENDER_STAGES)}
                                                  for side in SIDES} for r in table},
              "mix": {"scan_share": args.scan_share, "scanned": [a for a in args.assets if a in SCANNED]},
              "cost_model": {side: cost_model(total[side]) for side in SIDES}}
    write_report(args.out, report, [trained.SHIPPED])
    chart(report, args.out.with_suffix(".png"))
    print(json.dumps({k: report[k] for k in ("same_outputs", "not_fit_cpu_per_asset", "not_fit_after_over_before",
                                             "stage_totals", "cost_model")}, indent=1))


if __name__ == "__main__":
    main()
