"""Evaluations per second of the torch evaluator per type and batch size.

Shows that cost grows with the number of enabled lobes (pruning by constant
weights means Type 0 evaluates 2 lobes, Type 5 six). Each timing is the median
of several repeats; types are timed interleaved in one run so ratios compare
like with like on a shared machine.

    python -m bench.material.brdf_speed [--out docs/reports/brdf_speed.json] [--repeats 5]
"""
from __future__ import annotations

import argparse
import json
import statistics
import time
from pathlib import Path

import numpy as np
import torch

from bench.common import add_out_argument, pyplot, save_chart, write_report
from richmat_addon.core.enhance import enhance
from richmat_addon.core.enhancement_types import TYPES
from richmat_addon.core.maps import ParamMap, PbrInputs
from torch_models.brdf.model import LayeredBsdf

BATCHES = (1_024, 16_384, 131_072)


def bsdf_for(type_: int, metalness: float) -> LayeredBsdf:
    pbr = PbrInputs("bench", ParamMap.constant(0.6, 0.5, 0.4), ParamMap.constant(0.4),
                    ParamMap.constant(metalness))
    mat = enhance(pbr, type_, seed=1)
    params = {k: torch.from_numpy(m.value[None]) for k, m in mat.params.items()}
    return LayeredBsdf(params, torch.from_numpy(mat.base_color.value[None]))


def directions(n: int, gen: torch.Generator) -> torch.Tensor:
    v = torch.randn(n, 3, generator=gen)
    v[:, 2] = v[:, 2].abs()
    return v / v.norm(dim=-1, keepdim=True)


def time_eval(bsdf: LayeredBsdf, n: int, gen: torch.Generator, budget: float = 0.2) -> float:
    """Evaluations per second over as many calls as fit in ``budget`` seconds."""
    wi, wo = directions(n, gen), directions(n, gen)
    bsdf.eval(wi, wo)  # warm-up (tables are cached per process)
    calls, start = 0, time.perf_counter()
    while calls == 0 or time.perf_counter() - start < budget:
        bsdf.eval(wi, wo)
        calls += 1
    return calls * n / (time.perf_counter() - start)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_out_argument(parser, "brdf_speed.json")
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    torch.manual_seed(0)
    gen = torch.Generator().manual_seed(0)
    cases = {f"type {t}": bsdf_for(t, 0.0) for t in range(len(TYPES))}
    cases["type 0, metalness 0.5"] = bsdf_for(0, 0.5)
    samples: dict[str, dict[int, list[float]]] = {k: {n: [] for n in BATCHES} for k in cases}
    for _ in range(args.repeats):
        for n in BATCHES:
            for name, bsdf in cases.items():  # interleaved: drift hits every case alike
                samples[name][n].append(time_eval(bsdf, n, gen))
    report = {"torch_threads": torch.get_num_threads(), "repeats": args.repeats,
              "lobes": {k: [l.name for l in b.lobes] for k, b in cases.items()},
              "evals_per_second_median": {k: {str(n): statistics.median(v) for n, v in d.items()}
                                          for k, d in samples.items()}}
    base = report["evals_per_second_median"]["type 0"][str(BATCHES[-1])]
    report["cost_relative_to_type0_at_largest_batch"] = {
        k: base / v[str(BATCHES[-1])] for k, v in report["evals_per_second_median"].items()}
    write_report(args.out, report)
    chart(report, args.out.with_suffix(".png"))
    print(json.dumps(report["cost_relative_to_type0_at_largest_batch"], indent=2))


def chart(report: dict, path: Path) -> None:
    plt = pyplot()
    fig, ax = plt.subplots(1, 2, figsize=(11, 4))
    med = report["evals_per_second_median"]
    for name, per_batch in med.items():
        ax[0].plot([int(n) for n in per_batch], list(per_batch.values()), "o-",
                   label=f"{name} ({len(report['lobes'][name])} lobes)")
    ax[0].set(xscale="log", yscale="log", xlabel="batch size", ylabel="evaluations / s (median)",
              title="torch evaluator throughput")
    ax[0].legend(fontsize=7)
    names = list(med)
    largest = str(max(int(n) for n in next(iter(med.values()))))
    ax[1].bar(range(len(names)), [len(report["lobes"][n]) for n in names], color="#bbb",
              label="enabled lobes")
    ax[1].plot(range(len(names)), [report["cost_relative_to_type0_at_largest_batch"][n] for n in names],
               "ro-", label=f"time per eval / type 0 (batch {largest})")
    ax[1].set_xticks(range(len(names)), [n.replace(", ", "\n") for n in names], fontsize=7)
    ax[1].legend(fontsize=8)
    ax[1].set_title("cost grows with enabled lobes")
    save_chart(fig, path)


if __name__ == "__main__":
    np.seterr(all="ignore")
    main()
