"""Loading trained networks: safetensors only, never pickle."""
from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass
from pathlib import Path

from safetensors.torch import load_file
from torch import nn

from .loss import LOSS_WEIGHTS
from .decoders import AnyDecoder, AnySampler, build_decoder, build_sampler
from .networks import Encoder

SHIPPED = Path(__file__).resolve().parent / "weights"
BASELINE = SHIPPED / "mlp"  # the paper's direct 4 x 64 MLP, kept to measure the shipped decoder against


@dataclass
class NeuralModel:
    encoder: Encoder
    decoder: AnyDecoder
    sampler: AnySampler
    digest: str  # sha256 of the weights file: which decoder a fitted material belongs to
    alpha_floor: float = 0.0  # the training's angular floor, which fitting must apply too
    relative_weight: float = 0.0  # the training loss's relative term, which fitting uses too
    t_weight: float = LOSS_WEIGHTS[1]  # the training loss's weight of T, which fitting uses too


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


def load_networks(path: Path, nets: dict[str, nn.Module]) -> None:
    """Fill each network from a weights file whose keys are prefixed by its name (``decoder.net.0.weight``)."""
    tensors = load_file(str(path))
    for name, net in nets.items():
        net.load_state_dict({k[len(name) + 1:]: v for k, v in tensors.items() if k.startswith(name + ".")})


def load(folder: Path = SHIPPED) -> NeuralModel:
    """The networks of a training run folder (weights.safetensors + state.json), frozen,
    of the decoder kind its config names (``decoders.KINDS``)."""
    weights, state = folder / "weights.safetensors", folder / "state.json"
    if not weights.is_file() or not state.is_file():
        raise FileNotFoundError(f"{folder}: no trained decoder here (weights.safetensors, state.json); "
                                "run `python -m torch_models train-decoder` first")
    cfg = json.loads(state.read_text())["config"]
    decoder = build_decoder(cfg)
    sampler = build_sampler(decoder)
    nets = {"encoder": Encoder(), "decoder": decoder}
    if isinstance(sampler, nn.Module):
        nets["sampler"] = sampler
    load_networks(weights, nets)
    for net in nets.values():
        net.eval().requires_grad_(False)
    return NeuralModel(nets["encoder"], decoder, sampler, digest(folder),
                       cfg.get("alpha_floor", 0.0), cfg.get("relative_weight", 0.0), cfg.get("t_weight", LOSS_WEIGHTS[1]))
