"""Decoders side by side on Table 1's cases and on vectors of held-out real assets (issue 41, items 2 and 4).

Each decoder (``--weights``, repeatable; default: the shipped one alone) fits every case's
vector in one fit (``--per-vector`` samples per vector and step, the add-on's 300 steps), and
the torch renderer draws the ball of the analytic material (two seeds: the noise floor) and of
each decoder as the preview shows it: a decoder whose gates read both directions through its
closure form (its gates held per shading point, ``closure_form``), beside itself in full; a
view-gated decoder is its own closure form. Beside them, the first decoder's lobe form with its
own parameters per case (``free_lobes``, ``FREE_STEPS`` steps from that decoder's fit): what a
decoder with these lobes should not beat, so a decoder's distance from it is what its shared
networks and latent space cost. Two case sets:

* ``table1``: the agreement cases (``support/agreement_cases.py``, seed 0, ``--per-type`` per
  type, metals where the type allows);
* ``real``: ``--per-material`` vectors of every material of the real assets the benches hold out
  (``neural_error_budget.ASSETS``; ``support/real_cases.py``), none of which any decoder here
  trained on.

Two scenes (the probe; the probe and a sun). The chart sets each decoder's mean FLIP against
the torch cost of its preview form's gates per shading point.

    python -m bench.neural.decoder_candidates [--weights FOLDER ...] [--per-type 2] [--per-material 2]
        [--out docs/reports/decoder_candidates.json]

The candidates its reports measured (``LABELS``) have left the package; each is in git at 29f9efd
(docs/history.md, "Candidate decoders and configs"). To measure one again beside the shipped decoder::

    git checkout 29f9efd -- torch_models/neural/weights/view_gates_wide
    python -m bench.neural.decoder_candidates --weights torch_models/neural/weights \
        --weights torch_models/neural/weights/view_gates_wide

(The view-gated one, ``view_gates``, is also kept as a test fixture in ``tests/data/view_gated_decoder``.)
"""
from __future__ import annotations

import argparse
import dataclasses
import time
from pathlib import Path

import numpy as np
import torch

from bench.common import (FLIP_CONVENTION, add_out_argument, add_weights_argument, pyplot, save_chart,
                          weights_folders, write_report)
from bench.neural.neural_error_budget import ASSETS as HELD_OUT_ASSETS
from support.agreement_cases import Case, cases
from support.real_cases import real_cases
from torch_models.brdf.model import LayeredBsdf, params_from_vectors
from torch_models.neural import trained
from torch_models.neural.bsdf import NeuralBsdf
from torch_models.neural.evaluate import KEY_LIGHT, SCENES, BallSetup, ball_image
from torch_models.neural.fit.latents import deterministic, fit_latents, held_out_loss
from torch_models.neural.hybrid import free_lobes
from torch_models.neural.hybrid.closure_form import ClosureForm, closure_model
from torch_models.neural.model import NeuralModel
from torch_models.render.flip import mean_flip

FIT_STEPS = 300  # the add-on's Fit Steps
FREE_STEPS = 1500  # the free lobe form's fit: 168 parameters per case where a latent has 6
LABELS = {  # by weights folder name: the shipped decoder's, then the candidates (in git at 29f9efd)
    "shipped": "shipped, closure form (the preview)", "shipped_full": "shipped in full (torch only)",
    "view_gates": "view-gated, own encoder", "real": "view-gated, real vectors, shipped encoder",
    "view_gates_real": "view-gated, real vectors, own encoder",
    "view_gates_real_l4": "the same with four GGX lobes",
    "view_gates_l4": "view-gated, four GGX lobes, own encoder",
    "view_gates_l4_seed1": "the same, training seed 1",
    "view_gates_wide": "view-gated, head 128 wide", "view_gates_wide_seed1": "the same, training seed 1",
    "lobe_form": "lobe form, free per case (no decoder beats it)"}


def fitted(model: NeuralModel, vectors: np.ndarray, per_vector: int) -> tuple[torch.Tensor, float]:
    """Every vector's latent (one fit), and the held-out loss of the fit."""
    with deterministic():
        z = fit_latents(model, vectors, FIT_STEPS, seed=0, per_vector=per_vector).detach()
    return z, held_out_loss(model, vectors, z)


