"""The MLP's entry in ``kinds.KINDS``: the paper's decoder, its trained sampler, its furnace repair."""
from __future__ import annotations

from typing import cast

import numpy as np
from torch import Tensor

from richmat_addon.core import neural_osl_mlp

from ..config import TrainConfig
from ..furnace import BoundedFit
from ..decoder_kind import Phase, TrainingRun
from ..model import NeuralModel
from ..networks import DecoderNet
from . import energy, training
from .config import MlpConfig
from .networks import Decoder, SamplingDecoder


class MlpKind:
    name = Decoder.kind
    config = MlpConfig
    osl = neural_osl_mlp  # an emission integrating the lobe from the world probe

    def build_decoder(self, cfg: TrainConfig) -> Decoder:
        mlp = cast(MlpConfig, cfg)
        return Decoder(mlp.width, mlp.depth)

    def build_sampler(self, decoder: DecoderNet) -> SamplingDecoder:
        return SamplingDecoder()

    def phases(self, run: TrainingRun) -> list[Phase]:
        return training.phases(run)

    def fit_bounded(self, model: NeuralModel, vectors: np.ndarray, z: Tensor, seed: int,
                    steps: int | None) -> BoundedFit:
        return energy.fit_bounded(model, vectors, z, seed, energy.REFIT_STEPS if steps is None else steps)

    def guard(self, model: NeuralModel, z: Tensor, seed: int) -> Tensor:
        return energy.guard(model, z, seed)


KIND = MlpKind()
