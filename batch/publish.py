"""Atomic per-asset output: work in ``<id>.partial/``, write ``manifest.json`` last, rename.

A folder named ``<id>`` always holds a complete asset: the rename of the
finished ``.partial`` folder is atomic on one filesystem, and the manifest
inside it (file hashes, settings hash, timings) is written after everything
else. A run killed at any moment leaves only ``.partial`` folders, which the
next run deletes and redoes.
"""
from __future__ import annotations

import hashlib
import json
import os
import shutil
import uuid
from glob import escape as glob_escape
from pathlib import Path
from typing import Any

MANIFEST = "manifest.json"
PARTIAL = ".partial"


def final_dir(output: Path, asset_id: str) -> Path:
    path = output / asset_id
    if path.resolve().parent != output.resolve():  # ids are one safe component; never write elsewhere
        raise ValueError(f"asset id {asset_id!r} would leave {output}")
    return path


def partial_dir(output: Path, asset_id: str) -> Path:
    return final_dir(output, asset_id).with_name(asset_id + PARTIAL)


def fresh_partial(output: Path, asset_id: str) -> Path:
    """An empty work folder for the asset; a leftover from a killed run is discarded."""
    path = partial_dir(output, asset_id)
    for stale in [path, *output.glob(f"{glob_escape(asset_id)}.old-*{PARTIAL}")]:
        shutil.rmtree(stale, ignore_errors=True)
    path.mkdir(parents=True)
    return path


def read_manifest(folder: Path) -> dict[str, Any] | None:
    try:
        return json.loads((folder / MANIFEST).read_text(encoding="utf-8"))
    except (OSError, json.JSONDecodeError):
        return None


def is_done(output: Path, asset_id: str, settings_hash: str) -> bool:
    manifest = read_manifest(final_dir(output, asset_id))
    return manifest is not None and manifest.get("settings_hash") == settings_hash


def file_hashes(folder: Path) -> dict[str, str]:
    hashes = {}
    for path in sorted(p for p in folder.rglob("*") if p.is_file()):
        h = hashlib.sha256()
        with path.open("rb") as f:
            for block in iter(lambda: f.read(1 << 20), b""):
                h.update(block)
        hashes[path.relative_to(folder).as_posix()] = h.hexdigest()
    return hashes


def _fsync(path: Path) -> None:
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def publish(output: Path, asset_id: str, manifest: dict[str, Any]) -> Path:
    """Hash the partial folder's files, write the manifest last, and rename the folder into place."""
    partial, final = partial_dir(output, asset_id), final_dir(output, asset_id)
    manifest = {**manifest, "files": file_hashes(partial)}
    for path in partial.rglob("*"):
        if path.is_file():
            _fsync(path)
    tmp = partial / f".{MANIFEST}.tmp"
    tmp.write_text(json.dumps(manifest, indent=1, ensure_ascii=False, default=str), encoding="utf-8")
    _fsync(tmp)
    os.replace(tmp, partial / MANIFEST)
    if final.exists():  # an older render (other settings): move it aside, then swap in the new one
        old = final.with_name(f"{asset_id}.old-{uuid.uuid4().hex[:8]}{PARTIAL}")
        os.rename(final, old)
        os.rename(partial, final)
        shutil.rmtree(old, ignore_errors=True)
    else:
        os.rename(partial, final)
    _fsync(output)
    return final
