"""Fit cost against accuracy, and the decoder's throughput against this machine's peak.

(a) For M random materials per type, latents from: the encoder alone, the
    encoder + k Adam steps, and a random start + k steps. For each, the fit's
    wall time and decoder evaluations (forward, in the fit) against the median
    and worst FLIP of neural vs analytic on the preview ball. The analytic
    references are rendered once.
(d) Decoder evaluations per second (batch 65536, fp32, inference) against the
    measured fp32 matmul peak of this machine (square 2048 matmuls, same
    thread count): the fraction of peak the decoder reaches (its Linear layers'
    flops; the hybrid's closed-form lobes are not counted). Two regimes: every
    evaluation a new (latent, wi, wo), as in fitting; and a renderer's shading
    point, one (latent, wi) and ``SHADING_DIRECTIONS`` wo, where the hybrid's head
    runs once per point (the MLP has nothing to reuse).

    python -m bench.neural.fit_speed [--per-type M] [--seed S] [--repeats R] [--weights RUN ...] [--out FILE.json]

``--weights`` repeats: the decoders side by side on the same materials, interleaved.

Timings are medians of R runs, interleaved, on a shared machine: compare the
ratios, not the absolute seconds.
"""
from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
import torch

from support.agreement_cases import cases
from bench.common import add_out_argument, add_weights_argument, pyplot, save_chart, weights_folders, write_report
from torch_models.neural import trained
from torch_models.neural.model import NeuralModel
from torch_models.neural.evaluate import BallSetup, compare, render_neural, render_reference
from torch_models.neural.fit.latents import FIT_BATCH, fit_latents
from torch_models.neural.hybrid.networks import HybridDecoder
from torch_models.neural.networks import LATENT

STEPS = (0, 25, 50, 100, 200, 400, 800)


def fit_variant(model: NeuralModel, vectors: np.ndarray, start: str, steps: int,
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


SHADING_DIRECTIONS = 64  # wo per shading point in the second regime (the OSL preview's default samples)


def decoder_throughput(model: NeuralModel, batch: int = 65536, repeats: int = 5,
                       shading: int = 1) -> tuple[float, int]:
    """Median decoder evaluations per second, and Linear-layer FLOPs per evaluation, with
    ``shading`` wo per (latent, wi): the hybrid's head runs once per such point."""
    gen = torch.Generator().manual_seed(0)
    points = batch // shading
    z = torch.rand(points, LATENT, generator=gen) * 2 - 1
    wi = torch.nn.functional.normalize(torch.rand(points, 3, generator=gen) + torch.tensor([0, 0, 0.2]), dim=-1)
    wo = torch.nn.functional.normalize(torch.rand(batch, 3, generator=gen) + torch.tensor([0, 0, 0.2]), dim=-1)
    dec = model.decoder

    def run() -> None:
        z_all, wi_all = z.repeat_interleave(shading, 0), wi.repeat_interleave(shading, 0)
        if isinstance(dec, HybridDecoder):
            dec.lobe_sum(dec.head_at(z, wi).repeat(shading), z_all, wi_all, wo)
        else:
            dec(z_all, wi_all, wo)

    times = []
    with torch.no_grad():
        run()
        for _ in range(repeats):
            t0 = time.perf_counter()
            run()
            times.append(time.perf_counter() - t0)
    heads = [dec.head] if isinstance(dec, HybridDecoder) else []
    per_point = sum(2 * m.in_features * m.out_features for h in heads for m in h.modules() if isinstance(m, torch.nn.Linear))
    every = sum(2 * m.in_features * m.out_features for m in dec.modules() if isinstance(m, torch.nn.Linear)) - per_point
    return batch / float(np.median(times)), round(every + per_point / shading)


def measure(folders: list[Path], vectors: np.ndarray, repeats: int, seed: int) -> dict[Path, dict]:
    """Fit seconds (median of ``repeats``, interleaved over decoders and variants) and latents per variant."""
    models = {f: trained.load(f) for f in folders}
    variants = [("encoder", 0)] + [(s, k) for k in STEPS[1:] for s in ("encoder", "random")]
    seconds = {f: {v: [] for v in variants} for f in folders}
    latents: dict[Path, dict] = {f: {} for f in folders}
    for _ in range(repeats):  # interleaved, so load changes hit every decoder and variant alike
        for start, steps in variants:
            for f in folders:
                z, dt = fit_variant(models[f], vectors, start, steps, seed)
                seconds[f][(start, steps)].append(dt)
                latents[f][(start, steps)] = z
    return {f: {"model": models[f], "seconds": seconds[f], "latents": latents[f]} for f in folders}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--per-type", type=int, default=3)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--repeats", type=int, default=3, help="timed repeats per variant (median)")
    add_weights_argument(parser)
    add_out_argument(parser, "fit_speed.json")
    args = parser.parse_args()
    folders = weights_folders(args)

    drawn = cases(args.seed + 7, args.per_type, 0)
    vectors = np.stack([c.vector() for c in drawn])
    setup = BallSetup.default(resolution=96, spp=32, seed=args.seed)
    references = [render_reference(setup, vectors[k], np.array(c.base_color, np.float32))
                  for k, c in enumerate(drawn)]
    measured = measure(folders, vectors, args.repeats, args.seed)
    threads = torch.get_num_threads()
    peak = matmul_peak_flops()
    decoders = []
    for folder, m in measured.items():
        model, rows = m["model"], []
        for (start, steps), z in m["latents"].items():
            flips = [compare(references[k], render_neural(setup, model, z[k], np.array(c.base_color, np.float32))).flip
                     for k, c in enumerate(drawn)]
            rows.append({"start": start, "steps": steps, "fit_seconds": float(np.median(m["seconds"][(start, steps)])),
                         "decoder_evaluations": steps * FIT_BATCH, "median_flip": float(np.median(flips)),
                         "worst_flip": float(max(flips))})
            print(f"{model.decoder.kind:6s} {start:8s} + {steps:4d} steps: {rows[-1]['fit_seconds']:6.2f} s, "
                  f"median FLIP {rows[-1]['median_flip']:.4f}, worst {rows[-1]['worst_flip']:.4f}", flush=True)
        throughput = {}
        for regime, shading in (("per_evaluation", 1), ("per_shading_point", SHADING_DIRECTIONS)):
            evals, flops = decoder_throughput(model, shading=shading)
            throughput[regime] = {"decoder_evals_per_second": evals, "flops_per_eval": flops,
                                  "decoder_flops_per_second": evals * flops, "fraction_of_peak": evals * flops / peak}
            print(f"{model.decoder.kind} {regime}: {evals / 1e6:.2f} M evals/s, {flops} flops/eval, "
                  f"{evals * flops / peak:.1%} of the {peak / 1e9:.1f} GFLOP/s matmul peak", flush=True)
        decoders.append({"weights": str(folder), "kind": model.decoder.kind, "decoder_sha256": model.digest,
                         "variants": rows, "throughput": throughput})
    base = decoders[0]["throughput"]
    for d in decoders:
        d["evals_per_second_vs_first"] = {r: d["throughput"][r]["decoder_evals_per_second"]
                                          / base[r]["decoder_evals_per_second"] for r in base}
    report = {"seed": args.seed, "materials": len(drawn), "fit_batch": FIT_BATCH,
              "repeats": args.repeats, "threads": threads, "matmul_peak_flops_per_second": peak,
              "shading_directions": SHADING_DIRECTIONS, "decoders": decoders}
    write_report(args.out, report, folders)
    chart(report, args.out.with_suffix(".png"))


