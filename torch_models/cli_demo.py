"""Uplift the built-in material to every type, fit each as a neural material, generate from prompts.

The built-in input is procedural (chipped red paint over steel on a UV sphere,
see torch_models/demo_material.py), so the demo needs nothing beside the clone.
Writes OUT/type_<k>/ (parameter maps as EXR, params.json, material.mtlx) for
Types 0-5, and OUT/side_by_side.png: the original PBR material and Types 0-5
rendered on a ball under the shipped probe with the torch renderer. Then the
six types are fitted as neural materials with the shipped decoder (one fit of
all their distinct texel vectors; OUT/type_<k>/neural/: two latent EXRs and
neural.json) and OUT/neural_vs_analytic.png shows analytic | neural | FLIP map
per type, with the FLIPs in OUT/neural_vs_analytic.json. Last, the shipped
generator makes neural materials for a red sphere (not in its training corpus)
from prompts naming different enhancements (OUT/generated.png: per prompt the
reference, the rules' uplift to the prompt's type, beside the generated
material; OUT/generated.json: the prompts, types, warnings, timings).

The default sizes finish in about two minutes on 2 cores; --full runs the
larger version (a 256 px texture, 64 samples per pixel, 300 fit steps, the
full energy refit), about ten times longer.
"""
from __future__ import annotations

import argparse
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from richmat_addon.core.texel_vectors import TexelVectors

    from .neural.model import NeuralModel

HELP = "uplift the built-in material to Types 0-5, fit them as neural materials, generate from prompts"
DEFAULT_PROBE = Path(__file__).resolve().parent / "data" / "studio_small_03_512.hdr"

# Sizes of the default demo and of --full. The texture size, samples and steps cost time
# without changing what the 160 px pictures show (docs in the README's demo lines).
QUICK = {"size": 128, "spp": 32, "fit_steps": 100, "refit_steps": 20, "merge": 16, "generate_size": 32}
FULL = {"size": 256, "spp": 64, "fit_steps": 300, "refit_steps": 150, "merge": 0, "generate_size": 64}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    def sizes(key: str) -> str:
        return f"(default: {QUICK[key]}; --full: {FULL[key]})"

    parser.add_argument("--out", type=Path, default=Path("demo_out"), help="output folder (default: demo_out)")
    parser.add_argument("--full", action="store_true", help="the larger version: the --full sizes below")
    parser.add_argument("--seed", type=int, default=0, help="enhancement seed (default: 0)")
    parser.add_argument("--size", type=int, help=f"texture size of the built-in material {sizes('size')}")
    parser.add_argument("--resolution", type=int, default=160, help="ball image size in pixels (default: 160)")
    parser.add_argument("--spp", type=int, help=f"samples per pixel of the ball renders {sizes('spp')}")
    parser.add_argument("--probe", type=Path, default=DEFAULT_PROBE, help="equirectangular HDR probe")
    parser.add_argument("--fit-steps", type=int, help=f"neural fit steps {sizes('fit_steps')}")
    parser.add_argument("--refit-steps", type=int,
                        help=f"energy refit steps of the latents that gain energy {sizes('refit_steps')}")
    parser.add_argument("--merge", type=int,
                        help="texel vectors that round to the same multiple of 1/MERGE per normalised parameter "
                             f"share one fitted latent; 0: only fit's own merge {sizes('merge')}")
    parser.add_argument("--no-neural", action="store_true", help="skip fitting the neural materials")
    parser.add_argument("--no-generate", action="store_true", help="skip generating materials from prompts")
    parser.add_argument("--generate-size", type=int,
                        help="latent texture size of the generated materials; with a decoder that is not bounded "
                             f"by construction the energy guard's time grows with its texels {sizes('generate_size')}")
    parser.add_argument("--view-size", type=int, default=256, help="generated.png's view size in pixels (default: 256)")


def apply_sizes(args: argparse.Namespace) -> None:
    """The default or --full size of every size argument not given."""
    for key, value in (FULL if args.full else QUICK).items():
        if getattr(args, key) is None:
            setattr(args, key, value)


