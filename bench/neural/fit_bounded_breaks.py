"""Where the bounded fit breaks: a material with more distinct looks than the budget.

A photo scan holds hundreds of thousands of distinct vectors but few looks (a wood's
grain is one material at many nearby points), so a few hundred representatives serve it
(``fit_bounded.json``). A texture atlas of unrelated materials is the other extreme: every
vector a look of its own. This bench builds such a mosaic: ``L`` parameter vectors drawn
from the decoder's training distribution (``data.parameter_vectors``), each covering the
same share of a texture, for each ``L`` of ``--looks``, and fits it

- **bounded** at each ``--budgets`` as ``fit_material`` does (past the budget, k-means
  representatives in the encoder's latent space, each look taking its representative's
  latent; up to it, every look fitted in the shared batch);
- **per vector**, every look with its own 4 samples a step (the fit of every vector, as among
  a texture's tens of thousands), measured on the probe's looks only: each look's fit does
  not depend on the others'.

Accuracy is the fit error (the add-on's measure, ``neural/fit/error.py``) of up to 512 looks drawn
at random, each under the latent its design gives it: mean and 90th percentile (a merged
look is wrong everywhere it shows). One thread, 300 steps.

    python -m bench.neural.fit_bounded_breaks [--looks 64 256 1024 4096 16384] [--budgets 256 1024 4096]
        [--seed 0] [--out docs/reports/fit_bounded_breaks.json]
"""
from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import torch

from bench.common import add_out_argument, pyplot, save_chart, write_report
from bench.neural.fit_bounded import STEPS, cpu
from richmat_addon.core.texel_vectors import FIT_BUDGET
from torch_models.neural import trained
from torch_models.neural.data import parameter_vectors
from torch_models.neural.fit import representatives
from torch_models.neural.fit.error import vector_errors
from torch_models.neural.fit.latents import fit_latents
from torch_models.neural.model import NeuralModel

PROBE = 512
TEXELS = 1 << 20  # a 1k texture: each look's weight is its share of it


def errors(model: NeuralModel, vectors: np.ndarray, z: torch.Tensor, seed: int) -> dict:
    """Mean and 90th percentile of the fit error of ``vectors`` under latents ``z``."""
    e = vector_errors(model, vectors, z, torch.ones(len(vectors)), seed)
    return {"mean_error": float(np.mean(e)), "p90_error": float(np.percentile(e, 90))}


def bounded(model: NeuralModel, looks: np.ndarray, probe: np.ndarray, budget: int, seed: int) -> dict:
    """The shipped fit's path at ``budget``: representatives past it, every look up to it."""
    if len(looks) <= budget:
        z, fit = cpu(lambda: fit_latents(model, looks, STEPS, seed=seed))
        return {"fit_cpu": fit, "choose_cpu": 0.0, "vectors_fitted": len(looks),
                **errors(model, looks[probe], z[probe], seed)}
    counts = np.full(len(looks), TEXELS / len(looks))
    reps, choose = cpu(lambda: representatives.choose(model, looks, counts, budget, seed))
    z, fit = cpu(lambda: fit_latents(model, reps.vectors, STEPS, seed=seed))
    given = representatives.transfer(model, looks, reps, z, "nearest")
    return {"fit_cpu": fit, "choose_cpu": choose, "vectors_fitted": len(reps),
            **errors(model, looks[probe], given[probe], seed)}


def per_vector(model: NeuralModel, looks: np.ndarray, probe: np.ndarray, seed: int) -> dict:
    """Every look fitted with its own 4 samples a step, priced per look."""
    z, seconds = cpu(lambda: fit_latents(model, looks[probe], STEPS, batch=1, seed=seed))
    return {"fit_cpu": seconds / len(probe) * len(looks), "extrapolated": True, "vectors_fitted": len(looks),
            **errors(model, looks[probe], z, seed)}


def measure(model: NeuralModel, count: int, budgets: list[int], seed: int) -> dict:
    rng = np.random.default_rng(seed)
    looks = parameter_vectors(count, rng).astype(np.float32)
    probe = np.sort(rng.choice(count, min(PROBE, count), replace=False))
    rows = {"per vector": per_vector(model, looks, probe, seed)}
    for budget in budgets:
        rows[f"budget {budget}"] = bounded(model, looks, probe, budget, seed)
    for name, row in rows.items():
        print(f"{count} looks, {name}: mean {row['mean_error']:.4f}, p90 {row['p90_error']:.4f}, "
              f"fit {row['fit_cpu']:.1f} CPU s", flush=True)
    return {"looks": count, "probe": len(probe), "designs": rows}


def chart(report: dict, path: Path) -> None:
    """Fit error (mean and 90th percentile) against the looks in the material, one line per design."""
    plt = pyplot()
    fig, axes = plt.subplots(1, 3, figsize=(16, 5))
    rows = report["mosaics"]
    looks = [r["looks"] for r in rows]
    for name in rows[0]["designs"]:
        style = dict(color="tab:red", marker="*", ms=10, ls="--") if name == "per vector" else dict(marker="o")
        if name == f"budget {report['shipped_budget']}":
            style.update(lw=2.5)
        designs = [r["designs"][name] for r in rows]
        cost = [d["fit_cpu"] + d.get("choose_cpu", 0.0) for d in designs]
        for ax, values in zip(axes, ([d["mean_error"] for d in designs], [d["p90_error"] for d in designs], cost)):
            ax.plot(looks, values, label=name + (" (shipped)" if "lw" in style else ""), **style)
    for ax, label in zip(axes, ("fit error, mean over looks", "fit error, 90th percentile",
                                "CPU s, one thread: choosing + fitting (per vector extrapolated)")):
        ax.set_xscale("log", base=2)
        ax.set_xlabel("distinct looks in the material (a mosaic of training-distribution vectors)")
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    axes[2].set_yscale("log")
    fig.suptitle("Where the bounded fit breaks: more distinct looks than representatives", fontsize=11)
    save_chart(fig, path)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--looks", type=int, nargs="+", default=[64, 256, 1024, 4096, 16384])
    parser.add_argument("--budgets", type=int, nargs="+", default=[256, FIT_BUDGET, 4096])
    parser.add_argument("--seed", type=int, default=0)
    add_out_argument(parser, "fit_bounded_breaks.json")
    args = parser.parse_args()
    torch.set_num_threads(1)
    model = trained.load(trained.SHIPPED)
    report: dict = {"steps": STEPS, "threads": 1, "seed": args.seed, "shipped_budget": FIT_BUDGET,
                    "texels": TEXELS, "mosaics": []}
    for count in args.looks:
        report["mosaics"].append(measure(model, count, args.budgets, args.seed))
        write_report(args.out, report, [trained.SHIPPED])
        chart(report, args.out.with_suffix(".png"))


if __name__ == "__main__":
    main()
