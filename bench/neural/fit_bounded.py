"""The bounded fit: its cost against its accuracy, beside the per-vector fit, on photo-scanned textures.

Per material (the sample WaterBottle; the Poly Haven scan wooden_table_02 at 1k, and its
enhanced maps upsampled bicubically to 2k and 4k: as many distinct vectors as a scan of that
size, not its detail), enhanced at the farm's defaults (type auto, seed 0), at the add-on's
300 steps, one thread:

- **per vector** (the fit before the budget): every merged vector fitted with 4 samples a
  step. Its accuracy is measured on the probe's vectors, fitted exactly as it fits them
  (each vector's fit does not depend on the others'); its cost is its CPU seconds per
  vector times the material's vectors (the cost is linear in them past 4 096,
  ``fit_budget.json``).
- **bounded** at each ``--budgets`` (k-means in the encoder's latent space, each texel taking
  its representative's latent: what ships at ``FIT_BUDGET``), each also with the ``residual``
  transfer, and at ``FIT_BUDGET`` with the other metrics of ``representatives.METRICS``:
  measured whole, CPU seconds of choosing the representatives, fitting them, the energy check
  and the error readout.

Accuracy: the fit error (the add-on's measure, ``neural/fit/error.py``) of the probe's vectors
under the latents each design gives them: 2 048 texels drawn at random (texel-weighted: what
an image shows) and 512 distinct vectors (every vector alike: where merging loses most);
"transfer cost" is how much a design adds to the per-vector fit on the same vectors. The
readout's own estimate (one drawn vector per representative) stands beside. And the image:
the 32 x 32 crop with the most distinct vectors, a flat patch at 45 degrees under the probe,
neural against analytic (LDR-FLIP), with the analytic crop at another seed as the noise floor.

    python -m bench.neural.fit_bounded [--materials WaterBottle wooden_table_02_1k wooden_table_02_1k@4k ...]
        [--budgets 256 512 1024 2048 4096 16384] [--seed 0] [--out docs/reports/fit_bounded.json]
"""
from __future__ import annotations

import argparse
import tempfile
import time
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

import numpy as np
import torch

from bench.common import FLIP_CONVENTION, add_out_argument, pyplot, save_chart, write_report
from bench.neural.dedupe import CROP, flat_patch, texel_colours
from bench.farm.farm_cost import varied_crop
from richmat_addon.core import material_folder
from richmat_addon.core.maps import ParamMap
from richmat_addon.core.texel_vectors import FIT_BUDGET, QUANT, TexelVectors, read_vectors
from support.paths import SHARED_ASSETS
from torch_models.brdf.model import LayeredBsdf, params_from_vectors
from torch_models.neural import energy, trained
from torch_models.neural.bsdf import NeuralBsdf
from torch_models.neural.evaluate import DEFAULT_PROBE, compare
from torch_models.neural.fit import representatives
from torch_models.neural.fit.error import vector_errors
from torch_models.neural.fit.latents import fit_latents
from torch_models.neural.fit.material import FitSettings, fit_material
from torch_models.neural.model import NeuralModel
from torch_models.neural.real_vectors import enhanced_folders
from torch_models.render.envmap import EnvMap

SCAN_ASSET = "wooden_table_02_1k"  # a Poly Haven scan: 40 % of its 1k texels hold a distinct vector
MATERIALS = ("WaterBottle", SCAN_ASSET, f"{SCAN_ASSET}@2k", f"{SCAN_ASSET}@4k")
TEXEL_PROBE, VECTOR_PROBE = 2048, 512
STEPS = 300


