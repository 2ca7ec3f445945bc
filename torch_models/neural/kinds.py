"""The decoder kinds a weights folder can hold, one entry each (``decoder_kind.DecoderKind``).

``mlp`` is the paper's direct decoder, kept as the baseline; ``hybrid`` is analytic
lobes gated by a small network, the shipped kind. A run's config names its kind, so
every caller gets it from the run's ``state.json``, never from a flag.
"""
from __future__ import annotations

import json
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from .config import TrainConfig
from .hybrid.kind import KIND as HYBRID
from .decoder_kind import DecoderKind
from .mlp.kind import KIND as MLP
from .model import NeuralModel

KINDS: dict[str, DecoderKind] = {k.name: k for k in (MLP, HYBRID)}


def kind_named(name: str) -> DecoderKind:
    if name not in KINDS:
        raise ValueError(f"unknown decoder kind {name!r} in the run's config: one of {tuple(KINDS)}")
    return KINDS[name]


def of(model: NeuralModel) -> DecoderKind:
    """The kind of a loaded model."""
    return KINDS[model.decoder.kind]


def run_config(values: Mapping[str, Any]) -> TrainConfig:
    """A saved run's config (``state.json``), read leniently; runs saved before kinds existed are MLPs."""
    return kind_named(values.get("kind", MLP.name)).config.from_mapping(values, strict=False)


def load_config(path: Path) -> TrainConfig:
    """A config file, as the config of the kind it names (MLP when it names none)."""
    values = json.loads(path.read_text())
    return kind_named(values.get("kind", MLP.name)).config.from_file(path, values)
