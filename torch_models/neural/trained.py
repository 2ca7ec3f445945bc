"""Trained runs on disk: safetensors weights and a ``state.json``, loaded as a ``NeuralModel``.

Never pickle. ``SHIPPED`` is the decoder the add-on and farm use; ``BASELINE`` the
paper's MLP, kept to measure it against.
"""
from __future__ import annotations

import hashlib
import json
from pathlib import Path

from safetensors.torch import load_file
from torch import nn

from . import kinds
from .model import NeuralModel
from .networks import DecoderNet, Encoder, Sampler

SHIPPED = Path(__file__).resolve().parent / "weights"
BASELINE = SHIPPED / "mlp"  # the paper's direct 4 x 64 MLP, kept to measure the shipped decoder against


def digest(folder: Path = SHIPPED) -> str:
    """sha256 of a run's weights file: names the decoder without building the networks."""
    return hashlib.sha256((folder / "weights.safetensors").read_bytes()).hexdigest()


def encoder_digest(folder: Path = SHIPPED) -> str:
    """sha256 of the encoder's tensors alone: names the latent space. A decoder fine-tuned
    with its encoder frozen keeps it, and with it what the generator learned to produce."""
    h = hashlib.sha256()
    for name, tensor in sorted(load_file(str(folder / "weights.safetensors")).items()):
        if name.startswith("encoder."):
            h.update(name.encode())
            h.update(tensor.contiguous().numpy().tobytes())
    return h.hexdigest()


def networks(encoder: Encoder, decoder: DecoderNet, sampler: Sampler) -> dict[str, nn.Module]:
    """The networks a weights file holds, by the prefix of their tensors: a sampler only when it
    has weights of its own (the MLP's; the hybrid samples its lobes)."""
    nets = {"encoder": encoder, "decoder": decoder}
    if isinstance(sampler, nn.Module):
        nets["sampler"] = sampler
    return nets  # type: ignore[return-value]


def load_networks(path: Path, nets: dict[str, nn.Module]) -> None:
    """Fill each network from a weights file whose keys are prefixed by its name (``decoder.net.0.weight``)."""
    tensors = load_file(str(path))
    for name, net in nets.items():
        net.load_state_dict({k[len(name) + 1:]: v for k, v in tensors.items() if k.startswith(name + ".")})


def load(folder: Path = SHIPPED) -> NeuralModel:
    """The networks of a training run folder (weights.safetensors + state.json), frozen,
    of the decoder kind its config names (``kinds.KINDS``)."""
    weights, state = folder / "weights.safetensors", folder / "state.json"
    if not weights.is_file() or not state.is_file():
        raise FileNotFoundError(f"{folder}: no trained decoder here (weights.safetensors, state.json); "
                                "run `python -m torch_models train-decoder` first")
    cfg = kinds.run_config(json.loads(state.read_text())["config"])
    kind = kinds.kind_named(cfg.kind)
    decoder = kind.build_decoder(cfg)
    sampler = kind.build_sampler(decoder)
    nets = networks(Encoder(), decoder, sampler)
    load_networks(weights, nets)
    for net in nets.values():
        net.eval().requires_grad_(False)
    return NeuralModel(nets["encoder"], decoder, sampler, digest(folder), cfg.alpha_floor, cfg.relative_weight,
                       cfg.t_weight)
