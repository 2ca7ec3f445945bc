"""Text + mesh -> neural material: uplift prior, condition views, diffusion sampling of the residual,
projection to texture space."""
from __future__ import annotations

import json
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np
import torch
from safetensors.torch import load_file
from torch import Tensor

from richmat_addon.core.maps import PbrInputs, ParamMap
from richmat_addon.core.prompt import prompt_type
from richmat_addon.core.uv_raster import rasterize as uv_rasterize
from . import DEFAULT_SAMPLES, DEFAULT_STEPS, DEFAULT_TEXTURE_SIZE, DEFAULT_VIEWS, text
from .dit import Conditions, LatentGenerator
from .mesh_input import MeshInput
from .prior import prior_latents
from .projection import Projection, project
from .train import GeneratorTrainConfig
from .views import IntrinsicViews, orbit_cameras, render_intrinsics

SHIPPED = Path(__file__).resolve().parent / "weights"
SEEN_WARNING = 0.5  # below this share of directly seen texels the result is mostly inpainted: say so
PROJECTION_UPSAMPLE = 4  # generated views are upsampled this much before splatting, so texels get dense samples


def load_generator(folder: Path = SHIPPED) -> tuple[LatentGenerator, GeneratorTrainConfig]:
    """A trained generator (weights.safetensors + state.json of a train-generator run), in eval mode."""
    weights, state = folder / "weights.safetensors", folder / "state.json"
    if not weights.is_file() or not state.is_file():
        raise FileNotFoundError(f"{folder}: no trained generator here (weights.safetensors, state.json); "
                                "run `python -m torch_models train-generator` first")
    cfg = GeneratorTrainConfig.from_dict(json.loads(state.read_text())["config"])
    model = LatentGenerator(cfg.model)
    model.load_state_dict(load_file(str(weights)))
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
    from ..neural import weights
    from .encoding import pack_vectors

    plain = baseline(PbrInputs("fallback", ParamMap.constant(0.8, 0.8, 0.8), ParamMap.constant(1.0),
                               ParamMap.constant(0.0)))
    with torch.no_grad():
        return weights.load().encoder(torch.from_numpy(pack_vectors(plain, (1, 1))))[0]


@dataclass
class Generation:
    latents: np.ndarray  # (H, W, 6) texture
    prior: np.ndarray  # (H, W, 6) the uplift prior the residual was added to (prior.py)
    views: Tensor  # (V, 6, h, w) the sampled latent views (prior + residual) the texture was made from
    projection: Projection
    charts: Tensor
    type: int
    energy_scale: np.ndarray  # (H, W) f_neu scale per texel from the energy guard (1 where none is needed)
    warnings: list[str] = field(default_factory=list)
    seconds: dict[str, float] = field(default_factory=dict)


def _upsample(values: Tensor, coverage: Tensor, factor: int) -> Tensor:
    """(V, H, W, C) values at `factor` x the resolution, bilinear over covered pixels only."""
    cov = (coverage > 0.5).float()[:, None]
    up = lambda x: torch.nn.functional.interpolate(x, scale_factor=factor, mode="bilinear", align_corners=False)
    num, den = up(values.permute(0, 3, 1, 2) * cov), up(cov)
    return (num / den.clamp(min=1e-6)).permute(0, 2, 3, 1)


def default_texture_size(inp: MeshInput) -> int:
    """The latent texture's side: the base colour texture's, at most ``DEFAULT_TEXTURE_SIZE`` (the
    energy guard measures every distinct texel), and ``DEFAULT_TEXTURE_SIZE`` for a constant colour."""
    side = max(inp.base_color.shape[:2])
    return DEFAULT_TEXTURE_SIZE if side == 1 else max(8, min(side, DEFAULT_TEXTURE_SIZE))


