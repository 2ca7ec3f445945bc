"""Training of the universal encoder/decoder, then of the sampling decoder.

Phase 1 trains encoder and decoder together (an autoencoder through the BRDF):
z = encoder(params) + U(-jitter, jitter), loss = 0.95 L1(log(1 + f)) + 0.04 L1(T)
+ 0.01 L1(R). f spans ten decades, so its L1 is taken on log(1 + f) (targets
clamped to the decoder's exp ceiling). Phase 2 trains the sampling decoder
against the frozen decoder's luminance with the score-function estimate of the
forward KL divergence (Zeltner et al.; neural-notes sec. 1.2).

Data are generated on the fly into an in-memory buffer that is refreshed every
``refresh_every`` steps (generating a batch costs more than a training step on a
CPU). Checkpoints are safetensors written atomically, with a JSON state; a run
resumes from the last one.
"""
from __future__ import annotations

import json
import math
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np
import torch
from safetensors.torch import load_file, save_file
from torch import Tensor

from ..brdf.model import luminance
from .data import make_batch, parameter_vectors
from .networks import MAX_LOG_F, Decoder, Encoder, SamplingDecoder

LOSS_WEIGHTS = (0.95, 0.04, 0.01)  # f, T, R (paper sec. 4)


@dataclass
class TrainConfig:
    seed: int = 0
    width: int = 64
    depth: int = 4
    pool: int = 20_000  # distinct parameter vectors drawn from the enhancement rules
    buffer_batches: int = 8  # batches kept in memory, refreshed one at a time
    refresh_every: int = 4  # training steps per newly generated batch
    batch: int = 16_384
    steps: int = 20_000
    sampler_steps: int = 4_000
    lr: float = 2e-3
    lr_final: float = 2e-5
    jitter: float = 0.005
    checkpoint_every: int = 500
    threads: int = 0  # torch threads; 0 keeps torch's default
    history: list[dict] = field(default_factory=list)

    @classmethod
    def load(cls, path: Path) -> "TrainConfig":
        return cls(**json.loads(path.read_text()))


def decoder_loss(dec: Decoder, z: Tensor, batch) -> Tensor:  # type: ignore[no-untyped-def]
    f, t, r = dec(z, batch.wi, batch.wo)
    target = batch.f.clamp(max=math.exp(MAX_LOG_F))
    wf, wt, wr = LOSS_WEIGHTS
    return (wf * (torch.log1p(f) - torch.log1p(target)).abs().mean()
            + wt * (t - batch.t).abs().mean() + wr * (r - batch.r).abs().mean())


def sampler_loss(sampler: SamplingDecoder, dec: Decoder, z: Tensor, wi: Tensor, u: Tensor) -> Tensor:
    """-E[target / pdf * log pdf] with wo from the (detached) sampler: the forward KL's gradient."""
    with torch.no_grad():
        wo = sampler.sample(z, wi, u)
        target = luminance(dec(z, wi, wo)[0]).squeeze(-1)
    pdf = sampler.pdf(z, wi, wo)
    ok = (wo[:, 2] > 0) & (pdf > 0)
    weight = torch.where(ok, target / pdf.detach().clamp(min=1e-4), torch.zeros_like(target))
    return -(weight * pdf.clamp(min=1e-4).log()).mean()


def _cosine_lr(cfg: TrainConfig, step: int, total: int) -> float:
    return cfg.lr_final + 0.5 * (cfg.lr - cfg.lr_final) * (1 + math.cos(math.pi * min(step / total, 1.0)))


