"""Does generation follow the words? Colour, metal, type and strength, beside today's generator (issue 50).

Two ways of reading a prompt, on the same meshes, model and seeds:

- **today**: the generator before it read more than the type (the code before issue 50): the
  mesh's own base material (0.8 grey, roughness and metalness unknown, on a bare mesh) and the
  prior's worded settings drawn (``generate(..., strengths=False)``, no ``put_words_base``);
- **words**: ``generate``'s default: the base material the prompt names put on a one-colour
  material (``put_words_base``, ``--base auto``), the prior's worded settings set by the strength
  words.

Measured:

1. **Base material** (no sampling: what ``generate`` writes as the material's base colour and
   gives the views as roughness and metalness): on a bare UV sphere read as a user's OBJ, and on
   the held-out real assets (``corpus.held_out``) with ``--base words`` (the artist asks for the
   words' base; ``auto`` keeps their textures), a fixed set of prompts naming a colour of the
   table or a metal: CIEDE2000 between the mean base colour and the named colour (the table's, or
   the metal's own), whether a named metal gets metalness 1, whether the type read is the one the
   prompt names. Targets: dE <= 10, metals 100 %.
2. **Strength**: per enhancement family (dust, haze, fuzz, scattering), prompts that differ only in
   "light" / "moderate" / "heavy", on the bare sphere and on the held-out Avocado (textured, kept).
   The amount is what the enhancement changes in the reflectance: the mean difference, over charted
   texels and three view directions, between the decoded material's f cos (times pi: albedo units)
   and the decoded plain PBR material's, at 48 cosine-distributed outgoing directions for dust, fuzz
   and scattering (the reflectance they add), and for haze at 5 and 10 degrees from the mirror
   direction (the highlight's shoulder it takes into its wide lobe: reflectance lost). Three ways: the
   prior alone (the rules with the strength words' settings, no model: for the canonical words and
   for synonyms), today's generation and the words' generation (prior + the model's residual), each
   at sampling seeds 0 and 1. A triple is ordered when light < moderate < heavy; the seed spread
   (|seed 0 - seed 1| per prompt) is the noise floor the effect (heavy - light) is compared with.
   Target: >= 90 % of triples ordered.

Writes docs/reports/generate_follow.json, its chart (.png) and two galleries a person can judge:
generate_follow_gallery.png (per prompt: what was read, today's render and the words' render) and
generate_follow_strength.png (light / moderate / heavy, today's row above the words' row).
Generations are ``generate``'s defaults (18 steps, 12 views, 4 samples averaged, guidance per type):
about 80 of them, some 17 minutes on one thread.

``--accuracy`` asks whether reading the strengths costs accuracy where the prompt is a caption:
the first eight held-out procedural objects (as bench/generator/generate_eval.py makes them), each prompted
with its own caption, which words its settings; PSNR over 16 views at 64 px against the reference,
of the prior and the generation, both ways (docs/reports/generate_follow_accuracy.json).

    python -m bench.generator.generate_follow [--samples N] [--checkpoint DIR] [--accuracy]
"""
from __future__ import annotations

import argparse
import math
import tempfile
import textwrap
import time
from pathlib import Path

import numpy as np
import torch

from bench.common import REPORTS, provenance, pyplot, save_chart, write_report
from bench.generator.generate_eval import held_out, held_out_indices, psnr, render
from richmat_addon.core import named_colours
from richmat_addon.core.base_materials import METALS
from richmat_addon.core.captions import STRENGTHS
from richmat_addon.core.colour import ciede2000, linear_to_lab
from richmat_addon.core.enhance import baseline
from richmat_addon.core.enhancement_types import METAL_REMAP
from richmat_addon.core.prompt import read_prompt
from support.held_out_assets import SAMPLE_MODELS
from torch_models.generator import DEFAULT_SAMPLES, DEFAULT_STEPS, DEFAULT_VIEWS
from torch_models.generator import generate as gen
from torch_models.generator.encoding import latent_texture
from torch_models.generator.mesh_input import MeshInput, load_mesh, put_words_base
from torch_models.generator.prior import pbr_inputs, prior_latents
from torch_models.neural import trained
from torch_models.neural.bsdf import NeuralBsdf

