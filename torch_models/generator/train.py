"""Training of the multi-view latent generator: data, optimiser, checkpoints, resume, DDP.

Every step draws its batch and noise from a generator seeded by (seed, step,
rank), and checkpoints hold the weights and the Adam moments, so a run that is
stopped and resumed takes exactly the steps an uninterrupted run takes (tested).
Under ``torchrun`` the model is data-parallel (``torch_models/distributed.py``).
"""
from __future__ import annotations

import json
import math
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

import torch
from safetensors.torch import load_file, save_file
from torch import Tensor

from ..distributed import data_parallel, placement
from ..neural import trained
from . import corpus
from .dit import Conditions, DitConfig, LatentGenerator


@dataclass
class CorpusConfig:
    dir: str = "generator_corpus"  # relative paths (here and in batch_dirs) are relative to the config file
    procedural: int = 400  # procedural objects made (and kept) in dir
    batch_dirs: list[str] = field(default_factory=list)  # batch/ outputs to add (the assets their index lists)
    views: int = 8
    resolution: int = 32
    texture_size: int = 64
    fit_steps: int = 0
    supersample: int = 1  # anti-aliasing of the rasterised views (2: 4 samples per pixel)
    seed: int = 0
    held_out: list[str] = field(default_factory=list)  # asset ids never trained on besides the hashed split:
    # real assets kept for evaluation (python -m bench.generator.generate_eval --real)

    def trains_on(self, asset_id: str) -> bool:
        return not (corpus.is_held_out(asset_id) or asset_id in self.held_out)


@dataclass
class GeneratorTrainConfig:
    model: DitConfig = field(default_factory=DitConfig)
    corpus: CorpusConfig = field(default_factory=CorpusConfig)
    steps: int = 20000
    batch: int = 8
    lr: float = 3e-4
    lr_final: float = 3e-5
    warmup: int = 200
    drop_prob: float = 0.1  # prompt dropout, for classifier-free guidance
    pbr_drop_prob: float = 0.2  # roughness/metalness dropout: meshes without PBR maps get the same model
    checkpoint_every: int = 500
    seed: int = 0
    threads: int = 0  # 0: torch's default
    device: str = "cpu"

    @classmethod
    def from_dict(cls, d: dict) -> "GeneratorTrainConfig":
        d = dict(d)
        model = DitConfig(**d.pop("model", {}))
        data = CorpusConfig(**d.pop("corpus", {}))
        return cls(model=model, corpus=data, **d)

    @classmethod
    def load(cls, path: Path) -> "GeneratorTrainConfig":
        cfg = cls.from_dict(json.loads(path.read_text()))
        def here(d: str) -> str:
            return d if Path(d).is_absolute() else str((path.parent / d).resolve())

        cfg.corpus.dir = here(cfg.corpus.dir)
        cfg.corpus.batch_dirs = [here(d) for d in cfg.corpus.batch_dirs]
        return cfg

    def to_dict(self) -> dict:
        return asdict(self)


def learning_rate(cfg: GeneratorTrainConfig, step: int) -> float:
    """Linear warm-up, then cosine decay to ``lr_final``."""
    if step < cfg.warmup:
        return cfg.lr * (step + 1) / cfg.warmup
    t = min((step - cfg.warmup) / max(cfg.steps - cfg.warmup, 1), 1.0)
    return cfg.lr_final + 0.5 * (cfg.lr - cfg.lr_final) * (1 + math.cos(math.pi * t))


def load_corpus(cfg: CorpusConfig, progress: bool = True) -> list[corpus.Sample]:
    """All samples of the corpus (made where missing), held-out objects included; callers split."""
    paths = corpus.build_procedural(Path(cfg.dir), cfg.procedural, cfg.views, cfg.resolution, cfg.seed,
                                    cfg.texture_size, cfg.fit_steps, cfg.supersample, progress)
    samples = [corpus.Sample.load(p) for p in paths]
    samples += [s for d in cfg.batch_dirs for s in corpus.batch_samples(Path(d))]
    return samples


def _stack(samples: list[corpus.Sample]) -> tuple[Tensor, Tensor, Tensor, Tensor, Tensor]:
    return (torch.stack([s.target for s in samples]), torch.stack([s.conditions for s in samples]),
            torch.stack([s.text for s in samples]), torch.tensor([s.type for s in samples]),
            torch.stack([s.unknown_prior for s in samples]))


