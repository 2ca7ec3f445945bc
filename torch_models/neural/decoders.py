"""The decoder kinds a weights folder can hold, built from its own config.

``mlp`` is the paper's direct decoder (``networks.Decoder``) with its trained
sampling decoder; ``hybrid`` is analytic lobes gated by a small network
(``hybrid.HybridDecoder``), sampled through its own lobes. Every caller gets the
kind from the run's ``state.json``, never from a flag.
"""
from __future__ import annotations

from collections.abc import Mapping
from typing import Any, Union

from .hybrid import HybridDecoder, LobeSampler
from .networks import Decoder, SamplingDecoder

KINDS = ("mlp", "hybrid")
AnyDecoder = Union[Decoder, HybridDecoder]
AnySampler = Union[SamplingDecoder, LobeSampler]


def kind_of(config: Mapping[str, Any]) -> str:
    kind = config.get("kind", "mlp")
    if kind not in KINDS:
        raise ValueError(f"unknown decoder kind {kind!r} in the run's config: one of {KINDS}")
    return kind


def build_decoder(config: Mapping[str, Any]) -> AnyDecoder:
    """An untrained decoder of the kind and size a run's config names."""
    if kind_of(config) == "hybrid":
        floor = config.get("lobe_alpha_floor", (1e-3, 1e-3))[-1]
        return HybridDecoder(config.get("lobes", 3), config.get("head_width", 32), config.get("gate_width", 32),
                             config.get("gate_depth", 2), floor, config.get("unit_lobes", False),
                             config.get("sheen", False))
    return Decoder(config["width"], config["depth"], config.get("encoding", "half"))


def build_sampler(decoder: AnyDecoder) -> AnySampler:
    """The decoder's importance sampler: a trained network for the MLP, the lobes themselves for the hybrid."""
    return LobeSampler(decoder) if isinstance(decoder, HybridDecoder) else SamplingDecoder()
