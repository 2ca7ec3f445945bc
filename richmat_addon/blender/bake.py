"""Bake: the enhanced parameter maps at the inputs' full resolution, as EXR files.

A baked folder has the layout ``python -m torch_models enhance`` writes (one
half-float EXR per textured parameter, ``params.json`` with the constants,
``material.mtlx``), so the torch backend fits it as it is. Constants the user
edited in the panel (the Script node's unlinked sockets) override the sampled
ones. Each material bakes into its own folder, claimed by the material's id in
``params.json``: a folder claimed by another material is never written into.
"""
from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

import bpy
import numpy as np

from ..core import schema
from ..core.maps import EnhancedMaterial, ParamMap
from . import cycles_builder, uplift
from .osl_env import prefer_blender_bundled_modules
from .pbr_source import InputProblem

PARAMS_FORMAT = 1  # the params.json format of torch_models' enhance command
FOLDER_SUFFIX = "_richmat"


def output_root(scene: bpy.types.Scene) -> Path:
    """The chosen folder, or ``<blend name>_richmat`` beside the saved .blend file."""
    chosen = scene.richmat.output_dir
    if chosen:
        return Path(bpy.path.abspath(chosen)).resolve()
    if not bpy.data.filepath:
        raise InputProblem("save the .blend file first, or choose an output folder in the Richmat panel")
    blend = Path(bpy.data.filepath)
    return (blend.parent / f"{blend.stem}{FOLDER_SUFFIX}").resolve()


def claim_folder(root: Path, material: bpy.types.Material) -> Path:
    """``root/<clean name>[_n]``: this material's folder, never another material's."""
    stem = bpy.path.clean_name(material.name) or "material"
    n = 1
    while True:
        folder = (root / (stem if n == 1 else f"{stem}_{n}")).resolve()
        if folder.parent != root:
            raise InputProblem(f"material name {material.name!r} does not give a folder inside {root}")
        record = folder / "params.json"
        if not record.exists():
            return folder
        try:
            owner = json.loads(record.read_text()).get("material_uid")
        except (OSError, ValueError):
            owner = None
        if owner == material.richmat.uid:
            return folder
        n += 1


def write_exr(path: Path, value: np.ndarray) -> None:
    """An (H, W, C) map as a half-float ZIP EXR (top row first), written whole or not at all."""
    prefer_blender_bundled_modules()
    import OpenImageIO as oiio

    h, w, c = value.shape
    spec = oiio.ImageSpec(w, h, c, "half")
    spec.channelnames = ("Y",) if c == 1 else ("R", "G", "B", "A")[:c]
    spec.attribute("compression", "zip")
    tmp = path.with_name(f".{path.stem}.{os.getpid()}.tmp.exr")
    out = oiio.ImageOutput.create(str(tmp))
    try:
        if out is None or not out.open(str(tmp), spec) or \
                not out.write_image(np.ascontiguousarray(value, np.float32)):
            raise OSError(f"cannot write {path}: {oiio.geterror() or (out and out.geterror())}")
        out.close()
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)


def edited_constants(enhanced: bpy.types.Material | None) -> dict[str, ParamMap]:
    """Values of the Script node's unlinked parameter sockets (the panel edits them)."""
    script = enhanced.node_tree.nodes.get(cycles_builder.SCRIPT_NODE) if enhanced else None
    if script is None:
        return {}
    edits = {}
    for socket in script.inputs:
        param = schema.PARAM_BY_NAME.get(socket.name)
        if param is None or socket.is_linked:
            continue
        value = socket.default_value
        values = list(value)[:3] if param.channels == 3 else [value]
        edits[param.name] = ParamMap(np.clip(np.asarray(values, np.float32), param.lo, param.hi))
    return edits


def _plain(value: Any) -> Any:
    return value.item() if isinstance(value, np.generic) else value


def write_folder(folder: Path, mat: EnhancedMaterial, material: bpy.types.Material) -> dict[str, str]:
    """EXRs, material.mtlx, then params.json (its presence marks a complete folder)."""
    from ..core.mtlx import write_materialx  # imports MaterialX: Blender's bundled copy

    folder.mkdir(parents=True, exist_ok=True)
    textures, constants = {}, {}
    for name, pmap in {"base_color": mat.base_color, **mat.params}.items():
        file = folder / f"{name}.exr"
        if pmap.is_constant:
            values = [float(str(v)) for v in pmap.value]  # shortest float32 repr
            constants[name] = values[0] if pmap.channels == 1 else values
            file.unlink(missing_ok=True)
        else:
            write_exr(file, pmap.value)
            textures[name] = file.name
    write_materialx(mat, {k: str(folder / v) for k, v in textures.items()}, folder / "material.mtlx")
    record = {"format": PARAMS_FORMAT, "material": material.name, "material_uid": material.richmat.uid,
              "blend_file": bpy.data.filepath, "type": mat.type, "seed": mat.seed,
              "constants": constants, "textures": textures,
              "settings": {k: _plain(v) for k, v in mat.settings.items()}}
    (folder / "params.json").write_text(json.dumps(record, indent=2) + "\n", encoding="utf-8")
    return {k: str(folder / v) for k, v in textures.items()}


def bake(obj: bpy.types.Object, all_slots: bool, root: Path, relink: bool = True) -> list[str]:
    """Bake every enhanced slot into ``root``; with ``relink`` the material then uses the files."""
    plans = [p for p in uplift.plan(obj, all_slots) if p.original.richmat.enhanced is not None]
    if not plans:
        raise InputProblem(f"{obj.name!r} has no enhanced material; run Uplift first")
    lines = []
    for p in plans:
        enhanced = p.original.richmat.enhanced
        mat = uplift.enhance_slot(p, _requested(enhanced), enhanced.richmat.seed, max_size=None)
        mat.params.update(edited_constants(enhanced))
        folder = claim_folder(root, p.original)
        files = write_folder(folder, mat, p.original)
        if relink:
            rebuilt = uplift.build_enhanced(p, mat, files, json.loads(enhanced.richmat.record or "{}"))
            rebuilt.richmat.bake_dir = str(folder)
            rebuilt.richmat.neural_dir = enhanced.richmat.neural_dir
            uplift.install(p, rebuilt)
        else:
            enhanced.richmat.bake_dir = enhanced.richmat.bake_dir or str(folder)
        lines.append(f"{p.original.name}: {len(files)} maps -> {folder}")
    return lines


def _requested(enhanced: bpy.types.Material) -> str:
    """The type uplift resolved: bake repeats it exactly (never re-draws Auto)."""
    return str(enhanced.richmat.type)
