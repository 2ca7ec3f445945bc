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
"total", "loss"}`` per step, ``{"event": "stage", "text"}`` before the work
that has no steps (reading, choosing representatives, measuring the error), then ``{"event": "done", "out", "files"}``; bad input
is ``{"event": "error", "message"}`` with exit code 2.
"""
from __future__ import annotations

import argparse
from pathlib import Path

from richmat_addon.core.texel_vectors import FIT_BUDGET, QUANT

HELP = "fit the latent textures of an enhanced material against the frozen decoder"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("material", type=Path, help="an enhanced material folder (params.json + EXRs)")
    parser.add_argument("--out", type=Path, required=True, help="output folder")
    parser.add_argument("--steps", type=int, default=300,
                        help="optimisation steps (default: 300); the energy refit takes as many, at most 150")
    parser.add_argument("--weights", type=Path, default=None, help="a training run folder (default: shipped)")
    parser.add_argument("--resume", action="store_true", help="continue an interrupted fit in OUT")
    parser.add_argument("--seed", type=int, default=0, help="seed of the direction samples (default: 0)")
    parser.add_argument("--cluster-step", type=float, default=QUANT,
                        help="merge texel vectors that agree to this step per normalised parameter (default: "
                             "1/256); a coarser step leaves fewer vectors to fit")
    parser.add_argument("--budget", type=int, default=FIT_BUDGET,
                        help=f"fit at most this many vectors (default: {FIT_BUDGET}); past it, representatives "
                             "chosen by k-means in the encoder's latent space, each texel taking its "
                             "representative's latent; 0: every merged vector, at a cost linear in them")
    parser.add_argument("--progress", choices=("bar", "jsonl"), default="bar",
                        help="a progress bar (default) or JSON lines on stdout (for the Blender add-on)")


def run(args: argparse.Namespace) -> int:
    from tqdm import tqdm

    from richmat_addon.core import material_folder
    from richmat_addon.core.fit_error import grade

    from .cli import InputError, emit, emit_done
    from .neural import trained
    from .neural.fit.material import FitInterrupted, FitSettings, fit_material

    jsonl = args.progress == "jsonl"
    settings = FitSettings(steps=args.steps, seed=args.seed, budget=args.budget,
                           cluster_step=args.cluster_step)
    try:
        material_folder.read(args.material)  # a bad folder is named before the decoder is looked for
        model = trained.load(args.weights or trained.SHIPPED)
        with tqdm(total=args.steps, desc="fit", unit="step", disable=jsonl) as bar:
            def progress(step: int, loss: float) -> None:
                bar.update(step - bar.n)
                bar.set_postfix(loss=f"{loss:.4f}")
                if jsonl:
                    emit("progress", step=step, total=args.steps, loss=loss)

            def stage(text: str) -> None:
                bar.set_description(text)
                if jsonl:
                    emit("stage", text=text)

            record = fit_material(model, args.material, args.out, settings, args.resume, progress, stage)
    except (ValueError, FileNotFoundError, KeyError) as exc:
        if jsonl:
            emit("error", message=str(exc))
        raise InputError(str(exc)) from None
    except FitInterrupted as stop:
        print(stop)
        return 130
    if jsonl:
        emit_done(args.out)
        return 0
    furnace = record["furnace"]
    print(f"fitted {record['fitted_vectors']} vectors for {record['merged_vectors']} merged "
          f"({record['exact_unique_vectors']} exact) and {record['texels']} texels; furnace: "
          f"{furnace['passed_as_fitted']}/{furnace['checked']} pass as fitted, {furnace['passed_after_refit']} after "
          f"the energy refit, {furnace['repaired_by_scaling']} scaled; fit error {record['fit_error']['mean']:.3f} "
          f"({grade(record['fit_error']['mean'])}); wrote {args.out}")
    return 0
