"""What a decoder kind is: the entry each kind fills in (``kinds.KINDS`` lists them).

A kind builds its decoder and sampler from a run's config, names its training phases
(the shared decoder phase, and whatever else it trains), and keeps fitted and generated
latents from gaining energy: by construction (``DecoderNet.bounded``), or by a furnace
repair of its own. Its OSL preview shader (``osl``) is a module of the add-on's core,
which has no torch: the add-on picks it by the weights file's tensor names
(``richmat_addon.core.neural_osl``), the kind entry names it for everything else.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

import numpy as np
import torch
from torch import Tensor, nn

from ..distributed import Placement
from .config import TrainConfig
from .data import Batch
from .furnace import BoundedFit
from .model import NeuralModel
from .networks import DecoderNet, Encoder, Sampler

# An extra training loss: (decoder, the batch's jittered latents, generator) -> scalar
Penalty = Callable[[DecoderNet, Tensor, torch.Generator], Tensor]


@dataclass(frozen=True)
class Phase:
    """A stretch of training: ``steps`` calls of ``step``, each returning its loss (NaN if skipped)."""

    name: str
    steps: int
    step: Callable[[], float]


class TrainingRun(Protocol):
    """What a kind's training phases use of the trainer (``train.Trainer``)."""

    cfg: TrainConfig
    step: int
    encoder: Encoder
    decoder: nn.Module
    sampler: Sampler
    pool: Tensor
    gen: torch.Generator
    where: Placement

    def decoder_step(self, lr: float | None = None, penalty: Penalty | None = None) -> float: ...

    def buffered_batch(self) -> Batch: ...


class OslPreview(Protocol):
    """The add-on's preview shader of a kind (``richmat_addon.core.neural_osl_*``)."""

    def source(self, tensors: dict[str, np.ndarray]) -> str:
        """The shader's body for a trained model's tensors (read with numpy)."""
        ...


class DecoderKind(Protocol):
    name: str
    config: type[TrainConfig]
    osl: OslPreview

    def build_decoder(self, cfg: TrainConfig) -> DecoderNet:
        """An untrained decoder of the size ``cfg`` names."""
        ...

    def build_sampler(self, decoder: DecoderNet) -> Sampler:
        """The decoder's importance sampler (an ``nn.Module`` when it has weights of its own)."""
        ...

    def phases(self, run: TrainingRun) -> list[Phase]:
        """The training phases in order; the shared one is ``run.decoder_step``."""
        ...

    def fit_bounded(self, model: NeuralModel, vectors: np.ndarray, z: Tensor, seed: int,
                    steps: int | None) -> BoundedFit:
        """Fitted latents (K, 6) of ``vectors`` checked in the furnace, repaired where they gain
        energy (``steps`` bounds a refit; None: the kind's own)."""
        ...

    def guard(self, model: NeuralModel, z: Tensor, seed: int) -> Tensor:
        """(K,) energy scales for latents no fit can move (generated ones)."""
        ...