def chart(report: dict, path: Path) -> None:
    plt = pyplot()

    fig, (a, b) = plt.subplots(1, 2, figsize=(12, 4.5))
    for d, colour in zip(report["decoders"], plt.cm.tab10.colors):
        name = f"{d['kind']} {d['decoder_sha256'][:8]}"
        rows = [r for r in d["variants"] if r["start"] == "encoder" and r["steps"] > 0]
        a.plot([r["fit_seconds"] for r in rows], [r["median_flip"] for r in rows], "o-", color=colour,
               label=f"{name}: encoder start + k steps (median)")
        a.plot([r["fit_seconds"] for r in rows], [r["worst_flip"] for r in rows], "x:", color=colour,
               label=f"{name} (worst)")
        for r in rows:
            a.annotate(str(r["steps"]), (r["fit_seconds"], r["median_flip"]), fontsize=7)
    a.set_xscale("log")
    a.set_xlabel(f"fit wall time for {report['materials']} materials (s, median of {report['repeats']})")
    a.set_ylabel("FLIP, neural vs analytic")
    a.set_title(f"accuracy against fit cost (batch {report['fit_batch']} evaluations per step)")
    a.legend(fontsize=7)
    regimes = ("per_evaluation", "per_shading_point")
    width = 0.8 / len(report["decoders"])
    for k, (d, colour) in enumerate(zip(report["decoders"], plt.cm.tab10.colors)):
        values = [d["throughput"][r]["decoder_evals_per_second"] / 1e6 for r in regimes]
        bars = b.bar(np.arange(2) + k * width, values, width, color=colour, label=f"{d['kind']} {d['decoder_sha256'][:8]}")
        for bar, r in zip(bars, regimes):
            b.annotate(f"{d['throughput'][r]['fraction_of_peak']:.0%} of peak", (bar.get_x(), bar.get_height()), fontsize=7)
    b.set_xticks(np.arange(2) + width * (len(report["decoders"]) - 1) / 2,
                 ["every evaluation new", f"{report['shading_directions']} wo per shading point"])
    b.set_ylabel("M decoder evaluations / s (fp32)")
    b.set_title(f"throughput, {report['threads']} threads (matmul peak "
                f"{report['matmul_peak_flops_per_second'] / 1e9:.0f} GFLOP/s)")
    b.legend(fontsize=8)
    save_chart(fig, path)


if __name__ == "__main__":
    main()