def run(args: argparse.Namespace) -> int:
    from richmat_addon.core import material_folder
    from richmat_addon.core.enhance import baseline, enhance
    from richmat_addon.core.enhancement_types import TYPES

    from .cli import InputError
    from .demo_material import chipped_paint, sphere_texel_geometry
    from .demo_render import analytic_at, captioned_row, render_balls, save_sheet, to_u8

    from .neural import trained

    apply_sizes(args)
    if args.generate_size < 8:
        raise InputError("--generate-size must be >= 8")
    model = trained.load()
    progress = Progress(expected_seconds(args, bounded=model.decoder.bounded))
    progress.start("enhance")
    pbr = chipped_paint(args.size)
    normals, positions = sphere_texel_geometry(args.size, args.size)
    materials = []
    for type_ in range(len(TYPES)):
        mat = enhance(pbr, type_, args.seed, world_normals=normals, world_positions=positions)
        material_folder.write(args.out / f"type_{type_}", mat,
                              {"asset": "built-in chipped_paint", "material": pbr.name, "requested_type": type_})
        materials.append(mat)
        progress.advance(1 / len(TYPES))
    progress.start("render Types 0-5")
    balls = render_balls([analytic_at(m) for m in [baseline(pbr)] + materials], args.probe, args.resolution,
                         args.spp, args.seed, lambda: progress.advance(1 / (len(materials) + 1)))
    labels = ["original PBR"] + [f"Type {m.type}: {TYPES[m.type].label}" for m in materials]
    png = save_sheet([captioned_row([to_u8(b) for b in balls], labels)], args.out / "side_by_side.png")
    progress.write(f"wrote {args.out}/type_0..5 and {png}")
    if not args.no_neural:
        fit_types_and_compare(args, model, materials, balls[1:], progress)
    if not args.no_generate:
        generate_from_prompts(args.out, args.seed, args.generate_size, args.view_size, progress)
    progress.close()
    return 0


def fit_types_and_compare(args: argparse.Namespace, model: NeuralModel, materials: list,  # type: ignore[type-arg]
                    analytic: list, progress: Progress) -> None:  # type: ignore[type-arg]
    """Fit the six types as neural materials with the shipped decoder, write their latents, compare
    each with its analytic ball (``analytic``: the renders of side_by_side.png, same settings).

    One fit takes every distinct texel vector of the six types, as ``fit`` does for one textured
    material: a fit step costs the same for any number of vectors, so one fit of all costs a
    sixth of six, and the energy refit's per-step cost is bounded by its latent sample the same way."""
    import json

    import numpy as np
    import torch

    from richmat_addon.core.enhancement_types import TYPES
    from richmat_addon.core.maps import ParamMap

    from .demo_render import captioned_row, neural_bsdf, render_balls, save_sheet, to_u8
    from .neural import energy
    from .neural.evaluate import compare
    from .neural.fit import material_vectors
    from .neural.fit.latents import fit_latents

    folders = [args.out / f"type_{m.type}" for m in materials]
    vectors = [material_vectors.read_vectors(f) for f in folders]
    if args.merge:
        vectors = [merge_vectors(v, 1.0 / args.merge) for v in vectors]
    pool, rows = np.unique(np.concatenate([v.unique for v in vectors]), axis=0, return_inverse=True)
    per_type = np.split(rows.ravel(), np.cumsum([len(v.unique) for v in vectors])[:-1])
    progress.reweigh("energy guard", expected_seconds(args, len(pool), model.decoder.bounded)["energy guard"])
    progress.start("fit neural materials")
    progress.write(f"fitting the {len(pool)} distinct texel vectors of Types 0-5 with the shipped decoder")
    z = fit_latents(model, pool, args.fit_steps, seed=args.seed,
                    progress=lambda *_: progress.advance(1 / args.fit_steps))
    progress.start("energy guard")
    bounded = energy.fit_bounded(model, pool, z, seed=args.seed, steps=args.refit_steps)
    progress.advance(1.0)
    progress.start("render neural vs analytic")
    record = {"fitted_with": "the distinct texel vectors of the demo's six types, in one fit"}
    if args.merge:
        record["cluster_bound"] = (f"texels whose vectors round to the same multiple of 1/{args.merge} "
                                   "per normalised parameter share one latent")
    neural = []
    for mat, mv, index, folder in zip(materials, vectors, per_type, folders):
        part = _select(bounded, torch.from_numpy(index))
        material_vectors.write_fit(folder / "neural", mv, part, model.digest, record)
        latents, scales = ParamMap(mv.texels(part.z)), ParamMap(mv.texels(part.check.energy_scale()))
        neural.append(lambda n, m=mat, lt=latents, sc=scales: neural_bsdf(model, lt, sc, m.base_color, n.numpy()))
    renders = render_balls(neural, args.probe, args.resolution, args.spp, args.seed,
                           lambda: progress.advance(1 / len(neural)))
    results = [compare(a, n) for a, n in zip(analytic, renders)]
    png = save_sheet([captioned_row([to_u8(r.reference), to_u8(r.neural), to_u8(np.repeat(r.error[..., None], 3, -1))],
                                    [f"Type {m.type} {TYPES[m.type].label}: analytic", "neural",
                                     f"FLIP map, mean {r.flip:.3f}"])
                      for m, r in zip(materials, results)], args.out / "neural_vs_analytic.png")
    (args.out / "neural_vs_analytic.json").write_text(json.dumps(
        {"flip_convention": "LDR-FLIP on AgX sRGB, 67.02 ppd", "texture_size": args.size, "spp": args.spp,
         "merge": args.merge, "fit_steps": args.fit_steps, "refit_steps": args.refit_steps,
         "fitted_vectors": len(pool),
         "flip": {f"type_{m.type}": r.flip for m, r in zip(materials, results)}}, indent=1))
    progress.write("neural vs analytic FLIP: " + ", ".join(f"Type {m.type} {r.flip:.3f}"
                                                           for m, r in zip(materials, results)) + f"; wrote {png}")


