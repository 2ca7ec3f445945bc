"""Where the neural preview's error comes from, per material of real assets (issue 41, item 1).

Per asset: the add-on's defaults (Uplift's rules, type auto, seed 0, through the farm's
``enhance``; the full texture size; Fit's 300 steps at the 1/256 cluster step), one view
of the asset, its G-buffer rasterised in torch (``generator.views``), shaded by the torch
renderer in two scenes (the probe; the probe plus a sun). A chain of renders swaps one
thing at a time, from the analytic material Bake shows to what the preview shows:

    analytic, parameters read bilinearly (the reference: Bake's maps are linear)
    -> lookup:   parameters read at the nearest texel
    -> reach:    the decoder at an oracle fit (every visible vector alone, warm-started
                 from the shipped fit, ``--oracle-per-vector`` samples per step)
    -> fit:      the decoder at the fit as shipped
    -> sampling: the latents read bilinearly, as the preview's textures are
    -> closure:  the closure form (gates held per shading point, ``ClosureForm``), what
                 the preview shader gives Cycles

Each term is the rise of mean FLIP against the reference over the material's pixels;
the noise floor is the reference at another seed. G-buffer shading has no shadows and
no interreflection, so the terms are the material's own; what Cycles adds on top (its
light transport, the same for Bake and Preview) is measured by ``bench/addon/addon_assets.py``.

    python -m bench.neural.neural_error_budget [--assets WaterBottle ...] [--resolution 256] [--spp 64]
        [--weights FOLDER] [--out docs/reports/neural_error_budget.json]
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import tempfile
import time
from pathlib import Path

import numpy as np
import torch
from safetensors.torch import load_file, save_file

from bench.common import FLIP_CONVENTION, add_out_argument, pyplot, save_chart, write_report
from richmat_addon.core import material_folder
from richmat_addon.core.texel_vectors import QUANT, dedupe, texel_matrix
from support.paths import SHARED_ASSETS
from torch_models.brdf.model import LayeredBsdf, params_from_vectors
from torch_models.generator.generate import preview_cameras
from torch_models.generator.mesh_input import load_mesh
from torch_models.generator.views import render_intrinsics, sample_texture
from torch_models.neural import energy, trained
from torch_models.neural.fit.latents import fit_latents, held_out_loss
from torch_models.neural.mlp.energy import REFIT_STEPS
from torch_models.neural.model import NeuralModel
from torch_models.neural.real_vectors import enhanced_folders
from torch_models.neural.bsdf import NeuralBsdf
from torch_models.neural.hybrid.closure_form import closure_model
from torch_models.neural.evaluate import DEFAULT_PROBE, KEY_LIGHT, SCENES
from torch_models.render.ball import Sun, shade_gbuffer
from torch_models.render.envmap import EnvMap
from torch_models.render.flip import flip_map
from torch_models.render.tonemap import agx

ASSETS = ("WaterBottle", "CesiumMilkTruck", "BoomBox", "SheenCloth", "FlightHelmet")
CHAIN = ("reference", "lookup", "reach", "fit", "sampling", "closure")  # each render swaps one thing
TERMS = {"lookup": "nearest parameter lookup", "reach": "decoder reach (oracle fit)",
         "fit": "fit as shipped", "sampling": "bilinear latents", "closure": "closure form (gates held)"}
# Beside the chain: the latents read by a joint-bilateral filter (``Taps.bilateral``), without and with
# the closure form, for the sampling term's fix.
BESIDE = ("bilateral", "closure_bilateral")
FIT_STEPS = 300  # the add-on's Fit Steps, the default of --fit-steps


@dataclasses.dataclass
class Taps:
    """Texel indices (N, 4) and weights (N, 4) of a lookup; nearest uses the first tap alone."""

    index: torch.Tensor
    weight: torch.Tensor

    @classmethod
    def at(cls, uv: torch.Tensor, shape: tuple[int, int] | None, nearest: bool) -> "Taps":
        n = len(uv)
        if shape is None:
            return cls(torch.zeros(n, 4, dtype=torch.long), torch.tensor([1.0, 0, 0, 0]).expand(n, 4))
        h, w = shape
        if nearest:
            x = (uv[:, 0] * w).floor().long() % w
            y = (uv[:, 1] * h).floor().long() % h
            return cls((y * w + x)[:, None].expand(n, 4), torch.tensor([1.0, 0, 0, 0]).expand(n, 4))
        x, y = uv[:, 0] * w - 0.5, uv[:, 1] * h - 0.5  # sample_texture's convention (texel centres)
        x0, y0 = x.floor(), y.floor()
        fx, fy = x - x0, y - y0
        x0, y0 = x0.long(), y0.long()
        index = torch.stack([(yy % h) * w + (xx % w) for yy, xx in
                             ((y0, x0), (y0, x0 + 1), (y0 + 1, x0), (y0 + 1, x0 + 1))], 1)
        weight = torch.stack([(1 - fy) * (1 - fx), (1 - fy) * fx, fy * (1 - fx), fy * fx], 1)
        return cls(index, weight)

    def gather(self, per_texel: torch.Tensor) -> torch.Tensor:
        """(N, C) values of a (texels, C) table at these taps."""
        return (per_texel[self.index] * self.weight[..., None]).sum(1)

    def bilateral(self, latents: torch.Tensor, nearest: "Taps", tau: float) -> "Taps":
        """These bilinear taps reweighted by how close each tap's latent (a (texels, C) table) is to the
        nearest texel's: exp(-(max |z_j - z_nearest| / tau)^2). Within a material the filter stays
        bilinear; across an edge between materials the other side's taps drop out, so no latent
        between two materials (which decodes to neither) is read."""
        centre = latents[nearest.index[:, :1]]
        distance = (latents[self.index] - centre).abs().amax(-1)
        weight = self.weight * torch.exp(-(distance / tau).square())
        return Taps(self.index, weight / weight.sum(1, keepdim=True).clamp(min=1e-12))


@dataclasses.dataclass
class Material:
    """One material's inputs to the chain: its texel vectors, the shipped fit, its base colour map."""

    name: str
    type: int
    shape: tuple[int, int] | None
    texels: torch.Tensor  # (texels, 22) exact vectors
    representative: torch.Tensor  # (texels,) index of each texel's fitted vector
    unique: np.ndarray  # (K, 22)
    z: torch.Tensor  # (K, 6) shipped latents
    scale: torch.Tensor  # (K,) energy scale
    base: np.ndarray  # (h, w, 3)
    fit_seconds: float


