"""Train the universal neural-material encoder and a decoder of the kind the config names.

Data are generated on the fly from the enhancement rules (torch_models/neural/data.py).
Writes OUT/weights.safetensors, OUT/state.json and OUT/training_curve.png at every
checkpoint; ``--resume`` continues from OUT's last checkpoint. Ctrl-C keeps the
last checkpoint.
"""
from __future__ import annotations

import argparse
from pathlib import Path

HELP = "train the universal neural-material decoder (CPU or GPU)"
CONFIGS = Path(__file__).resolve().parent / "neural" / "configs"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--config", type=Path, default=CONFIGS / "decoder_hybrid_sheen.json",
                        help="training configuration JSON (default: neural/configs/decoder_hybrid_sheen.json, "
                             "the shipped decoder's)")
    parser.add_argument("--out", type=Path, default=Path("decoder_run"), help="run folder (default: decoder_run)")
    parser.add_argument("--resume", action="store_true", help="continue from the run folder's last checkpoint")


def run(args: argparse.Namespace) -> int:
    from .cli import InputError
    from .distributed import finish
    from .neural.kinds import load_config
    from .neural.train import Trainer

    if not args.config.is_file():
        raise InputError(f"{args.config}: no such configuration file")
    try:
        cfg = load_config(args.config)
    except (TypeError, ValueError) as exc:
        raise InputError(f"{args.config}: not a training configuration ({exc})") from None
    if cfg.init and not (Path(cfg.init) / "weights.safetensors").is_file():
        raise InputError(f"{args.config}: its init run {cfg.init} holds no weights.safetensors "
                         "(train that run first; runs removed from the package: docs/history.md)")
    trainer = Trainer(cfg, args.out)
    if args.resume and trainer.resume():
        print(f"resuming at step {trainer.step}")
    elif (args.out / "state.json").exists() and not args.resume:
        raise InputError(f"{args.out}: holds a run already; pass --resume or choose another --out")
    try:
        trainer.run()
        finish(trainer.where)
    except KeyboardInterrupt:
        print(f"interrupted at step {trainer.step}; the last checkpoint is in {args.out}")
        return 130
    return 0