DE_TARGET, METAL_TARGET, ORDER_TARGET = 10.0, 1.0, 0.9
REAL = ("Avocado", "BoomBox", "WaterBottle")  # held out (corpus.held_out); one material each
# (prompt, the colour it names: a table name or a metal, the type it names)
COLOUR_PROMPTS = (
    ("red paint with light dust", "red", 1), ("dark red plastic", "dark red", 0),
    ("pale blue ceramic with a glossy clearcoat", "pale blue", 2), ("off-white paint with moderate haze", "off white", 0),
    ("navy blue fabric with fuzz", "navy blue", 4), ("dark green paint with heavy dust", "dark green", 1),
    ("orange plastic", "orange", 0), ("light grey ceramic", "light grey", 0), ("purple velvet", "purple", 4),
    ("teal paint with a clear coat", "teal", 2), ("mustard yellow wood", "mustard yellow", 0),
    ("black rubber", "black", 0), ("firebrick lacquer", "firebrick", 2), ("sky blue waxy candle", "sky blue", 4),
)
METAL_PROMPTS = (
    ("brushed gold metal with a glossy clearcoat", "gold", 2), ("polished copper with light dust", "copper", 1),
    ("brass with heavy haze", "brass", 0), ("silver metal", "silver", 0),
    ("brushed aluminium with a clearcoat", "aluminium", 2), ("rough iron with heavy dust", "iron", 1),
    ("chrome with a glossy clearcoat", "chrome", 2),
)
# Per family: the bare sphere's prompt and the real asset's, "{}" the strength word.
STRENGTH_PROMPTS = {
    "dust": ("red paint with {} dust", "glazed ceramic with {} dust"),
    "haze": ("blue plastic with {} haze", "plastic with {} haze"),
    "fuzz": ("green fabric with {} fuzz", "velvet with {} fuzz"),
    "scatter": ("pale pink wax with {} subsurface scattering", "skin with {} subsurface scattering"),
}
REAL_STRENGTH = "Avocado"
REAL_STRENGTH_FAMILIES = ("dust",)  # the example; the other families on the sphere only (time)
SYNONYMS = ("a little", "medium", "thick")  # the same three strengths in other words (prior only)
GALLERY_COLOURS = 4  # colour prompts rendered in the gallery, beside the seven metals
ACCURACY_VIEWS = 16  # views rendered per held-out procedural object, at 64 px (as bench/generator/generate_eval.py)


def bare_sphere(folder: Path) -> MeshInput:
    """A UV sphere from trimesh, no material, written and read as a user's OBJ."""
    import trimesh

    path = folder / "sphere.obj"
    trimesh.creation.uv_sphere(radius=0.5, count=[32, 32]).export(str(path))
    return load_mesh(path)


def worded(inp: MeshInput, prompt: str, base: str = "auto") -> MeshInput:
    """A copy of ``inp`` with the words' base put on (``generate --base``)."""
    out = MeshInput(inp.mesh, [type(m)(m.name, m.base_color, m.roughness_metalness, m.record, m.unwrapped)
                               for m in inp.materials], list(inp.notes), list(inp.warnings))
    put_words_base(out, read_prompt(prompt), base)
    return out


