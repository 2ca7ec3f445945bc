"""The hybrid's entry in ``kinds.KINDS``: analytic lobes gated by a small network (``networks``).

It is energy-bounded by construction and samples its own lobes, so it trains the
decoder phase alone (annealing its lobes' alpha floor over the first ``anneal`` of it),
and its fits are checked off its head's slot weights, with nothing to repair.
"""
from __future__ import annotations

from typing import cast

import numpy as np
import torch
from torch import Tensor

from richmat_addon.core import neural_osl_hybrid

from ...stage_clock import StageClock
from ..config import TrainConfig
from ..data import view_directions
from ..furnace import BoundedFit, Furnace
from ..decoder_kind import Phase, TrainingRun
from ..model import NeuralModel
from ..networks import DecoderNet
from ..quadrature import VIEW_COSINES
from .config import HybridConfig
from .networks import HybridDecoder, LobeSampler


def annealed_floor(cfg: HybridConfig, step: int) -> float:
    """The lobes' alpha floor at ``step``: geometric from the first to the last value of
    ``lobe_alpha_floor`` over the first ``anneal`` share of the decoder phase, then held."""
    start, end = cfg.lobe_alpha_floor
    t = min(step / max(cfg.anneal * cfg.steps, 1.0), 1.0)
    return start * (end / start) ** t


def bound_furnace(model: NeuralModel, z: Tensor) -> Furnace:
    """The furnace read off the head's slot weights: at each of ``VIEW_COSINES`` the albedo is at
    most the weight of every slot but the absorbed one, and T is the transmitted slot's. Exact
    bounds, no samples (standard errors 0)."""
    dec = _bounded(model)
    rows, ts = [], []
    with torch.no_grad():
        for mu in VIEW_COSINES:
            weights = dec.head_at(z, view_directions(torch.full((len(z), 1), mu))).weights
            rows.append(weights[:, :-1].sum(-1))
            ts.append(weights[:, dec.t_slot])
    bound = torch.stack(rows, 1).clamp(max=1.0)  # < 1 exactly; a float32 softmax sums to 1 +- rounding
    return Furnace(bound, torch.zeros_like(bound), torch.stack(ts, 1), bound.clone())


def _bounded(model: NeuralModel) -> HybridDecoder:
    dec = cast(HybridDecoder, model.decoder)
    if not dec.bounded:
        raise ValueError("this hybrid's unit lobes divide by Cycles' own albedo table, which reads short "
                         "between nodes: it is not energy-bounded; retrain it (the upper table ships)")
    return dec


class HybridKind:
    name = HybridDecoder.kind
    config = HybridConfig
    osl = neural_osl_hybrid  # its lobes as Cycles' own closures

    def build_decoder(self, cfg: TrainConfig) -> HybridDecoder:
        h = cast(HybridConfig, cfg)
        return HybridDecoder(h.lobes, h.head_width, h.gate_width, h.gate_depth, h.lobe_alpha_floor[-1],
                             h.unit_lobes, h.sheen, h.view_gates)

    def build_sampler(self, decoder: DecoderNet) -> LobeSampler:
        return LobeSampler(cast(HybridDecoder, decoder))

    def phases(self, run: TrainingRun) -> list[Phase]:
        cfg, decoder = cast(HybridConfig, run.cfg), cast(HybridDecoder, run.decoder)

        def step() -> float:
            decoder.alpha_floor.fill_(annealed_floor(cfg, run.step))
            return run.decoder_step()

        return [Phase("decoder", cfg.steps, step)]

    def fit_bounded(self, model: NeuralModel, vectors: np.ndarray, z: Tensor, seed: int,
                    steps: int | None) -> BoundedFit:
        clock = StageClock()
        with clock.stage("check"):
            check = bound_furnace(model, z)
        return BoundedFit(z, check, torch.zeros(len(z), dtype=torch.bool), clock.record(whole_process=False))

    def guard(self, model: NeuralModel, z: Tensor, seed: int) -> Tensor:
        _bounded(model)
        return torch.ones(len(z))


KIND = HybridKind()
