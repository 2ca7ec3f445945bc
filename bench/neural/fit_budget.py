"""A texel's fit against the number of vectors fitted with it: the shared budget and the per-vector one.

One sample asset's material is enhanced at its textures' own size (as
bench/neural/fit_full_size.py does) and fitted at each cluster step of ``--sweep``, so that
the same texels are fitted among fewer or more unique vectors. Each fit runs twice on
the same vectors: with the old budget (``FIT_BATCH`` samples a step shared by all
vectors, ``per_vector=0``) and with today's (at least ``SAMPLES_PER_VECTOR`` a vector
and step). Accuracy is the fitting loss on held-out directions
(``fit.latents.held_out_loss``) of ``--texels`` random texels' own vectors under their
representatives' latents, so clustering's error counts as well as the fit's. CPU
seconds of each fit are recorded with one thread.

    python -m bench.neural.fit_budget [--asset WaterBottle] [--material BottleMat] [--sweep 32 64 128 256]
"""
from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np
import torch

from bench.common import add_out_argument, pyplot, save_chart, write_report
from bench.neural.fit_full_size import ADDON_FIT_STEPS, enhance_asset
from richmat_addon.core.texel_vectors import texel_matrix
from torch_models.neural import trained
from torch_models.neural.fit.latents import FIT_BATCH, SAMPLES_PER_VECTOR, fit_latents, held_out_loss
from torch_models.neural.fit.material_vectors import read_vectors

BUDGETS = {"shared": 0, "per vector": SAMPLES_PER_VECTOR}  # fit_latents' per_vector


def sweep(model: trained.NeuralModel, folder: Path, steps: list[int], texels: int, fit_steps: int) -> list[dict]:
    """Per cluster step 1/N and budget: vectors fitted, CPU seconds, held-out loss of the sampled texels."""
    _, vectors = texel_matrix(folder)
    rows = np.random.default_rng(0).choice(len(vectors), texels, replace=False)
    out = []
    for n in steps:
        mv = read_vectors(folder, 1 / n)
        for budget, per_vector in BUDGETS.items():
            t0 = time.process_time()
            z = fit_latents(model, mv.unique, fit_steps, per_vector=per_vector)
            cpu = time.process_time() - t0
            loss = held_out_loss(model, vectors[rows], z[torch.from_numpy(mv.inverse[rows])])
            out.append({"cluster_step": f"1/{n}", "vectors": len(mv.unique), "budget": budget,
                        "per_vector": per_vector, "fit_cpu_seconds": cpu, "held_out_loss": loss})
            print(f"1/{n}: {len(mv.unique)} vectors, {budget}: loss {loss:.4f}, {cpu:.1f} CPU s", flush=True)
    return out


def chart(report: dict, path: Path) -> None:
    """Held-out loss and fit CPU seconds against the vectors fitted, one line per budget."""
    plt = pyplot()
    fig, (a, b) = plt.subplots(1, 2, figsize=(11, 4.2))
    for budget in BUDGETS:
        rows = sorted((r for r in report["fits"] if r["budget"] == budget), key=lambda r: r["vectors"])
        x = [r["vectors"] for r in rows]
        line, = a.plot(x, [r["held_out_loss"] for r in rows], "o-", label=budget)
        b.plot(x, [r["fit_cpu_seconds"] for r in rows], "o-", label=budget, color=line.get_color())
        for r in rows:
            a.annotate(r["cluster_step"], (r["vectors"], r["held_out_loss"]), textcoords="offset points",
                       xytext=(4, 4), fontsize=7, color=line.get_color())
    for ax in (a, b):
        ax.set_xscale("log")
        ax.set_xlabel("unique vectors fitted (cluster step beside each point)")
        ax.legend(fontsize=8)
    a.set_ylabel(f"held-out fitting loss of {report['texels']} texels")
    b.set_ylabel("fit CPU seconds (one thread)")
    fig.suptitle(f"{report['asset']}/{report['material']}, {report['fit_steps']} steps: {FIT_BATCH} samples a step "
                 f"shared, or at least {SAMPLES_PER_VECTOR} per vector", fontsize=9)
    save_chart(fig, path)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--asset", default="WaterBottle")
    parser.add_argument("--material", default="BottleMat")
    parser.add_argument("--type", default="2", help="enhancement type (default: 2, as bench/neural/fit_full_size.py)")
    parser.add_argument("--sweep", type=int, nargs="+", default=[32, 64, 128, 256], help="cluster steps 1/N")
    parser.add_argument("--texels", type=int, default=512, help="texels whose held-out loss is measured")
    parser.add_argument("--steps", type=int, default=ADDON_FIT_STEPS)
    add_out_argument(parser, "fit_budget.json")
    args = parser.parse_args()
    torch.set_num_threads(1)
    model = trained.load(trained.SHIPPED)
    with tempfile.TemporaryDirectory(prefix="richmat_fit_budget_") as tmp:
        enhance_asset(args.asset, args.type, Path(tmp))
        fits = sweep(model, Path(tmp) / args.material, args.sweep, args.texels, args.steps)
    report = {"asset": args.asset, "material": args.material, "type": args.type, "fit_steps": args.steps,
              "texels": args.texels, "fit_batch": FIT_BATCH, "samples_per_vector": SAMPLES_PER_VECTOR,
              "threads": 1, "fits": fits}
    write_report(args.out, report, [trained.SHIPPED])
    chart(report, args.out.with_suffix(".png"))


if __name__ == "__main__":
    main()