def gate_seconds(model: NeuralModel, points: int = 1 << 15) -> float:
    """Torch seconds per million shading points of the preview form's gates (median of three)."""
    form = ClosureForm(model.decoder)
    z = torch.randn(points, 6)
    wi = torch.nn.functional.normalize(torch.rand(points, 3) + torch.tensor([0.0, 0.0, 0.2]), dim=-1)
    times = []
    with torch.no_grad():
        for _ in range(3):
            start = time.perf_counter()
            form.gates_at(z, wi)
            times.append(time.perf_counter() - start)
    return float(np.median(times)) * 1e6 / points


def previews(name: str, model: NeuralModel) -> dict[str, NeuralModel]:
    """What the preview renders of a decoder (``name``), and the decoder in full where they differ."""
    if model.decoder.view_gates:
        return {name: model}
    return {name: closure_model(model), f"{name}_full": model}


def is_metal(case: Case) -> bool:
    return case.params["metalness"][0] > 0.5


def measure(chosen: list[Case], decoders: dict[str, NeuralModel], per_vector: int, setup: BallSetup
            ) -> tuple[list[dict], dict[str, float]]:
    """Per case and scene: the noise floor and each preview's mean FLIP; and each decoder's fit loss."""
    vectors = np.stack([c.vector() for c in chosen])
    fits = {name: fitted(m, vectors, per_vector) for name, m in decoders.items()}
    first = next(iter(decoders))
    with deterministic():
        free, params = free_lobes.fit_free(decoders[first], vectors, fits[first][0], FREE_STEPS, per_vector)
    fits["lobe_form"] = params, held_out_loss(free, vectors, params)
    rows = []
    for i, case in enumerate(chosen):
        base = torch.tensor([case.base_color], dtype=torch.float32)
        analytic = LayeredBsdf(params_from_vectors(torch.from_numpy(vectors[i:i + 1])), base)
        row: dict = {"name": case.name, "metal": is_metal(case)}
        for scene, sun in SCENES.items():
            ref = ball_image(setup, analytic, 0, sun)
            row[scene] = {"noise_floor": mean_flip(ref, ball_image(setup, analytic, 1, sun))}
            for name, model in decoders.items():
                z = fits[name][0][i:i + 1]
                for label, form in previews(name, model).items():
                    row[scene][label] = mean_flip(ref, ball_image(setup, NeuralBsdf(form, z, base), 0, sun))
            bound = NeuralBsdf(free, params[i:i + 1], base)
            row[scene]["lobe_form"] = mean_flip(ref, ball_image(setup, bound, 0, sun))
        rows.append(row)
        print(case.name, {s: {k: round(v, 4) for k, v in row[s].items()} for s in SCENES}, flush=True)
    return rows, {name: loss for name, (_, loss) in fits.items()}


