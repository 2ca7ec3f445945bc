"""Fit unique materials, not texels: decoder evaluations with and without dedupe/clustering.

For each real asset (../shared/assets/models/*.glb), every material is enhanced
(Type auto, seed S) at its textures' own resolution and its texel vectors are
counted: all texels, exact-distinct vectors, and representatives after the
clustering of ``fit.material_vectors.read_vectors`` (each texel within 1/512 of its
representative per normalised parameter). At a fixed budget of samples per
fitted vector, a fit's decoder evaluations are proportional to the number of
vectors fitted, so the ratio texels / representatives is the saving.

Equal accuracy is measured, not assumed: on a 32 x 32 crop of one textured
material per asset, latents are fitted per texel and per representative with
the same samples per vector, both rendered in texture space (a flat patch seen
at 45 degrees under the probe) and compared with the analytic render by FLIP.

    python -m bench.neural.dedupe [--seed S] [--assets DIR] [--out FILE.json]
"""
from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np
import torch

from bench.common import REPO, add_out_argument, pyplot, save_chart, write_report
from richmat_addon.core import material_folder
from torch_models.brdf.model import LayeredBsdf, params_from_vectors
from torch_models.cli import main as cli
from torch_models.neural import trained
from torch_models.neural.model import NeuralModel
from torch_models.neural.bsdf import NeuralBsdf
from torch_models.neural.evaluate import DEFAULT_PROBE, compare
from torch_models.neural.fit.latents import fit_latents
from torch_models.neural.fit.material_vectors import MaterialVectors, read_vectors
from torch_models.render.ball import shade_gbuffer
from torch_models.render.envmap import EnvMap
from torch_models.render.tonemap import agx

CROP = 32
SAMPLES_PER_VECTOR = 32  # per Adam step, for either way of fitting
STEPS = 200


def flat_patch(bsdf_at, env: EnvMap, size: int, seed: int) -> np.ndarray:  # type: ignore[no-untyped-def]
    """AgX image of a size x size patch of texels facing +z, seen from 45 degrees."""
    normals = np.broadcast_to(np.array([0, 0, 1], np.float32), (size, size, 3)).copy()
    views = np.broadcast_to(np.array([0, -np.sqrt(0.5), np.sqrt(0.5)], np.float32), (size, size, 3)).copy()
    return agx(shade_gbuffer(bsdf_at, env, normals, views, np.ones((size, size), bool), spp=64, seed=seed))


def crop_rows(width: int, r0: int, c0: int) -> np.ndarray:
    """Texel indices (row-major, ``width`` texels a row) of the CROP x CROP crop at (r0, c0)."""
    return (np.arange(r0, r0 + CROP)[:, None] * width + np.arange(c0, c0 + CROP)[None, :]).ravel()


