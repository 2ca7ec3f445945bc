"""Fit one enhanced material folder into a neural folder: the fit that the CLI, the add-on's
backend (through the CLI) and the farm all run.

Read the texel vectors (deduplicated, merged at the cluster step), fit them, check their
energy, measure the fit error, write the neural folder. Above ``budget`` distinct vectors the
fit is bounded (``representatives.py``): ``budget`` representatives are fitted and every texel
takes its representative's latent, so a fit's decoder evaluations do not grow with the texture.
The error readout is bounded with it: each representative's error is measured at one of its
vectors, drawn with its texels' share, under the representative's latent, so that it includes
what the representative costs that vector.
"""
from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch
from safetensors.torch import load_file, save_file

from richmat_addon.core.texel_vectors import FIT_BUDGET, QUANT, TexelVectors, read_vectors

from ...stage_clock import StageClock
from .. import energy
from ..mlp.energy import REFIT_STEPS
from ..model import NeuralModel
from . import representatives
from .error import vector_errors
from .latents import fit_latents
from .material_vectors import write_fit

STATE_FILE = "fit_state.safetensors"  # an interrupted fit's latents and step, for resume
Progress = Callable[[int, float], None]  # (steps done, loss)
Stage = Callable[[str], None]  # what the fit does now, in words, before its steps and after them


@dataclass(frozen=True)
class FitSettings:
    """What a fit is asked for; the defaults are the add-on's Fit."""

    steps: int = 300
    seed: int = 0
    cluster_step: float = QUANT
    budget: int = FIT_BUDGET  # vectors fitted at most; 0: every merged vector, unbounded


class FitInterrupted(Exception):
    """Ctrl-C during the fit: its state was saved in ``path`` after ``step`` steps."""

    def __init__(self, step: int, path: Path) -> None:
        super().__init__(f"interrupted at step {step}; --resume continues from {path}")
        self.step, self.path = step, path


@dataclass
class FitPlan:
    """What is fitted: the texels deduplicated to the fitted vectors, and the vector whose error
    stands for each fitted one (itself when the fit is not bounded)."""

    fitted: TexelVectors
    measured: np.ndarray  # (B, 22)
    merged: int  # vectors after merging at the cluster step
    bounded: bool  # the budget chose representatives


def plan(model: NeuralModel, material: Path, settings: FitSettings, stage: Stage = lambda text: None) -> FitPlan:
    """The material's vectors and, past the budget, their representatives."""
    mv = read_vectors(material, settings.cluster_step)
    if not settings.budget or len(mv.unique) <= settings.budget:
        return FitPlan(mv, mv.unique, len(mv.unique), False)
    stage(f"choosing {settings.budget} representatives of {len(mv.unique)} distinct vectors")
    counts = np.bincount(mv.inverse, minlength=len(mv.unique)).astype(np.float64)
    reps = representatives.choose(model, mv.unique, counts, settings.budget, settings.seed)
    drawn = representatives.draw_members(reps, counts, settings.seed)
    return FitPlan(reps.of_texels(mv), mv.unique[drawn], len(mv.unique), True)


def fit_vectors(model: NeuralModel, vectors: np.ndarray, settings: FitSettings, state: Path, resume: bool,
                progress: Progress | None) -> tuple[torch.Tensor, float]:
    """Latents of ``vectors`` and the last loss; Ctrl-C saves them to ``state`` (``FitInterrupted``),
    which ``resume`` continues from."""
    start, done = None, 0
    if resume and state.exists():
        saved = load_file(str(state))
        if len(saved["latents"]) == len(vectors):
            start, done = saved["latents"], int(saved["step"])
    latest: dict[str, Any] = {"z": start, "step": done, "loss": float("nan")}

    def step_done(step: int, loss: float, z: torch.Tensor) -> None:
        latest.update(z=z, step=done + step + 1, loss=loss)
        if progress is not None:
            progress(done + step + 1, loss)

    try:
        z = fit_latents(model, vectors, max(0, settings.steps - done), seed=settings.seed + done,
                        start=start, progress=step_done)
    except KeyboardInterrupt:
        if latest["z"] is not None:
            tmp = state.with_name(state.name + ".tmp")
            save_file({"latents": latest["z"], "step": torch.tensor(latest["step"])}, str(tmp))
            os.replace(tmp, state)
        raise FitInterrupted(latest["step"], state) from None
    return z, latest["loss"]


def fit_material(model: NeuralModel, material: Path, out: Path, settings: FitSettings = FitSettings(),
                 resume: bool = False, progress: Progress | None = None,
                 stage: Stage = lambda text: None) -> dict[str, Any]:
    """Fit ``material`` (an enhanced material folder) into the neural folder ``out``; its record.

    ``progress(step, loss)`` is called after every step and ``stage(text)`` before the work
    without steps; Ctrl-C raises ``FitInterrupted`` with the state saved for ``resume``."""
    clock = StageClock()
    with clock.stage("read"):
        stage("reading the material")
        p = plan(model, material, settings, stage)
    out.mkdir(parents=True, exist_ok=True)
    state = out / STATE_FILE
    with clock.stage("fit"):
        z, loss = fit_vectors(model, p.fitted.unique, settings, state, resume, progress)
    # The energy refit gets no more steps than the fit had: a quick fit stays quick, and what the
    # short refit leaves over the bound is scaled, as the furnace check counts.
    refit_steps = min(REFIT_STEPS, settings.steps)
    with clock.stage("energy"):
        bounded = energy.fit_bounded(model, p.fitted.unique, z, seed=settings.seed, steps=refit_steps)
    with clock.stage("error"):
        stage("measuring the fit error")
        errors = vector_errors(model, p.measured, bounded.z, bounded.check.energy_scale(), seed=settings.seed)
    timed = clock.record(whole_process=False)
    for kind, parts in bounded.seconds.items():  # the energy check's own split: check, refit, recheck
        timed[kind].update({f"energy_{part}": value for part, value in parts.items()})
    fields = {"material": os.path.relpath(material, out), "steps": settings.steps, "refit_steps": refit_steps,
              "final_loss": loss, "budget": settings.budget, "merged_vectors": p.merged, **timed}
    if p.bounded:
        fields["cluster_bound"] = (f"{len(p.fitted.unique)} representatives of the {p.merged} merged vectors, "
                                   "k-means in the encoder's latent space (representatives.py)")
    record = write_fit(out, p.fitted, bounded, model.digest, fields, errors=errors)
    state.unlink(missing_ok=True)
    return record
