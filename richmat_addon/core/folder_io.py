"""The files of richmat's output folders: half-float EXR maps and versioned JSON records.

Core (no bpy, no torch): the add-on, the torch backend and the farm scripts write
and read the same folders through ``material_folder`` and ``neural_folder``, which
build on this (as does ``torch_models.assets.dataset_index``, the index of a farm output). OpenImageIO is
imported inside the functions, so inside Blender its bundled copy serves (the add-on
makes sure that copy comes first). Every write goes to a temporary file that replaces
the target only when complete.
"""
from __future__ import annotations

import json
import os
import uuid
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Iterable, Iterator

import numpy as np


class FormatError(ValueError):
    """A folder an older richmat or another program wrote: the message names the file and the field."""


@dataclass(frozen=True)
class CheckedFolder:
    """A folder whose record was read and checked by its format's module."""

    path: Path
    record: dict[str, Any]


@contextmanager
def atomic_path(path: Path) -> Iterator[Path]:
    """A temporary path beside ``path`` that replaces it only if the block succeeds.

    The temporary name keeps the suffix, so writers that pick a format from the
    extension (OpenImageIO) still work, and the writer creates the file, so it gets
    the usual permissions. Readers never see a half-written file.
    """
    tmp = path.with_name(f".{path.stem}.{os.getpid()}-{uuid.uuid4().hex[:8]}.tmp{path.suffix}")
    try:
        yield tmp
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)


def write_exr(path: Path, value: np.ndarray) -> None:
    """An (H, W, C) map as a half-float ZIP EXR (top row first): 11 mantissa bits, below 8-bit inputs."""
    import OpenImageIO as oiio

    h, w, c = value.shape
    spec = oiio.ImageSpec(w, h, c, "half")
    spec.channelnames = ("Y",) if c == 1 else ("R", "G", "B", "A")[:c]
    spec.attribute("compression", "zip")
    with atomic_path(path) as tmp:
        out = oiio.ImageOutput.create(str(tmp))
        if out is None or not out.open(str(tmp), spec) or \
                not out.write_image(np.ascontiguousarray(value, np.float32)):
            raise OSError(f"cannot write {path}: {oiio.geterror() or (out and out.geterror())}")
        out.close()


def read_exr(path: Path) -> np.ndarray:
    """An image file as an (H, W, C) float32 array; a missing or broken file is a ValueError."""
    import OpenImageIO as oiio

    buf = oiio.ImageBuf(str(path))
    if buf.has_error:
        raise ValueError(f"{path}: cannot read ({buf.geterror().strip()})")
    return np.asarray(buf.get_pixels(oiio.FLOAT), np.float32)


def _jsonable(value: Any) -> Any:
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, Path):
        return str(value)
    raise TypeError(f"not JSON serialisable: {type(value).__name__}")


def write_record(path: Path, record: dict[str, Any], indent: int, sort_keys: bool = False) -> None:
    """A JSON record (numpy values and paths made plain), atomically."""
    text = json.dumps(record, indent=indent, sort_keys=sort_keys, ensure_ascii=False, default=_jsonable)
    with atomic_path(path) as tmp:
        tmp.write_text(text + "\n", encoding="utf-8")


def read_record(path: Path, what: str, version_field: str, version: object,
                required: Iterable[str] = ()) -> dict[str, Any]:
    """The JSON record at ``path`` if it has this ``version`` and every ``required`` field.

    ``what`` names the folder kind for the error ("an enhanced material folder").
    """
    if not path.is_file():
        raise FormatError(f"{path.parent}: not {what} (no {path.name})")
    try:
        record = json.loads(path.read_text(encoding="utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise FormatError(f"{path}: not a JSON record ({exc})") from None
    return check_record(record, str(path), version_field, version, required)


def check_record(record: Any, where: str, version_field: str, version: object,
                 required: Iterable[str] = (), fix: str = "write it again") -> dict[str, Any]:
    """``record`` if it is an object with this ``version`` and every ``required`` field.

    Shared by the one-record files and the dataset index's lines, so that all of them name
    the place (``where``) and the field the same way; ``fix`` says how to get a readable one.
    """
    if not isinstance(record, dict):
        raise FormatError(f"{where}: not a JSON object")
    if version_field not in record:
        raise FormatError(f"{where}: no {version_field!r} field; written by an older richmat or another "
                          f"program (this one reads {version_field} {version!r}): {fix}")
    if record[version_field] != version:
        raise FormatError(f"{where}: {version_field} is {record[version_field]!r}, this richmat reads "
                          f"{version!r}: {fix}")
    missing = [name for name in required if name not in record]
    if missing:
        raise FormatError(f"{where}: no {', '.join(repr(m) for m in missing)} field")
    return record
