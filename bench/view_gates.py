"""The view-gated hybrid beside the shipped one: what an exact closure form costs (issue 41, item 2).

The preview gives Cycles the hybrid's lobes as closures, whose weights cannot depend on the
light direction; the shipped decoder's gates do, so the shader holds each gate at its mean
over its lobe (``closure_form.ClosureForm``). A view-gated decoder (``view_gates``: gates
from the latent and the view cosine) is its own closure form, exactly. For the agreement
cases (``support/agreement_cases.py``, seed 0, ``--per-type`` per type, metals where the type
allows), each decoder fits every case's vector (one fit, ``--per-vector`` samples per vector
and step), and the torch renderer draws the ball of

* the analytic material (two seeds: the noise floor),
* the shipped decoder as it is, and its closure form (what the preview shows in Cycles),
* the view-gated decoder (its closure form is itself),

in two scenes (the probe; the probe and a sun). The chart sets each against the cost of
its closure form's gates per shading point in torch.

    python -m bench.view_gates [--candidate RUN_FOLDER] [--per-type 4] [--resolution 48] [--spp 64]
        [--out docs/reports/view_gates.json]
"""
from __future__ import annotations

import argparse
import dataclasses
import time
from pathlib import Path

import numpy as np
import torch

from bench.common import FLIP_CONVENTION, add_out_argument, pyplot, save_chart, write_report
from support.agreement_cases import cases
from torch_models.brdf.model import LayeredBsdf, params_from_vectors
from torch_models.neural import fitting, trained
from torch_models.neural.bsdf import NeuralBsdf
from torch_models.neural.closure_form import ClosureForm, closure_model
from torch_models.neural.evaluate import KEY_LIGHT, SCENES, BallSetup
from torch_models.neural.model import NeuralModel
from torch_models.render.ball import Sun, render_ball
from torch_models.render.flip import mean_flip
from torch_models.render.tonemap import agx

FIT_STEPS = 300  # the add-on's Fit Steps


def fitted(model: NeuralModel, vectors: np.ndarray, per_vector: int) -> tuple[torch.Tensor, float]:
    """Every vector's latent (one fit), and the held-out loss of the fit."""
    with fitting.deterministic():
        z = fitting.fit_latents(model, vectors, FIT_STEPS, seed=0, per_vector=per_vector).detach()
    return z, fitting.held_out_loss(model, vectors, z)


def ball(bsdf: object, setup: BallSetup, seed: int, sun: Sun | None) -> np.ndarray:
    with torch.no_grad():
        return agx(render_ball(lambda n: bsdf, setup.env, setup.scene, setup.spp, seed, sun=sun).rgb)


