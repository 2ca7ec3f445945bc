"""The MLP's training config: the shared fields plus its size and its two extra phases."""
from __future__ import annotations

from dataclasses import dataclass

from ..config import TrainConfig
from .networks import Decoder


@dataclass
class MlpConfig(TrainConfig):
    kind: str = Decoder.kind
    width: int = 64
    depth: int = 4
    energy_steps: int = 0  # phase 2 (energy penalty on latents no material maps to); 0 skips it
    energy_weight: float = 1.0
    energy_latents: int = 256  # latents per penalty estimate, half uniform in the box, half perturbed
    energy_samples: int = 256  # cosine-sampled wo per latent
    sampler_steps: int = 4_000  # phase 3 (the sampling decoder)
