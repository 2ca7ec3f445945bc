"""Text + mesh -> neural material: per material an uplift prior; views chosen to see the surface;
condition views, diffusion sampling of the residual, projection into each material's texture space."""
from __future__ import annotations

import json
import math
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Callable

import numpy as np
import torch
from safetensors.torch import load_file
from torch import Tensor

from richmat_addon.core.enhancement_types import METAL_REMAP
from richmat_addon.core.maps import PbrInputs, ParamMap
from richmat_addon.core.prompt import read_prompt
from richmat_addon.core.uv_raster import UvRaster, rasterize as uv_rasterize
from ..stage_clock import StageClock
from . import DEFAULT_SAMPLES, DEFAULT_STEPS, DEFAULT_TEXTURE_SIZE, DEFAULT_VIEWS, guidance_for, text
from .coverage import TextureSpace, choose_cameras
from .dit import TYPE_EMBEDDING, Conditions, LatentGenerator
from .mesh_input import MeshInput
from .prior import prior_latents
from .projection import Projection, project, rim_trust
from .train import GeneratorTrainConfig
from .views import (ELEVATION_DEG, Cameras, IntrinsicViews, Mesh, Textures, direction, look_at, per_material,
                    render_intrinsics)

if TYPE_CHECKING:
    from ..neural.model import NeuralModel

SHIPPED = Path(__file__).resolve().parent / "weights"
SEEN_WARNING = 0.5  # below this share of directly seen texels the result is mostly inpainted: say so
PROJECTION_UPSAMPLE = 8  # generated views are upsampled this much before splatting, so texels get dense samples
CHOICE_UPSAMPLE = 4  # candidate views are judged at this multiple of the model's resolution


def load_generator(folder: Path = SHIPPED) -> tuple[LatentGenerator, GeneratorTrainConfig]:
    """A trained generator (weights.safetensors + state.json of a train-generator run), in eval mode."""
    weights, state = folder / "weights.safetensors", folder / "state.json"
    if not weights.is_file() or not state.is_file():
        raise FileNotFoundError(f"{folder}: no trained generator here (weights.safetensors, state.json); "
                                "run `python -m torch_models train-generator` first")
    cfg = GeneratorTrainConfig.from_dict(json.loads(state.read_text())["config"])
    tensors = load_file(str(weights))
    # the type count is the checkpoint's, not today's table's (state.json files before DitConfig.types lack it)
    cfg = replace(cfg, model=replace(cfg.model, types=tensors[TYPE_EMBEDDING].shape[0] - 1))
    model = LatentGenerator(cfg.model)
    model.load_state_dict(tensors)
    return model.eval().requires_grad_(False), cfg


def encoder_mismatch(folder: Path, encoder_digest: str) -> str | None:
    """A warning when the generator at ``folder`` learned the latents of another encoder:
    the decoder in use would read its output as materials it never meant."""
    trained = json.loads((folder / "state.json").read_text()).get("encoder_sha256")
    if trained is None or trained == encoder_digest:
        return None
    return (f"this generator was trained on the latent space of encoder {trained[:12]}, but the decoder in use "
            f"has encoder {encoder_digest[:12]}: its materials will not be the ones the prompt asks for; "
            "retrain it with `python -m torch_models train-generator`")


def diffuse_fallback_latent() -> Tensor:
    """(6,) the shipped encoder's latent of a plain rough dielectric: what unseen UV islands get."""
    from richmat_addon.core.enhance import baseline
    from ..neural import trained
    from .encoding import pack_vectors

    plain = baseline(PbrInputs("fallback", ParamMap.constant(0.8, 0.8, 0.8), ParamMap.constant(1.0),
                               ParamMap.constant(0.0)))
    with torch.no_grad():
        return trained.load().encoder(torch.from_numpy(pack_vectors(plain, (1, 1))))[0]


@dataclass
class MaterialLatents:
    """One material's generated latent texture and how it was made."""

    name: str
    latents: np.ndarray  # (H, W, 6) texture
    prior: np.ndarray  # (H, W, 6) the uplift prior the residual was added to (prior.py)
    energy_scale: np.ndarray  # (H, W) f_neu scale per texel from the energy guard (1 where none is needed)
    projection: Projection
    charts: Tensor  # (H, W) bool: the texels its UVs cover

    def stats(self) -> dict[str, float]:
        """Shares of its chart texels seen by a view, inpainted, given the fallback."""
        return self.projection.stats(self.charts)


