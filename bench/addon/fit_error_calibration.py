"""Calibrate the fit error's grades (good / visible / poor, ``core/fit_error.py``) against Table 1's FLIP.

Table 1's report (bench/neural/fit_flip.py) holds, per material, the FLIP of its fitted ball against
the analytic ball. This bench draws the same materials, fits them as that bench did (same
decoder, steps and seed: the fit is deterministic), measures each fit's error
(``neural/fit/error.py``) and sets it beside the reported FLIP: the rank correlation, and how
often the grade agrees with the FLIP bands (good: FLIP <= 0.05, Table 1's median level; poor:
FLIP > 0.10, its worst target). No rendering: the FLIP is read from the report.

    python -m bench.addon.fit_error_calibration [--table1 docs/reports/fit_flip_hybrid.json] [--out FILE.json]
"""
from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np
import torch

from support.agreement_cases import cases
from bench.common import REPORTS, add_out_argument, pyplot, save_chart, write_report
from richmat_addon.core import fit_error as grades
from torch_models.neural import trained
from torch_models.neural.energy import fit_bounded
from torch_models.neural.fit.error import vector_errors
from torch_models.neural.fit.latents import fit_latents

FLIP_GOOD, FLIP_POOR = 0.05, 0.10


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--table1", type=Path, default=REPORTS / "fit_flip_hybrid.json")
    add_out_argument(parser, "fit_error_calibration.json")
    args = parser.parse_args()
    started = time.perf_counter()
    model = trained.load(trained.SHIPPED)
    table1 = json.loads(args.table1.read_text())
    measured = next(d for d in table1["decoders"] if d["decoder_sha256"] == model.digest)
    drawn = cases(table1["seed"], table1["per_type"], 0)
    assert [c.name for c in drawn] == [m["name"] for m in measured["materials"]], "not Table 1's materials"
    vectors = np.stack([c.vector() for c in drawn])
    seed = table1["seed"]
    bounded = fit_bounded(model, vectors, fit_latents(model, vectors, table1["steps"], seed=seed), seed=seed)
    error = vector_errors(model, vectors, bounded.z, bounded.check.energy_scale())
    flip = np.array([m["flip"] for m in measured["materials"]])
    from scipy.stats import spearmanr

    rows = [{"material": c.name, "error": float(e), "flip": float(f)} for c, e, f in zip(drawn, error, flip)]
    report = {"table1": str(args.table1), "steps": table1["steps"], "rows": rows,
              "spearman": float(spearmanr(error, flip).statistic),
              "thresholds": {"good": grades.GOOD, "poor": grades.POOR},
              "flip_bands": {"good": FLIP_GOOD, "poor": FLIP_POOR}, "agreement": agreement(error, flip),
              "wall_seconds": time.perf_counter() - started}
    write_report(args.out, report, [trained.SHIPPED])
    chart(error, flip, args.out.with_suffix(".png"))
    print(f"spearman {report['spearman']:.3f}; agreement {report['agreement']}")
    return 0


def agreement(error: np.ndarray, flip: np.ndarray) -> dict[str, float]:
    """Of the fits FLIP calls good (poor), the share the thresholds grade good (poor), and the misses."""
    good, poor = flip <= FLIP_GOOD, flip > FLIP_POOR

    def share(mask: np.ndarray, hit: np.ndarray) -> float:
        return float(hit[mask].mean()) if mask.any() else float("nan")

    return {"good_graded_good": share(good, error <= grades.GOOD), "poor_graded_poor": share(poor, error > grades.POOR),
            "poor_graded_good": share(poor, error <= grades.GOOD), "good_graded_poor": share(good, error > grades.POOR)}


def chart(error: np.ndarray, flip: np.ndarray, path: Path) -> None:
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(5.5, 4))
    ax.scatter(error, flip, s=12)
    for x in (grades.GOOD, grades.POOR):
        ax.axvline(x, color="grey", ls="--", lw=0.8)
    for y in (FLIP_GOOD, FLIP_POOR):
        ax.axhline(y, color="grey", ls=":", lw=0.8)
    ax.set_xlabel("fit error (relative, log(1 + reflected light))")
    ax.set_ylabel("Table 1 ball FLIP vs analytic")
    ax.set_title("fit error against FLIP: grades good | visible | poor")
    save_chart(fig, path)


if __name__ == "__main__":
    torch.set_num_threads(2)
    raise SystemExit(main())