def upsampled(folder: Path, size: int, out: Path) -> Path:
    """A copy of the enhanced material ``folder`` with every map resized bicubically to ``size``
    (clamped to each map's own range): the distinct vectors of a scan that size, not its detail."""
    mat = material_folder.read(folder).material()

    def resize(m: ParamMap) -> ParamMap:
        if m.is_constant:
            return m
        image = torch.from_numpy(m.value).permute(2, 0, 1)[None]
        big = torch.nn.functional.interpolate(image, size=(size, size), mode="bicubic", align_corners=False)
        return ParamMap(big[0].permute(1, 2, 0).clamp(float(m.value.min()), float(m.value.max())).numpy())

    mat = replace(mat, base_color=resize(mat.base_color), params={k: resize(v) for k, v in mat.params.items()})
    target = out / f"{folder.name}_{size}"
    material_folder.write(target, mat, {"asset": SCAN_ASSET, "material": target.name, "upsampled_to": size})
    return target


def material(name: str, out: Path) -> Path:
    """The enhanced material folder of one of ``MATERIALS``."""
    asset, _, size = name.partition("@")
    folder = enhanced_folders(SHARED_ASSETS / "models" / f"{asset}.glb", out / asset)[0]
    return upsampled(folder, int(size.rstrip("k")) * 1024, out) if size else folder


def cpu(work: Callable[[], object]) -> tuple[object, float]:
    start = time.process_time()
    return work(), time.process_time() - start


class Probe:
    """The vectors a material's accuracy is measured on, and its crop."""

    def __init__(self, mv: TexelVectors, folder: Path, env: EnvMap, seed: int = 5) -> None:
        rng = np.random.default_rng(seed)
        counts = np.bincount(mv.inverse, minlength=len(mv.unique))
        texels = rng.choice(len(mv.unique), TEXEL_PROBE, p=counts / counts.sum())
        distinct = rng.choice(len(mv.unique), min(VECTOR_PROBE, len(mv.unique)), replace=False)
        self.index, inverse = np.unique(np.concatenate([texels, distinct]), return_inverse=True)
        self.texel_weight = np.bincount(inverse[:TEXEL_PROBE], minlength=len(self.index)).astype(float)
        self.vector_weight = np.bincount(inverse[TEXEL_PROBE:], minlength=len(self.index)).astype(float)
        shape, rows = mv.shape, None
        assert shape is not None, "a textured material"
        full = mv.unique[mv.inverse]
        rows = varied_crop(full, shape)
        self.crop = mv.inverse[rows]
        self.colours = torch.from_numpy(texel_colours(folder, shape, rows))
        analytic = LayeredBsdf(params_from_vectors(torch.from_numpy(full[rows])), self.colours)
        self.env = env
        with torch.no_grad():
            self.reference = flat_patch(lambda n: analytic, env, CROP, 0)
            self.noise_floor = compare(self.reference, flat_patch(lambda n: analytic, env, CROP, 1)).flip

    def accuracy(self, model: NeuralModel, vectors: np.ndarray, z: torch.Tensor) -> dict:
        """Fit error over the probe's texels and distinct vectors, and the crop's FLIP, of latents
        ``z`` (one per merged vector of ``vectors``)."""
        errors = vector_errors(model, vectors[self.index], z[self.index], torch.ones(len(self.index)))
        neural = NeuralBsdf(model, z[torch.from_numpy(self.crop)], self.colours)
        with torch.no_grad():
            flip = compare(self.reference, flat_patch(lambda n: neural, self.env, CROP, 0)).flip
        return {"texel_error": float(np.average(errors, weights=self.texel_weight)),
                "vector_error": float(np.average(errors, weights=self.vector_weight)), "crop_flip": flip,
                "errors": errors}