def merge_vectors(mv: TexelVectors, step: float) -> TexelVectors:
    """``mv`` with its representatives merged again where they round to the same multiple of ``step``
    in the normalised parameter space (a texel-weighted mean per cell): the demo's fit then takes as
    many vectors as the pictures tell apart, not the thousands of dust amounts ``QUANT`` keeps apart."""
    import numpy as np

    from richmat_addon.core.texel_vectors import normalise

    if mv.shape is None:  # a constant material is one vector already
        return mv
    _, cell = np.unique(np.round(normalise(mv.unique) / step).astype(np.int64), axis=0, return_inverse=True)
    cell = cell.ravel()
    texels = np.bincount(mv.inverse, minlength=len(mv.unique)).astype(np.float64)
    sums = np.zeros((cell.max() + 1, mv.unique.shape[1]))
    np.add.at(sums, cell, mv.unique * texels[:, None])
    merged = (sums / np.bincount(cell, weights=texels)[:, None]).astype(np.float32)
    return replace(mv, unique=merged, inverse=cell[mv.inverse])


def _select(bounded, rows):  # type: ignore[no-untyped-def]
    """The latents ``rows`` of a BoundedFit, with their furnace check."""
    from .neural.furnace import BoundedFit, Furnace

    check = bounded.check
    return BoundedFit(bounded.z[rows], Furnace(check.albedos[rows], check.std_errors[rows], check.transmissions[rows],
                                               check.quadrature[rows], check.tolerance), bounded.refitted[rows])


PREVIEW_SPP = 24  # samples per pixel of the prompt views: a coat's highlight or a dust film is not hidden in noise
DEMO_PROMPT_ENDINGS = ("heavy haze, heavy dust", "light haze, glossy clearcoat",
                       "moderate haze, heavy fuzz, light subsurface scattering")
# The prompts' object: a smooth sphere painted a rough dark red (linear base colour; sRGB 0.38, 0.12, 0.10).
# On a coloured, dark, rough, curved base each enhancement shows: dust whitens it, a coat adds sharp
# reflections over a deeper red, fuzz a pale velvet sheen. (A white base hides dust; a glossy one the coat,
# and a flat one its reflections.)
DEMO_PAINT = (0.12, 0.014, 0.01)
DEMO_ROUGHNESS = 0.7


