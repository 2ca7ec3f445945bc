"""Keeping fitted and generated latents from gaining energy, whatever the decoder kind.

``fit_bounded`` checks fitted latents in the white furnace and repairs those that
gain energy; ``guard`` gives latents no fit can move (generated ones) an energy scale.
A bounded kind (the hybrid) only checks, off its own lobe weights; the MLP refits and
scales (``mlp.energy``). The scales are recorded in ``neural.json``.
"""
from __future__ import annotations

import numpy as np
from torch import Tensor

from . import kinds
from .furnace import BoundedFit
from .model import NeuralModel


def fit_bounded(model: NeuralModel, vectors: np.ndarray, z: Tensor, seed: int = 0,
                steps: int | None = None) -> BoundedFit:
    """Fitted latents (K, 6) of ``vectors``, checked and repaired as the model's kind does it
    (``steps`` bounds a refit; None: the kind's own)."""
    return kinds.of(model).fit_bounded(model, vectors, z, seed, steps)


def guard(model: NeuralModel, z: Tensor, seed: int = 0) -> Tensor:
    """(K,) energy scales under which latents ``z`` hold up in fresh furnace estimates."""
    return kinds.of(model).guard(model, z, seed)
