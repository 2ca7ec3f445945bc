"""Is the Table 1 error the fit's or the decoder's? Fit variants on fit_flip's worst materials.

Runs Table 1 as ``bench/fit_flip.py`` does (``--seed``, ``--per-type``; the shipped
decoder) and takes its worst metals, and dielectrics spread over the FLIP range
for contrast. Each is fitted against the frozen decoder in several ways and
rendered on the preview ball (analytic vs neural, mean FLIP):

- the shipped fit: encoder start + 400 Adam steps of the fitting loss;
- encoder start + 2000 steps (is the fit converged?);
- the best of 8 uniform random starts + 400 steps each (with as many samples per
  start as the shipped fit gives one latent), chosen by the fitting loss on
  held-out samples (is the encoder start a poor local minimum?);
- encoder start + 400 steps with an RGB albedo term added to the loss (is the
  loss blind to what FLIP sees?): the relative L1 error, per colour channel, of
  f_neu's directional albedo at 8 random view angles, estimated from the same
  samples of the analytic lobes for decoder and reference.

If no variant moves the worst cases towards the targets, the decoder cannot
represent those materials and a better decoder is the only fix.

    python -m bench.fit_limits [--seed 0] [--per-type 50] [--metals 8] [--dielectrics 4] [--out FILE.json]
"""
from __future__ import annotations

import argparse
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import torch
from torch import Tensor

from support.agreement_cases import cases
from bench.common import add_out_argument, pyplot, save_chart, target_lines, write_report
from bench.fit_flip import ranked
from torch_models.neural import weights
from torch_models.neural.data import make_batch
from torch_models.neural.evaluate import BallSetup, compare, render_neural, render_reference
from torch_models.neural.fitting import FIT_BATCH, fit_latents, fitting_loss, fitting_pool
from torch_models.neural.loss import lobe_samples
from torch_models.neural.networks import LATENT

STARTS = 8


def pick(rows: list[dict], metals: int, dielectrics: int) -> list[str]:
    """The worst metals, and dielectrics evenly spaced over their FLIP ranking (``rows`` worst first)."""
    metal = [r["name"] for r in rows if "metal" in r["name"]][:metals]
    diel = [r["name"] for r in rows if "diel" in r["name"]]
    return metal + [diel[i] for i in np.linspace(0, len(diel) - 1, dielectrics).round().astype(int)]


def albedo_penalty(model: weights.NeuralModel, vectors: Tensor, weight: float, views: int = 8,
                   samples: int = 256, sets: int = 8, seed: int = 1) -> Callable[[int, Tensor], Tensor]:
    """``penalty(step, z)`` for ``fit_latents``: relative L1 error per channel of f_neu's albedo.

    ``sets`` sample sets (views x samples per material, from the analytic lobes, exact
    pdf) are drawn once with their reference albedos and cycled through."""
    k, gen = len(vectors), torch.Generator().manual_seed(seed)
    drawn = []
    for _ in range(sets):
        s = lobe_samples(vectors.repeat_interleave(views, 0), samples, gen)
        inv_pdf = torch.where(s.ok, 1 / s.pdf.clamp(min=1e-6), torch.zeros_like(s.pdf))[:, None]
        with torch.no_grad():
            reference = (s.bsdf.eval_neural_part(s.wi, s.wo) * inv_pdf).reshape(k, views, samples, 3).mean(2)
        drawn.append((s.wi, s.wo, inv_pdf, reference))

    def penalty(step: int, z: Tensor) -> Tensor:
        wi, wo, inv_pdf, reference = drawn[step % sets]
        f, _, _ = model.decoder(z.repeat_interleave(views * samples, 0), wi, wo)
        estimate = (f * inv_pdf).reshape(k, views, samples, 3).mean(2)
        return weight * ((estimate - reference).abs() / (reference + 0.05)).mean()

    return penalty


def held_out_loss(model: weights.NeuralModel, vectors: np.ndarray, z: Tensor, seed: int = 99) -> np.ndarray:
    """(K,) the fitting loss of each latent on fresh samples of its own material."""
    gen, pool = torch.Generator().manual_seed(seed), fitting_pool(model, vectors)
    losses = []
    for k in range(len(pool)):
        batch = make_batch(pool[k:k + 1], 8192, gen)
        with torch.no_grad():
            losses.append(fitting_loss(model, z[k].expand(len(batch.wi), LATENT), batch).item())
    return np.array(losses)


