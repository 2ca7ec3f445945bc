"""What one asset costs the farm at the real defaults, stage by stage, before and after a cheaper beauty pass.

1. The farm. Each asset goes through ``batch/render_dataset.py`` on its own at the
   defaults (512 px, 16 frames, 16 spp, 300 fit steps, the shipped decoder), with
   ``--max-texture`` above every texture (checked: no "downscaled" note) and one
   worker, so every child renders or fits with one thread, as on a node that runs
   one asset per core. Per stage, CPU seconds from the manifest (each child times its
   own stages with ``time.process_time``); the run's whole CPU comes from ``wait4``,
   and what no child claims is the orchestrator's ("overhead"). Twice, at the same
   time, so that the machine's load hits both alike: "before" with OIDN's accurate
   prefilter (the farm's earlier setting), "after" at today's defaults
   (bench/beauty_denoise.py measures what the fast prefilter costs in accuracy).
2. The fit at each cluster step of ``--sweep``, on the farm's own enhanced material
   folders, as ``batch/fit_job.py`` runs it (read and merge, fit), CPU-timed here, and
   its accuracy: per textured material, the 32 x 32 texel crop with the most distinct
   vectors (where merging has the most to lose), as a flat patch seen from 45 degrees
   under the probe (``bench/dedupe.py``), analytic against neural, LDR-FLIP. Past a
   few thousand vectors the fit gives each its own samples, so merging changes its cost
   (``bench/fit_budget.py`` measures the budget itself).

The cost model prices 10 000 assets and the paper's 10 640-asset dataset on 16-core
nodes from the mean CPU seconds per asset, before and after.

    python -m bench.farm_cost [--assets WaterBottle ...] [--work DIR] [--sweep 256 128 64 32]
"""
from __future__ import annotations

import argparse
import json
import os
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
from batch.options import DEFAULT_CLUSTER_STEP
from bench.common import (FLIP_CONVENTION, REPO, add_out_argument, child_env, provenance, pyplot, save_chart,
                          write_report)
from bench.dedupe import CROP, crop_rows, flat_patch, texel_colours
from richmat_addon.core.stage_clock import StageClock
from richmat_addon.core.texel_vectors import QUANT, read_vectors, texel_matrix
from torch_models.brdf.model import LayeredBsdf, params_from_vectors
from torch_models.neural import trained
from torch_models.neural.model import NeuralModel
from torch_models.neural.bsdf import NeuralBsdf
from torch_models.neural.evaluate import DEFAULT_PROBE, compare
from torch_models.neural.fitting import fit_latents
from torch_models.render.envmap import EnvMap

MODELS = REPO.parent / "shared" / "assets" / "models"
ASSETS = ("WaterBottle", "CesiumMilkTruck", "FlightHelmet")
STAGES = ("import", "enhance", "bake", "fit", "beauty", "intrinsics", "encode")
MAX_TEXTURE = 8192  # above every sample texture (2048 at most): nothing downscaled
FIT_STEPS = options.build_parser().get_default("fit_steps")  # the farm's own default
SIDES = {"before": ["--denoise-prefilter", "accurate"], "after": []}  # farm arguments besides the defaults
PAPER = {"assets": 10_640, "gpus": 80, "hours": 22.0}  # the paper's dataset and what rendering it took
NODE_CORES = 16


def run_farm(asset: Path, work: Path, extra: list[str]) -> dict:
    """One farm run of one asset at the defaults but ``extra`` arguments: its manifest, wall seconds and
    CPU seconds of everything (``wait4``'s usage of the run and every descendant it waited for), and
    the commit that ran it."""
    listing, out = work / "list.txt", work / "out"
    listing.write_text(f"{asset}\n")
    start = time.monotonic()
    child = subprocess.Popen([sys.executable, str(REPO / "batch" / "render_dataset.py"), "--input", str(listing),
                              "--output", str(out), "--max-texture", str(MAX_TEXTURE), "--workers", "1",
                              "--timeout", "86400", "--retries", "0", *extra], env=child_env(), cwd=REPO)
    _, status, usage = os.wait4(child.pid, 0)
    child.returncode = os.waitstatus_to_exitcode(status)
    if child.returncode:
        raise SystemExit(f"{asset.name}: the farm run {extra} failed ({child.returncode})")
    wall, cpu = time.monotonic() - start, usage.ru_utime + usage.ru_stime
    record = farm_record(asset.stem, next(p.parent for p in out.glob("*/manifest.json")), wall, cpu)
    return {**record, "arguments": extra, "git_commit": provenance()["git_commit"]}


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


