"""The hybrid's lobe form with its own parameters per material: how far any decoder of that form reaches.

A hybrid decoder draws every material through a 6D latent and two small shared networks,
so what it cannot draw may be the lobe form's limit (K GGX lobes, diffuse, sheen, T) or the
price of the shared networks and the latent space. Here each material gets its own head and
its own view gates, both linear in the view features (``networks.view_features``), so the slot
weights still follow the view angle as a coat's Fresnel needs, and the gates read wi only:
the result is exactly a set of closures, as a view-gated decoder's are. Fitted with the
decoder's own loss, it measures how far the lobes themselves reach, which a decoder drawing
them through shared networks and a 6D latent should not beat (issue 41's reach term, split in
two by ``bench/neural/decoder_candidates.py``).
"""
from __future__ import annotations

import copy
import dataclasses

import numpy as np
import torch
from torch import Tensor, nn

from ..fit.latents import FIT_BATCH, fit_latents
from ..model import NeuralModel
from .closure_form import ClosureForm
from .networks import HybridDecoder, LobeSampler, view_features

VIEW_FEATURES = 3  # networks.view_features: cos, sin and the Schlick term of the view angle


class ViewLinear(nn.Module):
    """Outputs a + B f of the view features f, with a (n) and B (n x 3) read from a slice of each
    row's parameters: the input is [parameters, f], as a hybrid's networks get [latent, f]."""

    def __init__(self, offset: int, outputs: int) -> None:
        super().__init__()
        self.offset, self.outputs = offset, outputs

    @property
    def size(self) -> int:
        return self.outputs * (1 + VIEW_FEATURES)

    def forward(self, x: Tensor) -> Tensor:
        params, f = x[:, :-VIEW_FEATURES], x[:, -VIEW_FEATURES:]
        p = params[:, self.offset:self.offset + self.size]
        a, b = p[:, :self.outputs], p[:, self.outputs:].reshape(-1, self.outputs, VIEW_FEATURES)
        return a + (b * f[:, None, :]).sum(-1)


def free_model(model: NeuralModel) -> NeuralModel:
    """``model`` (a hybrid) with its head and gates made per-material parameters, gates read at wi."""
    decoder = copy.deepcopy(model.decoder)
    if not isinstance(decoder, HybridDecoder):
        raise TypeError("the free lobe form exists for hybrid decoders only")
    head = ViewLinear(0, decoder.head[-1].out_features)
    decoder.head, decoder.gates = head, ViewLinear(head.size, decoder.gates[-1].out_features)
    decoder.view_gates = True
    return dataclasses.replace(model, decoder=decoder, sampler=LobeSampler(decoder))


def parameter_count(free: NeuralModel) -> int:
    """Parameters per material of a ``free_model``."""
    return free.decoder.head.size + free.decoder.gates.size


def view_fit(outputs: Tensor, features: Tensor) -> Tensor:
    """Per material, the least-squares a + B f of ``outputs`` (n, m, k) over ``features`` (m, 3) at m
    view angles, as ``ViewLinear`` parameters (n, 4k)."""
    design = torch.cat([torch.ones(len(features), 1), features], -1)  # (m, 4)
    coef = torch.linalg.pinv(design) @ outputs  # (n, 4, k)
    return torch.cat([coef[:, 0], coef[:, 1:].transpose(1, 2).flatten(1)], -1)


def start_from(model: NeuralModel, free: NeuralModel, z: Tensor, views: int = 16, grid: int = 6) -> Tensor:
    """Free parameters that start where the decoder's latents ``z`` are: per material, its head and
    the logits of its closure form's gates (held at their lobe means over a ``grid`` x ``grid``
    stratified set of directions) fitted linearly in the view features over ``views`` angles."""
    n, m = len(z), views
    cos = torch.linspace(0.05, 1.0, m)[:, None]
    features = view_features(cos)
    wi = torch.cat([(1.0 - cos.square()).sqrt(), torch.zeros_like(cos), cos], -1).repeat(n, 1)
    zm = z.repeat_interleave(m, 0)
    cells = torch.stack(torch.meshgrid(torch.arange(grid), torch.arange(grid), indexing="ij"), -1).reshape(-1, 2)
    with torch.no_grad():
        head = model.decoder.head(torch.cat([zm, features.repeat(n, 1)], -1))
        gates = ClosureForm(model.decoder).gates_at(zm, wi, points=(cells + 0.5) / grid)
        logits = torch.logit(gates.flatten(1), eps=1e-4)
    return torch.cat([view_fit(head.reshape(n, m, -1), features), view_fit(logits.reshape(n, m, -1), features)], -1)


def fit_free(model: NeuralModel, vectors: np.ndarray, z: Tensor, steps: int, per_vector: int, seed: int = 0,
             batch: int = FIT_BATCH) -> tuple[NeuralModel, Tensor]:
    """The free lobe form of ``model`` and its parameters for each vector, fitted with the decoder's
    loss, starting from the decoder's latents ``z`` of those vectors (its closure form there)."""
    free = free_model(model)
    params = fit_latents(free, vectors, steps, batch, seed=seed, per_vector=per_vector,
                         start=start_from(model, free, z))
    return free, params
