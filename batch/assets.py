"""The assets of a run: from a folder (recursively) or a list file, each with a stable id.

The id is a sanitised file stem plus a hash of the path as given relative to
the input, so names with spaces, unicode or ``../`` become one safe folder name
that cannot leave the output folder, and two ``chair.glb`` in different folders
stay apart.
"""
from __future__ import annotations

import hashlib
import os
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


@dataclass(frozen=True)
class Ignored:
    """An input file (or hidden folder) the run does not take as an asset, and why."""

    key: str  # as an asset's key: the path relative to the input folder
    reason: str
    sidecar: bool  # a texture, buffer or material file: read by the assets that refer to it


HIDDEN_FILE = "the name starts with a dot (a hidden file): not taken as an asset; rename it to render it"
HIDDEN_FOLDER = "the folder's name starts with a dot (a hidden folder): not searched"


def _walk(source: Path, skip: Path | None) -> tuple[list[Path], list[Ignored]]:
    """Files under ``source`` that may be assets, and what was passed over."""
    files: list[Path] = []
    ignored: list[Ignored] = []
    if skip is not None and source.resolve() == skip:
        return files, ignored
    for folder, subfolders, names in os.walk(source):
        here = Path(folder)
        kept = []
        for name in sorted(subfolders):
            path = here / name
            if skip is not None and path.resolve() == skip:
                continue
            if name.startswith("."):
                ignored.append(Ignored(path.relative_to(source).as_posix() + "/", HIDDEN_FOLDER, False))
            else:
                kept.append(name)
        subfolders[:] = kept
        for name in sorted(names):
            path = here / name
            key = path.relative_to(source).as_posix()
            if not path.is_file():
                continue
            if name.startswith("."):
                ignored.append(Ignored(key, HIDDEN_FILE, False))
            elif path.suffix.lower() in SIDECARS:
                ignored.append(Ignored(key, f"a {path.suffix.lower()} file: read by the asset that refers to it "
                                            "(texture, buffer, material library), not an asset itself", True))
            else:
                files.append(path)
    return sorted(files), sorted(ignored, key=lambda i: i.key)


def scan(source: Path, exclude: Path | None = None) -> tuple[list[Asset], list[Ignored]]:
    """Assets under a folder, or listed one per line in a file (``#`` comments, relative to the file), and
    the files of a folder that are not taken, each with its reason (hidden names, sidecar files).

    ``exclude`` (the output folder) is never searched, so an output inside the input
    folder does not turn rendered videos into assets on the next run.
    """
    ignored: list[Ignored] = []
    if source.is_dir():
        files, ignored = _walk(source, exclude.resolve() if exclude is not None else None)
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
    return assets, ignored


def collect(source: Path, exclude: Path | None = None) -> list[Asset]:
    """The assets of ``scan``."""
    return scan(source, exclude)[0]