class GeneratorTrainer:
    def __init__(self, cfg: GeneratorTrainConfig, out: Path, samples: list[corpus.Sample]) -> None:
        self.cfg, self.out = cfg, out
        if cfg.threads:
            torch.set_num_threads(cfg.threads)
        self.where = where = placement(cfg.device)
        self.rank, self.world, self.device = where.rank, where.world, where.device
        train = [s for s in samples if cfg.corpus.trains_on(s.asset_id)]
        if not train:
            raise ValueError("the corpus has no training objects")
        self.target, self.cond, self.text, self.type, self.unknown_prior = (t.to(self.device) for t in _stack(train))
        torch.manual_seed(cfg.seed)
        self.model = LatentGenerator(cfg.model).to(self.device)
        self.module = data_parallel(self.model, where)
        self.opt = torch.optim.AdamW(self.model.parameters(), lr=cfg.lr, weight_decay=0.0)
        self.step = 0
        self.history: list[dict] = []
        self.train_objects = len(train)
        self.encoder_digest = trained.encoder_digest()  # the corpus latents are the shipped encoder's

    # ---- checkpoints ---------------------------------------------------------------
    def save(self) -> None:
        if self.rank != 0:
            return
        from ..cli import atomic_path

        self.out.mkdir(parents=True, exist_ok=True)
        with atomic_path(self.out / "weights.safetensors") as tmp:
            save_file({k: v.detach().cpu().contiguous() for k, v in self.model.state_dict().items()}, str(tmp))
        moments = {}
        for i, p in enumerate(self.model.parameters()):
            for key, value in self.opt.state.get(p, {}).items():
                moments[f"{i}.{key}"] = value.detach().cpu().reshape(-1).clone() if key == "step" else \
                    value.detach().cpu().contiguous()
        with atomic_path(self.out / "optimizer.safetensors") as tmp:
            save_file(moments, str(tmp))
        state = {"step": self.step, "config": self.cfg.to_dict(), "history": self.history,
                 "train_objects": self.train_objects, "encoder_sha256": self.encoder_digest}
        with atomic_path(self.out / "state.json") as tmp:
            tmp.write_text(json.dumps(state, indent=1))
        plot_history(self.history, self.out / "training_curve.png")

    def resume(self) -> bool:
        state_path = self.out / "state.json"
        if not state_path.exists():
            return False
        state = json.loads(state_path.read_text())
        self.model.load_state_dict(load_file(str(self.out / "weights.safetensors")))
        moments = load_file(str(self.out / "optimizer.safetensors"))
        for i, p in enumerate(self.model.parameters()):
            keys = {k.split(".", 1)[1]: v for k, v in moments.items() if k.split(".", 1)[0] == str(i)}
            if keys:
                keys["step"] = keys["step"].reshape(())
                self.opt.state[p] = {k: v.to(self.device) if k != "step" else v for k, v in keys.items()}
        self.step, self.history = state["step"], state["history"]
        return True

    # ---- training -------------------------------------------------------------------
    def train_step(self) -> float:
        cfg = self.cfg
        gen = torch.Generator().manual_seed((cfg.seed * 1_000_003 + self.step) * 64 + self.rank)
        idx = torch.randint(len(self.target), (cfg.batch,), generator=gen).to(self.device)
        cond = Conditions(self.cond[idx], self.text[idx], self.type[idx], self.unknown_prior[idx])
        for group in self.opt.param_groups:
            group["lr"] = learning_rate(cfg, self.step)
        loss = self.module(self.target[idx], cond, gen, cfg.drop_prob, cfg.pbr_drop_prob)
        self.opt.zero_grad()
        loss.backward()
        torch.nn.utils.clip_grad_norm_(self.model.parameters(), 1.0)
        self.opt.step()
        self.step += 1
        return loss.item()

    def run(self, progress: bool = True, stop_at: int | None = None) -> None:
        """Train to the config's steps (or to ``stop_at``), checkpointing on the way and at the end."""
        from tqdm import tqdm

        losses, started = [], time.perf_counter()
        with tqdm(total=self.cfg.steps, initial=self.step, desc="train generator", unit="step",
                  disable=not progress or self.rank != 0) as bar:
            end = self.cfg.steps if stop_at is None else min(stop_at, self.cfg.steps)
            while self.step < end:
                losses.append(self.train_step())
                bar.update(1)
                bar.set_postfix(loss=f"{losses[-1]:.3f}")
                if self.step % self.cfg.checkpoint_every == 0 or self.step == end:
                    self.history.append({"step": self.step, "loss": sum(losses) / len(losses),
                                         "seconds": time.perf_counter() - started})
                    losses = []
                    self.save()


def plot_history(history: list[dict], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 3.2))
    ax.plot([h["step"] for h in history], [h["loss"] for h in history])
    ax.set_xlabel("step")
    ax.set_ylabel("uncertainty-weighted EDM loss")
    ax.set_title("generator training")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