def both_sides(asset: Path, work: Path) -> dict[str, dict]:
    """The asset's farm run for every side of ``SIDES``, all at once, so that the machine's load hits
    them alike (one thread each)."""
    def side(name: str) -> dict:
        folder = work / name
        folder.mkdir(parents=True, exist_ok=True)
        return cached(folder / "farm.json", {"arguments": SIDES[name]}, partial(run_farm, asset, folder, SIDES[name]))

    with ThreadPoolExecutor(len(SIDES)) as pool:
        runs = dict(zip(SIDES, pool.map(side, SIDES)))
    for name, run in runs.items():
        print(f"{asset.stem} {name}: {run['cpu_total']:.0f} CPU s, {run['wall_total']:.0f} s wall", flush=True)
    return runs


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
    """Left: CPU seconds per stage per asset, before and after. Right: fit CPU against crop FLIP per step."""
    plt = pyplot()
    fig, (a, b) = plt.subplots(1, 2, figsize=(14, 5.2))
    table = report["before_after"]
    bars = [(r["asset"], side, r[side]) for r in table for side in ("before", "after")]
    lefts = np.zeros(len(bars))
    for stage, colour in zip((*STAGES, "overhead"), plt.cm.tab10.colors):
        values = np.array([row[stage] for _, _, row in bars])
        a.barh(range(len(bars)), values, left=lefts, color=colour, label=stage)
        lefts += values
    a.set_yticks(range(len(bars)), [f"{asset}\n{side}" for asset, side, _ in bars], fontsize=8)
    a.invert_yaxis()
    a.set_xlabel("CPU seconds per asset (one thread per child)")
    a.set_title("Farm at 512 px x 16 frames, full-size textures: OIDN prefilter accurate (before) "
                "and fast (after)", fontsize=9)
    a.legend(fontsize=8)
    for asset in dict.fromkeys(r["asset"] for r in report["fits"]):
        rows = [r for r in report["fits"] if r["asset"] == asset]
        steps = sorted({r["step"] for r in rows})
        cpu = [sum(r["total_cpu"] for r in rows if r["step"] == s) for s in steps]
        flips = [np.mean([r["flip"] for r in rows if r["step"] == s and "flip" in r]) for s in steps]
        line, = b.plot(cpu, flips, "o-", label=asset)
        for s, x, y in zip(steps, cpu, flips):
            b.annotate(f"1/{round(1 / s)}", (x, y), textcoords="offset points", xytext=(4, 4), fontsize=7,
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
    parser.add_argument("--sweep", type=int, nargs="+", default=[256, 128, 64, 32], help="cluster steps 1/N")
    add_out_argument(parser, "farm_cost.json")
    args = parser.parse_args()
    torch.set_num_threads(1)
    model, env = trained.load(trained.SHIPPED), EnvMap.load(DEFAULT_PROBE)
    steps = sorted({1 / n for n in args.sweep} | {QUANT}, reverse=True)
    table, farms, fits = [], [], []
    with tempfile.TemporaryDirectory(prefix="richmat_farm_cost_") as tmp:
        work = args.work or Path(tmp)
        for name in args.assets:
            runs = both_sides(MODELS / f"{name}.glb", work / name)
            fits += cached(work / name / "sweep.json", {"steps": steps}, partial(sweep, runs["after"], steps, model, env))
            farms += [{"side": side, **run} for side, run in runs.items()]
            table.append({"asset": name, **{side: stage_table(run) for side, run in runs.items()}})
    total = {side: float(np.mean([sum(r[side].values()) for r in table])) for side in SIDES}
    flips = {f"1/{round(1 / s)}": float(np.mean([r["flip"] for r in fits if r["step"] == s and "flip" in r]))
             for s in steps}
    fit_cpu = {f"1/{round(1 / s)}": float(sum(r["total_cpu"] for r in fits if r["step"] == s)) for s in steps}
    report = {"settings": {side: next(f["settings"] for f in farms if f["side"] == side) for side in SIDES},
              "assets": args.assets, "threads_per_child": 1, "sides": SIDES,
              "cpu_measure": "time.process_time per child stage (user + system); the run's total by wait4; "
                             "both sides of an asset run at once",
              "flip_convention": FLIP_CONVENTION, "crop": CROP, "farm_default_step": DEFAULT_CLUSTER_STEP,
              "sweep_mean_crop_flip": flips, "sweep_fit_cpu_all_assets": fit_cpu,
              "farm": farms, "fits": fits, "before_after": table,
              "stage_totals": {side: {s: sum(r[side][s] for r in table) for s in (*STAGES, "overhead")}
                               for side in SIDES},
              "biggest_stage": {side: max(STAGES, key=lambda s: sum(r[side][s] for r in table)) for side in SIDES},
              "cost_model": {side: cost_model(total[side]) for side in SIDES}}
    write_report(args.out, report, [trained.SHIPPED])
    chart(report, args.out.with_suffix(".png"))
    print(json.dumps({k: report[k] for k in ("biggest_stage", "stage_totals", "sweep_mean_crop_flip", "cost_model")},
                     indent=1))


if __name__ == "__main__":
    main()