def base_scores(inp: MeshInput, prompt: str, named: str, type_: int) -> dict:
    """dE of the first material's mean base colour against the named colour, its metalness, the type read."""
    material = inp.materials[0]
    want = np.asarray(METALS[named]) if named in METALS else named_colours.table()[named]
    mean = material.base_color.reshape(-1, 3).mean(0)
    rm = material.roughness_metalness
    metalness = None if rm is None else float(rm[..., 1].mean())
    read = read_prompt(prompt, metallic=inp.metallic)
    if inp.metallic:  # fuzz and scattering fall back on a metal, as the enhancer does
        type_ = METAL_REMAP.get(type_, type_)
    return {"prompt": prompt, "named": named, "de": float(ciede2000(linear_to_lab(mean), linear_to_lab(want))),
            "base_color": mean.tolist(), "metalness": metalness, "metal_read": bool(metalness and metalness > 0.5),
            "type": read.type, "type_named": type_, "type_read": read.type == type_}


class Reflectance:
    """f cos of decoded latents at fixed direction pairs, per texel: what an enhancement adds to a material.

    Dust, fuzz and scattering add reflectance away from the mirror direction (48 cosine-distributed
    outgoing directions per view); haze moves it from the highlight's shoulder (5 and 10 degrees from the
    mirror direction) into its wide lobe, so its amount is the reflectance lost there."""

    def __init__(self, texels: int = 1024) -> None:
        self.model = trained.load()
        self.texels = texels
        u = (np.arange(48) + 0.5) / 48
        phi = 2 * np.pi * ((np.arange(48) * 0.618034) % 1.0)  # a golden-ratio spiral, cosine-distributed
        r = np.sqrt(u)
        wo = np.stack([r * np.cos(phi), r * np.sin(phi), np.sqrt(1 - u)], -1)
        wi = np.array([[math.sin(math.acos(c)), 0.0, c] for c in (1.0, 0.7, 0.4)])
        # the highlight's shoulder: 5 and 10 degrees from the mirror direction, in the plane of incidence
        mirror = np.arctan2(-wi[:, 0], wi[:, 2])
        shoulder = np.array([[math.sin(m + math.radians(d)), 0.0, math.cos(m + math.radians(d))]
                             for m in mirror for d in (5, 10)])
        self.pairs = {"diffuse": (torch.tensor(np.repeat(wi, len(wo), 0), dtype=torch.float32),
                                  torch.tensor(np.tile(wo, (len(wi), 1)), dtype=torch.float32)),
                      "shoulder": (torch.tensor(np.repeat(wi, 2, 0), dtype=torch.float32),
                                   torch.tensor(shoulder, dtype=torch.float32))}

    def sample(self, latents: np.ndarray, base: np.ndarray, charts: torch.Tensor) -> tuple[np.ndarray, np.ndarray]:
        """The charted texels (a fixed subset) of a (H, W, 6) latent texture and its base colour."""
        idx = np.flatnonzero(charts.numpy().reshape(-1))
        idx = idx[np.random.default_rng(0).permutation(len(idx))[:self.texels]]
        base = np.broadcast_to(base, (*latents.shape[:2], 3)) if base.shape[:2] == (1, 1) else base
        return latents.reshape(-1, 6)[idx], base.reshape(-1, 3)[idx]

    def of(self, latents: np.ndarray, base: np.ndarray, pairs: str) -> torch.Tensor:
        """(texels, pairs, 3) f cos times pi at the ``pairs`` directions."""
        wi, wo = self.pairs[pairs]
        k, n = len(latents), len(wi)
        z = torch.from_numpy(np.repeat(latents, n, 0).astype(np.float32))
        bsdf = NeuralBsdf(self.model, z, torch.from_numpy(np.repeat(base, n, 0).astype(np.float32)))
        with torch.no_grad():
            f = bsdf.eval(wi.repeat(k, 1), wo.repeat(k, 1))
        return (f * math.pi).reshape(k, n, 3)

    def added(self, family: str, latents: np.ndarray, plain: np.ndarray, base: np.ndarray,
              charts: torch.Tensor) -> float:
        """The enhancement's amount against the plain PBR material: signed, so the sampling's zero-mean
        wobble averages out rather than adding up."""
        lat, b = self.sample(latents, base, charts)
        ref, _ = self.sample(plain, base, charts)
        if family == "haze":
            return float((self.of(ref, b, "shoulder") - self.of(lat, b, "shoulder")).mean())
        return float((self.of(lat, b, "diffuse") - self.of(ref, b, "diffuse")).mean())


