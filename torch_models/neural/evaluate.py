"""Analytic against neural on the preview ball: the measurement every neural benchmark shares.

A constant material is a packed 22-vector plus a base colour. Its reference is
the analytic ``LayeredBsdf``; its neural version is the frozen decoder at a
fitted latent (``NeuralBsdf``). Both are rendered by the torch renderer with the
same probe, scene, seed and samples, tone mapped with AgX and compared with
LDR-FLIP (``torch_models/render/flip.py``).
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch
from tqdm import tqdm
from torch import Tensor

from ..brdf.model import LayeredBsdf, params_from_vectors
from ..render.ball import Sun, render_ball
from ..render.envmap import EnvMap
from ..render.flip import flip_map
from ..render.preview_scene import PreviewScene
from ..render.tonemap import agx
from .bsdf import NeuralBsdf
from .quadrature import VIEW_COSINES, half_vector_nodes
from .energy import fit_bounded
from .furnace import BoundedFit
from .fit.latents import fit_latents
from .model import NeuralModel

DEFAULT_PROBE = Path(__file__).resolve().parents[1] / "data" / "studio_small_03_512.hdr"
# The benches' artist scene: a key light from the camera's upper left, about 3x the probe's irradiance.
KEY_LIGHT = Sun((0.5773, -0.5773, 0.5773), 3.0)
SCENES: dict[str, Sun | None] = {"probe": None, "probe_and_sun": KEY_LIGHT}  # the two scenes the preview is judged in


@dataclass(frozen=True)
class BallSetup:
    """Where and how the balls are rendered; one instance per benchmark run."""

    env: EnvMap
    scene: PreviewScene
    spp: int
    seed: int

    @classmethod
    def default(cls, resolution: int = 128, spp: int = 64, seed: int = 0,
                probe: Path = DEFAULT_PROBE) -> "BallSetup":
        return cls(EnvMap.load(probe), PreviewScene(resolution=resolution), spp, seed)


def ball_image(setup: BallSetup, bsdf: object, seed: int | None = None, sun: Sun | None = None) -> np.ndarray:
    """AgX display image of one BSDF on the ball (at ``seed``, else the setup's; lit by the probe [and ``sun``])."""
    with torch.no_grad():
        return agx(render_ball(lambda n: bsdf, setup.env, setup.scene, setup.spp,
                               setup.seed if seed is None else seed, sun=sun).rgb)


def render_reference(setup: BallSetup, vector: np.ndarray, base_color: np.ndarray) -> np.ndarray:
    """AgX display image of the analytic material (22-vector) on the ball."""
    bsdf = LayeredBsdf(params_from_vectors(torch.as_tensor(vector, dtype=torch.float32)[None]),
                       torch.as_tensor(base_color, dtype=torch.float32)[None])
    return ball_image(setup, bsdf)


def render_neural(setup: BallSetup, model: NeuralModel, latent: Tensor, base_color: np.ndarray,
                  energy_scale: float = 1.0) -> np.ndarray:
    """AgX display image of the decoder at one latent (1, 6) on the ball."""
    bsdf = NeuralBsdf(model, latent.reshape(1, -1), torch.as_tensor(base_color, dtype=torch.float32)[None],
                      energy_scale)
    return ball_image(setup, bsdf)


@dataclass
class Comparison:
    reference: np.ndarray
    neural: np.ndarray
    error: np.ndarray  # per-pixel FLIP
    flip: float


def compare(reference: np.ndarray, neural: np.ndarray) -> Comparison:
    error, flip = flip_map(reference, neural)
    return Comparison(reference, neural, error, flip)


def side_by_side(rows: list[Comparison]) -> np.ndarray:
    """uint8 sheet: analytic | neural | FLIP map, one row per comparison."""

    def u8(x: np.ndarray) -> np.ndarray:
        return (np.clip(x, 0, 1) * 255 + 0.5).astype(np.uint8)

    return np.concatenate([np.concatenate([u8(c.reference), u8(c.neural),
                                           u8(np.repeat(c.error[..., None], 3, -1))], 1) for c in rows], 0)


def fit_and_compare(setup: BallSetup, model: NeuralModel, vectors: np.ndarray, base_colors: np.ndarray,
                    steps: int, references: list[np.ndarray] | None = None) -> tuple[list[Comparison], BoundedFit]:
    """Fit all materials together (K, 22), refit or repair those that gain energy, compare each on the ball.
    ``references`` are the analytic renders when already made (several decoders, same materials)."""
    bounded = fit_bounded(model, vectors, fit_latents(model, vectors, steps, seed=setup.seed), seed=setup.seed)
    z, scale = bounded.z, bounded.check.energy_scale()
    results = [compare(render_reference(setup, vectors[k], base_colors[k]) if references is None else references[k],
                       render_neural(setup, model, z[k], base_colors[k], float(scale[k])))
               for k in tqdm(range(len(vectors)), desc="render neural", unit="material")]
    return results, bounded


def reference_furnace(vectors: np.ndarray, chunk: int = 64) -> np.ndarray:
    """(K,) the analytic model's own white-furnace albedo (brightest channel, worst view angle,
    the furnace's half-vector quadrature): what a faithful fit of each material inherits."""
    pool = torch.from_numpy(vectors)
    worst = torch.zeros(len(pool))
    for mu in VIEW_COSINES:
        wi, wo, weight = half_vector_nodes(mu)
        m = len(wo)
        for k0 in range(0, len(pool), chunk):
            k = slice(k0, k0 + chunk)
            n = len(pool[k])
            bsdf = LayeredBsdf(params_from_vectors(pool[k].repeat_interleave(m, 0)), torch.zeros(1, 3))
            wi_k = wi.expand(n * m, 3)  # one tensor for both calls: the model keeps its per-view terms
            f = bsdf.eval_neural_part(wi_k, wo.repeat(n, 1)).reshape(n, m, 3)
            reflected = (f * weight[None, :, None]).sum(1).max(1).values
            worst[k] = torch.maximum(worst[k], reflected + bsdf.transmission(wi_k).reshape(n, m)[:, 0])
    return worst.numpy()
