"""The enhanced material folder: the one writer and reader of its files.

A folder holds one half-float EXR per *textured* map (``<name>.exr``: the base
colour and the schema parameters), ``material.mtlx`` (textures referenced by
relative path) and ``params.json``: ``format``, ``schema_version`` (a fingerprint
of the parameter layout), the caller's fields (asset, material, ...), ``type``,
``seed``, ``constants`` (every untextured map), ``textures`` (map -> file) and
``settings``. ``params.json`` is written last, so its presence marks a complete
folder. ``enhance``, the farm's prepare stage, the demo and the add-on's Bake write
it; fit, generate, the farm's render stage and the add-on's previews read it.
"""
from __future__ import annotations

import hashlib
import unicodedata
from pathlib import Path
from typing import Any

import numpy as np

from . import schema
from .folder_io import CheckedFolder, FormatError, atomic_path, read_exr, read_record, write_exr, write_record
from .maps import EnhancedMaterial, ParamMap

RECORD = "params.json"
FORMAT = 1
MAP_NAMES = ("base_color", *(p.name for p in schema.PARAMS))
REQUIRED = ("type", "seed", "constants", "textures", "settings")


def schema_version() -> str:
    """A fingerprint of the parameter schema (names, channels, ranges, order).

    Readers compare it to refuse maps written for a different parameter layout.
    """
    text = ";".join(f"{p.name}:{p.channels}:{p.lo}:{p.hi}" for p in schema.PARAMS)
    return f"{schema.N_CHANNELS}ch-{hashlib.sha256(text.encode()).hexdigest()[:12]}"


_FORBIDDEN = frozenset('/\\:*?"<>|')
_RESERVED = frozenset({"CON", "PRN", "AUX", "NUL", *(f"{p}{i}" for p in ("COM", "LPT") for i in range(1, 10))})


def safe_name(name: str, taken: set[str], max_bytes: int = 120) -> str:
    """A folder name for a material that cannot leave its parent folder.

    Unicode stays; path separators, characters Windows forbids and control/format
    characters become ``_``; leading and trailing dots and spaces go (so no ``..``
    and no hidden folders); Windows device names get a ``_`` prefix; names that are
    equal ignoring case get ``_2``, ``_3``, ... (``taken`` holds casefolded names).
    """
    text = unicodedata.normalize("NFC", name)
    text = "".join("_" if c in _FORBIDDEN or unicodedata.category(c).startswith("C") else c for c in text)
    text = text.encode("utf-8")[:max_bytes].decode("utf-8", "ignore").strip(" .")
    if not text:
        text = "material"
    elif text.split(".")[0].upper() in _RESERVED:
        text = f"_{text}"
    unique, n = text, 2
    while unique.casefold() in taken:
        unique, n = f"{text}_{n}", n + 1
    taken.add(unique.casefold())
    return unique


def write(folder: Path, mat: EnhancedMaterial, fields: dict[str, Any]) -> dict[str, str]:
    """Textures, then material.mtlx, then params.json; stale EXRs of a previous run go.

    ``fields`` (asset, material, ...) go into params.json after the version fields.
    Returns the written textures' paths by map name.
    """
    from .mtlx import write_materialx  # imports MaterialX: inside Blender, its bundled copy

    folder.mkdir(parents=True, exist_ok=True)
    textures: dict[str, str] = {}
    constants: dict[str, Any] = {}
    maps = {"base_color": mat.base_color, **{p.name: mat.params[p.name] for p in schema.PARAMS}}
    for name, pmap in maps.items():
        file = folder / f"{name}.exr"
        if pmap.is_constant:
            values = [float(str(v)) for v in pmap.value]  # shortest float32 repr: 0.01, not 0.0099999
            constants[name] = values[0] if pmap.channels == 1 else values
            file.unlink(missing_ok=True)
        else:
            write_exr(file, pmap.value)
            textures[name] = file.name
    paths = {k: str(folder / v) for k, v in textures.items()}
    with atomic_path(folder / "material.mtlx") as tmp:  # written relative to the .mtlx folder
        write_materialx(mat, paths, tmp)
    record = {"format": FORMAT, "schema_version": schema_version(), **fields,
              "type": mat.type, "seed": mat.seed, "constants": constants, "textures": textures,
              "settings": mat.settings}
    write_record(folder / RECORD, record, indent=2)
    return paths


class MaterialFolder(CheckedFolder):
    """A checked material folder: its params.json and the maps it names."""

    @property
    def texture_paths(self) -> dict[str, Path]:
        """The textured maps' files by map name."""
        return {name: self.path / file for name, file in self.record["textures"].items()}

    def map(self, name: str) -> ParamMap:
        """A map by name (``base_color`` or a schema parameter): its texture or its constant."""
        file = self.record["textures"].get(name)
        if file is not None:
            return ParamMap(read_exr(self.path / file))
        return ParamMap(np.atleast_1d(np.asarray(self.record["constants"][name], np.float32)))

    def material(self) -> EnhancedMaterial:
        """The enhanced material the folder holds, every map loaded."""
        maps = {name: self.map(name) for name in MAP_NAMES}
        return EnhancedMaterial(self.record.get("material", self.path.name), self.record["type"],
                                self.record["seed"], maps.pop("base_color"), maps, self.record["settings"])


def read(folder: Path) -> MaterialFolder:
    """The folder's params.json, checked: this format and schema, every field and map present."""
    path = folder / RECORD
    record = read_record(path, "an enhanced material folder", "format", FORMAT, ("schema_version", *REQUIRED))
    if record["schema_version"] != schema_version():
        raise FormatError(f"{path}: schema_version is {record['schema_version']!r}, this richmat's parameters "
                          f"are {schema_version()!r}: enhance or bake the material again")
    for field in ("constants", "textures", "settings"):
        if not isinstance(record[field], dict):
            raise FormatError(f"{path}: {field!r} is not an object")
    missing = [n for n in MAP_NAMES if n not in record["textures"] and n not in record["constants"]]
    if missing:
        raise FormatError(f"{path}: no 'constants' or 'textures' entry for {', '.join(missing)}")
    return MaterialFolder(folder, record)
