"""Where the neural material breaks down: FLIP against roughness, IOR, metalness and view angle.

One base material is drawn with the enhancement rules (Type 0, haze: the core
and haze lobes that roughness, IOR and metalness act on), and one PBR input is
swept at a time through ``enhance`` itself, with the same seed, so every other
parameter stays put and the derived ones follow the rules (alpha_core = r^p,
alpha_haze = min(1, s r^q)):

- roughness r in 0.02 .. 1, for a dielectric and for a metal;
- metalness 0 .. 1 (0.5: half dielectric, half conductor, the rarest case in
  training: only 10 % of training vectors are partial metals);
- the dielectric IOR over its schema range 1.3 .. 1.8 (set in the enhanced vector).

All sweep points are fitted together against the frozen decoder (then refitted
under the energy bound and scaled where still needed, as the fit command does), rendered analytically and
neurally on the preview ball and compared with mean FLIP.

Grazing angle is not a material parameter: the ball shows every view angle at
once. Two measures: the per-pixel FLIP maps of all sweep points averaged in
bands of theta_v = acos(n.v) at the pixel centres (what one sees, though FLIP's
spatial filter mixes the outermost band with the silhouette), and the relative
error of the directional albedo of f_neu (decoder against analytic, same
Monte Carlo samples) against theta_i (no image in between).

    python -m bench.neural.neural_failure_modes [--seed S] [--quick] [--weights RUN ...]

``--weights`` repeats: the decoders are measured side by side on the same sweep
points and the same analytic renders. Writes docs/reports/neural_failure_modes.json and
.png (one panel per parameter, a line per decoder, and analytic | neural | FLIP
of each decoder's worst sweep point).
"""
from __future__ import annotations

import argparse
import math
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch

from bench.common import (FLIP_CONVENTION, TARGET_WORST, add_out_argument, add_weights_argument, pyplot, save_chart,
                          target_lines, weights_folders, write_report)
from richmat_addon.core.enhance import enhance
from richmat_addon.core.maps import ParamMap, PbrInputs
from richmat_addon.core.schema import CHANNEL_SLICES
from torch_models.brdf.model import LayeredBsdf, luminance, params_from_vectors
from torch_models.neural import trained
from torch_models.neural.energy import fit_bounded
from torch_models.neural.mlp.energy import REFIT_STEPS
from torch_models.neural.evaluate import BallSetup, Comparison, compare, render_neural, render_reference, side_by_side
from torch_models.neural.fit.latents import fit_latents
from torch_models.neural.model import NeuralModel
from torch_models.render.camera import hit_sphere, primary_rays
from torch_models.render.preview_scene import PreviewScene

FULL = {"roughness": (0.02, 0.05, 0.1, 0.2, 0.4, 0.7, 1.0), "metalness": (0.0, 0.25, 0.4, 0.5, 0.6, 0.75, 1.0),
        "ior": (1.3, 1.4, 1.5, 1.6, 1.7, 1.8)}
QUICK = {"roughness": (0.02, 0.1, 0.4, 1.0), "metalness": (0.0, 0.5, 1.0), "ior": (1.3, 1.55, 1.8)}
VIEW_BANDS = (0.0, 0.1, 0.2, 0.35, 0.5, 0.7, 0.85, 1.0)  # n.v band edges on the ball
ALBEDO_ANGLES = (0.0, 30.0, 45.0, 60.0, 70.0, 80.0, 85.0, 88.0)  # theta_i, degrees


@dataclass(frozen=True)
class SweepPoint:
    sweep: str  # "roughness, dielectric", "roughness, metal", "metalness" or "ior"
    value: float
    vector: np.ndarray  # packed (22,)
    base_color: np.ndarray  # (3,)


def enhanced_vector(base_color: np.ndarray, roughness: float, metalness: float, seed: int) -> np.ndarray:
    """Packed Type 0 vector of constant PBR inputs; one seed, so only the inputs move the result."""
    pbr = PbrInputs("sweep", ParamMap.constant(*base_color), ParamMap.constant(roughness),
                    ParamMap.constant(metalness))
    mat = enhance(pbr, 0, seed)
    return np.concatenate([np.atleast_1d(mat.params[k].mean()) for k in CHANNEL_SLICES]).astype(np.float32)


def sweeps(seed: int, values: dict[str, tuple[float, ...]]) -> list[SweepPoint]:
    """The sweep points around one base material drawn from ``seed``."""
    rng = np.random.default_rng(seed)
    base = rng.uniform(0.05, 0.9, 3).astype(np.float32)
    rough = float(rng.uniform(0.2, 0.5))
    enhance_seed = int(rng.integers(1 << 30))
    points = [SweepPoint(f"roughness, {kind}", r, enhanced_vector(base, r, metal, enhance_seed), base)
              for kind, metal in (("dielectric", 0.0), ("metal", 1.0)) for r in values["roughness"]]
    points += [SweepPoint("metalness", m, enhanced_vector(base, rough, m, enhance_seed), base)
               for m in values["metalness"]]
    dielectric = enhanced_vector(base, rough, 0.0, enhance_seed)
    for ior in values["ior"]:
        vector = dielectric.copy()
        vector[CHANNEL_SLICES["diel_ior"]] = ior
        points.append(SweepPoint("ior", ior, vector, base))
    return points