@dataclass
class Generation:
    materials: list[MaterialLatents]  # as ``MeshInput.materials``
    views: Tensor  # (V, 6, h, w) the sampled latent views (prior + residual) the textures were made from
    cameras: Cameras  # the views' cameras (``coverage.choose_cameras``)
    type: int
    guidance: float  # the classifier-free guidance it was sampled with
    warnings: list[str] = field(default_factory=list)
    seconds: dict[str, float] = field(default_factory=dict)  # wall seconds per stage (``StageClock.wall``)

    def coverage(self) -> dict[str, float]:
        """Shares of all the materials' chart texels seen by a view, inpainted, given the fallback."""
        counts = [int(m.charts.sum()) for m in self.materials]
        return {k: sum(m.stats()[k] * c for m, c in zip(self.materials, counts)) / max(sum(counts), 1)
                for k in ("seen", "inpainted", "fallback")}

    @property
    def only(self) -> MaterialLatents:
        """The material of a one-material mesh (procedural objects, the demo, the benches)."""
        if len(self.materials) != 1:
            raise ValueError(f"the mesh has {len(self.materials)} materials; pick one from .materials")
        return self.materials[0]

    @property
    def latents(self) -> np.ndarray:
        return self.only.latents

    @property
    def prior(self) -> np.ndarray:
        return self.only.prior

    @property
    def energy_scale(self) -> np.ndarray:
        return self.only.energy_scale

    @property
    def projection(self) -> Projection:
        return self.only.projection

    @property
    def charts(self) -> Tensor:
        return self.only.charts


def _upsample(values: Tensor, coverage: Tensor, factor: int) -> Tensor:
    """(V, H, W, C) values at `factor` x the resolution, bilinear over covered pixels only."""
    cov = (coverage > 0.5).float()[:, None]
    up = lambda x: torch.nn.functional.interpolate(x, scale_factor=factor, mode="bilinear", align_corners=False)
    num, den = up(values.permute(0, 3, 1, 2) * cov), up(cov)
    return (num / den.clamp(min=1e-6)).permute(0, 2, 3, 1)


@dataclass
class MaterialSpace:
    """A material's texture space at its latent texture's size: what the views and the prior need."""

    charts: Tensor  # (H, W) bool
    base_color: np.ndarray  # (H, W, 3) or (1, 1, 3)
    roughness_metalness: np.ndarray | None
    prior: np.ndarray  # (H, W, 6)


def texture_rasters(inp: MeshInput, largest: int) -> list[UvRaster]:
    """Every material's mesh rasterised into its UV space at its latent texture's size (charts, and
    the world normals and positions the enhancement rules' masks read)."""
    rasters = []
    mesh = inp.mesh
    for index, material in enumerate(inp.materials):
        raster, reason = uv_rasterize(mesh.positions, mesh.normals, mesh.uvs, mesh.faces[mesh.materials == index],
                                      material.texture_shape(largest))
        if raster is None:
            raise ValueError(f"cannot project into the texture space of material {material.name!r}: {reason}")
        rasters.append(raster)
    return rasters


def texture_spaces(inp: MeshInput, type_: int, largest: int, fixed: dict[str, float]) -> list[MaterialSpace]:
    """Every material's charts, maps and uplift prior (``fixed``: the settings the prompt's strength words
    set) at its latent texture's size."""
    spaces = []
    for material, raster in zip(inp.materials, texture_rasters(inp, largest)):
        base, rm = material.maps_at(raster.coverage.shape)
        rm = rm if inp.pbr_known else None  # the generator's PBR flag is one per view pixel: all or none
        spaces.append(MaterialSpace(torch.from_numpy(raster.coverage), base, rm,
                             prior_latents(base, rm, type_, raster.normals, raster.positions, fixed)))
    return spaces