def enhance(asset: Path, out: Path) -> dict[str, Path]:
    """The farm's ``enhance`` at its defaults; {material name: folder}."""
    return {json.loads((f / "params.json").read_text())["material"]: f for f in enhanced_folders(asset, out)}


def subsample(image: np.ndarray, size: int) -> np.ndarray:
    """(H, W, C) image with at most ``size`` texels a side (every k-th texel: no value is invented)."""
    h, w = image.shape[:2]
    step = max(1, -(-max(h, w) // size)) if size else 1
    return np.ascontiguousarray(image[::step, ::step])


def fit_material(model: NeuralModel, folder: Path, name: str, size: int, steps: int,
                 cache: Path | None) -> Material:
    """The fit as the add-on's Fit runs it (``torch_models fit`` at its defaults), of the material's
    maps at most ``size`` texels a side (0: as they are); fits are kept in ``cache`` when given."""
    shape, texels = texel_matrix(folder)
    if shape is not None:
        image = subsample(texels.reshape(*shape, -1), size)
        shape, texels = image.shape[:2], image.reshape(-1, texels.shape[1])
    mv = dedupe(shape, texels, QUANT)
    key = (cache / f"{folder.parent.name}_{folder.name}_{size}_{steps}_{model.digest[:12]}.safetensors"
           if cache else None)
    if key is not None and key.exists():
        saved = load_file(str(key))
        z, scale, seconds = saved["z"], saved["scale"], float(saved["seconds"])
    else:
        start = time.perf_counter()
        z = fit_latents(model, mv.unique, steps, seed=0)
        bounded = energy.fit_bounded(model, mv.unique, z, seed=0, steps=min(REFIT_STEPS, steps))
        seconds = time.perf_counter() - start
        z, scale = bounded.z.detach().contiguous(), bounded.check.energy_scale().detach().contiguous()
        if key is not None:
            save_file({"z": z, "scale": scale, "seconds": torch.tensor(seconds)}, str(key))
    base = material_folder.read(folder).map("base_color").value
    base = subsample(base, size) if base.ndim == 3 else base.reshape(1, 1, 3)
    representative = torch.from_numpy(mv.inverse) if shape else torch.zeros(1, dtype=torch.long)
    params = json.loads((folder / "params.json").read_text())
    return Material(name, params["type"], shape, torch.from_numpy(texels), representative, mv.unique,
                    z, scale, base.astype(np.float32), seconds)


def oracle_latents(model: NeuralModel, m: Material, visible: torch.Tensor, args: argparse.Namespace,
                   key: Path | None) -> tuple[torch.Tensor, dict]:
    """Latents (K, 6) with the ``visible`` vectors refitted alone at a large budget (the rest as shipped);
    kept at ``key`` when given."""
    vectors = m.unique[visible.numpy()]
    start = time.perf_counter()
    if key is not None and key.exists():
        saved = load_file(str(key))
        refit, seconds = saved["z"], float(saved["seconds"])
    else:
        refit = fit_latents(model, vectors, args.oracle_steps, seed=1, start=m.z[visible],
                            per_vector=args.oracle_per_vector).detach().contiguous()
        seconds = time.perf_counter() - start
        if key is not None:
            save_file({"z": refit, "seconds": torch.tensor(seconds)}, str(key))
    z = m.z.clone()
    z[visible] = refit
    losses = {"shipped": held_out_loss(model, vectors, m.z[visible]),
              "oracle": held_out_loss(model, vectors, refit)}
    return z, {"vectors": int(len(visible)), "seconds": seconds, "held_out_loss": losses}


def chain_bsdfs(model: NeuralModel, m: Material, uv: torch.Tensor, z_oracle: torch.Tensor,
                tau: float) -> dict:
    """Per render of ``CHAIN`` and ``BESIDE``, the BSDF of this material's pixels (``uv`` (N, 2))."""
    base = sample_texture(m.base, uv).clamp(min=0.0)
    bilinear, nearest = Taps.at(uv, m.shape, False), Taps.at(uv, m.shape, True)
    per_texel = m.representative
    bilateral = bilinear.bilateral(m.z[per_texel], nearest, tau)

    def neural(z: torch.Tensor, taps: Taps, decoder_model: NeuralModel) -> NeuralBsdf:
        zt, st = z[per_texel], m.scale[per_texel][:, None]
        return NeuralBsdf(decoder_model, taps.gather(zt), base, taps.gather(st))

    closure = closure_model(model)
    return {"reference": LayeredBsdf(params_from_vectors(bilinear.gather(m.texels)), base),
            "lookup": LayeredBsdf(params_from_vectors(nearest.gather(m.texels)), base),
            "reach": neural(z_oracle, nearest, model),
            "fit": neural(m.z, nearest, model),
            "sampling": neural(m.z, bilinear, model),
            "closure": neural(m.z, bilinear, closure),
            "bilateral": neural(m.z, bilateral, model),
            "closure_bilateral": neural(m.z, bilateral, closure)}


class PixelBsdf:
    """The renderer's BSDF over all covered pixels, each pixel answered by its material's BSDF."""

    def __init__(self, parts: list[tuple[torch.Tensor, object]]) -> None:
        self.parts = parts  # (rows among the covered pixels, BSDF of those rows)

    def _each(self, method: str, wi: torch.Tensor, x: torch.Tensor, width: int | None) -> torch.Tensor:
        out = torch.zeros((len(wi), width) if width else (len(wi),))
        for rows, bsdf in self.parts:
            out[rows] = getattr(bsdf, method)(wi[rows], x[rows])
        return out

    def eval(self, wi: torch.Tensor, wo: torch.Tensor) -> torch.Tensor:
        return self._each("eval", wi, wo, 3)

    def pdf(self, wi: torch.Tensor, wo: torch.Tensor) -> torch.Tensor:
        return self._each("pdf", wi, wo, None)

    def sample(self, wi: torch.Tensor, u: torch.Tensor) -> torch.Tensor:
        return self._each("sample", wi, u, 3)


def asset_budget(name: str, model: NeuralModel, env: EnvMap, args: argparse.Namespace,
                 tmp: Path) -> tuple[dict, dict]:
    """The asset's report block and its images (scene -> chain name -> AgX image)."""
    path = SHARED_ASSETS / "models" / f"{name}.glb"
    folders = enhance(path, tmp / name)
    inp = load_mesh(path)
    cams = preview_cameras(inp.mesh, 1, args.resolution)
    iv = render_intrinsics(inp.mesh, cams, [m.base_color for m in inp.materials])
    mask = (iv.coverage[0] > 0.5).numpy()
    covered = torch.from_numpy(mask.ravel())
    uv = iv.uvs[0].reshape(-1, 2)[covered].float()
    material_of = iv.material[0].reshape(-1)[covered]
    to_cam = cams.origins[0].float() - iv.positions[0]
    views = (to_cam / to_cam.norm(dim=-1, keepdim=True).clamp(min=1e-12)).numpy()
    normals = iv.normals[0].numpy()

    by_name: dict[str, list[int]] = {}
    for index, mi in enumerate(inp.materials):
        by_name.setdefault(mi.name, []).append(index)
    materials, parts, block = {}, {k: [] for k in CHAIN + BESIDE}, {"materials": {}, "notes": inp.notes}
    for mat_name, indices in by_name.items():
        rows = torch.from_numpy(np.isin(material_of.numpy(), indices)).nonzero()[:, 0]
        if not len(rows) or mat_name not in folders:
            continue
        m = fit_material(model, folders[mat_name], mat_name, args.texture_size, args.fit_steps, args.cache)
        texel = Taps.at(uv[rows], m.shape, True).index[:, 0]
        visible = torch.unique(m.representative[texel])
        key = (args.cache / f"{name}_{mat_name}_{args.texture_size}_{args.resolution}_oracle{args.oracle_steps}x"
                            f"{args.oracle_per_vector}_{model.digest[:12]}.safetensors") if args.cache else None
        z_oracle, oracle = oracle_latents(model, m, visible, args, key)
        for k, bsdf in chain_bsdfs(model, m, uv[rows], z_oracle, args.tau).items():
            parts[k].append((rows, bsdf))
        materials[mat_name] = rows
        block["materials"][mat_name] = {"type": m.type, "texture": list(m.shape) if m.shape else None,
                                        "fitted_vectors": len(m.unique), "fit_seconds": m.fit_seconds,
                                        "pixels": int(len(rows)), "oracle": oracle}
        print(f"{name}/{mat_name}: {len(m.unique)} vectors fitted in {m.fit_seconds:.0f} s, oracle on "
              f"{oracle['vectors']} visible ({oracle['held_out_loss']['shipped']:.3f} -> "
              f"{oracle['held_out_loss']['oracle']:.3f}) in {oracle['seconds']:.0f} s", flush=True)

    images: dict = {}
    pixel_material = np.full(mask.sum(), "", dtype=object)
    for mat_name, rows in materials.items():
        pixel_material[rows.numpy()] = mat_name
    for scene, sun in SCENES.items():
        imgs = {}
        for k in CHAIN + BESIDE:
            imgs[k] = render(PixelBsdf(parts[k]), env, normals, views, mask, args, 0, sun)
        imgs["reference_seed1"] = render(PixelBsdf(parts["reference"]), env, normals, views, mask, args, 1, sun)
        images[scene] = imgs
        block[scene] = scene_terms(imgs, mask, pixel_material, list(materials))
    return block, images


def render(bsdf: PixelBsdf, env: EnvMap, normals: np.ndarray, views: np.ndarray, mask: np.ndarray,
           args: argparse.Namespace, seed: int, sun: Sun | None) -> np.ndarray:
    with torch.no_grad():
        return agx(shade_gbuffer(lambda n: bsdf, env, normals, views, mask, args.spp, seed, sun=sun))


def scene_terms(imgs: dict, mask: np.ndarray, pixel_material: np.ndarray, names: list[str]) -> dict:
    """Mean FLIP of each chain render against the reference, over each material's pixels and all of them,
    and the terms (the rise from one render to the next). The chain's renders share the reference's
    seed, so what they differ by is the material, not the noise; the noise floor (the reference at
    another seed) says how far apart two renders of one material are."""
    maps = {k: flip_map(imgs["reference"], imgs[k])[0][mask] for k in CHAIN[1:] + BESIDE}
    maps["noise_floor"] = flip_map(imgs["reference"], imgs["reference_seed1"])[0][mask]

    def block(select: np.ndarray) -> dict:
        flip = {k: float(v[select].mean()) for k, v in maps.items()}
        terms, previous = {}, 0.0
        for k in CHAIN[1:]:
            terms[k] = flip[k] - previous
            previous = flip[k]
        return {"flip": flip, "terms": terms}

    out = {"all": block(np.ones(len(pixel_material), bool))}
    out["per_material"] = {n: block(pixel_material == n) for n in names}
    return out


def chart(report: dict, path: Path) -> None:
    """Per material (and the asset's whole), one panel per scene: the chain's terms stacked, the noise
    floor as a tick, and the bilateral latents' preview (closure form included) as a diamond."""
    plt = pyplot()
    rows = [(f"{asset}\n{mat}"[:40], asset, mat) for asset, a in report["assets"].items()
            for mat in ["(all)", *a["probe"]["per_material"]]]
    fig, axes = plt.subplots(len(SCENES), 1, figsize=(max(8, 0.6 * len(rows) + 2), 8.5))
    colours = {"lookup": "tab:gray", "reach": "tab:red", "fit": "tab:orange", "sampling": "tab:purple",
               "closure": "tab:blue"}
    for ax, scene in zip(axes, SCENES):
        blocks = [report["assets"][asset][scene]["all"] if mat == "(all)"
                  else report["assets"][asset][scene]["per_material"][mat] for _, asset, mat in rows]
        x = np.arange(len(rows))
        bottom_pos, bottom_neg = np.zeros(len(x)), np.zeros(len(x))
        for key, colour in colours.items():
            v = np.array([b["terms"][key] for b in blocks])
            pos, neg = np.clip(v, 0, None), np.clip(v, None, 0)
            ax.bar(x, pos, 0.7, bottom=bottom_pos, color=colour, label=TERMS[key])
            ax.bar(x, neg, 0.7, bottom=bottom_neg, color=colour)
            bottom_pos += pos
            bottom_neg += neg
        ax.plot(x, [b["flip"]["noise_floor"] for b in blocks], "k_", ms=16, label="noise floor (another seed)")
        ax.plot(x, [b["flip"]["closure_bilateral"] for b in blocks], "D", color="tab:green", ms=5,
                label="with bilateral latents")
        ax.axhline(0.05, ls="--", color="k", lw=0.8, label="target 0.05")
        ax.set_xticks(x, [r[0] for r in rows], fontsize=6, rotation=60, ha="right")
        ax.set_ylabel("mean FLIP vs the analytic material")
        ax.set_title(f"where the neural preview's error comes from (torch, G-buffer); scene: {scene}")
        ax.set_ylim(top=1.45 * max(max(bottom_pos), 0.05))  # room for the legend above the bars
        ax.legend(fontsize=7, ncol=4, loc="upper right")
    save_chart(fig, path)


def sheet(images: dict, path: Path) -> None:
    """Per asset and scene: the chain's renders side by side, labelled, with the FLIP of the last."""
    from PIL import Image, ImageDraw

    rows = [(f"{asset} / {scene}", imgs) for asset, by_scene in images.items() for scene, imgs in by_scene.items()]
    size = next(iter(rows))[1]["reference"].shape[0]
    cols = [*CHAIN, "FLIP closure"]
    label, header = 150, 20
    out = Image.new("RGB", (label + size * len(cols), header + size * len(rows)), (255, 255, 255))
    draw = ImageDraw.Draw(out)
    for j, c in enumerate(cols):
        draw.text((label + j * size + 4, 4), c, fill=(0, 0, 0))
    for i, (name, imgs) in enumerate(rows):
        draw.text((4, header + i * size + size // 2), name, fill=(0, 0, 0))
        error = flip_map(imgs["reference"], imgs["closure"])[0]
        tiles = [imgs[k] for k in CHAIN] + [np.repeat(error[..., None], 3, -1)]
        for j, tile in enumerate(tiles):
            out.paste(Image.fromarray((np.clip(tile, 0, 1) * 255 + 0.5).astype(np.uint8)),
                      (label + j * size, header + i * size))
    out.save(path)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--assets", nargs="+", default=list(ASSETS))
    parser.add_argument("--resolution", type=int, default=256, help="render size in pixels")
    parser.add_argument("--spp", type=int, default=64, help="torch renderer samples per pixel")
    parser.add_argument("--fit-steps", type=int, default=FIT_STEPS, help="the fit's steps (the add-on's Fit Steps)")
    parser.add_argument("--oracle-steps", type=int, default=300)
    parser.add_argument("--oracle-per-vector", type=int, default=32, help="the oracle's samples per vector and step")
    parser.add_argument("--texture-size", type=int, default=0,
                        help="at most this many texels a side (every k-th texel); 0: the maps as they are")
    parser.add_argument("--tau", type=float, default=0.1, help="the bilateral filter's latent distance scale")
    parser.add_argument("--cache", type=Path, default=None, help="keep fits here, to rerun without refitting")
    parser.add_argument("--weights", type=Path, default=trained.SHIPPED,
                        help="the decoder's weights folder (default: the shipped one)")
    add_out_argument(parser, "neural_error_budget.json")
    args = parser.parse_args()
    start = time.perf_counter()
    model = trained.load(args.weights)
    env = EnvMap.load(DEFAULT_PROBE)
    report: dict = {"settings": {**{k: str(v) if isinstance(v, Path) else v for k, v in vars(args).items()
                                    if k != "out"},
                                 "cluster_step": QUANT, "sun": dataclasses.asdict(KEY_LIGHT)},
                    "flip_convention": FLIP_CONVENTION, "chain": {k: TERMS.get(k, "") for k in CHAIN},
                    "assets": {}}
    images = {}
    with tempfile.TemporaryDirectory() as tmp:
        for name in args.assets:
            report["assets"][name], images[name] = asset_budget(name, model, env, args, Path(tmp))
            for scene in SCENES:
                b = report["assets"][name][scene]["all"]
                print(f"{name} {scene}: floor {b['flip']['noise_floor']:.4f}, " +
                      ", ".join(f"{k} {v:+.4f}" for k, v in b["terms"].items()), flush=True)
            report["wall_seconds"] = time.perf_counter() - start
            write_report(args.out, report, [args.weights])
            chart(report, args.out.with_suffix(".png"))
            sheet(images, args.out.with_name(f"{args.out.stem}_sheet.png"))


if __name__ == "__main__":
    main()
