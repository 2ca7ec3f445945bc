"""How hard to push towards the prompt: classifier-free guidance against accuracy, prompt
sensitivity and speed.

Guidance scales the step from the unconditional denoiser to the prompted one. More of it
pulls the materials of different prompts further apart (prompt sensitivity,
bench/generator/generate_prompts.py) but can overshoot the residual the caption calls for, which
costs PSNR against the reference; guidance 1 is the prompted model alone and needs no
unconditional pass, so it samples in half the time. For each guidance value, on the same
inputs and seeds: PSNR and FLIP of the generation against its reference on the real
assets the corpus holds out (support/held_out_assets.py) and on held-out procedural objects
(bench/generator/generate_eval.py), on two seeds; prompt sensitivity on the real dielectric assets
(first seed); CPU seconds per generation. The table of defaults (``EnhancementType.guidance``) is,
per enhancement type, the value with the best mean PSNR on that type's procedural objects;
the real assets and the prompt sensitivity check it.

Writes docs/reports/generate_guidance.json and .png (PSNR against prompt sensitivity and
against CPU seconds, one point per guidance value).

    python -m bench.generator.generate_guidance [--guidance 1,1.25,1.5,2] [--objects 8] [--seeds 0,1] [--jobs 2]
"""
from __future__ import annotations

import argparse
import json
import multiprocessing
import time
from pathlib import Path

import numpy as np
import torch

from bench.common import REPORTS, pyplot, save_chart, write_report
from bench.generator.generate_eval import HeldOut, held_out, held_out_indices, render, scores
from bench.generator.generate_prompts import TARGET, prompt_pairs, real_prompts, sensitivity
from support.held_out_assets import real_held_out
from richmat_addon.core.enhancement_types import TYPES
from torch_models.generator import guidance_by_type
from torch_models.generator import generate as gen
from torch_models.generator.mesh_input import MeshInput
from torch_models.generator.train import GeneratorTrainConfig
from torch_models.neural import trained

_WORKER: dict = {}  # per worker process: the generator, its config and the objects, loaded once
PER_TYPE = "per type"  # the summary row of the chosen table (each object at its type's guidance)


def procedural_by_type(count: int, cfg: GeneratorTrainConfig) -> list[HeldOut]:
    """The first ``count`` held-out procedural objects of every enhancement type, in index order."""
    picked: dict[int, list[HeldOut]] = {t.index: [] for t in TYPES}
    for i in held_out_indices(100 * count * len(TYPES), cfg.corpus.seed):
        obj = held_out(i, cfg)
        if len(picked[obj.type]) < count:
            picked[obj.type].append(obj)
        if all(len(v) == count for v in picked.values()):
            break
    return [o for objs in picked.values() for o in objs]


def _load(checkpoint: Path, per_type: int) -> None:
    torch.set_num_threads(1)
    model, cfg = gen.load_generator(checkpoint)
    real = real_held_out(cfg)
    _WORKER.update(model=model, cfg=cfg, real=real, prompts=real_prompts(real, cfg.corpus.texture_size),
                   procedural=procedural_by_type(per_type, cfg))


def _generated(inp: MeshInput, prompt: str, seed: int, guidance: float, views: int, resolution: int, spp: int
               ) -> tuple[np.ndarray, int, float]:
    """Renders of one generation, the type it was generated as and its CPU seconds."""
    model, cfg = _WORKER["model"], _WORKER["cfg"]
    c0 = time.process_time()
    result = gen.generate(inp, prompt, model, cfg, seed, guidance=guidance, texture_size=cfg.corpus.texture_size)
    cpu = time.process_time() - c0
    return (render(inp, [m.latents for m in result.materials], views, resolution, spp,
                   [m.energy_scale for m in result.materials]), result.type, cpu)


def accuracy_task(task: tuple[str, int, list[float], list[int], int, int, int]) -> list[dict]:
    """One held-out object (``kind`` real or procedural) at every guidance value and seed."""
    kind, index, guidances, seeds, views, resolution, spp = task
    obj = _WORKER[kind][index]
    ref = render(obj.inp, obj.reference(_WORKER["cfg"].corpus.texture_size), views, resolution, spp)
    rows = []
    for g in guidances:
        for seed in seeds:
            img, type_, cpu = _generated(obj.inp, obj.prompt, seed, g, views, resolution, spp)
            rows.append({"kind": kind, "asset_id": obj.asset_id, "type": type_, "guidance": g, "seed": seed,
                         "cpu_seconds": cpu, **scores(ref, img)})
    print(f"{kind} {obj.asset_id} (Type {rows[0]['type']}): "
          + ", ".join(f"g {r['guidance']:g} s{r['seed']} {r['psnr']:.2f} dB" for r in rows), flush=True)
    return rows


