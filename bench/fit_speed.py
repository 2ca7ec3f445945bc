"""Fit cost against accuracy, and the decoder's throughput against this machine's peak.

(a) For M random materials per type, latents from: the encoder alone, the
    encoder + k Adam steps, and a random start + k steps. For each, the fit's
    wall time and decoder evaluations (forward, in the fit) against the median
    and worst FLIP of neural vs analytic on the preview ball. The analytic
    references are rendered once.
(d) Decoder evaluations per second (batch 65536, fp32, inference) against the
    measured fp32 matmul peak of this machine (square 2048 matmuls, same
    thread count): the fraction of peak the decoder reaches.

    python bench/fit_speed.py [--per-type M] [--seed S] [--repeats R] [--out FILE.json]

Timings are medians of R runs, interleaved, on a shared machine: compare the
ratios, not the absolute seconds.
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
from torch_models.neural.fitting import FIT_BATCH, fit_latents  # noqa: E402
from torch_models.neural.networks import LATENT  # noqa: E402

STEPS = (0, 25, 50, 100, 200, 400, 800)


def fit_variant(model: weights.NeuralModel, vectors: np.ndarray, start: str, steps: int,
                seed: int) -> tuple[torch.Tensor, float]:
    """Latents and wall seconds for one start ('encoder' or 'random') and step count."""
    t0 = time.perf_counter()
    init = None
    if start == "random":
        init = 2 * torch.rand(len(vectors), LATENT, generator=torch.Generator().manual_seed(seed)) - 1
    z = fit_latents(model, vectors, steps, seed=seed, start=init)
    return z, time.perf_counter() - t0


def matmul_peak_flops(size: int = 2048, repeats: int = 5) -> float:
    """Median fp32 FLOP/s of a square matmul (2 n^3 flops)."""
    a, b = torch.randn(size, size), torch.randn(size, size)
    a @ b
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        a @ b
        times.append(time.perf_counter() - t0)
    return 2 * size ** 3 / float(np.median(times))


def decoder_throughput(model: weights.NeuralModel, batch: int = 65536, repeats: int = 5) -> tuple[float, int]:
    """Median decoder evaluations per second, and multiply-add FLOPs per evaluation."""
    z = torch.rand(batch, LATENT) * 2 - 1
    wi = torch.nn.functional.normalize(torch.rand(batch, 3) + torch.tensor([0, 0, 0.2]), dim=-1)
    wo = torch.nn.functional.normalize(torch.rand(batch, 3) + torch.tensor([0, 0, 0.2]), dim=-1)
    times = []
    with torch.no_grad():
        model.decoder(z, wi, wo)
        for _ in range(repeats):
            t0 = time.perf_counter()
            model.decoder(z, wi, wo)
            times.append(time.perf_counter() - t0)
    linears = [m for m in model.decoder.modules() if isinstance(m, torch.nn.Linear)]
    flops = sum(2 * m.in_features * m.out_features for m in linears)
    return batch / float(np.median(times)), flops


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--per-type", type=int, default=3)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--repeats", type=int, default=3, help="timed repeats per variant (median)")
    parser.add_argument("--weights", type=Path, default=weights.SHIPPED)
    parser.add_argument("--out", type=Path, default=REPO / "docs" / "reports" / "fit_speed.json")
    args = parser.parse_args()

    model = weights.load(args.weights)
    drawn = cases(args.seed + 7, args.per_type, 0)
    vectors = np.stack([c.vector() for c in drawn])
    setup = BallSetup.default(resolution=96, spp=32, seed=args.seed)
    references = [render_reference(setup, vectors[k], np.array(c.base_color, np.float32))
                  for k, c in enumerate(drawn)]

    variants = [("encoder", 0)] + [(s, k) for k in STEPS[1:] for s in ("encoder", "random")]
    seconds: dict[tuple[str, int], list[float]] = {v: [] for v in variants}
    latents: dict[tuple[str, int], torch.Tensor] = {}
    for _ in range(args.repeats):  # interleaved, so load changes hit every variant alike
        for start, steps in variants:
            z, dt = fit_variant(model, vectors, start, steps, args.seed)
            seconds[(start, steps)].append(dt)
            latents[(start, steps)] = z
    rows = []
    for start, steps in variants:
        z = latents[(start, steps)]
        flips = [compare(references[k], render_neural(setup, model, z[k], np.array(c.base_color, np.float32))).flip
                 for k, c in enumerate(drawn)]
        rows.append({"start": start, "steps": steps, "fit_seconds": float(np.median(seconds[(start, steps)])),
                     "decoder_evaluations": steps * FIT_BATCH, "median_flip": float(np.median(flips)),
                     "worst_flip": float(max(flips))})
        print(f"{start:8s} + {steps:4d} steps: {rows[-1]['fit_seconds']:6.2f} s, "
              f"median FLIP {rows[-1]['median_flip']:.4f}, worst {rows[-1]['worst_flip']:.4f}", flush=True)

    threads = torch.get_num_threads()
    peak = matmul_peak_flops()
    evals, flops = decoder_throughput(model)
    report = {"seed": args.seed, "materials": len(drawn), "decoder_sha256": model.digest,
              "fit_batch": FIT_BATCH, "repeats": args.repeats, "threads": threads, "variants": rows,
              "throughput": {"decoder_evals_per_second": evals, "flops_per_eval": flops,
                             "decoder_flops_per_second": evals * flops, "matmul_peak_flops_per_second": peak,
                             "fraction_of_peak": evals * flops / peak}}
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(report, indent=1))
    chart(report, args.out.with_suffix(".png"))
    print(f"decoder: {evals / 1e6:.2f} M evals/s = {evals * flops / 1e9:.1f} GFLOP/s, "
          f"{evals * flops / peak:.1%} of the {peak / 1e9:.1f} GFLOP/s matmul peak ({threads} threads)")


def chart(report: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (a, b) = plt.subplots(1, 2, figsize=(11, 4))
    for start, colour in (("encoder", "tab:blue"), ("random", "tab:orange")):
        rows = [r for r in report["variants"] if r["start"] == start and r["steps"] > 0]
        a.plot([r["fit_seconds"] for r in rows], [r["median_flip"] for r in rows], "o-", color=colour,
               label=f"{start} start + k steps (median)")
        a.plot([r["fit_seconds"] for r in rows], [r["worst_flip"] for r in rows], "x:", color=colour,
               label=f"{start} start (worst)")
        for r in rows:
            a.annotate(str(r["steps"]), (r["fit_seconds"], r["median_flip"]), fontsize=7)
    enc = next(r for r in report["variants"] if r["steps"] == 0)
    a.axhline(enc["median_flip"], color="tab:green", ls="--", label="encoder only (median)")
    a.set_xscale("log")
    a.set_xlabel(f"fit wall time for {report['materials']} materials (s, median of {report['repeats']})")
    a.set_ylabel("FLIP, neural vs analytic")
    a.set_title(f"fit cost vs accuracy (batch {report['fit_batch']} evaluations per step)")
    a.legend(fontsize=7)
    t = report["throughput"]
    b.bar(["matmul peak", "decoder"], [t["matmul_peak_flops_per_second"] / 1e9, t["decoder_flops_per_second"] / 1e9],
          color=["gray", "tab:blue"])
    b.set_ylabel("GFLOP/s (fp32)")
    b.set_title(f"decoder at {t['fraction_of_peak']:.0%} of matmul peak "
                f"({t['decoder_evals_per_second'] / 1e6:.2f} M evals/s, {report['threads']} threads)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)


if __name__ == "__main__":
    main()