def plain_latents(inp: MeshInput, size: int) -> list[np.ndarray]:
    """Each material's plain PBR material (``core.enhance.baseline``) encoded, at its texture size."""
    out = []
    for material, raster in zip(inp.materials, gen.texture_rasters(inp, size)):
        shape = raster.coverage.shape
        out.append(latent_texture(baseline(pbr_inputs(material.base_color, material.roughness_metalness
                                                      if inp.pbr_known else None, shape, material.name)), shape))
    return out


def strength_runs(meshes: dict[str, MeshInput], model, cfg, args, reflectance: Reflectance) -> tuple[list, dict]:
    """Every strength triple: the prior alone and both generations, with their amounts; and the seed-0
    renders of the generations for the gallery."""
    size = cfg.corpus.texture_size
    rows, renders = [], {}
    for family, (sphere_prompt, real_prompt) in STRENGTH_PROMPTS.items():
        targets = [("sphere", sphere_prompt)]
        if family in REAL_STRENGTH_FAMILIES:
            targets.append((REAL_STRENGTH, real_prompt))
        for mesh_name, template in targets:
            for method in ("today", "words"):
                inp = meshes[mesh_name] if method == "today" else worded(meshes[mesh_name], template.format("heavy"))
                plain = plain_latents(inp, size)
                spaces = None
                for words, kind in ((STRENGTHS, "prior"), (SYNONYMS, "prior, synonyms")):
                    if method == "today" and kind != "prior":
                        continue
                    amounts, prompts = [], [template.format(w) for w in words]
                    for prompt in prompts:
                        reading = read_prompt(prompt, metallic=inp.metallic)
                        spaces = gen.texture_spaces(inp, reading.type, size,
                                                    reading.settings() if method == "words" else {})
                        amounts.append(reflectance.added(family, spaces[0].prior, plain[0], spaces[0].base_color,
                                                         spaces[0].charts))
                    rows.append({"family": family, "mesh": mesh_name, "method": method, "way": kind, "seed": None,
                                 "prompts": prompts, "amounts": amounts})
                for seed in args.seeds:
                    amounts, prompts, latents = [], [template.format(w) for w in STRENGTHS], []
                    for prompt in prompts:
                        t = time.perf_counter()
                        result = gen.generate(inp, prompt, model, cfg, seed, DEFAULT_STEPS, DEFAULT_VIEWS, None, size,
                                              samples=args.samples, strengths=method == "words")
                        m = result.materials[0]
                        amounts.append(reflectance.added(family, m.latents, plain[0], spaces[0].base_color,
                                                         m.charts))
                        latents.append(m.latents)
                        if seed == args.seeds[0]:
                            renders[(family, mesh_name, method, prompt)] = render(
                                inp, [x.latents for x in result.materials], 1, args.gallery_size, args.spp)[0]
                        print(f"{mesh_name} {method} seed {seed}: {prompt!r}: amount {amounts[-1]:.4f} "
                              f"({time.perf_counter() - t:.1f} s)", flush=True)
                    rows.append({"family": family, "mesh": mesh_name, "method": method, "way": "generated",
                                 "seed": seed, "prompts": prompts, "amounts": amounts,
                                 "latent_change_light_heavy": float(np.abs(latents[2] - latents[0]).mean())})
    return rows, renders


