"""Generator speed against accuracy: sampling steps and views vs PSNR vs seconds per object (issue 6, item 6).

Two sweeps around 18 Heun steps and 8 views (the training views): the number of sampling
steps at 8 views, and the number of views at the default steps. For each
setting every held-out object is generated once (PSNR against its reference over
16 orbit views, as bench/generate_eval.py measures it) and timed end to end
(prior, condition views, sampling, projection; not the energy guard, whose cost
depends on the texture's distinct latents rather than on steps or views and which
bench/generate_eval.py times), one thread; seconds are the median
over the objects, as CPU time of this process (the machine is shared, and one
thread's CPU time is what it takes on an idle core) and as wall time. The
suggested default is the fastest setting within 0.5 dB of the best mean PSNR.

    .venv/bin/python bench/generate_speed.py [--objects N] [--checkpoint DIR]
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np
import torch

REPO = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(REPO), str(REPO / "bench")]

from generate_eval import held_out, held_out_indices, latents_of, psnr, render  # noqa: E402
from torch_models.generator import generate as gen  # noqa: E402

STEPS = (2, 4, 8, 18, 32)
VIEWS = (4, 8, 12, 16)
CENTRE = {"steps": 18, "views": 8}  # the sweeps cross here (the default before this bench)
TOLERANCE_DB = 0.5


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--checkpoint", type=Path, default=gen.SHIPPED)
    ap.add_argument("--objects", type=int, default=8)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--eval-views", type=int, default=16)
    ap.add_argument("--resolution", type=int, default=64)
    ap.add_argument("--spp", type=int, default=8)
    ap.add_argument("--out", type=Path, default=REPO / "docs" / "generate_speed.json")
    args = ap.parse_args()
    torch.set_num_threads(1)
    model, cfg = gen.load_generator(args.checkpoint)
    objects = [held_out(i, cfg) for i in held_out_indices(args.objects, cfg.corpus.seed)]
    size = cfg.corpus.texture_size
    references = [render(o.inp, latents_of(o.material, size), args.eval_views, args.resolution, args.spp)
                  for o in objects]
    settings = [{"steps": s, "views": CENTRE["views"]} for s in STEPS]
    settings += [{"steps": CENTRE["steps"], "views": v} for v in VIEWS if v != CENTRE["views"]]
    rows = []
    for setting in settings:
        seconds, wall, scores = [], [], []
        for obj, reference in zip(objects, references):
            t0, c0 = time.perf_counter(), time.process_time()
            result = gen.generate(obj.inp, obj.prompt, model, cfg, args.seed, setting["steps"], setting["views"],
                                  texture_size=size, guard_energy=False)
            seconds.append(time.process_time() - c0)
            wall.append(time.perf_counter() - t0)
            image = render(obj.inp, result.latents, args.eval_views, args.resolution, args.spp)
            scores.append(psnr(reference, image, reference.sum(-1) > 0))
        rows.append({**setting, "psnr": float(np.mean(scores)), "psnr_per_object": scores,
                     "median_seconds": float(np.median(seconds)), "seconds": seconds,
                     "median_wall_seconds": float(np.median(wall))})
        print(f"{setting}: {rows[-1]['psnr']:.2f} dB, {rows[-1]['median_seconds']:.1f} s/object", flush=True)
    best = max(r["psnr"] for r in rows)
    chosen = min((r for r in rows if r["psnr"] >= best - TOLERANCE_DB), key=lambda r: r["median_seconds"])
    report = {"checkpoint": str(args.checkpoint), "objects": [o.asset.asset_id for o in objects],
              "threads": 1, "eval_views": args.eval_views, "tolerance_db": TOLERANCE_DB,
              "chosen": {"steps": chosen["steps"], "views": chosen["views"]}, "rows": rows}
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(report, indent=1))
    plot(report, args.out.with_suffix(".png"))
    print(f"chosen default: {report['chosen']}")
    return 0


def plot(report: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = report["rows"]
    fig, ax = plt.subplots(figsize=(6.4, 3.8))
    sweeps = (("steps", ("views", CENTRE["views"]), "o-"), ("views", ("steps", CENTRE["steps"]), "s--"))
    for key, fixed, marker in sweeps:
        sweep = sorted((r for r in rows if r[fixed[0]] == fixed[1]), key=lambda r: r[key])
        ax.plot([r["median_seconds"] for r in sweep], [r["psnr"] for r in sweep], marker,
                label=f"{key} ({fixed[0]} = {fixed[1]})")
        for r in sweep:
            ax.annotate(str(r[key]), (r["median_seconds"], r["psnr"]), fontsize=7, xytext=(3, 3),
                        textcoords="offset points")
    chosen = next(r for r in rows if (r["steps"], r["views"]) == tuple(report["chosen"].values()))
    ax.plot([chosen["median_seconds"]], [chosen["psnr"]], "r*", ms=12, label="chosen default")
    ax.set_xlabel("CPU seconds per object (median, 1 thread)")
    ax.set_ylabel("PSNR vs reference (dB)")
    ax.set_title("generator: sampling steps and views vs accuracy vs time", fontsize=10)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


if __name__ == "__main__":
    raise SystemExit(main())
