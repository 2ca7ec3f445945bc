"""The output's dataset index (``torch_models/assets/dataset_index.py``), made from the published assets' manifests.

The manifests are the truth about what is published, so the index is never
updated in place: every run's end (and ``--rebuild-index``) lists them again and
writes the whole file. Shards sharing an output each do so; see ``write``.
"""
from __future__ import annotations

from pathlib import Path
from typing import Any

from richmat_addon.core import neural_folder
from torch_models.assets import dataset_index

from .publish import PARTIAL, read_manifest


def record_of(folder: str, manifest: dict[str, Any]) -> dict[str, Any]:
    """The index line of the asset published in ``folder`` (its name in the output), from its manifest."""
    files = manifest.get("files", {})
    materials = []
    for mat in manifest["materials"]:
        neural = f"materials/{mat['folder']}/neural"
        latents = [f"{folder}/{neural}/{n}" for n in neural_folder.LATENT_FILES if f"{neural}/{n}" in files]
        materials.append(dataset_index.material(name=mat["name"], type=mat["type"], parameters=mat["settings"],
                                                neural=f"{folder}/{neural}", latents=latents))
    frames = manifest.get("frames") or []
    return dataset_index.record(
        asset_id=manifest["asset_id"], source=manifest["source"], caption=manifest["caption"],
        enhancement_type=manifest["enhancement_type"], materials=materials,
        frames=[f"{folder}/{f['beauty']}" for f in frames],
        intrinsics=[f"{folder}/{f['intrinsics']}" for f in frames],
        cameras=f"{folder}/cameras.json", settings_hash=manifest["settings_hash"])


def published_records(output: Path) -> list[dict[str, Any]]:
    """A record per published asset: a folder with a manifest, other than an unfinished ``.partial``
    one (whose manifest may be written already: the rename comes after it)."""
    records = []
    for folder in sorted(p for p in output.iterdir() if p.is_dir() and not p.name.endswith(PARTIAL)):
        manifest = read_manifest(folder)
        if manifest is not None:
            records.append(record_of(folder.name, manifest))
    return records


def write(output: Path) -> list[dict[str, Any]]:
    """Write ``output/_index.jsonl`` from the published assets; returns its records.

    Shards finishing together may each write it. The rename is atomic, so the file is
    always one writer's complete index; and since a writer lists the folders before its
    rename, it checks the listing again afterwards and rewrites when something was
    published meanwhile: the last rename then covers every asset published before it.
    """
    records = published_records(output)
    while True:
        dataset_index.write(output / dataset_index.INDEX, records)
        again = published_records(output)
        if again == records:
            return records
        records = again
