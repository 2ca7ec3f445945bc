"""The neural material folder: the one writer and reader of its files.

A textured material's 6 latent channels are two RGB half-float EXRs
(``latent_0.exr``: channels 0-2, ``latent_1.exr``: 3-5); a constant material
keeps its latent vector in ``neural.json`` (``latent``) instead. The energy
scale of texels the furnace repaired is ``energy_scale.exr`` (``energy_scale``
names it) or one number. A fit's error (``core/fit_error.py``) is ``fit_error`` in
``neural.json``: the texels' mean and, for a textured material, the per-texel map
``fit_error.exr``. ``neural.json`` also holds ``format``, the digest of
the decoder the latents belong to (``decoder_sha256``) and the writer's own
fields (fit: counts and furnace; generate: prompt, type, ...), and is written
last, so its presence marks a complete folder. ``fit``, ``generate`` and the demo
write it; the add-on, the farm and the benches read it.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from . import fit_error as fit_error_grades
from .folder_io import CheckedFolder, FormatError, read_record, write_exr, write_record

RECORD = "neural.json"
FORMAT = 1
LATENT_FILES = ("latent_0.exr", "latent_1.exr")
ENERGY_FILE = "energy_scale.exr"
ERROR_FILE = "fit_error.exr"
LATENT_CHANNELS = 6


def write(folder: Path, latents: np.ndarray, energy_scale: np.ndarray, decoder_sha256: str,
          fields: dict[str, Any], maps: dict[str, np.ndarray] | None = None,
          fit_error: np.ndarray | None = None) -> dict[str, Any]:
    """Write a neural material; returns the record written to neural.json.

    ``latents`` is (H, W, 6) for a textured material or (6,) for a constant one,
    ``energy_scale`` the per-texel (or single) scale, ``maps`` further (H, W, C)
    maps to keep beside the latents (``<name>.exr``), ``fit_error`` the fit's error per
    texel (H, W) or of the constant material (one number), when it was measured. Files of
    a previous run that this material has no use for go.
    """
    folder.mkdir(parents=True, exist_ok=True)
    for name, value in (maps or {}).items():
        write_exr(folder / f"{name}.exr", value)
    scale = np.asarray(energy_scale, np.float32)
    record: dict[str, Any] = {"format": FORMAT, **fields, "decoder_sha256": decoder_sha256}
    written: set[str] = set()
    if latents.ndim == 1:
        record["latent"] = [float(x) for x in latents]
        record["energy_scale"] = float(scale.reshape(-1)[0])
    else:
        write_exr(folder / LATENT_FILES[0], latents[..., :3])
        write_exr(folder / LATENT_FILES[1], latents[..., 3:])
        written.update(LATENT_FILES)
        if (scale < 1).any():
            write_exr(folder / ENERGY_FILE, scale.reshape(*latents.shape[:2], 1))
            written.add(ENERGY_FILE)
        record["energy_scale"] = ENERGY_FILE if ENERGY_FILE in written else 1.0
    if fit_error is not None:
        error = np.asarray(fit_error, np.float32)
        record["fit_error"] = {"measure": fit_error_grades.MEASURE, "mean": float(error.mean())}
        if latents.ndim == 3:
            write_exr(folder / ERROR_FILE, error.reshape(*latents.shape[:2], 1))
            written.add(ERROR_FILE)
            record["fit_error"]["map"] = ERROR_FILE
    for name in {*LATENT_FILES, ENERGY_FILE, ERROR_FILE} - written:
        (folder / name).unlink(missing_ok=True)
    write_record(folder / RECORD, record, indent=1, sort_keys=True)
    return record


@dataclass(frozen=True)
class FitError:
    """A fitted material's error: the texels' mean, its grade, and the per-texel map if textured."""

    mean: float
    map: Path | None

    @property
    def grade(self) -> str:
        return fit_error_grades.grade(self.mean)


class NeuralFolder(CheckedFolder):
    """A checked neural material folder: its neural.json and the files it names."""

    @property
    def decoder_sha256(self) -> str:
        return self.record["decoder_sha256"]

    @property
    def latent(self) -> list[float] | None:
        """The latent vector of a constant material; None when the latents are textures."""
        return self.record.get("latent")

    @property
    def latent_paths(self) -> tuple[Path, Path] | None:
        """The two latent textures; None for a constant material."""
        return None if self.latent is not None else (self.path / LATENT_FILES[0], self.path / LATENT_FILES[1])

    @property
    def energy_scale(self) -> Path | float:
        """The energy scale texture, or the scale of every texel."""
        scale = self.record["energy_scale"]
        return self.path / scale if isinstance(scale, str) else float(scale)

    @property
    def fit_error(self) -> FitError | None:
        """The fit's error; None where none was measured (the encoder alone, a generated material)."""
        error = self.record.get("fit_error")
        if not isinstance(error, dict) or not isinstance(error.get("mean"), (int, float)):
            return None
        name = error.get("map")
        return FitError(float(error["mean"]), self.path / name if isinstance(name, str) else None)


def read(folder: Path) -> NeuralFolder:
    """The folder's neural.json, checked: this format, the decoder digest, the latents and their files."""
    path = folder / RECORD
    record = read_record(path, "a neural material folder", "format", FORMAT, ("decoder_sha256", "energy_scale"))
    latent = record.get("latent")
    if latent is not None:
        if not isinstance(latent, list) or len(latent) != LATENT_CHANNELS:
            raise FormatError(f"{path}: 'latent' is not a list of {LATENT_CHANNELS} numbers")
        files = []
    else:
        files = list(LATENT_FILES)
    if isinstance(record["energy_scale"], str):
        files.append(record["energy_scale"])
    elif not isinstance(record["energy_scale"], (int, float)):
        raise FormatError(f"{path}: 'energy_scale' is neither a number nor a file name")
    missing = [f for f in files if not (folder / f).is_file()]
    if missing:
        raise FormatError(f"{path}: names {', '.join(missing)}, which the folder lacks")
    return NeuralFolder(folder, record)