def generate(inp: MeshInput, prompt: str, model: LatentGenerator, cfg: GeneratorTrainConfig, seed: int = 0,
             steps: int = DEFAULT_STEPS, views: int = DEFAULT_VIEWS, guidance: float = 2.0, texture_size: int = DEFAULT_TEXTURE_SIZE,
             progress: Callable[[int, int], None] | None = None, guard_energy: bool = True,
             samples: int = DEFAULT_SAMPLES) -> Generation:
    """The latent texture of ``inp`` for ``prompt``; ``progress(step, steps)`` follows the sampling.
    ``guard_energy`` False skips the energy guard (its scale map is then all 1); ``samples`` > 1
    averages that many residuals (``LatentGenerator.sample``)."""
    times: dict[str, float] = {}
    t0 = time.perf_counter()
    type_, warnings = prompt_type(prompt, metallic=inp.metallic)
    raster, reason = uv_rasterize(inp.mesh.positions, inp.mesh.normals, inp.mesh.uvs, inp.mesh.faces,
                                  (texture_size, texture_size))
    if raster is None:
        raise ValueError(f"cannot project into the mesh's texture space: {reason}")
    charts = torch.from_numpy(raster.coverage)
    prior = prior_latents(inp.base_color, inp.roughness_metalness, type_, raster.normals, raster.positions)
    res = cfg.model.size
    cams = orbit_cameras(views, res)
    cond_views = render_intrinsics(inp.mesh, cams, inp.base_color, prior, cfg.corpus.supersample,
                                   inp.roughness_metalness)
    cond = Conditions(cond_views.conditions(cond_views.latents)[None], text.embed([prompt]), torch.tensor([type_]))
    times["condition_views"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    residual = model.sample(cond, steps, seed, guidance, progress, samples)[0]
    times["sampling"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    fine_cams = orbit_cameras(views, res * PROJECTION_UPSAMPLE)
    fine = render_intrinsics(inp.mesh, fine_cams, inp.base_color)
    values = _upsample(residual.permute(0, 2, 3, 1), cond_views.coverage, PROJECTION_UPSAMPLE)
    prior_texture = torch.from_numpy(prior)
    # islands no view saw end on the diffuse fallback: their residual is fallback - prior
    proj = project(values * (fine.coverage > 0.5)[..., None], fine, fine_cams, charts,
                   diffuse_fallback_latent() - prior_texture)
    times["projection"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    texture = (prior_texture + proj.texture).clamp(-1.0, 1.0)  # the encoder's latent box
    texture = texture.numpy().astype(np.float16).astype(np.float32)  # as the half-float EXRs hold it
    energy = energy_guard(texture) if guard_energy else np.ones(texture.shape[:2], np.float32)
    times["energy_guard"] = time.perf_counter() - t0
    stats = proj.stats(charts)
    if stats["fallback"] > 0.05:
        warnings.append(f"{stats['fallback']:.0%} of the texels lie on UV islands no view saw: "
                        "they got the diffuse fallback (more --views may help)")
    if stats["seen"] < SEEN_WARNING:
        warnings.append(f"only {stats['seen']:.0%} of the texels were seen squarely by a view (thin parts, many "
                        "small UV islands or hidden surfaces): the rest is inpainted from their neighbours")
    generated = (cond.prior[0] + residual).clamp(-1.0, 1.0)
    return Generation(texture, prior, generated, proj, charts, type_, energy, warnings, times)


def energy_guard(latents: np.ndarray) -> np.ndarray:
    """(H, W) f_neu scale per texel that keeps every texel inside the white furnace.

    Sampling and view averaging can land on latents that gain energy (with the shipped
    decoder about half the texels sit just over the bound, as their references do):
    ``energy.guard`` measures each distinct latent and darkens the ones that do, as ``fit``
    repairs a fitted material."""
    from ..neural import energy, weights

    unique, inverse = np.unique(latents.reshape(-1, latents.shape[-1]), axis=0, return_inverse=True)
    scale = energy.guard(weights.load(), torch.from_numpy(unique))
    return scale.numpy()[inverse.reshape(-1)].reshape(latents.shape[:2])


def preview(inp: MeshInput, latents: np.ndarray, frames: int = 4, resolution: int = 128, spp: int = 16,
            energy_scale: np.ndarray | None = None) -> np.ndarray:
    """Scene-linear renders (frames, H, W, 3) of the mesh with the baked latents (f_neu scaled by
    the (H, W) ``energy_scale`` map when given), lit by the default probe.

    G-buffer shading (no shadows, no interreflection), the same as the neural material's ball preview."""
    from ..neural import weights
    from ..neural.bsdf import NeuralBsdf
    from ..neural.evaluate import DEFAULT_PROBE
    from ..render.ball import shade_gbuffer
    from ..render.envmap import EnvMap

    model = weights.load()
    env = EnvMap.load(DEFAULT_PROBE)
    cams = orbit_cameras(frames, resolution)
    scale = np.ones(latents.shape[:2], np.float32) if energy_scale is None else energy_scale
    iv: IntrinsicViews = render_intrinsics(inp.mesh, cams, inp.base_color,
                                           np.concatenate([latents, scale[..., None]], -1))
    out = []
    for f in range(frames):
        mask = (iv.coverage[f] > 0.5).numpy()
        to_cam = cams.origins[f].float() - iv.positions[f]
        to_cam = (to_cam / to_cam.norm(dim=-1, keepdim=True).clamp(min=1e-12)).numpy()
        packed = torch.from_numpy(iv.latents[f].numpy().reshape(-1, 7)[mask.ravel()])
        base = iv.base_color[f].numpy().reshape(-1, 3)[mask.ravel()]
        bsdf = NeuralBsdf(model, packed[:, :6], torch.from_numpy(base), packed[:, 6:])
        out.append(shade_gbuffer(lambda n: bsdf, env, iv.normals[f].numpy(), to_cam, mask, spp=spp, seed=f))
    return np.stack(out)