def demo_sphere(texture_size: int):  # -> MeshInput
    """The red sphere the prompts are written for; not in the generator's training corpus."""
    import numpy as np
    import trimesh

    from richmat_addon.core.maps import ParamMap, PbrInputs

    from .generator.mesh_input import MeshInput
    from .generator.procedural import unwrapped

    sphere = trimesh.creation.icosphere(subdivisions=4)
    mesh = unwrapped(trimesh.Trimesh(0.5 * sphere.vertices, sphere.faces, process=False))
    hw = (texture_size, texture_size)
    pbr = PbrInputs("red paint", ParamMap(np.tile(np.float32(DEMO_PAINT), (*hw, 1))),
                    ParamMap(np.full((*hw, 1), DEMO_ROUGHNESS, np.float32)), ParamMap(np.zeros((*hw, 1), np.float32)))
    return MeshInput.from_pbr(mesh, pbr)


def prompt_views(inp, prompts: list[str], seed: int, texture_size: int, view_size: int, spp: int,
                 done=None) -> list[tuple]:  # inp: MeshInput; done: Callable[[], None] | None
    """Per prompt: its generation, the view of its reference (the prior the generator starts from: the
    rules' uplift of the object's material to the prompt's type, encoded) and the view of the generated
    material, both display-referred (AgX) from the same camera with the same samples."""
    import numpy as np

    from .generator import generate as gen
    from .render.tonemap import agx

    model, cfg = gen.load_generator()
    rows = []
    for prompt in prompts:
        result = gen.generate(inp, prompt, model, cfg, seed, texture_size=texture_size)
        views = [gen.preview(inp, latents, frames=1, resolution=view_size, spp=spp, energy_scale=scale)[0]
                 for latents, scale in ((result.prior, None), (result.latents, result.energy_scale))]
        rows.append((result, *np.split(agx(np.concatenate(views, 0)), 2, axis=0)))  # one tall image
        if done is not None:
            done()
    return rows


def generate_from_prompts(out: Path, seed: int, texture_size: int, view_size: int, progress: Progress) -> None:
    """The paper's Fig. 8 on an object training never saw: one sphere, prompts naming different enhancements,
    each row of generated.png its reference (the rules' uplift) beside the generated material, under the
    prompt and the type it chose.

    The latents are ``texture_size`` texels a side (the shipped decoder needs no energy guard; with one
    that does, its time grows with the texels); the views are rendered at ``view_size``."""
    import json

    from richmat_addon.core.enhancement_types import TYPES

    from .demo_render import captioned_row, save_sheet, to_u8

    progress.start("generate from prompts")
    inp = demo_sphere(texture_size)
    prompts = [f"a sphere: red paint material with {ending}" for ending in DEMO_PROMPT_ENDINGS]
    rows, records = [], []
    for prompt, (result, reference, generated) in zip(prompts, prompt_views(
            inp, prompts, seed, texture_size, view_size, PREVIEW_SPP, lambda: progress.advance(1 / len(prompts)))):
        label = f"Type {result.type}: {TYPES[result.type].label}"
        rows.append(captioned_row([to_u8(reference), to_u8(generated)],
                                  [f"reference: the rules' {label}", f'generated: "{prompt}"']))
        records.append({"prompt": prompt, "type": result.type, "warnings": result.warnings,
                        "seconds": result.seconds})
    out.mkdir(parents=True, exist_ok=True)
    png = save_sheet(rows, out / "generated.png")
    (out / "generated.json").write_text(json.dumps({"object": "red paint sphere (not in the training corpus)",
                                                     "base_color": DEMO_PAINT, "roughness": DEMO_ROUGHNESS,
                                                     "seed": seed, "spp": PREVIEW_SPP, "rows": records}, indent=1))
    progress.write(f"generated {len(rows)} materials for the red sphere; wrote {png}")


# The stages' costs, the progress line's weights: wall seconds on this 2-core machine with nothing else
# running, at the default sizes; the stages only a decoder not bounded by construction runs (the
# furnace, its refit and the guard) as one-thread CPU seconds measured with the MLP kind.
ENHANCE_SECONDS_PER_TEXEL = 5e-6  # per type, writing its EXRs included
ANALYTIC_SECONDS_PER_SAMPLE = 3.5e-6  # per pixel and sample of a ball render
NEURAL_SECONDS_PER_SAMPLE = 2.1e-6
FIT_TARGET_SECONDS = 2.5  # the analytic targets a fit draws before its first step
FIT_STEP_SECONDS = 0.02
FURNACE_SECONDS_PER_VECTOR = 0.023
REFIT_STEP_SECONDS = 1.5  # with REFIT_LATENTS latents failing the furnace (about 40 % of the vectors fail)
PROMPT_SECONDS = 4.0  # sampling and projection of one prompt
GUARD_SECONDS_PER_TEXEL = 0.083  # the energy guard of a generated texel (a decoder not bounded by construction)
PREVIEW_SECONDS_PER_SAMPLE = 1.9e-6


