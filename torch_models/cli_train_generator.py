"""Train the text-to-neural-material generator (a multi-view diffusion model, paper sec. 5.2).

The corpus named in the configuration is made first where missing (procedural
objects, plus finished ``batch/`` outputs listed in ``corpus.batch_dirs``); objects
whose id hashes into the held-out split are never trained on. Writes
OUT/weights.safetensors, OUT/optimizer.safetensors, OUT/state.json and
OUT/training_curve.png at every checkpoint; ``--resume`` continues the run
exactly where its last checkpoint left it. Ctrl-C keeps the last checkpoint.
For several GPUs: ``torchrun --nproc_per_node N -m torch_models train-generator
--config torch_models/generator/configs/gpu.json``.
"""
from __future__ import annotations

import argparse
from pathlib import Path

HELP = "train the text-to-material multi-view diffusion generator (CPU, GPU or torchrun DDP)"
CONFIGS = Path(__file__).resolve().parent / "generator" / "configs"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--config", type=Path, default=CONFIGS / "cpu.json",
                        help="training configuration JSON (default: generator/configs/cpu.json)")
    parser.add_argument("--out", type=Path, default=Path("generator_run"), help="run folder (default: generator_run)")
    parser.add_argument("--resume", action="store_true", help="continue from the run folder's last checkpoint")
    parser.add_argument("--stop-at", type=int, default=None,
                        help="checkpoint and stop at this step, as an interruption would (the learning-rate "
                             "schedule still follows the config's steps; --resume goes on)")


def run(args: argparse.Namespace) -> int:
    import json

    from .cli import InputError
    from .distributed import finish
    from .generator.train import GeneratorTrainConfig, GeneratorTrainer, load_corpus

    if not args.config.is_file():
        raise InputError(f"{args.config}: no such configuration file")
    try:
        cfg = GeneratorTrainConfig.load(args.config)
    except (TypeError, ValueError, json.JSONDecodeError) as exc:
        raise InputError(f"{args.config}: not a generator training configuration ({exc})") from None
    if (args.out / "state.json").exists() and not args.resume:
        raise InputError(f"{args.out}: holds a run already; pass --resume or choose another --out")
    trainer = GeneratorTrainer(cfg, args.out, load_corpus(cfg.corpus))
    if args.resume and trainer.resume():
        print(f"resuming at step {trainer.step}")
    try:
        trainer.run(stop_at=args.stop_at)
        finish(trainer.where)
    except KeyboardInterrupt:
        print(f"interrupted at step {trainer.step}; the last checkpoint is in {args.out}")
        return 130
    print(f"trained {trainer.step} steps on {trainer.train_objects} objects; wrote {args.out}")
    return 0
