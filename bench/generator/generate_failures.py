"""Where the generator fails (issue 6, item 7): UV islands, thin parts, unseen texels, unknown words.

The first three are failures of the projection into texture space, so they are
measured by what the projection keeps: the shares of chart texels seen by a
view, inpainted from neighbours, or given the diffuse fallback, and the round-trip
error: the latent views re-rendered from the projected texture against the views
the model sampled (RMS over covered pixels, in latent units; 0 when the texture
holds exactly what the views said).
- many UV islands: held-out objects re-unwrapped by xatlas with a cap on the
  chart area, so the same surface falls into ever more islands;
- thin parts: a torus whose tube gets thinner (the object is normalised into the
  unit cube, so the tube shrinks against the views' pixels);
- views that miss texels: fewer views, on held-out objects and on a thick tube
  (annulus) whose inner wall few views see;
- prompts outside the vocabulary: the type keywords found, the warning, and the
  cosine of the prompt's MiniLM embedding to the nearest training caption.
Base colour is the object's mean (a constant), so every variant gets the same.

    python -m bench.generator.generate_failures [--checkpoint DIR] [--steps K]
"""
from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import torch

from bench.common import add_out_argument, pyplot, save_chart, write_report
from bench.generator.generate_eval import Retrieval, held_out, held_out_indices
from richmat_addon.core.prompt import prompt_type
from torch_models.generator import DEFAULT_STEPS, text
from torch_models.generator import generate as gen
from torch_models.generator.dit import LatentGenerator
from torch_models.generator.mesh_input import MaterialInput, MeshInput
from torch_models.generator.train import GeneratorTrainConfig
from torch_models.generator.views import Mesh, render_intrinsics
from torch_models.neural import trained

ISLAND_CAPS = (None, 1 / 16, 1 / 64, 1 / 256)  # max chart area as a share of the surface (None: xatlas default)
TUBE_RADII = (0.25, 0.1, 0.04, 0.015)  # torus minor radius, major radius 0.5
VIEW_COUNTS = (2, 4, 8, 16)
VIEWS = 8  # the training views, where the view count is not what varies
PROMPTS = {
    "in vocabulary": ("red plastic material with light haze, light dust",
                      "white ceramic material with heavy haze, glossy clearcoat",
                      "green fabric material with heavy fuzz, light subsurface scattering"),
    "outside": ("polished marble", "rusty corroded iron", "glowing neon tube", "wet muddy leather boots"),
}


def unwrap(positions: np.ndarray, faces: np.ndarray, normals: np.ndarray,
           max_area_share: float | None) -> tuple[Mesh, int]:
    """The surface unwrapped by xatlas, charts capped at a share of the total area; (mesh, chart count)."""
    import xatlas

    atlas = xatlas.Atlas()
    atlas.add_mesh(positions.astype(np.float32), faces.astype(np.uint32), normals.astype(np.float32))
    options = xatlas.ChartOptions()
    if max_area_share is not None:
        tri = positions[faces]
        area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1).sum()
        options.max_chart_area = float(area * max_area_share)
    atlas.generate(chart_options=options)
    vmap, new_faces, uvs = atlas[0]
    return (Mesh(positions[vmap].astype(np.float32), normals[vmap].astype(np.float32), uvs.astype(np.float32),
                 new_faces.astype(np.int64)), int(atlas.chart_count))


def welded(mesh: Mesh) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(positions, faces, normals) with the UV seams closed, so a new unwrap starts from the bare surface."""
    import trimesh

    surface = trimesh.Trimesh(mesh.positions, mesh.faces, process=True)
    return np.asarray(surface.vertices), np.asarray(surface.faces), np.asarray(surface.vertex_normals)


def primitive(kind: str, size: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A torus (tube radius ``size``) or annulus (inner radius ``size``), in the unit cube."""
    import trimesh

    if kind == "torus":
        m = trimesh.creation.torus(major_radius=0.5, minor_radius=size, major_sections=64, minor_sections=24)
    else:
        m = trimesh.creation.annulus(r_min=size, r_max=0.5, height=0.6, sections=64)
        m = m.subdivide().subdivide()
    v = np.asarray(m.vertices)
    v = (v - (v.max(0) + v.min(0)) / 2) / (v.max(0) - v.min(0)).max()
    return v, np.asarray(m.faces), np.asarray(m.vertex_normals)