def per_vector(model: NeuralModel, mv: TexelVectors, probe: Probe, seed: int) -> dict:
    """Today's fit of every vector, measured on the probe's vectors and priced per vector."""
    vectors = mv.unique[probe.index]
    # batch 1: every vector gets exactly its 4 samples a step, as among the tens of thousands of a 1k texture
    z, seconds = cpu(lambda: fit_latents(model, vectors, STEPS, batch=1, seed=seed))
    full = torch.zeros(len(mv.unique), 6)
    full[probe.index] = z
    crop = np.unique(probe.crop)
    missing = np.setdiff1d(crop, probe.index)
    if len(missing):
        full[missing] = fit_latents(model, mv.unique[missing], STEPS, batch=1, seed=seed)
    row = probe.accuracy(model, mv.unique, full)
    row.update(design="per vector", fit_cpu=seconds / len(vectors) * len(mv.unique), extrapolated=True,
               vectors_fitted=len(mv.unique))
    return row


def bounded(model: NeuralModel, mv: TexelVectors, probe: Probe, budget: int, metric: str, transfer: str,
            fitted: dict, seed: int) -> dict:
    """One bounded design, measured whole; fits are shared between transfers via ``fitted``."""
    key = (budget, metric)
    if key not in fitted:
        counts = np.bincount(mv.inverse, minlength=len(mv.unique)).astype(np.float64)
        reps, choose = cpu(lambda: representatives.choose(model, mv.unique, counts, budget, seed, metric))
        z, fit = cpu(lambda: fit_latents(model, reps.vectors, STEPS, seed=seed))
        checked, check = cpu(lambda: energy.fit_bounded(model, reps.vectors, z, seed, steps=min(150, STEPS)))
        drawn = representatives.draw_members(reps, counts, seed)
        estimate, readout = cpu(lambda: vector_errors(model, mv.unique[drawn], checked.z,
                                                      checked.check.energy_scale(), seed))
        weight = np.bincount(reps.of_vector, counts, len(reps))
        fitted[key] = (reps, checked.z, {"choose_cpu": choose, "fit_cpu": fit, "energy_cpu": check,
                                         "readout_cpu": readout, "vectors_fitted": len(reps),
                                         "readout_estimate": float(np.average(estimate, weights=weight))})
    reps, z, costs = fitted[key]
    row = probe.accuracy(model, mv.unique, representatives.transfer(model, mv.unique, reps, z, transfer))
    row.update(design=f"bounded {budget}, {metric}, {transfer}", budget=budget, metric=metric, transfer=transfer,
               extrapolated=False, **costs)
    return row


def shipped(model: NeuralModel, folder: Path, out: Path, seed: int) -> dict:
    """The shipped fit (``fit_material`` at its defaults) end to end: wall and CPU seconds per stage."""
    start = time.perf_counter()
    record = fit_material(model, folder, out / "neural", FitSettings(steps=STEPS, seed=seed))
    return {"wall_s": time.perf_counter() - start, "stages_cpu_s": record["cpu_s"],
            "stages_wall_s": record["timings_s"], "fit_error_readout": record["fit_error"]["mean"],
            "fitted_vectors": record["fitted_vectors"], "merged_vectors": record["merged_vectors"]}


def measure(name: str, model: NeuralModel, env: EnvMap, budgets: list[int], seed: int, tmp: Path) -> dict:
    folder = material(name, tmp)
    mv, read = cpu(lambda: read_vectors(folder, QUANT))
    probe = Probe(mv, folder, env)
    print(f"{name}: {mv.shape} texels, {mv.exact_unique} exact, {len(mv.unique)} merged; read {read:.1f} CPU s",
          flush=True)
    rows = [per_vector(model, mv, probe, seed)]
    fitted: dict = {}
    designs = [(b, "encoder", t) for b in budgets for t in representatives.TRANSFERS]
    designs += [(FIT_BUDGET, m, "nearest") for m in representatives.METRICS if m != "encoder"]
    for budget, metric, transfer in designs:
        if budget < len(mv.unique):
            rows.append(bounded(model, mv, probe, budget, metric, transfer, fitted, seed))
    reference = rows[0]["errors"]
    for row in rows:
        # what the design adds to the per-vector fit, vector by vector, over the probe's texels
        row["transfer_cost"] = float(np.average(row.pop("errors") - reference, weights=probe.texel_weight))
        row["read_cpu"] = read
        print(f"  {row['design']}: texel error {row['texel_error']:.4f}, vector error {row['vector_error']:.4f}, "
              f"crop FLIP {row['crop_flip']:.4f} (floor {probe.noise_floor:.4f}), fit {row['fit_cpu']:.1f} CPU s",
              flush=True)
    return {"texture": list(mv.shape), "texels": int(len(mv.inverse)), "exact_unique": mv.exact_unique,
            "merged_vectors": len(mv.unique), "crop_noise_floor": probe.noise_floor, "designs": rows,
            "shipped_fit": shipped(model, folder, tmp / name, seed)}


