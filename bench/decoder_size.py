"""Decoder width and depth against accuracy and speed.

Decoders of several sizes are trained with one short schedule (the CPU
config's data and rates, fewer steps, no energy phase), then each fits the same
random materials (2 per type by default) and is compared with the analytic
reference on the ball (median FLIP), and timed (evaluations per second,
batch 65536). The shipped decoder (the paper's 4 x 64, full schedule) is
measured alongside, so the chart shows both what size buys at equal training
and what the longer schedule adds.

    python -m bench.decoder_size [--steps N] [--batch B] [--per-type M] [--seed S] [--out FILE.json]
"""
from __future__ import annotations

import argparse
import json
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from support.agreement_cases import cases
from bench.common import REPO, add_out_argument, pyplot, save_chart, write_report
from bench.fit_speed import decoder_throughput
from torch_models.neural import weights
from torch_models.neural.evaluate import BallSetup, fit_and_compare
from torch_models.neural.train import TrainConfig, Trainer

SIZES = ((2, 16), (2, 32), (3, 64), (4, 64), (4, 128))  # (depth, width)
CPU_CONFIG = REPO / "torch_models" / "neural" / "configs" / "decoder_cpu.json"


def measure(model: weights.NeuralModel, setup: BallSetup, vectors: np.ndarray, colours: np.ndarray,
            fit_steps: int) -> dict:
    results, _ = fit_and_compare(setup, model, vectors, colours, fit_steps)
    flips = [r.flip for r in results]
    evals, flops = decoder_throughput(model)
    params = sum(p.numel() for p in model.decoder.parameters())
    return {"median_flip": float(np.median(flips)), "worst_flip": float(max(flips)),
            "evals_per_second": evals, "flops_per_eval": flops, "parameters": params}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=4000, help="training steps per size (default: 4000)")
    parser.add_argument("--batch", type=int, default=4096, help="training batch per size (default: 4096)")
    parser.add_argument("--per-type", type=int, default=2)
    parser.add_argument("--fit-steps", type=int, default=300)
    parser.add_argument("--seed", type=int, default=0)
    add_out_argument(parser, "decoder_size.json")
    args = parser.parse_args()

    drawn = cases(args.seed + 11, args.per_type, 0)
    vectors = np.stack([c.vector() for c in drawn])
    colours = np.array([c.base_color for c in drawn], np.float32)
    setup = BallSetup.default(resolution=96, spp=32, seed=args.seed)
    base = TrainConfig.load(CPU_CONFIG)
    rows = []
    with tempfile.TemporaryDirectory(prefix="richmat_decoder_size_") as tmp:
        for depth, width in SIZES:
            cfg = replace(base, depth=depth, width=width, steps=args.steps, batch=args.batch, energy_steps=0,
                          sampler_steps=args.steps // 5, checkpoint_every=10 ** 9, history=[])
            t0 = time.perf_counter()
            Trainer(cfg, Path(tmp) / f"{depth}x{width}").run()
            row = {"depth": depth, "width": width, "training_steps": args.steps, "training_batch": args.batch,
                   "training_seconds": time.perf_counter() - t0}
            row.update(measure(weights.load(Path(tmp) / f"{depth}x{width}"), setup, vectors, colours, args.fit_steps))
            rows.append(row)
            print(f"{depth} x {width:3d}: median FLIP {row['median_flip']:.4f}, "
                  f"{row['evals_per_second'] / 1e6:.2f} M evals/s", flush=True)
    shipped = weights.load()
    state = json.loads((weights.SHIPPED / "state.json").read_text())["config"]
    ship = {"depth": shipped.decoder.depth, "width": shipped.decoder.width, "training_steps": state["steps"],
            "training_batch": state["batch"]}
    ship.update(measure(shipped, setup, vectors, colours, args.fit_steps))
    report = {"seed": args.seed, "materials": len(drawn), "fit_steps": args.fit_steps, "sizes": rows,
              "shipped": ship}
    write_report(args.out, report, [weights.SHIPPED])
    chart(report, args.out.with_suffix(".png"))


def chart(report: dict, path: Path) -> None:
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(7, 4.2))
    for r in report["sizes"]:
        ax.scatter(r["evals_per_second"] / 1e6, r["median_flip"], color="tab:blue")
        ax.annotate(f"{r['depth']}x{r['width']}", (r["evals_per_second"] / 1e6, r["median_flip"]), fontsize=8)
    s = report["shipped"]
    ax.scatter(s["evals_per_second"] / 1e6, s["median_flip"], color="tab:red", marker="*", s=120,
               label=f"shipped {s['depth']}x{s['width']}, {s['training_steps']} steps")
    ax.set_xlabel("decoder evaluations per second (millions, CPU)")
    ax.set_ylabel(f"median FLIP over {report['materials']} materials")
    first = report["sizes"][0]
    ax.set_title(f"decoder size: blue = {first['training_steps']} steps x {first['training_batch']} samples each")
    ax.legend(fontsize=8)
    save_chart(fig, path)


if __name__ == "__main__":
    main()
