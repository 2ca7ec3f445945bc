"""The neural preview's OSL shader, generated from a trained decoder's weights (numpy only).

The weights are written into the source as constant arrays, so the shader needs
nothing but its latent textures. The decoder kind is read from the tensor names
(``decoder.head.*``, ``decoder.gates.*`` and ``decoder.alpha_floor`` for the
hybrid; ``decoder.net.*`` with ``sampler.net.*`` for the paper's MLP), and each
kind has its own shader:

* the hybrid (``neural_osl_hybrid``) outputs its lobes as Cycles' own closures,
  lit by Cycles' light transport (lamps, shadows, indirect light);
* the MLP (``neural_osl_mlp``) integrates its lobe from the world probe into an
  emission, since no closure draws a free-form network.

What both share is in ``neural_osl_parts``.
"""
from __future__ import annotations

import numpy as np

from . import neural_osl_hybrid, neural_osl_mlp
from .neural_osl_parts import HEADER


def is_hybrid(tensors: dict[str, np.ndarray]) -> bool:
    return "decoder.alpha_floor" in tensors or any(k.startswith("decoder.head.") for k in tensors)


def neural_osl_source(tensors: dict[str, np.ndarray]) -> str:
    """The preview shader for a trained model's tensors, of the decoder kind their names say."""
    return HEADER + (neural_osl_hybrid.source(tensors) if is_hybrid(tensors) else neural_osl_mlp.source(tensors))