def chart(report: dict, path: Path) -> None:
    """Per material: fit error over the probe's texels against the fit's CPU seconds, and the crop's
    FLIP against them with its noise floor."""
    plt = pyplot()
    names = list(report["materials"])
    fig, axes = plt.subplots(2, len(names), figsize=(4.2 * len(names), 8.4), squeeze=False)
    for col, name in enumerate(names):
        m = report["materials"][name]
        for ax, key, label in ((axes[0, col], "texel_error", "fit error over texels"),
                               (axes[1, col], "crop_flip", "crop FLIP, neural vs analytic")):
            for row in m["designs"]:
                cost = row["fit_cpu"] + row.get("choose_cpu", 0.0)
                style = ("*", "tab:red", 14) if row["design"] == "per vector" else (
                    ("o", "tab:blue", 7) if row.get("metric") == "encoder" and row["transfer"] == "nearest"
                    else ("s", "tab:gray", 6))
                ax.plot(cost, row[key], style[0], color=style[1], ms=style[2])
                short = "per vector (cost extrapolated)" if row["design"] == "per vector" else \
                    row["design"].replace("bounded ", "").replace("encoder, ", "")
                ax.annotate(short, (cost, row[key]), textcoords="offset points", xytext=(4, 3), fontsize=6)
            if key == "crop_flip":
                ax.axhline(m["crop_noise_floor"], ls="--", color="k", lw=0.8, label="noise floor (another seed)")
                ax.legend(fontsize=7)
            ax.set_xscale("log")
            ax.set_xlabel("CPU s, one thread: choosing + fitting")
            ax.set_ylabel(label)
            ax.set_title(f"{name} {m['texture'][0]}x{m['texture'][1]}: {m['merged_vectors']} vectors", fontsize=9)
    fig.suptitle("Bounded fit (blue: encoder metric, nearest; grey: other metric or residual transfer) "
                 "against the per-vector fit (red star)", fontsize=10)
    save_chart(fig, path)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--materials", nargs="+", default=list(MATERIALS), choices=MATERIALS)
    parser.add_argument("--budgets", type=int, nargs="+", default=[256, 512, 1024, 2048, 4096, 16384])
    parser.add_argument("--seed", type=int, default=0,
                        help="seed of every fit and of the representatives (the probe is the same at every seed)")
    add_out_argument(parser, "fit_bounded.json")
    args = parser.parse_args()
    torch.set_num_threads(1)
    model, env = trained.load(trained.SHIPPED), EnvMap.load(DEFAULT_PROBE)
    report: dict = {"steps": STEPS, "threads": 1, "seed": args.seed, "budgets": args.budgets, "shipped_budget": FIT_BUDGET,
                    "probe": {"texels": TEXEL_PROBE, "distinct_vectors": VECTOR_PROBE, "crop": CROP},
                    "flip_convention": FLIP_CONVENTION, "materials": {}}
    with tempfile.TemporaryDirectory(prefix="richmat_fit_bounded_") as tmp:
        for name in args.materials:
            report["materials"][name] = measure(name, model, env, args.budgets, args.seed, Path(tmp))
            write_report(args.out, report, [trained.SHIPPED])
            chart(report, args.out.with_suffix(".png"))


if __name__ == "__main__":
    main()
