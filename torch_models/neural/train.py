"""Training of the universal encoder/decoder, then (MLP kind) of the sampling decoder.

The run's config names the decoder kind (``decoders.KINDS``). Phase 1 trains
encoder and decoder together (an autoencoder through the BRDF):
z = encoder(params) + U(-jitter, jitter) and ``loss.decoder_loss``, plus a penalty
on saturated encoder outputs (``networks.saturation``). Phase 2 (MLP) goes on with
an energy penalty on latents no material maps to (uniform in the enlarged
training latent box, and encoded latents perturbed by ten times the jitter), so
generated or edited latents do not gain energy. Phase 3 (MLP) trains the sampling
decoder against the frozen decoder's luminance with the score-function estimate
of the forward KL divergence (Zeltner et al.; neural-notes sec. 1.2). A hybrid
decoder needs neither: it is energy-bounded by construction and samples its own
lobes; its lobes' alpha floor is annealed over the first ``anneal`` of phase 1.

The per-pair loss does not tie the integral of f_neu to the material's albedo,
and a decoder trained with it alone kept 31 % of the analytic albedo at cos 0.1
(bench/albedo_agreement.py). ``albedo_weight`` adds the squared relative error
of an importance-sampled estimate of that albedo against the analytic R(wi)
(``albedo_loss``). ``init`` starts from another run's networks (``init_networks``
names which) and ``freeze_encoder`` keeps its encoder, so a fine-tune, or a new
decoder trained against the old encoder, keeps the latent space that fitted
materials and the generator's corpus were made in.

Data are generated on the fly into an in-memory buffer that is refreshed every
``refresh_every`` steps (generating a batch costs more than a training step on a
CPU). Checkpoints are safetensors written atomically, with a JSON state; a run
resumes from the last one.
"""
from __future__ import annotations

import json
import math
import sys
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np
import torch
from safetensors.torch import save_file
from torch import Tensor, nn

from ..distributed import data_parallel, placement
from .data import Batch, angular_floor, make_batch, parameter_vectors
from .decoders import AnyDecoder, build_decoder, build_sampler
from .hybrid import HybridDecoder
from .loss import CHROMA_WEIGHT, LOSS_WEIGHTS, albedo_loss, decoder_loss, energy_penalty, sampler_loss
from .networks import Encoder, SamplingDecoder, saturation
from .validity import enlarged
from .weights import load_networks


@dataclass
class TrainConfig:
    seed: int = 0
    kind: str = "mlp"  # decoders.KINDS: the paper's direct MLP, or analytic lobes gated by a small network
    width: int = 64
    depth: int = 4
    lobes: int = 3  # hybrid: GGX lobes
    head_width: int = 32  # hybrid: width of the lobe and mixture heads
    gate_width: int = 32  # hybrid: the gate network
    gate_depth: int = 2
    lobe_alpha_floor: tuple[float, float] = (0.05, 1e-3)  # hybrid: the lobes' alpha floor, annealed from, to
    unit_lobes: bool = False  # hybrid: GGX lobes normalised to unit albedo (hybrid.HybridDecoder)
    sheen: bool = False  # hybrid: a unit-albedo LTC sheen lobe beside the GGX and diffuse lobes
    anneal: float = 0.6  # hybrid: share of the decoder phase over which the floor falls (geometrically)
    encoding: str = "half"  # decoder direction encoding (networks.DIRECTION_ENCODINGS)
    pool: int = 20_000  # distinct parameter vectors drawn from the enhancement rules
    alpha_floor: float = 0.0  # GGX alphas below this are trained (and fitted) as this (data.angular_floor)
    relative_weight: float = 0.0  # decoder_loss's relative term, in training and in fitting
    t_weight: float = LOSS_WEIGHTS[1]  # decoder_loss's weight of T; a hybrid's T shares the lobes' budget
    buffer_batches: int = 8  # batches kept in memory, refreshed one at a time
    refresh_every: int = 4  # training steps per newly generated batch
    batch: int = 16_384
    steps: int = 20_000
    sampler_steps: int = 4_000
    energy_steps: int = 0  # phase 2 length; 0 skips it
    energy_weight: float = 1.0
    energy_latents: int = 256  # latents per penalty estimate, half uniform in the box, half perturbed
    energy_samples: int = 256  # cosine-sampled wo per latent
    chroma_weight: float = CHROMA_WEIGHT
    saturation_weight: float = 0.1
    albedo_weight: float = 0.0  # 0 leaves the albedo term out
    albedo_materials: int = 64  # materials per albedo estimate, each at one random view angle
    albedo_samples: int = 128  # importance-sampled wo per material
    init: str = ""  # run folder to start from (relative to the config file); "" starts from scratch
    init_networks: list[str] = field(default_factory=lambda: ["encoder", "decoder", "sampler"])  # taken from init
    freeze_encoder: bool = False  # with init: train the decoder only, keeping the latent space
    lr: float = 2e-3
    grad_clip: float = 0.0  # > 0: clip the gradient norm to this (a hybrid from scratch: near-mirror lobes spike)
    lr_final: float = 2e-5
    jitter: float = 0.005
    checkpoint_every: int = 500
    threads: int = 0  # torch threads; 0 keeps torch's default
    device: str = "cpu"  # "cuda": one GPU per torchrun rank
    history: list[dict] = field(default_factory=list)

    @classmethod
    def load(cls, path: Path) -> "TrainConfig":
        cfg = cls(**json.loads(path.read_text()))
        if cfg.init and not Path(cfg.init).is_absolute():
            cfg.init = str((path.parent / cfg.init).resolve())
        return cfg


