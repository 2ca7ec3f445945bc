"""The training configuration every decoder kind shares.

Each kind extends it with its own fields (``mlp.config.MlpConfig``,
``hybrid.config.HybridConfig``); ``kinds.load_config`` reads a file into the kind it names.
"""
from __future__ import annotations

import json
from collections.abc import Mapping
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any, TypeVar

from .loss import CHROMA_WEIGHT, LOSS_WEIGHTS

C = TypeVar("C", bound="TrainConfig")


@dataclass
class TrainConfig:
    kind: str  # kinds.KINDS: set by each kind's config
    seed: int = 0
    pool: int = 20_000  # distinct parameter vectors drawn from the enhancement rules
    real_assets: list[str] = field(default_factory=list)  # glTF files uplifted into the pool (real_vectors.py)
    real_per_group: int = 2000  # vectors kept per (real asset, enhancement type)
    real_share: float = 0.0  # share of draws from the real vectors
    emphasis: float = 1.0  # metals and near-mirrors drawn this many times as often (real_vectors.emphasised)
    alpha_floor: float = 0.0  # GGX alphas below this are trained (and fitted) as this (data.angular_floor)
    relative_weight: float = 0.0  # decoder_loss's relative term, in training and in fitting
    t_weight: float = LOSS_WEIGHTS[1]  # decoder_loss's weight of T
    buffer_batches: int = 8  # batches kept in memory, refreshed one at a time
    refresh_every: int = 4  # training steps per newly generated batch
    batch: int = 16_384
    steps: int = 20_000  # the decoder phase
    chroma_weight: float = CHROMA_WEIGHT
    saturation_weight: float = 0.1
    albedo_weight: float = 0.0  # 0 leaves the albedo term out
    albedo_materials: int = 64  # materials per albedo estimate, each at one random view angle
    albedo_samples: int = 128  # importance-sampled wo per material
    init: str = ""  # run folder to start from (relative to the config file); "" starts from scratch
    init_networks: list[str] = field(default_factory=lambda: ["encoder", "decoder", "sampler"])  # taken from init
    freeze_encoder: bool = False  # with init: train the decoder only, keeping the latent space
    lr: float = 2e-3
    grad_clip: float = 0.0  # > 0: clip the gradient norm to this (near-mirror lobes can spike)
    lr_final: float = 2e-5
    jitter: float = 0.005
    checkpoint_every: int = 500
    threads: int = 0  # torch threads; 0 keeps torch's default
    device: str = "cpu"  # "cuda": one GPU per torchrun rank
    history: list[dict] = field(default_factory=list)

    @classmethod
    def from_mapping(cls: type[C], values: Mapping[str, Any], strict: bool = True) -> C:
        """The config of ``values``. ``strict`` refuses keys this kind does not know (a misspelt
        key in a config file); a run's saved state is read leniently (runs saved before the
        kinds had their own configs carry the other kind's fields)."""
        names = {f.name for f in fields(cls)}
        unknown = sorted(set(values) - names)
        if strict and unknown:
            raise ValueError(f"unknown keys for a {cls.__name__}: {unknown}")
        return cls(**{k: v for k, v in values.items() if k in names})

    @classmethod
    def from_file(cls: type[C], path: Path, values: Mapping[str, Any] | None = None) -> C:
        """A config file (its ``init`` resolved against the file's folder)."""
        cfg = cls.from_mapping(json.loads(path.read_text()) if values is None else values)
        if cfg.init and not Path(cfg.init).is_absolute():
            cfg.init = str((path.parent / cfg.init).resolve())
        cfg.real_assets = [str((path.parent / a).resolve()) for a in cfg.real_assets]
        return cfg