def summarise(rows: list[dict]) -> dict:
    keys = [k for k in rows[0][next(iter(SCENES))]]
    out = {}
    for scene in SCENES:
        for group, keep in (("all", lambda r: True), ("metals", lambda r: r["metal"]),
                            ("dielectrics", lambda r: not r["metal"])):
            chosen = [r for r in rows if keep(r)]
            if chosen:
                out[f"{scene}_{group}"] = {k: {"mean": float(np.mean([r[scene][k] for r in chosen])),
                                               "median": float(np.median([r[scene][k] for r in chosen])),
                                               "worst": float(max(r[scene][k] for r in chosen)),
                                               "count": len(chosen)} for k in keys}
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_weights_argument(parser)
    parser.add_argument("--per-type", type=int, default=2, help="Table 1 cases per type")
    parser.add_argument("--per-material", type=int, default=2, help="real cases per material of the held-out assets")
    parser.add_argument("--per-vector", type=int, default=1365, help="the fit's samples per vector and step")
    parser.add_argument("--resolution", type=int, default=48)
    parser.add_argument("--spp", type=int, default=64)
    add_out_argument(parser, "decoder_candidates.json")
    args = parser.parse_args()
    start = time.perf_counter()
    folders = weights_folders(args)
    names = ["shipped" if f.resolve() == trained.SHIPPED.resolve() else f.name for f in folders]
    decoders = {name: trained.load(f) for name, f in zip(names, folders)}
    setup = BallSetup.default(args.resolution, args.spp, 0)
    sets = {"table1": cases(0, args.per_type, 0), "real": real_cases(list(HELD_OUT_ASSETS), args.per_material)}
    report: dict = {"decoders": {n: str(f) for n, f in zip(names, folders)}, "sets": {}, "held_out_loss": {},
                    "gate_seconds_per_million_points": {n: gate_seconds(m) for n, m in decoders.items()},
                    "settings": {"per_type": args.per_type, "per_material": args.per_material,
                                 "held_out_assets": list(HELD_OUT_ASSETS), "per_vector": args.per_vector,
                                 "fit_steps": FIT_STEPS, "resolution": args.resolution, "spp": args.spp,
                                 "sun": dataclasses.asdict(KEY_LIGHT)},
                    "flip_convention": FLIP_CONVENTION}
    for set_name, chosen in sets.items():
        rows, losses = measure(chosen, decoders, args.per_vector, setup)
        report["sets"][set_name] = {"cases": rows, "summary": summarise(rows)}
        report["held_out_loss"][set_name] = losses
        report["wall_seconds"] = time.perf_counter() - start
        write_report(args.out, report, folders)
        chart(report, args.out.with_suffix(".png"))
        for key, block in report["sets"][set_name]["summary"].items():
            print(set_name, key, {k: f"{v['mean']:.4f}/{v['worst']:.4f}" for k, v in block.items()}, flush=True)


def chart(report: dict, path: Path) -> None:
    """Per case set and scene: mean and worst FLIP of each preview by group; then speed against accuracy."""
    plt = pyplot()
    sets = list(report["sets"])
    fig, axes = plt.subplots(1, 2 * len(sets) + 1, figsize=(5.2 * (2 * len(sets) + 1), 4.8))
    labels = [k for k in next(iter(report["sets"][sets[0]]["summary"].values())) if k != "noise_floor"]
    colours = dict(zip(labels, plt.get_cmap("tab10").colors))
    for col, (set_name, scene) in enumerate((s, sc) for s in sets for sc in SCENES):
        ax = axes[col]
        summary = report["sets"][set_name]["summary"]
        groups = [g for g in ("metals", "dielectrics") if f"{scene}_{g}" in summary]
        width = 0.8 / len(labels)
        for j, label in enumerate(labels):
            x = np.arange(len(groups)) + (j - (len(labels) - 1) / 2) * width
            means = [summary[f"{scene}_{g}"][label]["mean"] for g in groups]
            worst = [summary[f"{scene}_{g}"][label]["worst"] for g in groups]
            ax.bar(x, means, width, color=colours[label], label=LABELS.get(label, label))
            ax.scatter(x, worst, color=colours[label], marker="v", edgecolor="k", zorder=3)
        ax.axhline(0.05, ls="--", color="k", lw=0.8)
        counts = [summary[f"{scene}_{g}"][labels[0]]["count"] for g in groups]
        ax.set_xticks(np.arange(len(groups)), [f"{g} ({n})" for g, n in zip(groups, counts)])
        ax.set_ylabel("mean FLIP vs analytic (bar: mean, triangle: worst)")
        ax.set_title(f"{set_name} cases, {scene}")
        if col == 0:
            ax.legend(fontsize=7)
    ax = axes[-1]
    seconds = report["gate_seconds_per_million_points"]
    for set_name, marker in zip(sets, "os"):
        summary = report["sets"][set_name]["summary"]
        for label in labels:
            if label not in seconds:
                continue  # the full decoders and the lobe-form bound are not previews: no gate cost
            ax.scatter(seconds[label], summary[f"{next(iter(SCENES))}_all"][label]["mean"], color=colours[label],
                       marker=marker, s=60, label=f"{LABELS.get(label, label)}, {set_name} cases")
    ax.set_xscale("log")
    ax.set_xlabel("torch s per million shading points (the preview's gates)")
    ax.set_ylabel(f"mean FLIP vs analytic ({next(iter(SCENES))})")
    ax.set_title("speed against accuracy")
    ax.legend(fontsize=7)
    save_chart(fig, path)


if __name__ == "__main__":
    main()
