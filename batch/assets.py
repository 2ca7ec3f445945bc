"""The assets of a run: from a folder (recursively) or a list file, each with a stable id.

The id is a sanitised file stem plus a hash of the path as given relative to
the input, so names with spaces, unicode or ``../`` become one safe folder name
that cannot leave the output folder, and two ``chair.glb`` in different folders
stay apart.
"""
from __future__ import annotations

import hashlib
from dataclasses import dataclass
from pathlib import Path

from richmat_addon.core.material_folder import safe_name

IMPORTABLE = frozenset({".glb", ".gltf", ".obj", ".fbx", ".ply", ".stl",
                        ".usd", ".usda", ".usdc", ".usdz", ".blend"})
# Files that belong to another asset (textures, buffers, OBJ materials): not assets themselves.
SIDECARS = frozenset({".png", ".jpg", ".jpeg", ".tga", ".bmp", ".tif", ".tiff", ".exr", ".hdr",
                      ".webp", ".ktx2", ".dds", ".bin", ".mtl", ".txt", ".md", ".json", ".blend1"})


@dataclass(frozen=True)
class Asset:
    path: Path  # the file as found (absolute)
    key: str  # the path relative to the input folder (or as listed): what the id hashes
    id: str  # output folder name: one safe path component

    @property
    def supported(self) -> bool:
        return self.path.suffix.lower() in IMPORTABLE


def asset_id(key: str) -> str:
    stem = Path(key.replace("\\", "/")).name
    stem = stem[: -len(Path(stem).suffix)] if Path(stem).suffix else stem
    digest = hashlib.sha256(key.encode("utf-8", "surrogateescape")).hexdigest()[:10]
    return f"{safe_name(stem, set(), max_bytes=80)}-{digest}"


def collect(source: Path, exclude: Path | None = None) -> list[Asset]:
    """Assets under a folder, or listed one per line in a file (``#`` comments, relative to the file).

    ``exclude`` (the output folder) is never searched, so an output inside the input
    folder does not turn rendered videos into assets on the next run.
    """
    if source.is_dir():
        skip = exclude.resolve() if exclude is not None else None
        files = sorted(p for p in source.rglob("*")
                       if p.is_file() and not any(part.startswith(".") for part in p.relative_to(source).parts)
                       and p.suffix.lower() not in SIDECARS
                       and (skip is None or skip not in p.resolve().parents))
        entries = [(p.resolve(), p.relative_to(source).as_posix()) for p in files]
    elif source.is_file():
        lines = [ln.strip() for ln in source.read_text(encoding="utf-8").splitlines()]
        entries = [((source.parent / ln).resolve(), ln) for ln in lines if ln and not ln.startswith("#")]
    else:
        raise FileNotFoundError(f"--input {source}: no such folder or list file")
    seen: set[str] = set()
    assets = []
    for path, key in entries:
        if key not in seen:
            seen.add(key)
            assets.append(Asset(path, key, asset_id(key)))
    return assets
