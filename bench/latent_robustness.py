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

    python bench/latent_robustness.py [--seed S] [--count N] [--per-type M] [--out FILE.json]

Target: 100 % valid in both sets (as the tool renders them, i.e. guarded).
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

from agreement_cases import cases  # noqa: E402
from torch_models.neural import weights  # noqa: E402
from torch_models.neural.evaluate import BallSetup, compare, render_neural, render_reference  # noqa: E402
from torch_models.neural.fitting import fit_latents  # noqa: E402
from torch_models.neural.energy import guard  # noqa: E402
from torch_models.neural.validity import Validity, check_latents, enlarged, training_latent_box  # noqa: E402

NOISE = 0.05
ENLARGE = 1.1


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--count", type=int, default=5000, help="uniform latents in set (a) (default: 5000)")
    parser.add_argument("--per-type", type=int, default=4, help="fitted materials per type in set (b) (default: 4)")
    parser.add_argument("--steps", type=int, default=400, help="fit steps for set (b)")
    parser.add_argument("--weights", type=Path, default=weights.SHIPPED)
    parser.add_argument("--out", type=Path, default=REPO / "docs" / "reports" / "latent_robustness.json")
    args = parser.parse_args()

    start = time.perf_counter()
    torch.manual_seed(args.seed)
    model = weights.load(args.weights)
    box = training_latent_box(model, seed=args.seed)
    lo, hi = enlarged(box, ENLARGE)
    uniform = lo + (hi - lo) * torch.rand(args.count, len(lo), generator=torch.Generator().manual_seed(args.seed))
    set_a, guarded_a = raw_and_guarded(model, uniform, args.seed)
    print(f"(a) uniform in the box x{ENLARGE}: raw {set_a.summary()}, guarded {guarded_a.summary()}", flush=True)

    drawn = cases(args.seed + 1, args.per_type, 0)
    vectors = np.stack([c.vector() for c in drawn])
    fitted = fit_latents(model, vectors, args.steps, seed=args.seed)
    noise = NOISE * (2 * torch.rand(fitted.shape, generator=torch.Generator().manual_seed(args.seed + 2)) - 1)
    perturbed = fitted + noise
    set_b, guarded_b = raw_and_guarded(model, perturbed, args.seed)
    print(f"(b) fitted +-{NOISE}: raw {set_b.summary()}, guarded {guarded_b.summary()}", flush=True)
    scale_b = guard(model, perturbed, seed=args.seed)

    setup = BallSetup.default(resolution=96, spp=32, seed=args.seed)
    rows = []
    for k, case in enumerate(drawn):
        base = np.array(case.base_color, np.float32)
        ref = render_reference(setup, vectors[k], base)
        clean = render_neural(setup, model, fitted[k], base)
        noisy = render_neural(setup, model, perturbed[k], base, float(scale_b[k]))
        rows.append({"name": case.name, "flip_fitted": compare(ref, clean).flip,
                     "flip_perturbed": compare(ref, noisy).flip, "flip_change": compare(clean, noisy).flip})
        print(f"{case.name:22s} FLIP vs analytic {rows[-1]['flip_fitted']:.4f} -> {rows[-1]['flip_perturbed']:.4f}"
              f" (fitted vs perturbed {rows[-1]['flip_change']:.4f})", flush=True)

    report = {"seed": args.seed, "decoder_sha256": model.digest, "noise": NOISE, "box_enlargement": ENLARGE,
              "training_box": {"lo": box[0].tolist(), "hi": box[1].tolist()},
              "uniform_in_box": {"raw": set_a.summary(), "guarded": guarded_a.summary()},
              "perturbed_fitted": {"raw": set_b.summary(), "guarded": guarded_b.summary()},
              "flip_change": {"median": float(np.median([r["flip_change"] for r in rows])),
                              "max": float(max(r["flip_change"] for r in rows)),
                              "median_increase_vs_analytic": float(np.median(
                                  [r["flip_perturbed"] - r["flip_fitted"] for r in rows]))},
              "passed": guarded_a.summary()["valid"] == 1.0 and guarded_b.summary()["valid"] == 1.0,
              "wall_seconds": time.perf_counter() - start, "materials": rows}
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(report, indent=1))
    chart(report, set_a.furnace.albedo.numpy(), set_b.furnace.albedo.numpy(), args.out.with_suffix(".png"))
    print(f"valid raw / guarded: (a) {set_a.summary()['valid']:.2%} / {guarded_a.summary()['valid']:.2%}, "
          f"(b) {set_b.summary()['valid']:.2%} / {guarded_b.summary()['valid']:.2%}; "
          f"median FLIP change {report['flip_change']['median']:.4f}; wrote {args.out}")
    sys.exit(0 if report["passed"] else 1)


def raw_and_guarded(model: weights.NeuralModel, z: torch.Tensor, seed: int) -> tuple[Validity, Validity]:
    """Validity of the latents as decoded, and with the energy guard (re-checked on fresh samples)."""
    raw = check_latents(model, z, seed=seed)
    guarded = check_latents(model, z, seed=seed + 1000, energy_scale=guard(model, z, seed=seed))
    return raw, guarded


def chart(report: dict, albedo_a: np.ndarray, albedo_b: np.ndarray, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (a, b) = plt.subplots(1, 2, figsize=(10, 3.8))
    bins = np.linspace(0, max(1.1, float(max(albedo_a.max(), albedo_b.max())) + 0.02), 50)
    a.hist(albedo_a, bins, alpha=0.6, density=True, label=f"(a) uniform in box x{report['box_enlargement']}")
    a.hist(albedo_b, bins, alpha=0.6, density=True, label=f"(b) fitted +-{report['noise']}")
    a.axvline(1.0, color="red", ls="--", label="energy bound")
    a.set_xlabel("worst white-furnace albedo over view angles (raw, before the guard)")
    a.set_title("raw valid: (a) {:.1%}, (b) {:.1%}; guarded: {:.1%}, {:.1%}".format(
        report["uniform_in_box"]["raw"]["valid"], report["perturbed_fitted"]["raw"]["valid"],
        report["uniform_in_box"]["guarded"]["valid"], report["perturbed_fitted"]["guarded"]["valid"]), fontsize=9)
    a.legend(fontsize=8)
    rows = report["materials"]
    b.scatter([r["flip_fitted"] for r in rows], [r["flip_perturbed"] for r in rows], s=12)
    top = max(max(r["flip_perturbed"] for r in rows), max(r["flip_fitted"] for r in rows)) * 1.1
    b.plot([0, top], [0, top], color="gray", lw=0.8)
    b.set_xlabel("FLIP vs analytic, fitted latent")
    b.set_ylabel(f"FLIP vs analytic, latent +-{report['noise']}")
    b.set_title(f"median FLIP change {report['flip_change']['median']:.4f}")
    fig.tight_layout()
    fig.savefig(path, dpi=110)


if __name__ == "__main__":
    main()