def generate(inp: MeshInput, prompt: str, model: LatentGenerator, cfg: GeneratorTrainConfig, seed: int = 0,
             steps: int = DEFAULT_STEPS, views: int = DEFAULT_VIEWS, guidance: float | None = None,
             texture_size: int = DEFAULT_TEXTURE_SIZE, progress: Callable[[int, int], None] | None = None,
             guard_energy: bool = True, samples: int = DEFAULT_SAMPLES, cameras: Cameras | None = None,
             strengths: bool = True) -> Generation:
    """The latent textures of ``inp``'s materials for ``prompt``; ``progress(step, steps)`` follows the
    sampling. Each material's texture follows its maps' size up to ``texture_size`` a side.
    ``guidance`` None samples with the prompt's type's default (``guidance_for``);
    ``guard_energy`` False skips the energy guard (its scale maps are then all 1); ``samples`` > 1
    averages that many residuals (``LatentGenerator.sample``); ``cameras`` (at the model's resolution)
    replaces the ``views`` chosen to see the surface; ``strengths`` False draws the prior's worded settings
    instead of reading them from the prompt's strength words (the generator before it read them)."""
    clock = StageClock()
    with clock.stage("prior"):
        reading = read_prompt(prompt, metallic=inp.metallic)
        type_, warnings = reading.type, reading.warnings + inp.warnings
        if type_ in METAL_REMAP:
            warnings += [f"material {m.name!r} is a metal: its prior takes Type {METAL_REMAP[type_]} instead"
                         for m in inp.materials if m.metallic]
        spaces = texture_spaces(inp, type_, texture_size, reading.settings() if strengths else {})
    res = cfg.model.size
    with clock.stage("view_choice"):
        cams = cameras or choose_cameras(inp.mesh, [TextureSpace(s.charts) for s in spaces], views,
                                         cfg.corpus.views, res, res * CHOICE_UPSAMPLE)
    with clock.stage("condition_views"):
        bases = [s.base_color for s in spaces]
        cond_views = render_intrinsics(inp.mesh, cams, bases, [s.prior for s in spaces], cfg.corpus.supersample,
                                       [s.roughness_metalness for s in spaces] if inp.pbr_known else None)
        cond = Conditions(cond_views.conditions(cond_views.latents)[None], text.embed([prompt]),
                          torch.tensor([type_]))
    guidance = guidance_for(type_) if guidance is None else guidance
    with clock.stage("sampling"):
        residual = model.sample(cond, steps, seed, guidance, progress, samples)[0]
    with clock.stage("projection"):
        fine_cams = Cameras(res * PROJECTION_UPSAMPLE, cams.focal_px * PROJECTION_UPSAMPLE, cams.camera_to_world)
        fine = render_intrinsics(inp.mesh, fine_cams, bases)
        values = _upsample(residual.permute(0, 2, 3, 1), cond_views.coverage, PROJECTION_UPSAMPLE)
        values = values * (fine.coverage > 0.5)[..., None]
        fallback = diffuse_fallback_latent()
        trust = rim_trust(fine, fine_cams, PROJECTION_UPSAMPLE // 2)  # half a model pixel from an edge
        textures, projections = [], []
        for index, space in enumerate(spaces):
            prior = torch.from_numpy(space.prior)
            # islands no view saw end on the diffuse fallback: their residual is fallback - prior
            proj = project(values, fine, fine_cams, space.charts, fallback - prior, pixels=fine.material == index,
                           trust=trust)
            texture = (prior + proj.texture).clamp(-1.0, 1.0)  # the encoder's latent box
            textures.append(texture.numpy().astype(np.float16).astype(np.float32))  # as the half-float EXRs hold it
            projections.append(proj)
    with clock.stage("energy_guard"):
        texels = np.concatenate([t.reshape(-1, 1, 6) for t in textures])
        energy = energy_guard(texels) if guard_energy else np.ones(texels.shape[:2], np.float32)
        scales = np.split(energy.reshape(-1), np.cumsum([t.shape[0] * t.shape[1] for t in textures])[:-1])
    materials = [MaterialLatents(m.name, t, s.prior, scale.reshape(t.shape[:2]), p, s.charts)
                 for m, t, s, scale, p in zip(inp.materials, textures, spaces, scales, projections)]
    generation = Generation(materials, (cond.prior[0] + residual).clamp(-1.0, 1.0), cams, type_, guidance, warnings,
                            clock.wall)
    stats = generation.coverage()
    if stats["fallback"] > 0.05:
        warnings.append(f"{stats['fallback']:.0%} of the texels lie on UV islands no view saw: "
                        "they got the diffuse fallback (more --views may help)")
    if stats["seen"] < SEEN_WARNING:
        warnings.append(f"only {stats['seen']:.0%} of the texels were seen squarely by a view (thin parts, many "
                        "small UV islands or hidden surfaces): the rest is inpainted from their neighbours")
    return generation


def energy_guard(latents: np.ndarray, model: NeuralModel | None = None) -> np.ndarray:
    """(H, W) f_neu scale per texel that keeps every texel inside the white furnace.

    Sampling and view averaging can land on latents that gain energy when the decoder is not
    bounded by construction (the MLP kind): ``energy.guard`` measures each distinct latent and
    darkens the ones that do, as ``fit`` repairs a fitted material. A bounded decoder (the shipped
    hybrid) needs no measurement: every scale is 1. ``model`` defaults to the shipped decoder."""
    from ..neural import energy, trained

    unique, inverse = np.unique(latents.reshape(-1, latents.shape[-1]), axis=0, return_inverse=True)
    scale = energy.guard(model or trained.load(), torch.from_numpy(unique))
    return scale.numpy()[inverse.reshape(-1)].reshape(latents.shape[:2])


def preview_cameras(mesh: Mesh, frames: int, resolution: int) -> Cameras:
    """``frames`` cameras around the object at batch's mean elevation, a quarter turn off its axes (so a
    box shows two sides), each framing the mesh's own bounding sphere."""
    centre = (mesh.positions.max(0) + mesh.positions.min(0)) / 2
    radius = float(np.linalg.norm(mesh.positions - centre, axis=1).max())
    directions = [direction(math.pi / 4 + 2 * math.pi * i / frames, math.radians(ELEVATION_DEG)) for i in range(frames)]
    return look_at(np.stack(directions), resolution, radius, centre)


def preview(inp: MeshInput, latents: Textures, frames: int = 4, resolution: int = 128, spp: int = 16,
            energy_scale: Textures | None = None) -> np.ndarray:
    """Scene-linear renders (frames, H, W, 3) of the mesh with each material's baked latents (f_neu
    scaled by its (H, W) ``energy_scale`` map when given) over its base colour, lit by the default probe.

    G-buffer shading (no shadows, no interreflection), the same as the neural material's ball preview."""
    from ..neural import trained
    from ..neural.bsdf import NeuralBsdf
    from ..neural.evaluate import DEFAULT_PROBE
    from ..render.ball import shade_gbuffer
    from ..render.envmap import EnvMap

    model = trained.load()
    env = EnvMap.load(DEFAULT_PROBE)
    cams = preview_cameras(inp.mesh, frames, resolution)
    textures = per_material(latents)
    scales = (per_material(energy_scale) if energy_scale is not None
              else [np.ones(t.shape[:2], np.float32) for t in textures])
    packed = [np.concatenate([t, s[..., None]], -1) for t, s in zip(textures, scales)]
    iv: IntrinsicViews = render_intrinsics(inp.mesh, cams, [m.base_color for m in inp.materials], packed)
    out = []
    for f in range(frames):
        mask = (iv.coverage[f] > 0.5).numpy()
        to_cam = cams.origins[f].float() - iv.positions[f]
        to_cam = (to_cam / to_cam.norm(dim=-1, keepdim=True).clamp(min=1e-12)).numpy()
        texel = torch.from_numpy(iv.latents[f].numpy().reshape(-1, 7)[mask.ravel()])
        base = iv.base_color[f].numpy().reshape(-1, 3)[mask.ravel()]
        bsdf = NeuralBsdf(model, texel[:, :6], torch.from_numpy(base), texel[:, 6:])
        out.append(shade_gbuffer(lambda n: bsdf, env, iv.normals[f].numpy(), to_cam, mask, spp=spp, seed=f))
    return np.stack(out)