class Trainer:
    """Holds the networks, optimiser and data buffer; ``run`` trains and checkpoints."""

    def __init__(self, cfg: TrainConfig, out: Path) -> None:
        self.cfg, self.out = cfg, out
        torch.manual_seed(cfg.seed)
        if cfg.threads:
            torch.set_num_threads(cfg.threads)
        self.encoder, self.decoder = Encoder(), Decoder(cfg.width, cfg.depth)
        self.sampler = SamplingDecoder()
        self.step = 0
        self.gen = torch.Generator().manual_seed(cfg.seed)
        self.pool = torch.from_numpy(parameter_vectors(cfg.pool, np.random.default_rng(cfg.seed)))
        self.buffer = [make_batch(self.pool, cfg.batch, self.gen) for _ in range(cfg.buffer_batches)]
        self.opt = torch.optim.Adam([*self.encoder.parameters(), *self.decoder.parameters()], lr=cfg.lr)
        self.sampler_opt = torch.optim.Adam(self.sampler.parameters(), lr=1e-3)

    # ---- checkpoints ---------------------------------------------------------------
    def weights(self) -> dict[str, Tensor]:
        out = {}
        for name, net in (("encoder", self.encoder), ("decoder", self.decoder), ("sampler", self.sampler)):
            out.update({f"{name}.{k}": v.detach().contiguous() for k, v in net.state_dict().items()})
        return out

    def save(self) -> None:
        from ..cli import atomic_path

        self.out.mkdir(parents=True, exist_ok=True)
        with atomic_path(self.out / "weights.safetensors") as tmp:
            save_file(self.weights(), str(tmp))
        state = {"step": self.step, "config": asdict(self.cfg)}
        with atomic_path(self.out / "state.json") as tmp:
            tmp.write_text(json.dumps(state, indent=1))

    def resume(self) -> bool:
        state_path = self.out / "state.json"
        if not state_path.exists():
            return False
        state = json.loads(state_path.read_text())
        tensors = load_file(str(self.out / "weights.safetensors"))
        for name, net in (("encoder", self.encoder), ("decoder", self.decoder), ("sampler", self.sampler)):
            net.load_state_dict({k[len(name) + 1:]: v for k, v in tensors.items() if k.startswith(name + ".")})
        self.step = state["step"]
        self.cfg.history = state["config"]["history"]
        self.gen.manual_seed(self.cfg.seed + self.step)  # fresh data after a resume, reproducibly
        return True

    # ---- training -------------------------------------------------------------------
    def _decoder_step(self) -> float:
        cfg = self.cfg
        if self.step % cfg.refresh_every == 0:
            self.buffer[(self.step // cfg.refresh_every) % len(self.buffer)] = make_batch(self.pool, cfg.batch,
                                                                                          self.gen)
        batch = self.buffer[torch.randint(len(self.buffer), (1,), generator=self.gen).item()]
        for group in self.opt.param_groups:
            group["lr"] = _cosine_lr(cfg, self.step, cfg.steps)
        z = self.encoder(batch.vectors)
        z = z + cfg.jitter * (2 * torch.rand(z.shape, generator=self.gen) - 1)
        loss = decoder_loss(self.decoder, z, batch)
        self.opt.zero_grad()
        loss.backward()
        self.opt.step()
        return loss.item()

    def _sampler_step(self) -> float:
        batch = self.buffer[torch.randint(len(self.buffer), (1,), generator=self.gen).item()]
        with torch.no_grad():
            z = self.encoder(batch.vectors)
        u = torch.rand(len(z), 3, generator=self.gen)
        loss = sampler_loss(self.sampler, self.decoder, z, batch.wi, u)
        self.sampler_opt.zero_grad()
        loss.backward()
        self.sampler_opt.step()
        return loss.item()

    def run(self) -> None:
        from tqdm import tqdm

        cfg = self.cfg
        total = cfg.steps + cfg.sampler_steps
        losses: list[float] = []
        start = time.perf_counter()
        with tqdm(total=total, initial=self.step, desc="train", unit="step") as bar:
            while self.step < total:
                phase = "decoder" if self.step < cfg.steps else "sampler"
                losses.append(self._decoder_step() if phase == "decoder" else self._sampler_step())
                self.step += 1
                bar.update(1)
                if self.step % 50 == 0:
                    bar.set_postfix(phase=phase, loss=f"{np.mean(losses[-50:]):.4f}")
                if self.step % cfg.checkpoint_every == 0 or self.step == total:
                    cfg.history.append({"step": self.step, "phase": phase, "loss": float(np.mean(losses)),
                                        "seconds": time.perf_counter() - start})
                    losses = []
                    self.save()
                    plot_history(cfg.history, self.out / "training_curve.png")


def plot_history(history: list[dict], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(9, 3.2))
    for ax, phase in zip(axes, ("decoder", "sampler")):
        rows = [h for h in history if h["phase"] == phase]
        if rows:
            ax.plot([h["step"] for h in rows], [h["loss"] for h in rows])
        ax.set_title(f"{phase} loss")
        ax.set_xlabel("step")
        ax.set_yscale("symlog" if phase == "sampler" else "log")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
