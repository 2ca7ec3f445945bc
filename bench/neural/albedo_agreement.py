"""Directional albedo of fitted neural materials against the analytic model, by view angle.

FLIP on the preview ball mixes every error into one number; this bench isolates the
energy: for fit_flip's materials (the enhancement rules on random PBR inputs, fitted
the same way), the albedo of f_neu (luminance) and of the analytic part it stands for
(``LayeredBsdf.eval_neural_part``), both integrated with the furnace's deterministic
half-vector quadrature, at view cosines from 1 down to 0.05. A ratio below 1 is a
material rendered too dark at that angle, above 1 too bright (or gaining energy).

    python -m bench.neural.albedo_agreement [--per-type N] [--seed S] [--out FILE.json] [--weights RUN]
"""
from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
import torch

from support.agreement_cases import cases
from bench.common import add_out_argument, pyplot, save_chart, write_report
from richmat_addon.core.enhancement_types import TYPES
from torch_models.brdf.model import LayeredBsdf, luminance, params_from_vectors
from torch_models.neural import trained
from torch_models.neural.model import NeuralModel
from torch_models.neural.fit.latents import fit_latents
from torch_models.neural.quadrature import half_vector_nodes

VIEW_COSINES = (1.0, 0.9, 0.8, 0.7, 0.6, 0.5, 0.4, 0.3, 0.2, 0.15, 0.1, 0.05)


def albedos(model: NeuralModel, vectors: np.ndarray, z: torch.Tensor) -> tuple[np.ndarray, np.ndarray]:
    """(K, A) luminance albedo of the analytic neural part and of f_neu at ``VIEW_COSINES``."""
    analytic, neural = np.zeros((2, len(vectors), len(VIEW_COSINES)))
    with torch.no_grad():
        for a, mu in enumerate(VIEW_COSINES):
            wi, wo, weight = half_vector_nodes(mu)
            m = len(wo)
            wi_m = wi.expand(m, 3)
            for k, vector in enumerate(vectors):
                bsdf = LayeredBsdf(params_from_vectors(torch.as_tensor(vector)[None].expand(m, -1)), torch.zeros(m, 3))
                analytic[k, a] = float((luminance(bsdf.eval_neural_part(wi_m, wo))[:, 0] * weight).sum())
                f, _, _ = model.decoder(z[k:k + 1].expand(m, -1), wi_m, wo)
                neural[k, a] = float((luminance(f)[:, 0] * weight).sum())
    return analytic, neural


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--per-type", type=int, default=10)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--steps", type=int, default=400, help="fit steps, as fit_flip")
    add_out_argument(parser, "albedo_agreement.json")
    parser.add_argument("--weights", type=Path, default=trained.SHIPPED)
    args = parser.parse_args()

    start = time.perf_counter()
    model = trained.load(args.weights)
    drawn = cases(args.seed, args.per_type, 0)
    vectors = np.stack([c.vector() for c in drawn])
    z = fit_latents(model, vectors, args.steps, seed=args.seed)
    analytic, neural = albedos(model, vectors, z)
    ratio = neural / np.maximum(analytic, 1e-6)
    types = np.array([int(c.name[4]) for c in drawn])
    summary = {str(mu): {"median_ratio": float(np.median(ratio[:, a])),
                         "p10": float(np.percentile(ratio[:, a], 10)), "p90": float(np.percentile(ratio[:, a], 90)),
                         "median_ratio_per_type": [float(np.median(ratio[types == t, a])) for t in range(len(TYPES))]}
               for a, mu in enumerate(VIEW_COSINES)}
    report = {"per_type": args.per_type, "seed": args.seed, "steps": args.steps,
              "view_cosines": VIEW_COSINES, "summary": summary, "wall_seconds": time.perf_counter() - start,
              "materials": [{"name": c.name, "analytic": analytic[k].tolist(), "neural": neural[k].tolist()}
                            for k, c in enumerate(drawn)]}
    write_report(args.out, report, [args.weights])
    chart(ratio, types, args.out.with_suffix(".png"), args.seed)
    for mu, s in summary.items():
        print(f"cos {mu:>5}: neural / analytic albedo median {s['median_ratio']:.3f} "
              f"(10-90 %: {s['p10']:.3f}-{s['p90']:.3f})")


def chart(ratio: np.ndarray, types: np.ndarray, path: Path, seed: int) -> None:
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(7, 4))
    mu = np.array(VIEW_COSINES)
    ax.fill_between(mu, np.percentile(ratio, 10, 0), np.percentile(ratio, 90, 0), color="gray", alpha=0.25,
                    label="all materials, 10-90 %")
    for t in range(len(TYPES)):
        ax.plot(mu, np.median(ratio[types == t], 0), "o-", ms=3, label=f"Type {t} median")
    ax.axhline(1.0, color="black", lw=0.8)
    ax.set_xscale("log")
    ax.set_xticks([0.05, 0.1, 0.2, 0.5, 1.0], ["0.05", "0.1", "0.2", "0.5", "1"])
    ax.set_xlabel("cos(theta_i), view angle (grazing on the left)")
    ax.set_ylabel("albedo of f_neu / analytic")
    ax.set_title(f"Directional albedo, fitted neural vs analytic (seed {seed})")
    ax.legend(fontsize=7, ncol=2)
    save_chart(fig, path)


if __name__ == "__main__":
    main()