def gate_seconds(model: NeuralModel, points: int = 1 << 15) -> float:
    """Torch seconds per million shading points of the closure form's gates (median of three)."""
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


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--candidate", type=Path, default=trained.SHIPPED / "view_gates",
                        help="the view-gated decoder's run folder (default: the one kept beside the shipped decoder)")
    parser.add_argument("--per-type", type=int, default=4)
    parser.add_argument("--per-vector", type=int, default=2048, help="the fit's samples per vector and step")
    parser.add_argument("--resolution", type=int, default=48)
    parser.add_argument("--spp", type=int, default=64)
    add_out_argument(parser, "view_gates.json")
    args = parser.parse_args()
    start = time.perf_counter()
    shipped, candidate = trained.load(trained.SHIPPED), trained.load(args.candidate)
    if not candidate.decoder.view_gates:
        raise SystemExit(f"{args.candidate}: its decoder's gates read both directions; train one with view_gates")
    chosen = cases(0, args.per_type, 0)
    vectors = np.stack([c.vector() for c in chosen])
    decoders = {"shipped": shipped, "view_gated": candidate}
    fits = {name: fitted(m, vectors, args.per_vector) for name, m in decoders.items()}
    # what each preview renders: the shipped decoder through its closure form; the view-gated one as it is
    renders = {"shipped": shipped, "shipped_closure_form": closure_model(shipped), "view_gated": candidate}
    latent_of = {"shipped": "shipped", "shipped_closure_form": "shipped", "view_gated": "view_gated"}
    setup = BallSetup.default(args.resolution, args.spp, 0)
    rows = []
    for i, case in enumerate(chosen):
        base = torch.tensor([case.base_color], dtype=torch.float32)
        analytic = LayeredBsdf(params_from_vectors(torch.from_numpy(vectors[i:i + 1])), base)
        row: dict = {"name": case.name, "metal": "metal" in case.name}
        for scene, sun in SCENES.items():
            ref = ball(analytic, setup, 0, sun)
            row[scene] = {"noise_floor": mean_flip(ref, ball(analytic, setup, 1, sun))}
            for name, model in renders.items():
                z = fits[latent_of[name]][0][i:i + 1]
                row[scene][name] = mean_flip(ref, ball(NeuralBsdf(model, z, base), setup, 0, sun))
        rows.append(row)
        print(case.name, {s: {k: round(v, 4) for k, v in row[s].items()} for s in SCENES}, flush=True)
    summary = {}
    for scene in SCENES:
        for group, keep in (("all", lambda r: True), ("metals", lambda r: r["metal"]),
                            ("dielectrics", lambda r: not r["metal"])):
            chosen_rows = [r for r in rows if keep(r)]
            summary[f"{scene}_{group}"] = {k: {"mean": float(np.mean([r[scene][k] for r in chosen_rows])),
                                               "worst": float(max(r[scene][k] for r in chosen_rows))}
                                           for k in ("noise_floor", *renders)}
    report = {"candidate": str(args.candidate), "cases": rows, "summary": summary,
              "held_out_loss": {name: loss for name, (_, loss) in fits.items()},
              "gate_seconds_per_million_points": {"shipped_closure_form": gate_seconds(shipped),
                                                  "view_gated": gate_seconds(candidate)},
              "settings": {"per_type": args.per_type, "per_vector": args.per_vector, "fit_steps": FIT_STEPS,
                           "resolution": args.resolution, "spp": args.spp, "sun": dataclasses.asdict(KEY_LIGHT)},
              "flip_convention": FLIP_CONVENTION, "wall_seconds": time.perf_counter() - start}
    write_report(args.out, report, [trained.SHIPPED, args.candidate])
    chart(report, args.out.with_suffix(".png"))
    for key, block in summary.items():
        print(key, {k: f"{v['mean']:.4f}/{v['worst']:.4f}" for k, v in block.items()})


def chart(report: dict, path: Path) -> None:
    plt = pyplot()
    fig, axes = plt.subplots(1, 3, figsize=(17, 4.8), gridspec_kw={"width_ratios": [2, 2, 1]})
    colours = {"shipped": "tab:gray", "shipped_closure_form": "tab:blue", "view_gated": "tab:green"}
    labels = {"shipped": "shipped decoder (torch only)", "shipped_closure_form": "shipped, closure form (preview)",
              "view_gated": "view-gated (its own closure form)"}
    names = [r["name"] for r in report["cases"]]
    x = np.arange(len(names))
    for ax, scene in zip(axes[:2], SCENES):
        for j, (key, colour) in enumerate(colours.items()):
            ax.bar(x + (j - 1) * 0.27, [r[scene][key] for r in report["cases"]], 0.27, color=colour, label=labels[key])
        ax.plot(x, [r[scene]["noise_floor"] for r in report["cases"]], "k_", ms=10, label="noise floor")
        ax.axhline(0.05, ls="--", color="k", lw=0.8)
        ax.set_xticks(x, [n.replace("_", "\n", 1) for n in names], fontsize=6)
        ax.set_ylabel("mean FLIP vs the analytic material")
        ax.set_title(f"fitted latents on the ball; scene: {scene}")
        ax.legend(fontsize=7)
    ax = axes[2]
    seconds = report["gate_seconds_per_million_points"]
    for key in ("shipped_closure_form", "view_gated"):
        for scene, marker in zip(SCENES, "os"):
            ax.scatter(seconds[key], report["summary"][f"{scene}_all"][key]["mean"], c=colours[key], marker=marker,
                       s=60, label=f"{labels[key]}, {scene}")
    ax.set_xlabel("torch s per million shading points (the gates)")
    ax.set_ylabel("mean FLIP vs analytic")
    ax.set_title("speed against accuracy")
    ax.legend(fontsize=6)
    save_chart(fig, path)


if __name__ == "__main__":
    main()
