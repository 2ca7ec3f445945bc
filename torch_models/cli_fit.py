"""Fit a neural material: an enhanced material folder to two RGB latent textures.

MATERIAL_DIR is a folder written by ``enhance`` (params.json and parameter EXRs).
Writes OUT/latent_0.exr and OUT/latent_1.exr (latent channels 0-2 and 3-5 at
the material's texture resolution) or, for a constant material, the latent in
OUT/neural.json, which also records the decoder's digest, how many distinct
vectors were fitted, the loss, the white-furnace result, the fit error (its
mean; the per-texel map is OUT/fit_error.exr) and the wall and CPU seconds of
reading, fitting, the energy check and the error measure. Ctrl-C saves the state;
``--resume`` continues it.

``--progress jsonl`` replaces the progress bar with one JSON object per line on
stdout, for the Blender add-on (docs/addon.md): ``{"event": "progress", "step",
"total", "loss"}`` per step, then ``{"event": "done", "out", "files"}``; bad input
is ``{"event": "error", "message"}`` with exit code 2.
"""
from __future__ import annotations

import argparse
import os
from pathlib import Path

HELP = "fit the latent textures of an enhanced material against the frozen decoder"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("material", type=Path, help="an enhanced material folder (params.json + EXRs)")
    parser.add_argument("--out", type=Path, required=True, help="output folder")
    parser.add_argument("--steps", type=int, default=300,
                        help="optimisation steps (default: 300); the energy refit takes as many, at most 150")
    parser.add_argument("--weights", type=Path, default=None, help="a training run folder (default: shipped)")
    parser.add_argument("--resume", action="store_true", help="continue an interrupted fit in OUT")
    parser.add_argument("--seed", type=int, default=0, help="seed of the direction samples (default: 0)")
    parser.add_argument("--cluster-step", type=float, default=None,
                        help="merge texel vectors that agree to this step per normalised parameter (default: "
                             "1/256); a coarser step fits fewer vectors, and the energy check costs per vector")
    parser.add_argument("--progress", choices=("bar", "jsonl"), default="bar",
                        help="a progress bar (default) or JSON lines on stdout (for the Blender add-on)")


def run(args: argparse.Namespace) -> int:
    import torch
    from safetensors.torch import load_file, save_file
    from tqdm import tqdm

    from richmat_addon.core.fit_error import grade
    from richmat_addon.core.stage_clock import StageClock

    from .cli import InputError, atomic_path, emit, emit_done
    from .neural import energy, fit_error, fitting, material_vectors, trained
    from .neural.mlp.energy import REFIT_STEPS

    jsonl = args.progress == "jsonl"
    clock = StageClock()
    try:
        with clock.stage("read"):
            step = material_vectors.QUANT if args.cluster_step is None else args.cluster_step
            mv = material_vectors.read_vectors(args.material, step)
            model = trained.load(args.weights or trained.SHIPPED)
    except (ValueError, FileNotFoundError, KeyError) as exc:
        if jsonl:
            emit("error", message=str(exc))
        raise InputError(str(exc)) from None
    args.out.mkdir(parents=True, exist_ok=True)
    state = args.out / "fit_state.safetensors"
    start, done = None, 0
    if args.resume and state.exists():
        saved = load_file(str(state))
        start, done = saved["latents"], int(saved["step"])
    latest = {"z": start, "step": done, "loss": float("nan")}

    def progress(step: int, loss: float, z: torch.Tensor) -> None:
        latest.update(z=z, step=done + step + 1, loss=loss)
        bar.update(1)
        bar.set_postfix(loss=f"{loss:.4f}")
        if jsonl:
            emit("progress", step=done + step + 1, total=args.steps, loss=loss)

    with tqdm(total=args.steps, initial=done, desc=f"fit {len(mv.unique)} vectors", unit="step",
              disable=jsonl) as bar:
        try:
            with clock.stage("fit"):
                z = fitting.fit_latents(model, mv.unique, max(0, args.steps - done), seed=args.seed + done,
                                        start=start, progress=progress)
        except KeyboardInterrupt:
            if latest["z"] is not None:
                with atomic_path(state) as tmp:
                    save_file({"latents": latest["z"], "step": torch.tensor(latest["step"])}, str(tmp))
            print(f"interrupted at step {latest['step']}; --resume continues from {state}")
            return 130
    # The energy refit gets no more steps than the fit had: a quick fit stays quick, and what the
    # short refit leaves over the bound is scaled, as the furnace check counts.
    refit_steps = min(REFIT_STEPS, args.steps)
    with clock.stage("energy"):
        bounded = energy.fit_bounded(model, mv.unique, z, seed=args.seed, steps=refit_steps)
    with clock.stage("error"):
        errors = fit_error.vector_errors(model, mv.unique, bounded.z, bounded.check.energy_scale(), seed=args.seed)
    timed = clock.record(whole_process=False)
    for kind, parts in bounded.seconds.items():  # the energy check's own split: check, refit, recheck
        timed[kind].update({f"energy_{part}": value for part, value in parts.items()})
    record = material_vectors.write_fit(args.out, mv, bounded, model.digest, {
        "material": os.path.relpath(args.material, args.out), "steps": args.steps, "refit_steps": refit_steps,
        "final_loss": latest["loss"], **timed}, errors=errors)
    state.unlink(missing_ok=True)
    if jsonl:
        emit_done(args.out)
        return 0
    print(f"fitted {len(mv.unique)} vectors ({mv.exact_unique} exact) for {record['texels']} texels; "
          f"furnace: {record['furnace']['passed_as_fitted']}/{len(z)} pass as fitted, "
          f"{record['furnace']['passed_after_refit']} after the energy refit, "
          f"{record['furnace']['repaired_by_scaling']} scaled; fit error {record['fit_error']['mean']:.3f} "
          f"({grade(record['fit_error']['mean'])}); wrote {args.out}")
    return 0

