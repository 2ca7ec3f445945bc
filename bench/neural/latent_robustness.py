"""Latent robustness: do latents nobody fitted still decode to valid materials?

(a) latents drawn uniformly from the training latent box (the encoder's range
    over training-like vectors) enlarged by 10 % about its centre;
(b) fitted latents of random materials of every type, perturbed by uniform
    noise of +-0.05 per channel (ten times the training jitter).

For each: the fraction that decodes finite, non-negative and energy-bounded
(white furnace <= 1 + 3 standard errors; torch_models/neural/validity.py),
raw and after the energy guard the tool applies to latents it did not fit
(f_neu scaled by the furnace repair, re-checked with fresh samples). For (b)
also the FLIP change the perturbation causes on the preview ball.

    python -m bench.neural.latent_robustness [--seed S] [--count N] [--per-type M] [--weights RUN ...] [--out FILE.json]

``--weights`` repeats: decoders side by side on the same draws (each in its own
encoder's box). Target: 100 % valid in both sets as the tool renders them
(guarded), and for a decoder bounded by construction (the hybrid) 100 % raw.
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
import torch

from support.agreement_cases import cases
from bench.common import add_out_argument, add_weights_argument, pyplot, save_chart, weights_folders, write_report
from torch_models.neural import trained
from torch_models.neural.model import NeuralModel
from torch_models.neural.energy import guard
from torch_models.neural.evaluate import BallSetup, compare, render_neural, render_reference
from torch_models.neural.fit.latents import fit_latents
from torch_models.neural.validity import Validity, check_latents, enlarged, training_latent_box

NOISE = 0.05
ENLARGE = 1.1


def evaluate(folder: Path, args: argparse.Namespace, drawn: list, vectors: np.ndarray,
             references: list[np.ndarray], setup: BallSetup) -> tuple[dict, np.ndarray, np.ndarray]:
    """One decoder's block of the report, and its raw worst furnace albedos of sets (a) and (b)."""
    model = trained.load(folder)
    torch.manual_seed(args.seed)
    box = training_latent_box(model, seed=args.seed)
    lo, hi = enlarged(box, ENLARGE)
    uniform = lo + (hi - lo) * torch.rand(args.count, len(lo), generator=torch.Generator().manual_seed(args.seed))
    set_a, guarded_a = raw_and_guarded(model, uniform, args.seed)
    print(f"{model.decoder.kind} (a) uniform in the box x{ENLARGE}: raw {set_a.summary()}, "
          f"guarded {guarded_a.summary()}", flush=True)
    fitted = fit_latents(model, vectors, args.steps, seed=args.seed)
    noise = NOISE * (2 * torch.rand(fitted.shape, generator=torch.Generator().manual_seed(args.seed + 2)) - 1)
    perturbed = fitted + noise
    set_b, guarded_b = raw_and_guarded(model, perturbed, args.seed)
    print(f"{model.decoder.kind} (b) fitted +-{NOISE}: raw {set_b.summary()}, guarded {guarded_b.summary()}", flush=True)
    scale_b = guard(model, perturbed, seed=args.seed)
    rows = []
    for k, case in enumerate(drawn):
        base = np.array(case.base_color, np.float32)
        clean = render_neural(setup, model, fitted[k], base)
        noisy = render_neural(setup, model, perturbed[k], base, float(scale_b[k]))
        rows.append({"name": case.name, "flip_fitted": compare(references[k], clean).flip,
                     "flip_perturbed": compare(references[k], noisy).flip, "flip_change": compare(clean, noisy).flip})
    block = {"weights": str(folder), "kind": model.decoder.kind, "decoder_sha256": model.digest,
             "training_box": {"lo": box[0].tolist(), "hi": box[1].tolist()},
             "uniform_in_box": {"raw": set_a.summary(), "guarded": guarded_a.summary()},
             "perturbed_fitted": {"raw": set_b.summary(), "guarded": guarded_b.summary()},
             "flip_change": {"median": float(np.median([r["flip_change"] for r in rows])),
                             "max": float(max(r["flip_change"] for r in rows)),
                             "median_increase_vs_analytic": float(np.median(
                                 [r["flip_perturbed"] - r["flip_fitted"] for r in rows]))},
             "passed": guarded_a.summary()["valid"] == 1.0 and guarded_b.summary()["valid"] == 1.0,
             "materials": rows}
    print(f"{model.decoder.kind} valid raw / guarded: (a) {set_a.summary()['valid']:.2%} / "
          f"{guarded_a.summary()['valid']:.2%}, (b) {set_b.summary()['valid']:.2%} / {guarded_b.summary()['valid']:.2%}; "
          f"median FLIP change {block['flip_change']['median']:.4f}", flush=True)
    return block, set_a.furnace.albedo.numpy(), set_b.furnace.albedo.numpy()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--count", type=int, default=5000, help="uniform latents in set (a) (default: 5000)")
    parser.add_argument("--per-type", type=int, default=4, help="fitted materials per type in set (b) (default: 4)")
    parser.add_argument("--steps", type=int, default=400, help="fit steps for set (b)")
    add_weights_argument(parser)
    add_out_argument(parser, "latent_robustness.json")
    args = parser.parse_args()
    folders = weights_folders(args)

    start = time.perf_counter()
    drawn = cases(args.seed + 1, args.per_type, 0)
    vectors = np.stack([c.vector() for c in drawn])
    setup = BallSetup.default(resolution=96, spp=32, seed=args.seed)
    references = [render_reference(setup, vectors[k], np.array(c.base_color, np.float32)) for k, c in enumerate(drawn)]
    decoders, albedos = [], []
    for folder in folders:
        block, albedo_a, albedo_b = evaluate(folder, args, drawn, vectors, references, setup)
        decoders.append(block)
        albedos.append((albedo_a, albedo_b))
    report = {"seed": args.seed, "noise": NOISE, "box_enlargement": ENLARGE, "decoders": decoders,
              "wall_seconds": time.perf_counter() - start}
    write_report(args.out, report, folders)
    chart(report, albedos, args.out.with_suffix(".png"))
    sys.exit(0 if all(d["passed"] for d in decoders) else 1)


