"""The dataset index of a farm output: the one writer and reader of ``_index.jsonl``.

A trainer should not have to walk folders or know the per-asset layout, so a
``batch/render_dataset.py`` output carries one JSON Lines file with one object per
published asset, every line with the same fields (``json`` line by line, or a
dataframe library, reads it as a table): ``format``, ``asset_id``, ``source`` (the
asset's path relative to the input), ``caption``, ``enhancement_type`` (the asset's
drawn type), ``materials`` (per material ``name``, ``type``, ``parameters``: the
enhancement's settings, ``neural``: its neural material folder, ``latents``: the two
latent EXRs, empty for a constant material whose vector is in ``neural.json``),
``frames`` (beauty PNGs), ``intrinsics`` (multilayer EXRs), ``cameras`` and
``settings_hash``. Paths are relative to the index's folder, with ``/``. The leading
``_`` of its name is the output's mark of bookkeeping (``_ledger/``, ``_logs/``): every
other entry of the folder is an asset.

batch writes it (``batch/index.py``) from the published assets' manifests; the torch
loader (``torch_models/dataset.py``) reads it.
"""
from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Iterable

from richmat_addon.core import neural_folder
from richmat_addon.core.folder_io import FormatError, atomic_path, check_record

INDEX = "_index.jsonl"
FORMAT = 1
REQUIRED = ("asset_id", "source", "caption", "enhancement_type", "materials", "frames", "intrinsics",
            "cameras", "settings_hash")
MATERIAL_REQUIRED = ("name", "type", "parameters", "neural", "latents")
KINDS = ("frames", "intrinsics", "latents", "cameras")  # the kinds of file a record names


def rebuild_hint(root: Path) -> str:
    return f"rebuild it with `python batch/render_dataset.py --rebuild-index {root}`"


def record(*, asset_id: str, source: str, caption: str, enhancement_type: int,
           materials: list[dict[str, Any]], frames: list[str], intrinsics: list[str], cameras: str,
           settings_hash: str) -> dict[str, Any]:
    """One asset's line (the keywords are the format's fields, so a writer cannot leave one out)."""
    return {"format": FORMAT, "asset_id": asset_id, "source": source, "caption": caption,
            "enhancement_type": enhancement_type, "materials": materials, "frames": frames,
            "intrinsics": intrinsics, "cameras": cameras, "settings_hash": settings_hash}


def material(*, name: str, type: int, parameters: dict[str, Any], neural: str,
             latents: list[str]) -> dict[str, Any]:
    """One material of a record."""
    return {"name": name, "type": type, "parameters": parameters, "neural": neural, "latents": latents}


def write(path: Path, records: Iterable[dict[str, Any]]) -> None:
    """The records, sorted by asset id (the same assets give the same file), atomically.

    Concurrent writers (shards finishing together) each write their own temporary file
    and rename it into place, so a reader sees one writer's complete index, never a mix.
    """
    lines = [json.dumps(r, ensure_ascii=False) + "\n" for r in sorted(records, key=lambda r: r["asset_id"])]
    with atomic_path(path) as tmp:
        tmp.write_text("".join(lines), encoding="utf-8")


@dataclass(frozen=True)
class DatasetIndex:
    """A checked index: its file and its records, in file order."""

    path: Path
    records: list[dict[str, Any]]

    @property
    def root(self) -> Path:
        """The output folder the records' paths are relative to."""
        return self.path.parent

    def files(self, rec: dict[str, Any], kind: str) -> list[Path]:
        """The files of one ``kind`` (``KINDS``) that ``rec`` names; ``latents`` includes each
        material's neural.json, which a constant material's vector lives in."""
        if kind == "latents":
            names = [p for m in rec["materials"] for p in (f"{m['neural']}/{neural_folder.RECORD}", *m["latents"])]
        elif kind == "cameras":
            names = [rec["cameras"]]
        else:
            names = rec[kind]
        return [self.root / name for name in names]

    def check_files(self, kinds: Iterable[str]) -> None:
        """Raise FileNotFoundError naming every asset that lacks a file of these kinds."""
        kinds = list(kinds)
        unknown = sorted(set(kinds) - set(KINDS))
        if unknown:
            raise ValueError(f"unknown kinds {unknown}; an index names {', '.join(KINDS)}")
        lacking = []
        for rec in self.records:
            missing = [p for kind in kinds for p in self.files(rec, kind) if not p.is_file()]
            if missing:
                more = f" and {len(missing) - 1} more" if len(missing) > 1 else ""
                lacking.append(f"{rec['asset_id']}: {missing[0].relative_to(self.root).as_posix()}{more}")
        if lacking:
            raise FileNotFoundError(f"{self.path}: {len(lacking)} of {len(self.records)} assets lack files "
                                    f"({', '.join(kinds)}): " + "; ".join(lacking))


def read(path: Path) -> DatasetIndex:
    """The index at ``path`` (a file, or the output folder holding ``_index.jsonl``), every line checked."""
    if path.is_dir():
        path = path / INDEX
    if not path.is_file():
        raise FormatError(f"{path.parent}: no {path.name} (not a render_dataset.py output, or one from before "
                          f"the index): {rebuild_hint(path.parent)}")
    records = []
    for number, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
        where = f"{path}, line {number}"
        try:
            rec = json.loads(line)
        except json.JSONDecodeError as exc:
            raise FormatError(f"{where}: not JSON ({exc})") from None
        check_record(rec, where, "format", FORMAT, REQUIRED, fix=rebuild_hint(path.parent))
        for i, mat in enumerate(rec["materials"]):
            absent = [f for f in MATERIAL_REQUIRED if f not in mat]
            if absent:
                raise FormatError(f"{where}: no {', '.join(f'materials[{i}].{f}' for f in absent)} field")
        records.append(rec)
    return DatasetIndex(path, records)
