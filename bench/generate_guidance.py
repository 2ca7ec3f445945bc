"""How hard to push towards the prompt: classifier-free guidance against accuracy, prompt
sensitivity and speed.

Guidance scales the step from the unconditional denoiser to the prompted one. More of it
pulls the materials of different prompts further apart (prompt sensitivity,
bench/generate_prompts.py) but can overshoot the residual the caption calls for, which
costs PSNR against the reference; guidance 1 is the prompted model alone and needs no
unconditional pass, so it samples in half the time. For each guidance value, on the same
inputs and seeds: PSNR and FLIP of the generation against its reference on the real
assets the corpus holds out (bench/held_out_assets.py) and on held-out procedural objects
(bench/generate_eval.py), on two seeds; prompt sensitivity on the real dielectric assets
(first seed); CPU seconds per generation. The default (``DEFAULT_GUIDANCE``) is the most
accurate value on the real assets whose prompt sensitivity meets the issue's 0.7.

Writes docs/reports/generate_guidance.json and .png (PSNR against prompt sensitivity and
against CPU seconds, one point per guidance value).

    python -m bench.generate_guidance [--guidance 1,1.25,1.5,2] [--objects 8] [--seeds 0,1] [--jobs 2]
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
from bench.generate_eval import held_out, held_out_indices, psnr, render
from bench.generate_prompts import TARGET, prompt_pairs, real_prompts, sensitivity
from bench.held_out_assets import real_held_out
from torch_models.generator import DEFAULT_GUIDANCE
from torch_models.generator import generate as gen
from torch_models.neural import weights
from torch_models.render.flip import mean_flip

_WORKER: dict = {}  # per worker process: the generator, its config and the objects, loaded once


def _load(checkpoint: Path, objects: int) -> None:
    torch.set_num_threads(1)
    model, cfg = gen.load_generator(checkpoint)
    _WORKER.update(model=model, cfg=cfg, real=real_held_out(cfg), prompts=real_prompts(cfg),
                   procedural=[held_out(i, cfg) for i in held_out_indices(objects, cfg.corpus.seed)])


def _generated(inp, prompt: str, seed: int, guidance: float, views: int, resolution: int, spp: int
               ) -> tuple[np.ndarray, float]:
    """Renders of one generation and its CPU seconds."""
    model, cfg = _WORKER["model"], _WORKER["cfg"]
    c0 = time.process_time()
    result = gen.generate(inp, prompt, model, cfg, seed, guidance=guidance, texture_size=cfg.corpus.texture_size)
    cpu = time.process_time() - c0
    return render(inp, [m.latents for m in result.materials], views, resolution, spp,
                  [m.energy_scale for m in result.materials]), cpu


def accuracy_task(task: tuple[str, int, list[float], list[int], int, int, int]) -> list[dict]:
    """One held-out object (``kind`` real or procedural) at every guidance value and seed."""
    kind, index, guidances, seeds, views, resolution, spp = task
    obj = _WORKER[kind][index]
    ref = render(obj.inp, obj.reference(_WORKER["cfg"].corpus.texture_size), views, resolution, spp)
    mask = ref.sum(-1) > 0
    rows = []
    for g in guidances:
        for seed in seeds:
            img, cpu = _generated(obj.inp, obj.prompt, seed, g, views, resolution, spp)
            rows.append({"kind": kind, "asset_id": obj.asset_id, "guidance": g, "seed": seed, "cpu_seconds": cpu,
                         "psnr": psnr(ref, img, mask),
                         "flip": float(np.mean([mean_flip(r, t) for r, t in zip(ref, img)]))})
    print(f"{kind} {obj.asset_id}: " + ", ".join(f"g {r['guidance']:g} s{r['seed']} {r['psnr']:.2f} dB"
                                                 for r in rows), flush=True)
    return rows


def prompts_task(task: tuple[str, int, list[float], list[int], int, int, int]) -> list[dict]:
    """One real dielectric asset's prompt pairs at every guidance value (first seed)."""
    _, index, guidances, seeds, views, resolution, spp = task
    asset_id, inp, prompts = _WORKER["prompts"][index]
    refs = [render(inp, p["reference"], views, resolution, spp) for p in prompts]
    rows = []
    for g in guidances:
        outs = [_generated(inp, p["prompt"], seeds[0], g, views, resolution, spp)[0] for p in prompts]
        rows.append({"kind": "prompts", "asset_id": asset_id, "guidance": g, "pairs": prompt_pairs(refs, outs)})
    print(f"prompts {asset_id} done", flush=True)
    return rows