def raw_and_guarded(model: NeuralModel, z: torch.Tensor, seed: int) -> tuple[Validity, Validity]:
    """Validity of the latents as decoded, and with the energy guard (re-checked on fresh samples)."""
    raw = check_latents(model, z, seed=seed)
    guarded = check_latents(model, z, seed=seed + 1000, energy_scale=guard(model, z, seed=seed))
    return raw, guarded


def chart(report: dict, albedos: list[tuple[np.ndarray, np.ndarray]], path: Path) -> None:
    plt = pyplot()

    decoders = report["decoders"]
    fig, axes = plt.subplots(len(decoders), 2, figsize=(10, 3.6 * len(decoders)), squeeze=False)
    top = max(1.1, max(float(max(a.max(), b.max())) for a, b in albedos) + 0.02)
    for (a, b), d, (albedo_a, albedo_b) in zip(axes, decoders, albedos):
        bins = np.linspace(0, top, 50)
        a.hist(albedo_a, bins, alpha=0.6, density=True, label=f"(a) uniform in box x{report['box_enlargement']}")
        a.hist(albedo_b, bins, alpha=0.6, density=True, label=f"(b) fitted +-{report['noise']}")
        a.axvline(1.0, color="red", ls="--", label="energy bound")
        a.set_xlabel("worst white-furnace albedo over view angles (raw, no guard)")
        a.set_title("{} {}: raw valid (a) {:.1%}, (b) {:.1%}; guarded {:.1%}, {:.1%}".format(
            d["kind"], d["decoder_sha256"][:8], d["uniform_in_box"]["raw"]["valid"],
            d["perturbed_fitted"]["raw"]["valid"], d["uniform_in_box"]["guarded"]["valid"],
            d["perturbed_fitted"]["guarded"]["valid"]), fontsize=9)
        a.legend(fontsize=8)
        rows = d["materials"]
        b.scatter([r["flip_fitted"] for r in rows], [r["flip_perturbed"] for r in rows], s=12)
        lim = max(max(r["flip_perturbed"] for r in rows), max(r["flip_fitted"] for r in rows)) * 1.1
        b.plot([0, lim], [0, lim], color="gray", lw=0.8)
        b.set_xlabel("FLIP vs analytic, fitted latent")
        b.set_ylabel(f"FLIP vs analytic, latent +-{report['noise']}")
        b.set_title(f"{d['kind']}: median FLIP change {d['flip_change']['median']:.4f}", fontsize=9)
    save_chart(fig, path)


if __name__ == "__main__":
    main()