def prompts_task(task: tuple[str, int, list[float], list[int], int, int, int, dict[int, float]]) -> list[dict]:
    """One real dielectric asset's prompt pairs (first seed) at every guidance value, and with each
    prompt at its type's guidance in ``table``."""
    _, index, guidances, seeds, views, resolution, spp, table = task
    asset_id, inp, prompts = _WORKER["prompts"][index]
    refs = [render(inp, p["reference"], views, resolution, spp) for p in prompts]
    outs = {g: [_generated(inp, p["prompt"], seeds[0], g, views, resolution, spp)[0] for p in prompts]
            for g in guidances}
    rows = [{"kind": "prompts", "asset_id": asset_id, "guidance": g, "pairs": prompt_pairs(refs, outs[g])}
            for g in guidances]
    per_type = [outs[table[p["type"]]][k] for k, p in enumerate(prompts)]
    rows.append({"kind": "prompts", "asset_id": asset_id, "guidance": PER_TYPE, "pairs": prompt_pairs(refs, per_type)})
    print(f"prompts {asset_id} done", flush=True)
    return rows


def _run(task: tuple) -> list[dict]:
    return prompts_task(task) if task[0] == "prompts" else accuracy_task(task)


def choose_table(rows: list[dict], guidances: list[float]) -> dict[int, float]:
    """Per enhancement type, the guidance with the best mean PSNR on its procedural objects."""
    return {t: guidances[int(np.argmax(psnrs))] for t, psnrs in per_type_psnr(rows, guidances).items()}


def at_table(rows: list[dict], table: dict[int, float]) -> list[dict]:
    """The accuracy rows each object would get at its type's guidance, relabelled ``PER_TYPE``."""
    return [{**r, "guidance": PER_TYPE} for r in rows
            if r["kind"] != "prompts" and r["guidance"] == table[r["type"]]]


def summarise(rows: list[dict], settings: list) -> list[dict]:
    """Per guidance setting: PSNR/FLIP means and minima per kind, prompt sensitivity, CPU seconds."""
    out = []
    for g in settings:
        entry: dict = {"guidance": g}
        for kind in ("real", "procedural"):
            mine = [r for r in rows if r["kind"] == kind and r["guidance"] == g]
            entry[kind] = {"psnr": float(np.mean([r["psnr"] for r in mine])),
                           "min_psnr": float(min(r["psnr"] for r in mine)),
                           "flip": float(np.mean([r["flip"] for r in mine])),
                           "objects_below_30": sorted({r["asset_id"] for r in mine if r["psnr"] < 30.0})}
        per_pair, ratio = sensitivity([r["pairs"] for r in rows if r["kind"] == "prompts" and r["guidance"] == g])
        entry["prompt_sensitivity"] = {"ratio": ratio, "per_pair": {k: v["ratio"] for k, v in per_pair.items()}}
        entry["median_cpu_seconds"] = float(np.median([r["cpu_seconds"] for r in rows
                                                       if r["guidance"] == g and "cpu_seconds" in r]))
        out.append(entry)
    return out


def per_type_psnr(rows: list[dict], guidances: list[float]) -> dict[int, list[float]]:
    """Mean procedural PSNR per type at each guidance value (the curves the table is read from)."""
    procedural = [r for r in rows if r["kind"] == "procedural" and r["guidance"] != PER_TYPE]
    return {t: [float(np.mean([r["psnr"] for r in procedural if r["type"] == t and r["guidance"] == g]))
                for g in guidances] for t in sorted({r["type"] for r in procedural})}