def measure(mesh: Mesh, base: np.ndarray, prompt: str, model: LatentGenerator, cfg: GeneratorTrainConfig,
            steps: int, views: int) -> dict:
    """Projection shares, round-trip error and warnings of one generation."""
    colour = base.reshape(1, 1, 3).astype(np.float32)
    inp = MeshInput(mesh, [MaterialInput("object", colour)])
    result = gen.generate(inp, prompt, model, cfg, 0, steps, views, texture_size=cfg.corpus.texture_size,
                          guard_energy=False)  # the guard scales f_neu; it changes no latent measured here
    again = render_intrinsics(mesh, result.cameras, colour, result.latents, cfg.corpus.supersample)
    covered = (again.coverage > 0.5)[..., None]
    diff = (again.latents - result.views.permute(0, 2, 3, 1)) * covered
    rms = float(torch.sqrt((diff ** 2).sum() / (covered.sum() * 6).clamp(min=1)))
    return {**result.projection.stats(result.charts), "round_trip_rms": rms, "warnings": result.warnings}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--checkpoint", type=Path, default=gen.SHIPPED)
    ap.add_argument("--objects", type=int, default=2)
    ap.add_argument("--steps", type=int, default=DEFAULT_STEPS)
    add_out_argument(ap, "generate_failures.json")
    args = ap.parse_args()
    torch.set_num_threads(1)
    model, cfg = gen.load_generator(args.checkpoint)
    objects = [held_out(i, cfg) for i in held_out_indices(args.objects, cfg.corpus.seed)]
    report: dict = {"checkpoint": str(args.checkpoint), "steps": args.steps, "islands": [], "thin": [],
                    "views": [], "prompts": []}
    for obj in objects:
        base = obj.asset.pbr.base_color.value.reshape(-1, 3).mean(0)
        surface = welded(obj.asset.mesh)
        for cap in ISLAND_CAPS:
            mesh, charts = unwrap(*surface, cap)
            row = {"object": obj.asset.asset_id, "max_chart_area": cap, "islands": charts,
                   **measure(mesh, base, obj.prompt, model, cfg, args.steps, VIEWS)}
            report["islands"].append(row)
            print("islands", {k: row[k] for k in ("object", "islands", "seen", "inpainted", "round_trip_rms")},
                  flush=True)
        for views in VIEW_COUNTS:
            row = {"object": obj.asset.asset_id, "views": views,
                   **measure(obj.asset.mesh, base, obj.prompt, model, cfg, args.steps, views)}
            report["views"].append(row)
            print("views", {k: row[k] for k in ("object", "views", "seen", "fallback")}, flush=True)
    grey = np.full(3, 0.5)
    tube_prompt = "grey plastic material with light haze, light dust"
    for radius in TUBE_RADII:
        mesh, _ = unwrap(*primitive("torus", radius), None)
        row = {"tube_radius": radius, **measure(mesh, grey, tube_prompt, model, cfg, args.steps, VIEWS)}
        report["thin"].append(row)
        print("thin", {k: row[k] for k in ("tube_radius", "seen", "inpainted", "round_trip_rms")}, flush=True)
    annulus, _ = unwrap(*primitive("annulus", 0.35), None)
    for views in VIEW_COUNTS:
        row = {"object": "annulus", "views": views, **measure(annulus, grey, tube_prompt, model, cfg, args.steps,
                                                               views)}
        report["views"].append(row)
        print("views", {k: row[k] for k in ("object", "views", "seen", "fallback")}, flush=True)
    captions = Retrieval(cfg.corpus).embeddings
    for group, prompts in PROMPTS.items():
        for prompt in prompts:
            type_, warnings = prompt_type(prompt)
            similarity = float((captions @ text.embed([prompt])[0]).max())
            report["prompts"].append({"group": group, "prompt": prompt, "type": type_, "warnings": warnings,
                                      "nearest_caption_cosine": similarity})
    write_report(args.out, report, [trained.SHIPPED], args.checkpoint)
    plot(report, args.out.with_suffix(".png"))
    print(f"wrote {args.out}")
    return 0


def _shares(ax, xs: list, rows: list[dict], xlabel: str, log: bool = False) -> None:
    """Stacked seen / inpainted / fallback shares, round-trip error on a second axis."""
    bottom = np.zeros(len(rows))
    positions = np.arange(len(rows))
    for key, colour in (("seen", "tab:green"), ("inpainted", "tab:orange"), ("fallback", "tab:red")):
        values = np.array([r[key] for r in rows])
        ax.bar(positions, values, bottom=bottom, color=colour, label=key)
        bottom += values
    ax.set_xticks(positions, [str(x) for x in xs], fontsize=7)
    ax.set_xlabel(xlabel, fontsize=8)
    ax.set_ylabel("share of chart texels", fontsize=8)
    twin = ax.twinx()
    twin.plot(positions, [r["round_trip_rms"] for r in rows], "k.-", label="round-trip RMS")
    twin.set_ylabel("round-trip RMS (latent units)", fontsize=8)
    twin.set_ylim(bottom=0)


def plot(report: dict, path: Path) -> None:
    plt = pyplot()
    fig, axes = plt.subplots(2, 2, figsize=(10, 7))
    first = report["islands"][0]["object"]
    islands = [r for r in report["islands"] if r["object"] == first]
    _shares(axes[0, 0], [r["islands"] for r in islands], islands, f"UV islands ({first}, same surface)")
    axes[0, 0].legend(fontsize=7, loc="lower left")
    axes[0, 0].set_title("many UV islands", fontsize=9)
    _shares(axes[0, 1], [r["tube_radius"] for r in report["thin"]], report["thin"],
            "torus tube radius (major radius 0.5)")
    axes[0, 1].set_title("thin parts", fontsize=9)
    views = [r for r in report["views"] if r["object"] == "annulus"]
    _shares(axes[1, 0], [r["views"] for r in views], views, "views (annulus: inner wall hidden)")
    axes[1, 0].set_title("views that miss texels", fontsize=9)
    ax = axes[1, 1]
    prompts = report["prompts"]
    colours = ["tab:blue" if p["group"] == "in vocabulary" else "tab:red" for p in prompts]
    ax.barh(np.arange(len(prompts)), [p["nearest_caption_cosine"] for p in prompts], color=colours)
    ax.set_yticks(np.arange(len(prompts)),
                  [p["prompt"][:38] + (" (warned)" if p["warnings"] else "") for p in prompts], fontsize=6.5)
    ax.set_xlabel("cosine to the nearest training caption (MiniLM)", fontsize=8)
    ax.set_title("prompts in (blue) and outside (red) the vocabulary", fontsize=9)
    save_chart(fig, path)


if __name__ == "__main__":
    raise SystemExit(main())