def _run(task: tuple) -> list[dict]:
    return prompts_task(task) if task[0] == "prompts" else accuracy_task(task)


def summarise(rows: list[dict], guidances: list[float]) -> list[dict]:
    """Per guidance value: PSNR/FLIP means and minima per kind, prompt sensitivity, CPU seconds."""
    out = []
    for g in guidances:
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


def choose(summary: list[dict]) -> float | None:
    """The guidance with the best mean real-asset PSNR among those meeting the sensitivity target."""
    ok = [s for s in summary if s["prompt_sensitivity"]["ratio"] >= TARGET]
    return max(ok, key=lambda s: s["real"]["psnr"])["guidance"] if ok else None


def chart(report: dict, path: Path) -> None:
    plt = pyplot()
    fig, (left, right) = plt.subplots(1, 2, figsize=(11, 4.2))
    rows = report["summary"]
    for kind, colour in (("real", "tab:blue"), ("procedural", "tab:green")):
        ratio = [s["prompt_sensitivity"]["ratio"] for s in rows]
        left.plot(ratio, [s[kind]["psnr"] for s in rows], "o-", color=colour, label=f"{kind}: mean")
        left.plot(ratio, [s[kind]["min_psnr"] for s in rows], "v--", color=colour, alpha=0.6, label=f"{kind}: worst")
        right.plot([s["median_cpu_seconds"] for s in rows], [s[kind]["psnr"] for s in rows], "o-", color=colour,
                   label=f"{kind}: mean")
    for s in rows:
        left.annotate(f"g {s['guidance']:g}", (s["prompt_sensitivity"]["ratio"], s["real"]["psnr"]),
                      textcoords="offset points", xytext=(4, 4), fontsize=8)
        right.annotate(f"g {s['guidance']:g}", (s["median_cpu_seconds"], s["real"]["psnr"]),
                       textcoords="offset points", xytext=(4, 4), fontsize=8)
    left.axvline(TARGET, color="tab:red", ls="--", lw=1, label=f"sensitivity target {TARGET}")
    left.axhline(30, color="grey", ls=":", lw=1, label="30 dB")
    left.set_xlabel("prompt sensitivity (real dielectric assets)")
    left.set_ylabel("PSNR against the reference (dB)")
    left.legend(fontsize=7)
    right.set_xlabel("median CPU seconds per generation")
    right.set_ylabel("PSNR against the reference (dB)")
    right.legend(fontsize=7)
    fig.suptitle(f"classifier-free guidance: seeds {report['seeds']}; chosen {report['chosen']}", fontsize=10)
    save_chart(fig, path)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--guidance", default="1,1.25,1.5,2", help="comma-separated guidance values")
    ap.add_argument("--objects", type=int, default=8, help="held-out procedural objects")
    ap.add_argument("--seeds", default="0,1")
    ap.add_argument("--checkpoint", type=Path, default=gen.SHIPPED)
    ap.add_argument("--eval-views", type=int, default=16, help="views rendered for the metrics")
    ap.add_argument("--jobs", type=int, default=2, help="worker processes (one thread each)")
    ap.add_argument("--out", type=Path, default=REPORTS / "generate_guidance.json")
    args = ap.parse_args()
    guidances = [float(g) for g in args.guidance.split(",")]
    seeds = [int(s) for s in args.seeds.split(",")]
    _load(args.checkpoint, args.objects)
    tasks = ([("real", i, guidances, seeds, args.eval_views, 96, 16) for i in range(len(_WORKER["real"]))]
             + [("prompts", i, guidances, seeds, 8, 64, 16) for i in range(len(_WORKER["prompts"]))]
             + [("procedural", i, guidances, seeds, args.eval_views, 64, 16) for i in range(args.objects)])
    with multiprocessing.get_context("fork").Pool(args.jobs) as pool:
        rows = [r for chunk in pool.imap_unordered(_run, tasks) for r in chunk]
    summary = summarise(rows, guidances)
    report = {"guidances": guidances, "seeds": seeds, "procedural_objects": args.objects,
              "shipped_default": DEFAULT_GUIDANCE, "chosen": choose(summary), "target_sensitivity": TARGET,
              "summary": summary, "rows": rows}
    write_report(args.out, report, [weights.SHIPPED], args.checkpoint)
    chart(report, args.out.with_suffix(".png"))
    print(json.dumps({"chosen": report["chosen"], "summary": summary}, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