def strength_summary(rows: list[dict]) -> dict:
    """Per way of reading: the share of ordered triples, and for the generations the effect against the
    seeds' spread."""
    out = {}
    for key in ("today, generated", "words, prior", "words, prior, synonyms", "words, generated", "today, prior"):
        method, way = key.split(", ", 1)
        picked = [r for r in rows if r["method"] == method and r["way"] == way]
        if not picked:
            continue
        ordered = [bool(np.all(np.diff(r["amounts"]) > 0)) for r in picked]
        entry = {"triples": len(picked), "ordered": int(sum(ordered)), "ordered_share": float(np.mean(ordered))}
        if way == "generated":
            effects, spreads = [], []
            for r in picked:
                if r["seed"] != picked[0]["seed"]:
                    continue
                twin = next(o for o in picked if o["seed"] != r["seed"] and o["family"] == r["family"]
                            and o["mesh"] == r["mesh"])
                mean = (np.asarray(r["amounts"]) + np.asarray(twin["amounts"])) / 2
                effects.append(float(mean[2] - mean[0]))
                spreads.append(float(np.abs(np.asarray(r["amounts"]) - np.asarray(twin["amounts"])).mean()))
            entry.update(median_effect=float(np.median(effects)), median_seed_spread=float(np.median(spreads)),
                         effect_over_spread=[e / s if s > 0 else math.inf for e, s in zip(effects, spreads)])
        out[key] = entry
    return out


def measure(args: argparse.Namespace, folder: Path) -> tuple[dict, dict]:
    model, cfg = gen.load_generator(args.checkpoint)
    size = cfg.corpus.texture_size
    sphere = bare_sphere(folder)
    real = {name: load_mesh(SAMPLE_MODELS / f"{name}.glb") for name in REAL}
    base_rows = []
    for prompt, named, type_ in COLOUR_PROMPTS + METAL_PROMPTS:
        for mesh_name, inp, base in [("sphere", sphere, "auto")] + [(n, m, "words") for n, m in real.items()]:
            for method in ("today", "words"):
                scored = inp if method == "today" else worded(inp, prompt, base)
                base_rows.append({"mesh": mesh_name, "method": method, "base": base,
                                  **base_scores(scored, prompt, named, type_)})
    reflectance = Reflectance()
    strength, strength_renders = strength_runs({"sphere": sphere, REAL_STRENGTH: real[REAL_STRENGTH]}, model, cfg,
                                               args, reflectance)
    gallery_renders = {}
    for prompt, named, _ in COLOUR_PROMPTS[:GALLERY_COLOURS] + METAL_PROMPTS:
        for method in ("today", "words"):
            inp = sphere if method == "today" else worded(sphere, prompt)
            result = gen.generate(inp, prompt, model, cfg, args.seeds[0], DEFAULT_STEPS, DEFAULT_VIEWS, None, size,
                                  samples=args.samples, strengths=method == "words")
            gallery_renders[(prompt, method)] = render(inp, [m.latents for m in result.materials], 1,
                                                       args.gallery_size, args.spp)[0]
        print(f"gallery: {prompt!r}", flush=True)

    def base_summary(method: str) -> dict:
        rows = [r for r in base_rows if r["method"] == method]
        metals = [r for r in rows if r["named"] in METALS]
        des = [r["de"] for r in rows]
        return {"median_de": float(np.median(des)), "worst_de": float(np.max(des)),
                "within_target": float(np.mean([d <= DE_TARGET for d in des])),
                "metals_read": float(np.mean([r["metal_read"] for r in metals])),
                "types_read": float(np.mean([r["type_read"] for r in rows]))}

    report = {"seeds": args.seeds, "samples": args.samples, "steps": DEFAULT_STEPS, "views": DEFAULT_VIEWS,
              "checkpoint": str(args.checkpoint), "real_assets": list(REAL), "targets": {
                  "de": DE_TARGET, "metals_read": METAL_TARGET, "ordered_share": ORDER_TARGET},
              "base": {m: base_summary(m) for m in ("today", "words")},
              "strength": strength_summary(strength), "base_rows": base_rows, "strength_rows": strength}
    return report, {"gallery": gallery_renders, "strength": strength_renders}


