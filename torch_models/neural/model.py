"""A trained neural material model: encoder, decoder, sampler and what fitting must repeat of training.

``trained.load`` builds one from a run folder; fitting, the furnace, the renderer's
BSDF and the generator take it whatever its kind (``kinds``).
"""
from __future__ import annotations

from dataclasses import dataclass

from .networks import DecoderNet, Encoder, Sampler


@dataclass
class NeuralModel:
    encoder: Encoder
    decoder: DecoderNet
    sampler: Sampler
    digest: str  # sha256 of the weights file: which decoder a fitted material belongs to
    alpha_floor: float  # the training's angular floor, which fitting must apply too
    relative_weight: float  # the training loss's relative term, which fitting uses too
    t_weight: float  # the training loss's weight of T, which fitting uses too
