"""Generator speed against accuracy: sampling steps, views and samples vs PSNR vs seconds per object (issue 6, item 6).

Three sweeps: the number of sampling steps at 8 views (the training views), the
number of views at 18 Heun steps, and the number of samples averaged (``generate``'s
``samples``) at 18 steps and 12 views; ``--sweeps`` picks which run. For each
setting every held-out object is generated once per seed (PSNR against its reference
over 16 orbit views, as bench/generator/generate_eval.py measures it; the mean over objects and
seeds) and timed end to end (prior, condition views, sampling, projection; not the
energy guard, whose cost depends on the texture's distinct latents rather than on
these settings and which bench/generator/generate_eval.py times), one thread; seconds are the
median over objects and seeds, as CPU time of this process (the machine is shared,
and one thread's CPU time is what it takes on an idle core) and as wall time. The
suggested default is the fastest setting within 0.5 dB of the best mean PSNR.
Averaging samples only pays where one draw's spread is what costs accuracy, which
a single seed can hide: measure it over several (``--seeds 0,1``).

    python -m bench.generator.generate_speed [--objects N] [--seeds 0,1] [--sweeps steps,views,samples] [--out FILE]
"""
from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
import torch

from bench.common import add_out_argument, pyplot, save_chart, write_report
from bench.generator.generate_eval import held_out, held_out_indices, latents_of, psnr, render
from torch_models.generator import generate as gen
from torch_models.neural import trained

STEPS = (2, 4, 8, 18, 32)
VIEWS = (4, 8, 12, 16)
SAMPLES = (1, 2, 4, 8)
# The steps and views sweeps cross here (the default before this bench).
CENTRE = {"steps": 18, "views": 8, "samples": 1}
SAMPLES_AT = {"steps": 18, "views": 12}  # the samples sweep runs at the steps and views chosen by the other two
SWEEP_AXES = (("steps", {"views": CENTRE["views"], "samples": 1}, STEPS),  # (swept key, fixed keys, values)
              ("views", {"steps": CENTRE["steps"], "samples": 1}, VIEWS),
              ("samples", SAMPLES_AT, SAMPLES))
TOLERANCE_DB = 0.5
SWEEPS = ("steps", "views", "samples")


def settings(sweeps: list[str]) -> list[dict[str, int]]:
    """The settings of the named sweeps, each once (the sweeps share their crossing points)."""
    if unknown := set(sweeps) - set(SWEEPS):
        raise SystemExit(f"unknown sweep(s): {', '.join(sorted(unknown))} (choose from {', '.join(SWEEPS)})")
    out: list[dict[str, int]] = []
    for key, fixed, values in SWEEP_AXES:
        if key in sweeps:
            out += [s for s in ({**fixed, key: v} for v in values) if s not in out]
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--checkpoint", type=Path, default=gen.SHIPPED)
    ap.add_argument("--objects", type=int, default=8)
    ap.add_argument("--seeds", default="0", help="sampling seeds, comma-separated (default: 0)")
    ap.add_argument("--sweeps", default=",".join(SWEEPS), help=f"which sweeps (default: {','.join(SWEEPS)})")
    ap.add_argument("--eval-views", type=int, default=16)
    ap.add_argument("--resolution", type=int, default=64)
    ap.add_argument("--spp", type=int, default=8)
    add_out_argument(ap, "generate_speed.json")
    args = ap.parse_args()
    torch.set_num_threads(1)
    model, cfg = gen.load_generator(args.checkpoint)
    objects = [held_out(i, cfg) for i in held_out_indices(args.objects, cfg.corpus.seed)]
    size = cfg.corpus.texture_size
    references = [render(o.inp, latents_of(o.material, size), args.eval_views, args.resolution, args.spp)
                  for o in objects]
    seeds = [int(s) for s in args.seeds.split(",")]
    rows = []
    for setting in settings(args.sweeps.split(",")):
        seconds, wall, scores = [], [], {str(seed): [] for seed in seeds}
        for seed in seeds:
            for obj, reference in zip(objects, references):
                t0, c0 = time.perf_counter(), time.process_time()
                result = gen.generate(obj.inp, obj.prompt, model, cfg, seed, setting["steps"], setting["views"],
                                      texture_size=size, guard_energy=False, samples=setting["samples"])
                seconds.append(time.process_time() - c0)
                wall.append(time.perf_counter() - t0)
                image = render(obj.inp, result.latents, args.eval_views, args.resolution, args.spp)
                scores[str(seed)].append(psnr(reference, image, reference.sum(-1) > 0))
        rows.append({**setting, "psnr": float(np.mean(list(scores.values()))),
                     "psnr_per_seed": {s: float(np.mean(v)) for s, v in scores.items()},
                     "psnr_per_object": scores, "median_seconds": float(np.median(seconds)), "seconds": seconds,
                     "median_wall_seconds": float(np.median(wall))})
        print(f"{setting}: {rows[-1]['psnr']:.2f} dB, {rows[-1]['median_seconds']:.1f} s/object", flush=True)
    best = max(r["psnr"] for r in rows)
    chosen = min((r for r in rows if r["psnr"] >= best - TOLERANCE_DB), key=lambda r: r["median_seconds"])
    report = {"checkpoint": str(args.checkpoint), "objects": [o.asset.asset_id for o in objects],
              "seeds": seeds, "threads": 1, "eval_views": args.eval_views, "tolerance_db": TOLERANCE_DB,
              "chosen": {k: chosen[k] for k in CENTRE}, "rows": rows}
    write_report(args.out, report, [trained.SHIPPED], args.checkpoint)
    plot(report, args.out.with_suffix(".png"))
    print(f"chosen default: {report['chosen']}")
    return 0


def plot(report: dict, path: Path) -> None:
    plt = pyplot()
    rows = report["rows"]
    fig, ax = plt.subplots(figsize=(6.4, 3.8))
    for (key, fixed, _), marker in zip(SWEEP_AXES, ("o-", "s--", "^:")):
        sweep = sorted((r for r in rows if all(r[k] == v for k, v in fixed.items())), key=lambda r: r[key])
        if len(sweep) < 2:
            continue
        ax.plot([r["median_seconds"] for r in sweep], [r["psnr"] for r in sweep], marker,
                label=f"{key} ({', '.join(f'{k} = {v}' for k, v in fixed.items())})")
        for r in sweep:
            ax.annotate(str(r[key]), (r["median_seconds"], r["psnr"]), fontsize=7, xytext=(3, 3),
                        textcoords="offset points")
        if len(report.get("seeds", [])) > 1:  # each seed's mean beside the mean over seeds: their spread
            colour = ax.lines[-1].get_color()
            for seed in report["seeds"]:
                ax.plot([r["median_seconds"] for r in sweep], [r["psnr_per_seed"][str(seed)] for r in sweep],
                        marker[0], ms=4, alpha=0.4, color=colour,
                        label=f"{key}, one seed each" if seed == report["seeds"][0] else None)
    chosen = next(r for r in rows if all(r[k] == v for k, v in report["chosen"].items()))
    ax.plot([chosen["median_seconds"]], [chosen["psnr"]], "r*", ms=12, label="chosen default")
    ax.set_xlabel("CPU seconds per object (median, 1 thread)")
    ax.set_ylabel("PSNR vs reference (dB)")
    seeds = ", ".join(map(str, report.get("seeds", [0])))
    ax.set_title(f"generator: steps, views and samples vs accuracy vs time (seed {seeds})", fontsize=10)
    ax.legend(fontsize=8)
    save_chart(fig, path)


if __name__ == "__main__":
    raise SystemExit(main())