def view_cosines(scene: PreviewScene) -> np.ndarray:
    """n.v at every pixel centre of the ball (H, W); NaN off the ball."""
    origin, d = primary_rays(scene, torch.full((scene.resolution ** 2, 2), 0.5))
    hit, p = hit_sphere(origin, d, scene.radius)
    cos = (-(p / scene.radius) * d).sum(-1)
    return torch.where(hit, cos, torch.full_like(cos, math.nan)).reshape(scene.resolution, -1).numpy()


def flip_by_view_band(errors: list[np.ndarray], cosines: np.ndarray) -> list[dict]:
    """Mean per-pixel FLIP of all maps in each band of n.v."""
    stack = np.stack(errors)
    out = []
    for lo, hi in zip(VIEW_BANDS[:-1], VIEW_BANDS[1:]):
        band = (cosines >= lo) & (cosines < hi if hi < 1.0 else cosines <= hi)
        out.append({"cos_lo": lo, "cos_hi": hi, "theta_mid_deg": math.degrees(math.acos((lo + hi) / 2)),
                    "pixels": int(band.sum()), "flip": float(stack[:, band].mean())})
    return out


def albedo_errors(model: NeuralModel, vectors: np.ndarray, z: torch.Tensor, scale: torch.Tensor,
                  n: int = 2048, seed: int = 0) -> np.ndarray:
    """|A_neural - A_analytic| / A_analytic of f_neu's directional albedo (luminance), (K, angles).

    Both estimated with the same samples, a third each from the analytic model's
    sampler, the sampling decoder and a cosine lobe (so energy either model puts
    off the other's lobes is seen). Every (material, angle, sample) is one row.
    """
    gen = torch.Generator().manual_seed(seed)
    k, a = len(vectors), len(ALBEDO_ANGLES)
    rows = torch.arange(k).repeat_interleave(a * n)
    theta = torch.tensor(ALBEDO_ANGLES).deg2rad().repeat_interleave(n).repeat(k)
    wi = torch.stack([theta.sin(), torch.zeros_like(theta), theta.cos()], -1)
    with torch.no_grad():
        bsdf = LayeredBsdf(params_from_vectors(torch.from_numpy(vectors)[rows]), torch.ones(1, 3))
        u = torch.rand(len(rows), 3, generator=gen)
        r, phi = u[:, 1].sqrt(), 2 * math.pi * u[:, 2]
        cosine = torch.stack([r * phi.cos(), r * phi.sin(), (1 - u[:, 1]).clamp(min=0).sqrt()], -1)
        pick = u[:, :1] * 3.0
        wo = torch.where(pick < 1.0, bsdf.sample(wi, torch.rand(len(rows), 3, generator=gen)),
                         torch.where(pick < 2.0, model.sampler.sample(z[rows], wi, torch.rand(len(rows), 3,
                                                                                              generator=gen)), cosine))
        pdf = (bsdf.pdf(wi, wo) + model.sampler.pdf(z[rows], wi, wo) + wo[:, 2].clamp(min=0) / math.pi) / 3.0
        weight = torch.where((wo[:, 2] > 0) & (pdf > 0), 1.0 / pdf.clamp(min=1e-12), torch.zeros_like(pdf))
        analytic = luminance(bsdf.eval_neural_part(wi, wo))[:, 0] * weight
        neural = luminance(scale[rows, None] * model.decoder(z[rows], wi, wo)[0])[:, 0] * weight
    analytic, neural = (x.reshape(k, a, n).mean(-1) for x in (analytic, neural))
    return ((neural - analytic).abs() / analytic.clamp(min=1e-6)).numpy()


