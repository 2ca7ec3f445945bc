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

from richmat_addon.core.preview import PreviewScene
from ..brdf.model import LayeredBsdf, params_from_vectors
from ..render.ball import render_ball
from ..render.envmap import EnvMap
from ..render.flip import flip_map
from ..render.tonemap import agx
from .bsdf import NeuralBsdf
from .fit import Furnace, fit_latents, furnace
from .weights import NeuralModel

DEFAULT_PROBE = Path(__file__).resolve().parents[1] / "data" / "studio_small_03_512.hdr"


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


def render_reference(setup: BallSetup, vector: np.ndarray, base_color: np.ndarray) -> np.ndarray:
    """AgX display image of the analytic material (22-vector) on the ball."""
    bsdf = LayeredBsdf(params_from_vectors(torch.as_tensor(vector, dtype=torch.float32)[None]),
                       torch.as_tensor(base_color, dtype=torch.float32)[None])
    return agx(render_ball(lambda n: bsdf, setup.env, setup.scene, setup.spp, setup.seed).rgb)


def render_neural(setup: BallSetup, model: NeuralModel, latent: Tensor, base_color: np.ndarray,
                  energy_scale: float = 1.0) -> np.ndarray:
    """AgX display image of the decoder at one latent (1, 6) on the ball."""
    bsdf = NeuralBsdf(model, latent.reshape(1, -1), torch.as_tensor(base_color, dtype=torch.float32)[None],
                      energy_scale)
    with torch.no_grad():
        return agx(render_ball(lambda n: bsdf, setup.env, setup.scene, setup.spp, setup.seed).rgb)


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
                    steps: int) -> tuple[list[Comparison], Furnace]:
    """Fit all materials together (K, 22), repair them with the furnace, compare each on the ball."""
    z = fit_latents(model, vectors, steps, seed=setup.seed)
    check = furnace(model, z)
    scale = check.energy_scale()
    results = [compare(render_reference(setup, vectors[k], base_colors[k]),
                       render_neural(setup, model, z[k], base_colors[k], float(scale[k])))
               for k in tqdm(range(len(vectors)), desc="render analytic and neural", unit="material")]
    return results, check