def expected_seconds(args: argparse.Namespace, vectors: int = 1000, bounded: bool = True) -> dict[str, float]:
    """Each stage's expected cost at the run's sizes: the progress line's weights. A decoder
    bounded by construction needs no furnace or guard; otherwise the energy stage grows with
    the ``vectors`` fitted, guessed until the types are made."""
    from .neural.mlp.energy import REFIT_LATENTS

    ball = args.resolution ** 2 * args.spp
    stages = {"enhance": 6 * args.size ** 2 * ENHANCE_SECONDS_PER_TEXEL,
              "render Types 0-5": 7 * ball * ANALYTIC_SECONDS_PER_SAMPLE}
    if not args.no_neural:
        refitted = min(0.4 * vectors, REFIT_LATENTS) / REFIT_LATENTS
        stages["fit neural materials"] = FIT_TARGET_SECONDS + args.fit_steps * FIT_STEP_SECONDS
        stages["energy guard"] = 0.0 if bounded else (vectors * FURNACE_SECONDS_PER_VECTOR
                                                      + args.refit_steps * refitted * REFIT_STEP_SECONDS)
        stages["render neural vs analytic"] = 6 * ball * NEURAL_SECONDS_PER_SAMPLE
    if not args.no_generate:
        prompt = (PROMPT_SECONDS + (0.0 if bounded else args.generate_size ** 2 * GUARD_SECONDS_PER_TEXEL)
                  + 2 * args.view_size ** 2 * PREVIEW_SPP * PREVIEW_SECONDS_PER_SAMPLE)  # reference and generated
        stages["generate from prompts"] = len(DEMO_PROMPT_ENDINGS) * prompt
    return stages


class Progress:
    """One line over all the demo's stages: which stage runs, the time spent and an estimate of the time left.

    Each stage weighs its expected seconds (``expected_seconds``). Until a tenth of the
    weight is done the estimate is the expected seconds left; then it is the elapsed time
    times the remaining weight over the done weight, which follows this machine's speed
    (extrapolating from the first few seconds would be off by orders of magnitude)."""

    CALIBRATED = 0.1  # share of the weight done before the measured speed is trusted

    def __init__(self, stages: dict[str, float]) -> None:
        from tqdm import tqdm

        self.stages = stages
        self.current = next(iter(stages))
        self.bar = tqdm(total=sum(stages.values()), smoothing=0.0,
                        bar_format="{desc} {percentage:3.0f}%|{bar:20}| {elapsed} elapsed{postfix}")
        self._show_left()

    def start(self, stage: str) -> None:
        self.current = stage
        self.bar.set_description(f"[{list(self.stages).index(stage) + 1}/{len(self.stages)}] {stage}")

    def seconds_left(self) -> float:
        left = self.bar.total - self.bar.n
        if self.bar.n < self.CALIBRATED * self.bar.total:
            return left
        return self.bar.format_dict["elapsed"] * left / self.bar.n

    def _show_left(self) -> None:
        self.bar.set_postfix_str(f"~{self.bar.format_interval(self.seconds_left())} left")

    def advance(self, share: float) -> None:
        """``share`` of the current stage is done (at most all of the line: shares may sum to 1 + rounding)."""
        self.bar.update(min(share * self.stages[self.current], self.bar.total - self.bar.n))
        self._show_left()

    def reweigh(self, stage: str, seconds: float) -> None:
        """A better estimate of a stage's seconds, known once it can be made."""
        self.bar.total += seconds - self.stages[stage]
        self.stages[stage] = seconds
        self._show_left()

    def write(self, message: str) -> None:
        self.bar.write(message)

    def close(self) -> None:
        self.bar.close()
