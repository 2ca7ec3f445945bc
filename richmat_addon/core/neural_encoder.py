"""The neural material's encoder in numpy, and the encoder-only fit it makes possible.

A stock Blender has numpy but no torch, so Fit Neural Material starts here: the
encoder (torch_models/neural/networks.py ``Encoder``: parameters normalised by
the schema's bounds, ReLU MLP, tanh to 6 latents) maps each deduplicated texel
vector to its latent, and the latents are written at once in the neural folder
format. The torch fit refines them when a backend is there; the record says
``encoder_only`` until then. As the torch fit does (fit.latents.fitting_pool), GGX
alphas are raised to the decoder's training floor before encoding.
"""
from __future__ import annotations

import hashlib
import json
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from . import neural_folder
from .schema import ALPHA_MIN, CHANNEL_SLICES, PARAMS
from .tensor_file import linear_layers, read_safetensors
from .texel_vectors import normalise, read_vectors

WEIGHTS_FILE = "weights.safetensors"
STATE_FILE = "state.json"  # the training run's record; its config holds the angular floor
# The GGX alphas are the parameters floored at ALPHA_MIN (torch_models/neural/data.py GGX_ALPHAS).
GGX_ALPHAS = tuple(p.name for p in PARAMS if p.lo == ALPHA_MIN)


@dataclass(frozen=True)
class Encoder:
    """The encoder of one trained decoder folder (weights.safetensors + state.json)."""

    layers: list[tuple[np.ndarray, np.ndarray]]
    alpha_floor: float
    decoder_sha256: str  # the weights file's digest: which decoder the latents belong to

    @classmethod
    def load(cls, folder: Path) -> Encoder:
        weights, state = folder / WEIGHTS_FILE, folder / STATE_FILE
        if not weights.is_file() or not state.is_file():
            raise FileNotFoundError(f"{folder}: no trained decoder here ({WEIGHTS_FILE}, {STATE_FILE}); "
                                    "run `python -m torch_models train-decoder` first")
        raw = weights.read_bytes()
        layers = linear_layers(read_safetensors(weights), "encoder.net")
        if not layers:
            raise ValueError(f"{weights}: no encoder tensors (encoder.net.*)")
        config = json.loads(state.read_text())["config"]
        return cls(layers, float(config.get("alpha_floor", 0.0)), hashlib.sha256(raw).hexdigest())

    def __call__(self, vectors: np.ndarray) -> np.ndarray:
        """Latents (N, 6) in (-1, 1) of packed (N, 22) parameter vectors, as given (no floor)."""
        x = normalise(vectors)
        for k, (weight, bias) in enumerate(self.layers):
            x = x @ weight.T + bias
            if k < len(self.layers) - 1:
                np.maximum(x, 0.0, out=x)
        return np.tanh(x)

    def floored(self, vectors: np.ndarray) -> np.ndarray:
        """The vectors as the decoder was trained and is fitted on: every GGX alpha at least the floor."""
        out = np.array(vectors, np.float32)
        for name in GGX_ALPHAS:
            sl = CHANNEL_SLICES[name]
            out[:, sl] = np.maximum(out[:, sl], self.alpha_floor)
        return out


def encode_material(material: Path, out: Path, decoder: Path) -> dict[str, Any]:
    """Write the encoder's latents of a baked material folder as a neural folder; returns its record."""
    encoder = Encoder.load(decoder)
    vectors = read_vectors(material)
    z = encoder(encoder.floored(vectors.unique))
    record = {"texels": int(len(vectors.inverse)) if vectors.shape else 1,
              "exact_unique_vectors": vectors.exact_unique, "fitted_vectors": len(vectors.unique),
              "material": os.path.relpath(material, out), "steps": 0, "encoder_only": True}
    if vectors.shape is None:
        return neural_folder.write(out, z[0], np.ones(1, np.float32), encoder.decoder_sha256, record)
    return neural_folder.write(out, vectors.texels(z), np.ones((*vectors.shape, 1), np.float32),
                               encoder.decoder_sha256, record)