def chart(report: dict, path: Path) -> None:
    plt = pyplot()
    fig, (curves, left, right) = plt.subplots(1, 3, figsize=(16, 4.6))
    for t, psnrs in report["per_type_psnr"].items():
        curves.plot(report["guidances"], psnrs, "o-", label=f"Type {t}: chosen {report['table'][t]:g}")
    curves.set_xlabel("guidance")
    curves.set_ylabel("mean PSNR, procedural held-out (dB)")
    curves.set_title(f"{report['procedural_per_type']} objects per type x {len(report['seeds'])} seeds", fontsize=9)
    curves.legend(fontsize=7)
    rows = report["summary"]
    label = lambda s: f"g {s['guidance']:g}" if s["guidance"] != PER_TYPE else PER_TYPE
    for kind, colour in (("real", "tab:blue"), ("procedural", "tab:green")):
        ratio = [s["prompt_sensitivity"]["ratio"] for s in rows]
        left.plot(ratio, [s[kind]["psnr"] for s in rows], "o", color=colour, label=f"{kind}: mean")
        left.plot(ratio, [s[kind]["min_psnr"] for s in rows], "v", color=colour, alpha=0.6, label=f"{kind}: worst")
        right.plot([s["median_cpu_seconds"] for s in rows], [s[kind]["psnr"] for s in rows], "o", color=colour,
                   label=f"{kind}: mean")
    for s in rows:
        left.annotate(label(s), (s["prompt_sensitivity"]["ratio"], s["real"]["psnr"]),
                      textcoords="offset points", xytext=(4, 4), fontsize=8)
        left.annotate(label(s), (s["prompt_sensitivity"]["ratio"], s["real"]["min_psnr"]),
                      textcoords="offset points", xytext=(4, -10), fontsize=7)
        right.annotate(label(s), (s["median_cpu_seconds"], s["real"]["psnr"]),
                       textcoords="offset points", xytext=(4, 4), fontsize=8)
    left.axvline(TARGET, color="tab:red", ls="--", lw=1, label=f"sensitivity target {TARGET}")
    left.axhline(30, color="grey", ls=":", lw=1, label="30 dB")
    left.set_xlabel("prompt sensitivity (real dielectric assets)")
    left.set_ylabel("PSNR against the reference (dB)")
    left.legend(fontsize=7)
    right.set_xlabel("median CPU seconds per generation")
    right.set_ylabel("PSNR against the reference (dB)")
    right.legend(fontsize=7)
    fig.suptitle(f"classifier-free guidance, seeds {report['seeds']}: the per-type table is chosen on procedural "
                 "objects and checked on the real held-out assets", fontsize=10)
    save_chart(fig, path)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--guidance", default="1,1.5,2,2.5", help="comma-separated guidance values")
    ap.add_argument("--per-type", type=int, default=3, help="held-out procedural objects per enhancement type")
    ap.add_argument("--seeds", default="0,1")
    ap.add_argument("--checkpoint", type=Path, default=gen.SHIPPED)
    ap.add_argument("--eval-views", type=int, default=16, help="views rendered for the metrics")
    ap.add_argument("--jobs", type=int, default=2, help="worker processes (one thread each)")
    ap.add_argument("--out", type=Path, default=REPORTS / "generate_guidance.json")
    args = ap.parse_args()
    guidances = [float(g) for g in args.guidance.split(",")]
    seeds = [int(s) for s in args.seeds.split(",")]
    _load(args.checkpoint, args.per_type)
    with multiprocessing.get_context("fork").Pool(args.jobs) as pool:
        rows = [r for chunk in pool.imap_unordered(_run, [
            ("procedural", i, guidances, seeds, args.eval_views, 64, 16) for i in range(len(_WORKER["procedural"]))])
            for r in chunk]
        table = choose_table(rows, guidances)
        rows += [r for chunk in pool.imap_unordered(_run, [
            ("real", i, guidances, seeds, args.eval_views, 96, 16) for i in range(len(_WORKER["real"]))]
            + [("prompts", i, guidances, seeds, 8, 64, 16, table) for i in range(len(_WORKER["prompts"]))])
            for r in chunk]
    rows += at_table(rows, table)
    summary = summarise(rows, guidances + [PER_TYPE])
    report = {"guidances": guidances, "seeds": seeds, "procedural_per_type": args.per_type,
              "shipped": guidance_by_type(), "table": table,
              "target_sensitivity": TARGET, "per_type_psnr": per_type_psnr(rows, guidances),
              "summary": summary, "rows": rows}
    write_report(args.out, report, [trained.SHIPPED], args.checkpoint)
    chart(report, args.out.with_suffix(".png"))
    print(json.dumps({"table": table, "summary": summary}, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
