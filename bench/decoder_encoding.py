"""Decoder direction encoding against accuracy and speed, at equal training.

The paper fixes the decoder's size (4 x 64) but not how it sees the directions.
Each encoding of ``networks.DIRECTION_ENCODINGS`` gets a decoder of the shipped
size trained from scratch with one schedule against the shipped (frozen)
encoder, so every decoder reads the same latent space; each then fits the same
Table 1 materials (``--per-type`` per type, as bench/fit_flip.py draws them) and
is compared with the analytic reference on the ball, and timed.

    python -m bench.decoder_encoding [--steps N] [--batch B] [--per-type M] [--seed S] [--out FILE.json]
"""
from __future__ import annotations

import argparse
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from support.agreement_cases import cases
from bench.common import REPO, add_out_argument, pyplot, save_chart, target_lines, write_report
from bench.fit_speed import decoder_throughput
from richmat_addon.core.enhancement_types import TYPES
from torch_models.neural import weights
from torch_models.neural.evaluate import BallSetup, fit_and_compare
from torch_models.neural.networks import DIRECTION_ENCODINGS
from torch_models.neural.train import TrainConfig, Trainer

CPU_CONFIG = REPO / "torch_models" / "neural" / "configs" / "decoder_cpu.json"


def train(encoding: str, args: argparse.Namespace, out: Path) -> dict:
    """A decoder with this encoding against the shipped encoder; its loss history and seconds."""
    cfg = replace(TrainConfig.load(CPU_CONFIG), encoding=encoding, steps=args.steps, batch=args.batch,
                  energy_steps=0, sampler_steps=args.steps // 5, albedo_weight=0.1, threads=1,
                  init=str(weights.SHIPPED), init_networks=["encoder"], freeze_encoder=True,
                  checkpoint_every=max(args.steps // 8, 1), history=[])
    t0 = time.perf_counter()
    Trainer(cfg, out).run()
    return {"training_seconds": time.perf_counter() - t0,
            "loss_history": [(h["step"], h["loss"]) for h in cfg.history if h["phase"] == "decoder"]}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=4000, help="decoder training steps per encoding")
    parser.add_argument("--batch", type=int, default=8192)
    parser.add_argument("--per-type", type=int, default=10)
    parser.add_argument("--fit-steps", type=int, default=400)
    parser.add_argument("--seed", type=int, default=3)
    add_out_argument(parser, "decoder_encoding.json")
    args = parser.parse_args()

    drawn = cases(args.seed, args.per_type, 0)
    vectors = np.stack([c.vector() for c in drawn])
    colours = np.array([c.base_color for c in drawn], np.float32)
    types = np.array([int(c.name[4]) for c in drawn])
    setup = BallSetup.default(resolution=128, spp=64, seed=args.seed)
    rows = []
    with tempfile.TemporaryDirectory(prefix="richmat_decoder_encoding_") as tmp:
        for encoding in DIRECTION_ENCODINGS:
            row = {"encoding": encoding, "features": DIRECTION_ENCODINGS[encoding]}
            row.update(train(encoding, args, Path(tmp) / encoding))
            model = weights.load(Path(tmp) / encoding)
            results, _ = fit_and_compare(setup, model, vectors, colours, args.fit_steps)
            flips = np.array([r.flip for r in results])
            row["per_type"] = [{"type": t, "median": float(np.median(flips[types == t])),
                                "worst": float(flips[types == t].max())} for t in range(len(TYPES))]
            row["median_flip"], row["worst_flip"] = float(np.median(flips)), float(flips.max())
            row["evals_per_second"], row["flops_per_eval"] = decoder_throughput(model)
            rows.append(row)
            print(f"{encoding}: final loss {row['loss_history'][-1][1]:.4f}, median FLIP {row['median_flip']:.4f}, "
                  f"worst {row['worst_flip']:.4f}, {row['evals_per_second'] / 1e6:.2f} M evals/s", flush=True)
    report = {"seed": args.seed, "per_type": args.per_type, "steps": args.steps, "batch": args.batch,
              "fit_steps": args.fit_steps, "encodings": rows}
    write_report(args.out, report, [weights.SHIPPED])  # its encoder, frozen, under every decoder
    chart(report, args.out.with_suffix(".png"))


def chart(report: dict, path: Path) -> None:
    plt = pyplot()
    fig, axes = plt.subplots(1, 3, figsize=(14, 4))
    types = range(len(TYPES))
    for r in report["encodings"]:
        steps, loss = zip(*r["loss_history"])
        axes[0].plot(steps, loss, marker="o", ms=3, label=r["encoding"])
        line = axes[1].plot(types, [p["median"] for p in r["per_type"]], "o-", label=f"{r['encoding']} median")[0]
        axes[1].plot(types, [p["worst"] for p in r["per_type"]], "s:", color=line.get_color(),
                     label=f"{r['encoding']} worst")
        axes[2].scatter(r["evals_per_second"] / 1e6, r["median_flip"], color=line.get_color(), label=r["encoding"])
    axes[0].set(title="decoder loss (training)", xlabel="step", yscale="log")
    target_lines(axes[1], labelled=False)
    axes[1].set(title=f"FLIP per type ({report['per_type']} materials each, seed {report['seed']})",
                xlabel="type", ylabel="mean FLIP, neural vs analytic")
    axes[2].set(title="accuracy vs speed", xlabel="decoder evaluations per second (millions, one thread)",
                ylabel="median FLIP, all types")
    for ax in axes:
        ax.legend(fontsize=7)
    fig.suptitle(f"direction encodings, 4 x 64 decoders, {report['steps']} steps x {report['batch']} each, "
                 "shipped encoder frozen", fontsize=10)
    save_chart(fig, path)


if __name__ == "__main__":
    main()
