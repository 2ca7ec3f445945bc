"""The paper's Table 1: FLIP of fitted neural materials against the analytic reference.

N random materials per type (the enhancement rules on random PBR inputs, as in
bench/agreement_cases.py) are fitted together against the frozen decoder, then
rendered on the preview ball with the torch renderer, analytically and neurally
(same seed, same samples), and compared with mean LDR-FLIP (AgX, sRGB, 67 ppd).
Reports best / median / worst per type next to the paper's numbers, and the white
furnace: how many fits pass as fitted, after ``fit``'s energy refit, or only with the
energy scale, and on how many materials the analytic reference itself exceeds 1.

    python bench/fit_flip.py [--per-type N] [--seed S] [--out FILE.json] [--weights RUN]

Targets: every type median <= 0.05 and worst <= 0.12.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np
from PIL import Image

REPO = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(REPO), str(REPO / "bench")]

from agreement_cases import cases  # noqa: E402
from torch_models.neural import weights  # noqa: E402
from torch_models.neural.evaluate import BallSetup, fit_and_compare, reference_furnace, side_by_side  # noqa: E402
from torch_models.neural.energy import QUADRATURE_TOLERANCE  # noqa: E402

PAPER = {0: (0.0487, 0.0920, 0.1871), 1: (0.0312, 0.0727, 0.1670), 2: (0.0649, 0.0858, 0.1192),
         3: (0.0554, 0.0877, 0.1664), 4: (0.0276, 0.0643, 0.1705), 5: (0.0454, 0.0807, 0.1754)}
TARGET_MEDIAN, TARGET_WORST = 0.05, 0.12


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--per-type", type=int, default=50)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", type=Path, default=REPO / "docs" / "reports" / "fit_flip.json")
    parser.add_argument("--weights", type=Path, default=weights.SHIPPED)
    parser.add_argument("--steps", type=int, default=400, help="fit steps (all materials fitted together)")
    parser.add_argument("--resolution", type=int, default=128)
    parser.add_argument("--spp", type=int, default=64)
    args = parser.parse_args()

    start = time.perf_counter()
    model = weights.load(args.weights)
    drawn = cases(args.seed, args.per_type, 0)
    vectors = np.stack([c.vector() for c in drawn])
    base_colors = np.array([c.base_color for c in drawn], np.float32)
    setup = BallSetup.default(args.resolution, args.spp, args.seed)
    results, bounded = fit_and_compare(setup, model, vectors, base_colors, args.steps)
    check, reference = bounded.check, reference_furnace(vectors)
    rows, worst = [], {}
    for k, (case, result) in enumerate(zip(drawn, results)):
        type_ = int(case.name[4])
        rows.append({"name": case.name, "type": type_, "flip": result.flip,
                     "furnace_albedo": float(check.albedo[k]), "reference_albedo": float(reference[k]),
                     "refitted": bool(bounded.refitted[k]), "repaired": bool(check.failing[k])})
        if result.flip >= (worst[type_].flip if type_ in worst else -1.0):
            worst[type_] = result
    summary = {}
    for t in range(6):
        f = sorted(r["flip"] for r in rows if r["type"] == t)
        summary[t] = {"best": f[0], "median": float(np.median(f)), "worst": f[-1], "paper": PAPER[t],
                      "passed": float(np.median(f)) <= TARGET_MEDIAN and f[-1] <= TARGET_WORST}
    report = {"per_type": args.per_type, "seed": args.seed, "steps": args.steps, "resolution": args.resolution,
              "spp": args.spp, "decoder_sha256": model.digest,
              "flip_convention": "LDR-FLIP on AgX-tone-mapped sRGB, 67.02 pixels per degree",
              "summary": summary, "all_passed": all(s["passed"] for s in summary.values()),
              "furnace": dict(bounded.counts(), pass_fraction=float((~check.failing).float().mean()),
                              reference_over_tolerance=int((reference > 1 + QUADRATURE_TOLERANCE).sum())),
              "wall_seconds": time.perf_counter() - start, "materials": rows}
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(report, indent=1))
    chart(report, args.out.with_suffix(".png"))
    Image.fromarray(side_by_side([worst[t] for t in sorted(worst)])).save(args.out.with_name(args.out.stem + "_worst.png"))
    for t, s in summary.items():
        print(f"Type {t}: best {s['best']:.4f} median {s['median']:.4f} worst {s['worst']:.4f} "
              f"(paper {s['paper'][1]:.4f} / {s['paper'][2]:.4f})")
    f = report["furnace"]
    print(f"furnace: {f['passed_as_fitted']}/{f['checked']} pass as fitted, {f['passed_after_refit']} after the "
          f"energy refit, {f['repaired_by_scaling']} scaled; the analytic reference itself exceeds 1 on "
          f"{f['reference_over_tolerance']}")
    sys.exit(0 if report["all_passed"] else 1)


def chart(report: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(8, 4))
    for t in range(6):
        f = [r["flip"] for r in report["materials"] if r["type"] == t]
        ax.scatter(np.full(len(f), t) - 0.1 + 0.05 * np.random.default_rng(t).standard_normal(len(f)), f,
                   s=8, color="tab:blue", alpha=0.6, label="ours (each material)" if t == 0 else None)
        best, med, worst = report["summary"][t]["paper"]
        ax.plot([t + 0.15] * 3, [best, med, worst], "o-", color="tab:red", label="paper best/median/worst" if t == 0 else None)
    ax.axhline(TARGET_MEDIAN, ls="--", color="gray", lw=0.8, label="target median 0.05")
    ax.axhline(TARGET_WORST, ls=":", color="gray", lw=0.8, label="target worst 0.12")
    ax.set_xticks(range(6), [f"Type {t}" for t in range(6)])
    ax.set_ylabel("mean FLIP, neural vs analytic")
    ax.set_title(f"Fitted neural materials, {report['per_type']} per type, seed {report['seed']}")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


if __name__ == "__main__":
    main()