def evaluate(folder: Path, points: list[SweepPoint], references: list[np.ndarray], setup: BallSetup,
             steps: int, batch: int, albedo_n: int, seed: int) -> tuple[dict, Comparison]:
    """One decoder on every sweep point, fitted as ``fit`` does; its report block and worst comparison."""
    model = trained.load(folder)
    vectors = np.stack([p.vector for p in points])
    z = fit_latents(model, vectors, steps, batch=batch, seed=seed)
    bounded = fit_bounded(model, vectors, z, seed=seed, steps=min(steps, REFIT_STEPS))  # as `fit` does
    z, check = bounded.z, bounded.check
    scale = check.energy_scale()
    rows, results = [], []
    for k, point in enumerate(points):
        result = compare(references[k], render_neural(setup, model, z[k], point.base_color, float(scale[k])))
        results.append(result)
        v = point.vector
        rows.append({"sweep": point.sweep, "value": point.value, "flip": result.flip,
                     "alpha_core": float(v[CHANNEL_SLICES["alpha_core"]][0]),
                     "alpha_haze": float(v[CHANNEL_SLICES["alpha_haze"]][0]),
                     "furnace_albedo": float(check.albedo[k]), "refitted": bool(bounded.refitted[k]),
                     "energy_scale": float(scale[k])})
        print(f"{model.decoder.kind:6s} {point.sweep:22s} {point.value:5.2f}  FLIP {result.flip:.4f}", flush=True)
    errors = albedo_errors(model, vectors, z, scale, albedo_n, seed)
    worst = int(np.argmax([r["flip"] for r in rows]))
    return {"weights": str(folder), "kind": model.decoder.kind, "decoder_sha256": model.digest, "points": rows,
            "grazing": {"flip_by_view_band": flip_by_view_band([r.error for r in results], view_cosines(setup.scene)),
                        "albedo_theta_deg": list(ALBEDO_ANGLES),
                        "albedo_rel_error_median": np.median(errors, 0).tolist(),
                        "albedo_rel_error_max": errors.max(0).tolist()},
            "worst": rows[worst], "above_target_worst": [r for r in rows if r["flip"] > TARGET_WORST]}, results[worst]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--quick", action="store_true", help="fewer points, smaller and noisier balls (< 2 min)")
    add_weights_argument(parser)
    add_out_argument(parser, "neural_failure_modes.json")
    parser.add_argument("--steps", type=int, help="fit steps (all sweep points fitted together)")
    args = parser.parse_args()
    folders = weights_folders(args)
    # Full: 200 x 4096 samples give each of the 27 points ~30 k, more than fit_flip.py gives each of its 300.
    resolution, spp, steps, batch, albedo_n = (64, 16, 20, 1024, 512) if args.quick else (96, 32, 200, 4096, 4096)
    steps = args.steps or steps

    start = time.perf_counter()
    points = sweeps(args.seed, QUICK if args.quick else FULL)
    setup = BallSetup.default(resolution, spp, args.seed)
    references = [render_reference(setup, p.vector, p.base_color) for p in points]
    decoders, worst = [], []
    for folder in folders:
        block, comparison = evaluate(folder, points, references, setup, steps, batch, albedo_n, args.seed)
        decoders.append(block)
        worst.append(comparison)
        print(f"{block['kind']} worst: {block['worst']['sweep']} {block['worst']['value']} "
              f"FLIP {block['worst']['flip']:.4f}")
    report = {"seed": args.seed, "quick": args.quick, "resolution": resolution, "spp": spp, "fit_steps": steps,
              "flip_convention": FLIP_CONVENTION,
              "base_color": points[0].base_color.tolist(), "decoders": decoders,
              "wall_seconds": time.perf_counter() - start}
    write_report(args.out, report, folders)
    chart(report, worst, args.out.with_suffix(".png"))
    print(f"{report['wall_seconds']:.0f} s")


def chart(report: dict, worst: list[Comparison], path: Path) -> None:
    plt = pyplot()

    decoders = report["decoders"]
    fig = plt.figure(figsize=(13, 4.2 + 2.6 * len(decoders)))
    grid = fig.add_gridspec(1 + len(decoders), 4, height_ratios=[1.6] + [1.0] * len(decoders))
    panels = [fig.add_subplot(grid[0, k]) for k in range(4)]
    for d, style in zip(decoders, ("o-", "s--", "^:", "d-.")):
        rows, name = d["points"], f"{d['kind']} {d['decoder_sha256'][:8]}"

        def series(ax, sweep: str, label: str) -> None:  # type: ignore[no-untyped-def]
            pts = [r for r in rows if r["sweep"] == sweep]
            ax.plot([r["value"] for r in pts], [r["flip"] for r in pts], style, label=label, ms=4)

        series(panels[0], "roughness, dielectric", f"{name}, dielectric")
        series(panels[0], "roughness, metal", f"{name}, metal")
        series(panels[1], "ior", name)
        series(panels[2], "metalness", name)
        bands = d["grazing"]["flip_by_view_band"]
        panels[3].plot([b["theta_mid_deg"] for b in bands], [b["flip"] for b in bands], style, ms=4, label=name)
    panels[0].set_xscale("log")
    panels[0].set(xlabel="PBR roughness r (alpha_core = r^p)", ylabel="mean FLIP, neural vs analytic", title="Roughness")
    panels[1].set(xlabel="dielectric IOR", title="IOR")
    panels[2].set(xlabel="metalness", title="Metalness")
    panels[3].set(xlabel="view angle theta (deg)", title="Grazing angle (FLIP per view band on the ball)")
    for ax in panels:
        target_lines(ax, labelled=False)
        ax.set_ylim(bottom=0)
        ax.legend(fontsize=6)
    for k, (d, comparison) in enumerate(zip(decoders, worst)):
        sheet = fig.add_subplot(grid[1 + k, :])
        sheet.imshow(side_by_side([comparison]))
        sheet.set_axis_off()
        w = d["worst"]
        sheet.set_title(f"{d['kind']}: worst point {w['sweep']} = {w['value']:g} (alpha_core {w['alpha_core']:.2g}), "
                        f"FLIP {w['flip']:.3f}: analytic | neural | FLIP map", fontsize=9)
    fig.suptitle(f"Where the neural material breaks down (Type 0 base, seed {report['seed']}, "
                 f"{report['resolution']} px, {report['spp']} spp; dashed 0.05, dotted 0.12)")
    save_chart(fig, path)


if __name__ == "__main__":
    main()