def best_of_random_starts(model: weights.NeuralModel, vectors: np.ndarray, steps: int) -> Tensor:
    k = len(vectors)
    gen = torch.Generator().manual_seed(5)
    starts = torch.rand(STARTS * k, LATENT, generator=gen) * 1.8 - 0.9  # inside the encoder's box
    z = fit_latents(model, np.concatenate([vectors] * STARTS), steps, batch=STARTS * FIT_BATCH, start=starts)
    loss = held_out_loss(model, np.concatenate([vectors] * STARTS), z).reshape(STARTS, k)
    return z.reshape(STARTS, k, LATENT)[torch.from_numpy(loss.argmin(0)), torch.arange(k)]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=0, help="the Table 1 draw, as bench/fit_flip.py's")
    parser.add_argument("--per-type", type=int, default=50)
    parser.add_argument("--metals", type=int, default=8)
    parser.add_argument("--dielectrics", type=int, default=4)
    parser.add_argument("--resolution", type=int, default=96)
    parser.add_argument("--spp", type=int, default=32)
    add_out_argument(parser, "fit_limits.json")
    args = parser.parse_args()
    torch.set_num_threads(1)

    names = pick(ranked(args.per_type, args.seed), args.metals, args.dielectrics)
    drawn = {c.name: c for c in cases(args.seed, args.per_type, 0)}
    chosen = [drawn[n] for n in names]
    vectors = np.stack([c.vector() for c in chosen])
    base_colors = np.array([c.base_color for c in chosen], np.float32)
    model = weights.load(weights.SHIPPED)
    setup = BallSetup.default(args.resolution, args.spp, args.seed)
    pool = torch.from_numpy(vectors)
    variants: dict[str, Callable[[], Tensor]] = {
        "encoder + 400 steps (shipped)": lambda: fit_latents(model, vectors, 400),
        "encoder + 2000 steps": lambda: fit_latents(model, vectors, 2000),
        f"best of {STARTS} random starts + 400": lambda: best_of_random_starts(model, vectors, 400),
        "+ RGB albedo term 0.3": lambda: fit_latents(model, vectors, 400, penalty=albedo_penalty(model, pool, 0.3)),
        "+ RGB albedo term 1": lambda: fit_latents(model, vectors, 400, penalty=albedo_penalty(model, pool, 1.0)),
    }
    references = [render_reference(setup, v, c) for v, c in zip(vectors, base_colors)]
    results = {}
    for label, run in variants.items():
        start = time.perf_counter()
        z = run()
        seconds = time.perf_counter() - start
        flips = [compare(ref, render_neural(setup, model, z[k:k + 1], base_colors[k])).flip
                 for k, ref in enumerate(references)]
        results[label] = {"seconds": seconds, "flip": flips, "loss": held_out_loss(model, vectors, z).tolist()}
        print(f"{label}: {seconds:.0f} s, FLIP metals median {np.median(flips[:args.metals]):.3f} "
              f"worst {max(flips[:args.metals]):.3f}", flush=True)
    report = {"seed": args.seed, "per_type": args.per_type, "materials": names, "resolution": args.resolution,
              "spp": args.spp, "metals": args.metals, "variants": results}
    write_report(args.out, report, [weights.SHIPPED])
    chart(report, args.out.with_suffix(".png"))


def chart(report: dict, path: Path) -> None:
    plt = pyplot()
    labels = list(report["variants"])
    flips = np.array([report["variants"][v]["flip"] for v in labels])  # (variants, materials)
    m = report["metals"]
    fig, (ax, bx) = plt.subplots(1, 2, figsize=(11, 4.2), gridspec_kw={"width_ratios": [3, 1.3]})
    x = np.arange(len(labels))
    for k, name in enumerate(report["materials"]):
        ax.plot(x, flips[:, k], "o-", color="tab:red" if k < m else "tab:blue", alpha=0.55, ms=3, lw=0.8,
                label=("metals (worst of Table 1)" if k == 0 else "dielectrics" if k == m else None))
    target_lines(ax)
    ax.set_xticks(x, [label.replace(" (", "\n(").replace(" + ", "\n+ ") for label in labels], fontsize=7)
    ax.set_ylabel("mean FLIP, neural vs analytic")
    ax.set_title("Fit variants on the worst materials: the decoder, not the fit, sets the error", fontsize=9)
    ax.legend(fontsize=7)
    seconds = [report["variants"][v]["seconds"] for v in labels]
    bx.scatter(seconds, np.median(flips[:, :m], 1), color="tab:red")
    for s, f, label in zip(seconds, np.median(flips[:, :m], 1), labels):
        bx.annotate(label.split(" (")[0], (s, f), fontsize=6)
    bx.set_xscale("log")
    bx.set_xlabel("fit seconds (all materials, one thread)")
    bx.set_ylabel("median FLIP of the metals")
    save_chart(fig, path)


if __name__ == "__main__":
    main()