def texel_colours(folder: Path, shape: tuple[int, int], rows: np.ndarray) -> np.ndarray:
    """Base colours (N, 3) of the texels ``rows`` of a ``shape`` texture (the base colour map may be smaller)."""
    base = material_folder.read(folder).map("base_color")
    if base.is_constant:
        return np.broadcast_to(base.value[:3], (len(rows), 3)).astype(np.float32)
    img = base.value
    ys, xs = np.divmod(rows, shape[1])
    return np.ascontiguousarray(img[ys * img.shape[0] // shape[0], xs * img.shape[1] // shape[1], :3], np.float32)


def crop_vectors(folder: Path, mv: MaterialVectors) -> tuple[np.ndarray, np.ndarray]:
    """Texel vectors (CROP^2, 22) and base colours of the crop at the texture's centre."""
    h, w = mv.shape  # type: ignore[misc]
    rows = crop_rows(w, (h - CROP) // 2, (w - CROP) // 2)
    return mv.unique[mv.inverse[rows]], texel_colours(folder, (h, w), rows)


def equal_budget_fits(model: NeuralModel, vectors: np.ndarray, seed: int) -> dict[str, tuple]:
    """Latents per texel: fitted per texel, or per representative and shared (same samples per vector)."""
    uniq, inverse = np.unique(vectors, axis=0, return_inverse=True)
    out = {}
    for name, fitted, index in (("per_texel", vectors, np.arange(len(vectors))), ("deduplicated", uniq, inverse)):
        t0 = time.perf_counter()
        z = fit_latents(model, fitted, STEPS, batch=SAMPLES_PER_VECTOR * len(fitted), seed=seed)
        out[name] = (z[torch.from_numpy(index.ravel())], len(fitted), time.perf_counter() - t0)
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--assets", type=Path, default=REPO.parent / "shared" / "assets" / "models")
    parser.add_argument("--weights", type=Path, default=trained.SHIPPED)
    add_out_argument(parser, "dedupe.json")
    args = parser.parse_args()
    if not args.assets.is_dir():
        raise SystemExit(f"{args.assets}: no sample assets here")

    model = trained.load(args.weights)
    env = EnvMap.load(DEFAULT_PROBE)
    materials, crops = [], []
    with tempfile.TemporaryDirectory(prefix="richmat_dedupe_") as tmp:
        for asset in sorted(args.assets.glob("*.glb")):
            out = Path(tmp) / asset.stem
            if cli(["enhance", str(asset), "--type", "auto", "--seed", str(args.seed), "--out", str(out)]) != 0:
                print(f"{asset.name}: enhance refused it, skipped")
                continue
            largest = None
            for folder in sorted(p.parent for p in out.rglob(material_folder.RECORD)):
                mv = read_vectors(folder)
                texels = len(mv.inverse) if mv.shape else 1
                materials.append({"asset": asset.name, "material": folder.name, "texels": texels,
                                  "exact_unique": mv.exact_unique, "representatives": len(mv.unique)})
                print(f"{asset.name:28s} {folder.name:24s} texels {texels:9d}  exact {mv.exact_unique:8d}  "
                      f"fitted {len(mv.unique):6d}", flush=True)
                if mv.shape and min(mv.shape) >= CROP and (largest is None or texels > largest[1]):
                    largest = (folder, texels, mv)
            if largest is not None:
                vectors, colours = crop_vectors(largest[0], largest[2])
                ref = flat_patch(lambda n: LayeredBsdf(params_from_vectors(torch.from_numpy(vectors)),
                                                       torch.from_numpy(colours)), env, CROP, args.seed)
                row = {"asset": asset.name, "material": largest[0].name}
                for name, (z, fitted, seconds) in equal_budget_fits(model, vectors, args.seed).items():
                    bsdf = NeuralBsdf(model, z, torch.from_numpy(colours))
                    with torch.no_grad():
                        image = flat_patch(lambda n: bsdf, env, CROP, args.seed)
                    row[name] = {"fitted_vectors": fitted, "decoder_evaluations": STEPS * SAMPLES_PER_VECTOR * fitted,
                                 "fit_seconds": seconds, "flip": compare(ref, image).flip}
                crops.append(row)
                print(f"  crop: per texel FLIP {row['per_texel']['flip']:.4f} ({row['per_texel']['fitted_vectors']}"
                      f" vectors), deduplicated {row['deduplicated']['flip']:.4f} "
                      f"({row['deduplicated']['fitted_vectors']})", flush=True)

    texels = sum(m["texels"] for m in materials)
    reps = sum(m["representatives"] for m in materials)
    report = {"seed": args.seed, "samples_per_vector_per_step": SAMPLES_PER_VECTOR,
              "steps": STEPS, "total_texels": texels, "total_exact_unique": sum(m["exact_unique"] for m in materials),
              "total_representatives": reps, "evaluation_ratio": texels / reps, "target_ratio": 10.0,
              "passed": texels / reps >= 10.0, "materials": materials, "equal_flip_crops": crops}
    write_report(args.out, report, [args.weights])
    chart(report, args.out.with_suffix(".png"))
    print(f"{texels} texels -> {reps} fitted vectors: {texels / reps:.0f}x fewer decoder evaluations; wrote {args.out}")


def chart(report: dict, path: Path) -> None:
    plt = pyplot()
    fig, (a, b) = plt.subplots(1, 2, figsize=(12, 4.2))
    rows = report["materials"]
    x = np.arange(len(rows))
    for key, label in (("texels", "texels (no dedupe)"), ("exact_unique", "exact dedupe"),
                       ("representatives", "dedupe + clustering")):
        a.bar(x + {"texels": -0.27, "exact_unique": 0, "representatives": 0.27}[key], [r[key] for r in rows], 0.27,
              label=label)
    a.set_yscale("log")
    a.set_xticks(x, [f"{r['asset'][:10]}/{r['material'][:10]}" for r in rows], rotation=70, ha="right", fontsize=6)
    a.set_ylabel("vectors fitted (decoder evaluations scale with it)")
    a.set_title(f"{report['evaluation_ratio']:.0f}x fewer decoder evaluations over all sample assets")
    a.legend(fontsize=8)
    crops = report["equal_flip_crops"]
    for name, colour in (("per_texel", "tab:blue"), ("deduplicated", "tab:green")):
        b.scatter([c[name]["decoder_evaluations"] for c in crops], [c[name]["flip"] for c in crops], color=colour,
                  label=name.replace("_", " "))
    for c in crops:
        b.plot([c["per_texel"]["decoder_evaluations"], c["deduplicated"]["decoder_evaluations"]],
               [c["per_texel"]["flip"], c["deduplicated"]["flip"]], color="gray", lw=0.6)
    b.set_xscale("log")
    b.set_xlabel(f"decoder evaluations to fit a {CROP}x{CROP} crop")
    b.set_ylabel("FLIP vs analytic (texture-space patch)")
    b.set_title("same samples per fitted vector: equal accuracy, fewer evaluations")
    b.legend(fontsize=8)
    save_chart(fig, path)


if __name__ == "__main__":
    main()
