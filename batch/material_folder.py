"""Read back an enhanced material folder (``params.json`` + EXRs) and its fitted latents.

No bpy: the render stage calls it after Blender's bundled OpenImageIO is
imported (OSL compilation needs that copy), the tests with PyPI's.
"""
from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from richmat_addon.core.maps import EnhancedMaterial, ParamMap
from richmat_addon.core.schema import PARAMS


def read_exr(path: Path) -> np.ndarray:
    import OpenImageIO as oiio

    buf = oiio.ImageBuf(str(path))
    if buf.has_error:
        raise ValueError(f"{path}: cannot read ({buf.geterror().strip()})")
    return np.asarray(buf.get_pixels(oiio.FLOAT), np.float32)


def load(folder: Path) -> tuple[EnhancedMaterial, dict[str, str], dict[str, Any]]:
    """The material, the files of its textured maps (by parameter name) and params.json."""
    record = json.loads((folder / "params.json").read_text(encoding="utf-8"))
    paths = {name: str(folder / file) for name, file in record["textures"].items()}
    maps: dict[str, ParamMap] = {}
    for name in ["base_color", *(p.name for p in PARAMS)]:
        if name in paths:
            maps[name] = ParamMap(read_exr(Path(paths[name])))
        else:
            maps[name] = ParamMap(np.atleast_1d(np.asarray(record["constants"][name], np.float32)))
    mat = EnhancedMaterial(record["material"], record["type"], record["seed"], maps.pop("base_color"), maps,
                           record["settings"])
    return mat, paths, record


def latents(folder: Path) -> tuple[list[str] | None, list[float] | None]:
    """The two latent texture files, or for a constant material the 6 latent values."""
    neural = json.loads((folder / "neural" / "neural.json").read_text(encoding="utf-8"))
    if "latent" in neural:
        return None, [float(x) for x in neural["latent"]]
    return [str(folder / "neural" / f"latent_{i}.exr") for i in (0, 1)], None