def accuracy(args: argparse.Namespace) -> dict:
    """Held-out procedural objects prompted with their own captions (which word their strengths), as
    bench/generator/generate_eval.py scores them: PSNR of each way's prior and generation against the reference."""
    model, cfg = gen.load_generator(args.checkpoint)
    size = cfg.corpus.texture_size
    rows = []
    for index in held_out_indices(args.objects, cfg.corpus.seed):
        obj = held_out(index, cfg)
        reference = render(obj.inp, obj.reference(size), ACCURACY_VIEWS, 64, args.spp)
        mask = reference.sum(-1) > 0
        row = {"asset_id": obj.asset_id, "prompt": obj.prompt, "type": obj.type}
        for method in ("today", "words"):
            result = gen.generate(obj.inp, obj.prompt, model, cfg, args.seeds[0], DEFAULT_STEPS, DEFAULT_VIEWS, None,
                                  size, samples=args.samples, strengths=method == "words")
            for way, latents in (("prior", result.prior), ("generated", result.latents)):
                row[f"{method}, {way}"] = psnr(reference, render(obj.inp, latents, ACCURACY_VIEWS, 64, args.spp), mask)
        rows.append(row)
        print(f"{obj.asset_id} {obj.prompt!r}: " + ", ".join(f"{k} {v:.2f}" for k, v in row.items()
                                                            if isinstance(v, float)), flush=True)
    keys = [k for k in rows[0] if ", " in k]
    return {"seed": args.seeds[0], "samples": args.samples, "views": ACCURACY_VIEWS, "objects": rows,
            "mean_psnr": {k: float(np.mean([r[k] for r in rows])) for k in keys},
            "worst_psnr": {k: float(np.min([r[k] for r in rows])) for k in keys}}


def chart(report: dict, path: Path) -> None:
    plt = pyplot()
    fig, axes = plt.subplots(1, 3, figsize=(13, 3.6))
    methods = ("today", "words")
    base = report["base"]
    ax = axes[0]
    for i, m in enumerate(methods):
        des = [r["de"] for r in report["base_rows"] if r["method"] == m]
        ax.scatter(np.full(len(des), i) + np.random.default_rng(i).uniform(-0.15, 0.15, len(des)), des, s=10)
    ax.axhline(DE_TARGET, color="tab:red", ls="--", lw=1, label=f"target dE {DE_TARGET:g}")
    ax.set_xticks(range(2), [f"{m}\nmedian {base[m]['median_de']:.1f}" for m in methods])
    ax.set_ylabel("CIEDE2000, mean base colour vs named")
    ax.set_title("named colour", fontsize=9)
    ax.legend(fontsize=7)
    ax = axes[1]
    ax.bar(np.arange(2) - 0.2, [base[m]["metals_read"] * 100 for m in methods], 0.4, label="metals read")
    ax.bar(np.arange(2) + 0.2, [base[m]["types_read"] * 100 for m in methods], 0.4, label="type read")
    ax.set_xticks(range(2), methods)
    ax.set_ylabel("%")
    ax.set_title("metalness where a metal is named; type", fontsize=9)
    ax.legend(fontsize=7)
    ax = axes[2]
    keys = list(report["strength"])
    ax.bar(range(len(keys)), [report["strength"][k]["ordered_share"] * 100 for k in keys], color="tab:green")
    ax.axhline(ORDER_TARGET * 100, color="tab:red", ls="--", lw=1, label="target 90 %")
    ax.set_xticks(range(len(keys)), [textwrap.fill(k, 12) for k in keys], fontsize=7)
    ax.set_ylabel("% of triples light < moderate < heavy")
    ax.set_title("strength words, reflectance the enhancement adds", fontsize=9)
    ax.legend(fontsize=7)
    save_chart(fig, path)


def _crop(image: np.ndarray) -> np.ndarray:
    ys, xs = np.nonzero(image.sum(-1) > 0)
    return image[max(ys.min() - 4, 0):ys.max() + 5, max(xs.min() - 4, 0):xs.max() + 5]


