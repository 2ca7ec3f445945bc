"""Can the decoder's network represent the materials the universal decoder fails on?

The worst materials of a Table 1 run (by default the six worst of the shipped
decoder's run at seed 3, 10 per type, measured first as bench/fit_flip.py does)
each get decoders of the shipped size trained on that one material alone, one
per direction encoding (encoder, decoder and sampling decoder from scratch, the
shipped loss with the albedo term), then fitted and rendered as bench/fit_flip.py
does. The shipped universal decoder is fitted and rendered beside
them in the same run. A single-material decoder far below the universal one means
the network can draw the material and what fails is sharing one decoder and one 6D
latent space across all materials; one as bad means the network itself cannot.

    python -m bench.single_material_decoder [--materials A,B,..] [--steps N] [--out FILE.json]
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
from bench.common import REPO, add_out_argument, pyplot, save_chart, target_lines, write_report
from bench.fit_flip import ranked
from torch_models.neural import weights
from torch_models.neural.evaluate import BallSetup, fit_and_compare
from torch_models.neural.networks import DIRECTION_ENCODINGS
from torch_models.neural.train import TrainConfig, Trainer

CPU_CONFIG = REPO / "torch_models" / "neural" / "configs" / "decoder_cpu.json"
SAMPLER_STEPS = 600


def single_material_flip(setup: BallSetup, vector: np.ndarray, base_color: np.ndarray, encoding: str,
                         steps: int, out: Path) -> tuple[float, float]:
    """FLIP of a decoder trained on this material alone, and its training seconds."""
    cfg = replace(TrainConfig.load(CPU_CONFIG), encoding=encoding, steps=steps, batch=8192, energy_steps=0,
                  sampler_steps=SAMPLER_STEPS, albedo_weight=0.1, threads=1,
                  checkpoint_every=steps + SAMPLER_STEPS, history=[])  # one checkpoint, at the end
    t0 = time.perf_counter()
    Trainer(cfg, out, vectors=vector[None]).run()
    seconds = time.perf_counter() - t0
    results, _ = fit_and_compare(setup, weights.load(out), vector[None], base_color[None], 100)
    return results[0].flip, seconds


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--materials", type=lambda s: s.split(","), default=None,
                        help="comma-separated case names (default: the six worst of the Table 1 run)")
    parser.add_argument("--steps", type=int, default=2000, help="decoder training steps per material")
    parser.add_argument("--seed", type=int, default=3, help="the Table 1 draw the names refer to")
    parser.add_argument("--per-type", type=int, default=10)
    add_out_argument(parser, "single_material_decoder.json")
    args = parser.parse_args()

    import torch

    torch.set_num_threads(1)
    names = args.materials or [r["name"] for r in ranked(args.per_type, args.seed)[:6]]
    drawn = {c.name: c for c in cases(args.seed, args.per_type, 0)}
    unknown = [n for n in names if n not in drawn]
    if unknown:
        parser.error(f"no such case in seed {args.seed}, {args.per_type} per type: {', '.join(unknown)}")
    setup = BallSetup.default(128, 64, args.seed)
    shipped = weights.load()
    rows = []
    for name in names:
        case = drawn[name]
        vector, base = case.vector(), np.array(case.base_color, np.float32)
        universal, _ = fit_and_compare(setup, shipped, vector[None], base[None], 400)
        row = {"name": name, "universal": universal[0].flip}
        for encoding in DIRECTION_ENCODINGS:
            with tempfile.TemporaryDirectory() as tmp:
                row[encoding], row[f"{encoding}_seconds"] = single_material_flip(
                    setup, vector, base, encoding, args.steps, Path(tmp))
        print(json.dumps(row), flush=True)
        rows.append(row)
    report = {"seed": args.seed, "per_type": args.per_type, "steps": args.steps, "batch": 8192, "materials": rows}
    write_report(args.out, report, [weights.SHIPPED])
    chart(report, args.out.with_suffix(".png"))


def chart(report: dict, path: Path) -> None:
    plt = pyplot()
    rows = report["materials"]
    series = ["universal", *DIRECTION_ENCODINGS]
    labels = {"universal": "shipped universal decoder", "half": "one-material decoder, half",
              "half_log_slope": "one-material decoder, half + log slope"}
    fig, ax = plt.subplots(figsize=(10, 4))
    x = np.arange(len(rows))
    for k, key in enumerate(series):
        ax.bar(x + (k - 1) * 0.27, [r[key] for r in rows], 0.27, label=labels[key])
    target_lines(ax)
    ax.set_xticks(x, [r["name"] for r in rows], fontsize=8)
    ax.set(ylabel="mean FLIP, neural vs analytic",
           title=f"the worst Table 1 materials (seed {report['seed']}): one 4 x 64 decoder for all, "
                 f"or one per material ({report['steps']} steps)")
    ax.legend(fontsize=8)
    save_chart(fig, path)


if __name__ == "__main__":
    main()
