"""Training of the universal encoder and a decoder of the kind the run's config names.

The shared decoder phase trains encoder and decoder together (an autoencoder
through the BRDF): z = encoder(params) + U(-jitter, jitter) and ``loss.decoder_loss``,
plus a penalty on saturated encoder outputs (``networks.saturation``). Each kind
names its phases (``decoder_kind.DecoderKind.phases``): the hybrid anneals its lobes' alpha
floor through that phase, the MLP adds an energy phase and trains its sampling
decoder (``mlp.training``).

The per-pair loss does not tie the integral of f_neu to the material's albedo;
``albedo_weight`` adds the squared relative error of an importance-sampled estimate
of that albedo against the analytic R(wi) (``albedo_loss``). ``init`` starts from
another run's networks (``init_networks`` names which) and ``freeze_encoder`` keeps
its encoder, so a fine-tune, or a new decoder trained against the old encoder, keeps
the latent space that fitted materials and the generator's corpus were made in.

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
from dataclasses import asdict
from pathlib import Path

import numpy as np
import torch
from safetensors.torch import save_file
from torch import Tensor, nn

from ..distributed import data_parallel, placement
from . import kinds, real_vectors
from .data import Batch, angular_floor, make_batch, parameter_vectors
from .config import TrainConfig
from .decoder_kind import Penalty
from .loss import albedo_loss, decoder_loss
from .networks import DecoderNet, Encoder, saturation
from .trained import load_networks, networks


def _cosine_lr(cfg: TrainConfig, step: int, total: int) -> float:
    return cfg.lr_final + 0.5 * (cfg.lr - cfg.lr_final) * (1 + math.cos(math.pi * min(step / total, 1.0)))


class Objective(nn.Module):
    """A decoder step's loss as one module call, so DistributedDataParallel can average the
    gradients of encoder and decoder together."""

    def __init__(self, encoder: Encoder, decoder: DecoderNet, cfg: TrainConfig) -> None:
        super().__init__()
        self.encoder, self.decoder, self.cfg = encoder, decoder, cfg

    def forward(self, batch: Batch, gen: torch.Generator, penalty: Penalty | None = None) -> Tensor:
        """Loss of a batch, plus a kind's ``penalty`` of the batch's latents when given."""
        cfg = self.cfg
        pre = self.encoder.pre_activation(batch.vectors)
        z = torch.tanh(pre)
        z = z + cfg.jitter * (2 * torch.rand(z.shape, generator=gen) - 1).to(z.device)
        loss = (decoder_loss(self.decoder, z, batch, cfg.chroma_weight, cfg.relative_weight, cfg.t_weight)
                + cfg.saturation_weight * saturation(pre))
        if cfg.albedo_weight:
            k = cfg.albedo_materials
            loss = loss + cfg.albedo_weight * albedo_loss(self.decoder, z[:k], batch.vectors[:k], cfg.albedo_samples, gen)
        if penalty is not None:
            loss = loss + penalty(self.decoder, z, gen)
        return loss


class Trainer:
    """Holds the networks, optimiser and data buffer; ``run`` trains the kind's phases and checkpoints.

    Under ``torchrun`` each rank draws its own data (generators seeded with the
    rank) and rank 0 alone writes checkpoints."""

    def __init__(self, cfg: TrainConfig, out: Path) -> None:
        self.cfg, self.out = cfg, out
        self.kind = kinds.kind_named(cfg.kind)
        self.where = placement(cfg.device)
        torch.manual_seed(cfg.seed)
        if cfg.threads:
            torch.set_num_threads(cfg.threads)
        self.encoder = Encoder()
        self.decoder = self.kind.build_decoder(cfg)
        self.sampler = self.kind.build_sampler(self.decoder)
        self.networks = networks(self.encoder, self.decoder, self.sampler)
        for net in self.networks.values():
            net.to(self.where.device)
        self.objective = data_parallel(Objective(self.encoder, self.decoder, cfg), self.where)
        self.step = 0
        self.skipped = 0  # batches skipped since the last checkpoint (non-finite gradients)
        self.gen = torch.Generator().manual_seed(self._data_seed(0))
        vectors = parameter_vectors(cfg.pool, np.random.default_rng(cfg.seed))
        if cfg.real_assets:
            vectors = np.concatenate([vectors, real_vectors.load_or_build(
                [Path(a) for a in cfg.real_assets], cfg.real_per_group, out / "real_vectors.npz")])
        # uniform draws (None) unless real vectors or an emphasis reweight the pool
        self.draw_weights = (torch.from_numpy(real_vectors.sampling_weights(vectors, cfg.pool, cfg.real_share,
                                                                            cfg.emphasis))
                             if cfg.real_assets or cfg.emphasis != 1.0 else None)
        self.pool = angular_floor(vectors, cfg.alpha_floor)
        self.buffer = [self._new_batch() for _ in range(cfg.buffer_batches)]
        if cfg.init:
            self._load(Path(cfg.init) / "weights.safetensors", cfg.init_networks)
        if cfg.freeze_encoder:
            self.encoder.requires_grad_(False)
        trained = [p for p in (*self.encoder.parameters(), *self.decoder.parameters()) if p.requires_grad]
        self.opt = torch.optim.Adam(trained, lr=cfg.lr)
        self.phases = self.kind.phases(self)

    def _data_seed(self, step: int) -> int:
        return (self.cfg.seed + step) * 1024 + self.where.rank

    def _new_batch(self) -> Batch:
        return make_batch(self.pool, self.cfg.batch, self.gen, weights=self.draw_weights).to(self.where.device)

    def buffered_batch(self) -> Batch:
        """A random batch of the buffer."""
        return self.buffer[torch.randint(len(self.buffer), (1,), generator=self.gen).item()]

    # ---- checkpoints ---------------------------------------------------------------
    def weights(self) -> dict[str, Tensor]:
        out = {}
        for name, net in self.networks.items():
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
        load_networks(path, {k: v for k, v in self.networks.items() if names is None or k in names})

    # ---- training -------------------------------------------------------------------
    def decoder_step(self, lr: float | None = None, penalty: Penalty | None = None) -> float:
        """One step of encoder and decoder: at ``lr`` (None: the cosine schedule over the decoder
        phase), with a kind's ``penalty`` added to the loss."""
        cfg = self.cfg
        if self.step % cfg.refresh_every == 0:
            self.buffer[(self.step // cfg.refresh_every) % len(self.buffer)] = self._new_batch()
        batch = self.buffered_batch()
        for group in self.opt.param_groups:
            group["lr"] = _cosine_lr(cfg, self.step, cfg.steps) if lr is None else lr
        loss = self.objective(batch, self.gen, penalty)
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

    def run(self) -> None:
        from tqdm import tqdm

        cfg = self.cfg
        total = sum(phase.steps for phase in self.phases)
        losses: list[float] = []
        start = time.perf_counter()
        with tqdm(total=total, initial=self.step, desc="train", unit="step", disable=not self.where.is_main) as bar:
            while self.step < total:
                end = 0
                for phase in self.phases:
                    end += phase.steps
                    if self.step < end:
                        break
                losses.append(phase.step())
                self.step += 1
                bar.update(1)
                if self.step % 50 == 0:
                    bar.set_postfix(phase=phase.name, loss=f"{np.nanmean(losses[-50:]):.4f}")
                if self.step % cfg.checkpoint_every == 0 or self.step == total:
                    cfg.history.append({"step": self.step, "phase": phase.name, "loss": float(np.nanmean(losses)),
                                        "seconds": time.perf_counter() - start, "skipped": self.skipped})
                    losses, self.skipped = [], 0
                    self.save()


def plot_history(history: list[dict], path: Path) -> None:
    """One loss chart per phase the history holds (log scale; symlog where a loss goes negative,
    as the sampler's does)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    phases = list(dict.fromkeys(h["phase"] for h in history)) or ["decoder"]
    fig, axes = plt.subplots(1, len(phases), figsize=(4.4 * len(phases), 3.2), squeeze=False)
    for ax, phase in zip(axes[0], phases):
        rows = [h for h in history if h["phase"] == phase]
        ax.plot([h["step"] for h in rows], [h["loss"] for h in rows], marker="o", ms=3)
        ax.set_title(f"{phase} loss")
        ax.set_xlabel("step")
        ax.set_yscale("symlog" if any(h["loss"] <= 0 for h in rows) else "log")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