def annealed_floor(cfg: TrainConfig, step: int) -> float:
    """The hybrid lobes' alpha floor at ``step``: geometric from the first to the last value of
    ``lobe_alpha_floor`` over the first ``anneal`` share of the decoder phase, then held."""
    start, end = cfg.lobe_alpha_floor
    t = min(step / max(cfg.anneal * cfg.steps, 1.0), 1.0)
    return start * (end / start) ** t


def _cosine_lr(cfg: TrainConfig, step: int, total: int) -> float:
    return cfg.lr_final + 0.5 * (cfg.lr - cfg.lr_final) * (1 + math.cos(math.pi * min(step / total, 1.0)))


class Objective(nn.Module):
    """Phases 1 and 2 as one module call, so DistributedDataParallel can average the
    gradients of encoder and decoder together."""

    def __init__(self, encoder: Encoder, decoder: AnyDecoder, cfg: TrainConfig) -> None:
        super().__init__()
        self.encoder, self.decoder, self.cfg = encoder, decoder, cfg

    def forward(self, batch: Batch, gen: torch.Generator, box: tuple[Tensor, Tensor] | None = None) -> Tensor:
        """Loss of a batch; with the latent ``box`` (phase 2) plus the energy penalty."""
        cfg = self.cfg
        pre = self.encoder.pre_activation(batch.vectors)
        z = torch.tanh(pre)
        z = z + cfg.jitter * (2 * torch.rand(z.shape, generator=gen) - 1).to(z.device)
        loss = (decoder_loss(self.decoder, z, batch, cfg.chroma_weight, cfg.relative_weight, cfg.t_weight)
                + cfg.saturation_weight * saturation(pre))
        if cfg.albedo_weight:
            k = cfg.albedo_materials
            loss = loss + cfg.albedo_weight * albedo_loss(self.decoder, z[:k], batch.vectors[:k], cfg.albedo_samples, gen)
        if box is not None:
            odd = odd_latents(z.detach(), box, cfg.energy_latents // 2, gen)
            loss = loss + cfg.energy_weight * energy_penalty(self.decoder, odd, cfg.energy_samples, gen)
        return loss


class SamplerObjective(nn.Module):
    """Phase 3 as one module call (the decoder stays frozen and outside the module)."""

    def __init__(self, sampler: SamplingDecoder) -> None:
        super().__init__()
        self.sampler = sampler

    def forward(self, decoder: AnyDecoder, z: Tensor, wi: Tensor, u: Tensor) -> Tensor:
        return sampler_loss(self.sampler, decoder, z, wi, u)


def odd_latents(z: Tensor, box: tuple[Tensor, Tensor], n: int, gen: torch.Generator) -> Tensor:
    """Latents no training material maps to: n uniform in the (enlarged) training latent
    box, n encoded latents perturbed by +-0.05 (ten times the jitter)."""
    lo, hi = box
    uniform = lo + (hi - lo) * torch.rand(n, len(lo), generator=gen).to(z.device)
    perturbed = z[:n] + 0.05 * (2 * torch.rand(n, z.shape[1], generator=gen) - 1).to(z.device)
    return torch.cat([uniform, perturbed])


class Trainer:
    """Holds the networks, optimiser and data buffer; ``run`` trains and checkpoints.

    Under ``torchrun`` each rank draws its own data (generators seeded with the
    rank) and rank 0 alone writes checkpoints."""

    def __init__(self, cfg: TrainConfig, out: Path, vectors: np.ndarray | None = None) -> None:
        """``vectors`` (K, 22) replaces the pool drawn from the enhancement rules: a decoder
        of a few materials only, to tell what the network can represent from what the
        shared latent space makes it give up (bench/single_material_decoder.py)."""
        self.cfg, self.out = cfg, out
        self.where = placement(cfg.device)
        torch.manual_seed(cfg.seed)
        if cfg.threads:
            torch.set_num_threads(cfg.threads)
        device = self.where.device
        self.encoder, self.decoder = Encoder().to(device), build_decoder(asdict(cfg)).to(device)
        sampler = build_sampler(self.decoder)
        # a hybrid samples its own lobes: there is no sampling network to train
        self.sampler = sampler.to(device) if isinstance(sampler, SamplingDecoder) else None
        self.objective = data_parallel(Objective(self.encoder, self.decoder, cfg), self.where)
        self.step = 0
        self.skipped = 0  # batches skipped since the last checkpoint (non-finite gradients)
        self.box: tuple[Tensor, Tensor] | None = None  # training latent box, set when phase 2 starts
        self.gen = torch.Generator().manual_seed(self._data_seed(0))
        drawn = parameter_vectors(cfg.pool, np.random.default_rng(cfg.seed)) if vectors is None else vectors
        self.pool = angular_floor(drawn, cfg.alpha_floor)
        self.buffer = [self._new_batch() for _ in range(cfg.buffer_batches)]
        if cfg.init:
            self._load(Path(cfg.init) / "weights.safetensors", cfg.init_networks)
        if cfg.freeze_encoder:
            self.encoder.requires_grad_(False)
        trained = [p for p in (*self.encoder.parameters(), *self.decoder.parameters()) if p.requires_grad]
        self.opt = torch.optim.Adam(trained, lr=cfg.lr)
        if self.sampler is not None:
            self.sampler_objective = data_parallel(SamplerObjective(self.sampler), self.where)
            self.sampler_opt = torch.optim.Adam(self.sampler.parameters(), lr=1e-3)

    def _data_seed(self, step: int) -> int:
        return (self.cfg.seed + step) * 1024 + self.where.rank

    def _new_batch(self) -> Batch:
        return make_batch(self.pool, self.cfg.batch, self.gen).to(self.where.device)

    # ---- checkpoints ---------------------------------------------------------------
    def _networks(self) -> dict[str, nn.Module]:
        nets = {"encoder": self.encoder, "decoder": self.decoder}
        if self.sampler is not None:
            nets["sampler"] = self.sampler
        return nets

    def weights(self) -> dict[str, Tensor]:
        out = {}
        for name, net in self._networks().items():
            out.update({f"{name}.{k}": v.detach().contiguous() for k, v in net.state_dict().items()})
        return out

    def save(self) -> None:
        from ..cli import atomic_path

        if not self.where.is_main:
            return
        self.out.mkdir(parents=True, exist_ok=True)
        with atomic_path(self.out / "weights.safetensors") as tmp:
            save_file(self.weights(), str(tmp))
        state = {"step": self.step, "config": asdict(self.cfg)}
        with atomic_path(self.out / "state.json") as tmp:
            tmp.write_text(json.dumps(state, indent=1))
        plot_history(self.cfg.history, self.out / "training_curve.png")

    def resume(self) -> bool:
        state_path = self.out / "state.json"
        if not state_path.exists():
            return False
        state = json.loads(state_path.read_text())
        self._load(self.out / "weights.safetensors")
        self.step = state["step"]
        self.cfg.history = state["config"]["history"]
        self.gen.manual_seed(self._data_seed(self.step))  # fresh data after a resume, reproducibly
        return True

    def _load(self, path: Path, names: list[str] | None = None) -> None:
        load_networks(path, {k: v for k, v in self._networks().items() if names is None or k in names})

    # ---- training -------------------------------------------------------------------
    def _decoder_step(self, energy: bool = False) -> float:
        """One step of phase 1 (cosine learning rate) or, with ``energy``, of phase 2
        (a low constant rate, plus the energy penalty)."""
        cfg = self.cfg
        if self.step % cfg.refresh_every == 0:
            self.buffer[(self.step // cfg.refresh_every) % len(self.buffer)] = self._new_batch()
        batch = self.buffer[torch.randint(len(self.buffer), (1,), generator=self.gen).item()]
        for group in self.opt.param_groups:
            group["lr"] = 5 * cfg.lr_final if energy else _cosine_lr(cfg, self.step, cfg.steps)
        if isinstance(self.decoder, HybridDecoder):
            self.decoder.alpha_floor.fill_(annealed_floor(cfg, self.step))
        loss = self.objective(batch, self.gen, self._latent_box() if energy else None)
        self.opt.zero_grad()
        loss.backward()
        norm = torch.nn.utils.clip_grad_norm_(self.objective.parameters(), cfg.grad_clip or math.inf)
        if not torch.isfinite(norm):  # one non-finite gradient would make every weight NaN: skip the batch
            self.opt.zero_grad()
            self.skipped += 1
            print(f"train: step {self.step}: non-finite gradient (loss {loss.item():.4g}), batch skipped",
                  file=sys.stderr)
            return math.nan
        self.opt.step()
        return loss.item()

    def _latent_box(self) -> tuple[Tensor, Tensor]:
        """The encoded pool's bounding box enlarged by 10 %, fixed when phase 2 starts."""
        if self.box is None:
            with torch.no_grad():
                pool_z = self.encoder(self.pool.to(self.where.device))
            self.box = enlarged((pool_z.min(0).values, pool_z.max(0).values), 1.1)
        return self.box

    def _sampler_step(self) -> float:
        batch = self.buffer[torch.randint(len(self.buffer), (1,), generator=self.gen).item()]
        with torch.no_grad():
            z = self.encoder(batch.vectors)
        u = torch.rand(len(z), 3, generator=self.gen).to(z.device)
        loss = self.sampler_objective(self.decoder, z, batch.wi, u)
        self.sampler_opt.zero_grad()
        loss.backward()
        self.sampler_opt.step()
        return loss.item()

    def run(self) -> None:
        from tqdm import tqdm

        cfg = self.cfg
        phases = [("decoder", cfg.steps, self._decoder_step), ("energy", cfg.energy_steps, lambda: self._decoder_step(energy=True)),
                  ("sampler", cfg.sampler_steps if self.sampler is not None else 0, self._sampler_step)]
        total = sum(length for _, length, _ in phases)
        losses: list[float] = []
        start = time.perf_counter()
        with tqdm(total=total, initial=self.step, desc="train", unit="step", disable=not self.where.is_main) as bar:
            while self.step < total:
                end = 0
                for phase, length, step_fn in phases:
                    end += length
                    if self.step < end:
                        break
                losses.append(step_fn())
                self.step += 1
                bar.update(1)
                if self.step % 50 == 0:
                    bar.set_postfix(phase=phase, loss=f"{np.nanmean(losses[-50:]):.4f}")
                if self.step % cfg.checkpoint_every == 0 or self.step == total:
                    cfg.history.append({"step": self.step, "phase": phase, "loss": float(np.nanmean(losses)),
                                        "seconds": time.perf_counter() - start, "skipped": self.skipped})
                    losses, self.skipped = [], 0
                    self.save()


def plot_history(history: list[dict], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 3, figsize=(13, 3.2))
    for ax, phase in zip(axes, ("decoder", "energy", "sampler")):
        rows = [h for h in history if h["phase"] == phase]
        if rows:
            ax.plot([h["step"] for h in rows], [h["loss"] for h in rows], marker="o", ms=3)
        ax.set_title(f"{phase} loss")
        ax.set_xlabel("step")
        ax.set_yscale("symlog" if phase == "sampler" else "log")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