def gallery(renders: dict, path: Path, record: dict) -> None:
    """One column per prompt: the prompt and what was read above, today's render, the words' render."""
    plt = pyplot()
    prompts = [p for p, _ in dict.fromkeys(k[0] for k in renders).items()]
    cols = 7
    rows = math.ceil(len(prompts) / cols)
    fig, axes = plt.subplots(2 * rows, cols, figsize=(2.9 * cols, 3.3 * 2 * rows), squeeze=False)
    for ax in axes.ravel():
        ax.axis("off")
    for i, prompt in enumerate(prompts):
        r, c = divmod(i, cols)
        read = "\n".join(textwrap.fill(line, 36) for line in read_prompt(prompt).lines())
        for k, method in enumerate(("today", "words")):
            ax = axes[2 * r + k][c]
            ax.imshow(_crop(renders[(prompt, method)]))
            title = f'"{textwrap.fill(prompt, 34)}"\nread: {read}\n' if k == 0 else ""
            ax.set_title(title + ("today's generator" if method == "today" else "following the words"), fontsize=7)
    save_chart(fig, path, record)


def strength_gallery(renders: dict, path: Path, record: dict) -> None:
    """Per family and mesh two rows (today, words), one column per strength word."""
    plt = pyplot()
    groups = list(dict.fromkeys((k[0], k[1]) for k in renders))
    fig, axes = plt.subplots(2 * len(groups), 3, figsize=(3.0 * 3, 3.1 * 2 * len(groups)), squeeze=False)
    for g, (family, mesh) in enumerate(groups):
        for k, method in enumerate(("today", "words")):
            cells = [(key[3], image) for key, image in renders.items() if key[:3] == (family, mesh, method)]
            for c, (prompt, image) in enumerate(cells):
                ax = axes[2 * g + k][c]
                ax.imshow(_crop(image))
                ax.set_title(f"{'today' if method == 'today' else 'words'}, {mesh}:\n{textwrap.fill(prompt, 34)}",
                             fontsize=7)
                ax.axis("off")
    save_chart(fig, path, record)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, nargs="+", default=[0, 1], help="sampling seeds (two: the noise floor)")
    ap.add_argument("--samples", type=int, default=DEFAULT_SAMPLES, help="residuals averaged per generation "
                    f"(default: generate's, {DEFAULT_SAMPLES})")
    ap.add_argument("--checkpoint", type=Path, default=gen.SHIPPED)
    ap.add_argument("--gallery-size", type=int, default=192)
    ap.add_argument("--spp", type=int, default=16)
    ap.add_argument("--accuracy", action="store_true",
                    help="instead: held-out procedural objects with their own captions, PSNR against the reference "
                         "for both ways (docs/reports/generate_follow_accuracy.json)")
    ap.add_argument("--objects", type=int, default=8, help="held-out procedural objects for --accuracy")
    ap.add_argument("--out", type=Path, default=None,
                    help="report JSON (default: docs/reports/generate_follow[_accuracy].json)")
    args = ap.parse_args()
    torch.set_num_threads(1)
    if args.accuracy:
        out = args.out or REPORTS / "generate_follow_accuracy.json"
        write_report(out, accuracy(args), [trained.SHIPPED], args.checkpoint)
        return 0
    args.out = args.out or REPORTS / "generate_follow.json"
    start = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        report, renders = measure(args, Path(tmp))
    report["wall_seconds"] = time.perf_counter() - start
    write_report(args.out, report, [trained.SHIPPED], args.checkpoint)
    chart(report, args.out.with_suffix(".png"))
    record = provenance([trained.SHIPPED], args.checkpoint)
    gallery(renders["gallery"], args.out.with_name(args.out.stem + "_gallery.png"), record)
    strength_gallery(renders["strength"], args.out.with_name(args.out.stem + "_strength.png"), record)
    print({k: report[k] for k in ("base", "strength")})
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
