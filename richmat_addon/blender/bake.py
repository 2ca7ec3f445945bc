"""Bake: the enhanced parameter maps at the inputs' full resolution, as EXR files.

A baked folder has the layout ``python -m torch_models enhance`` writes (one
half-float EXR per textured parameter, ``params.json`` with the constants,
``material.mtlx``), so the torch backend fits it as it is. Constants the user
edited in the panel (the ``const_<parameter>`` nodes both graphs read) override
the sampled ones. Each material bakes into its own folder, claimed by the material's id in
``params.json``: a folder claimed by another material is never written into.
"""
from __future__ import annotations

import json
import tempfile
from pathlib import Path

import bpy
import numpy as np

from ..core import material_folder
from ..core.folder_io import FormatError
from ..core.maps import EnhancedMaterial, ParamMap
from . import cycles_builder, uplift
from .osl_env import prefer_blender_bundled_modules
from .pbr_source import InputProblem

FOLDER_SUFFIX = "_richmat"
UNSAVED_FOLDER = "richmat_unsaved"  # under the system's temporary folder, for a .blend never saved


def output_root(scene: bpy.types.Scene) -> Path:
    """The chosen folder, or ``<blend name>_richmat`` beside the saved .blend file, or for an unsaved
    file ``richmat_unsaved`` in the temporary folder (a first Bake never stops at a question of where)."""
    chosen = scene.richmat.output_dir
    if chosen:
        return Path(bpy.path.abspath(chosen)).resolve()
    if not bpy.data.filepath:
        return (Path(tempfile.gettempdir()) / UNSAVED_FOLDER).resolve()
    blend = Path(bpy.data.filepath)
    return (blend.parent / f"{blend.stem}{FOLDER_SUFFIX}").resolve()


def unsaved_note(scene: bpy.types.Scene) -> str:
    """What the report says when Bake wrote into the temporary folder: how to keep the maps."""
    if scene.richmat.output_dir or bpy.data.filepath:
        return ""
    return ("; the .blend is not saved, so the maps went to the temporary folder: choose a Folder in the "
            "Richmat panel (or save the file) and Bake again to keep them")


def claim_folder(root: Path, material: bpy.types.Material) -> Path:
    """``root/<clean name>[_n]``: this material's folder, never another material's."""
    stem = bpy.path.clean_name(material.name) or "material"
    n = 1
    while True:
        folder = (root / (stem if n == 1 else f"{stem}_{n}")).resolve()
        if folder.parent != root:
            raise InputProblem(f"material name {material.name!r} does not give a folder inside {root}")
        if not (folder / material_folder.RECORD).exists():
            return folder
        try:
            owner = material_folder.read(folder).record.get("material_uid")
        except (OSError, FormatError):  # another program's folder, or one an older richmat baked
            owner = None
        if owner == material.richmat.uid:
            return folder
        n += 1


def edited_constants(enhanced: bpy.types.Material | None) -> dict[str, ParamMap]:
    """Values of the material's constant parameter nodes (the panel edits them)."""
    edits = {}
    for param, socket in cycles_builder.constant_sockets(enhanced).items():
        value = socket.default_value
        values = list(value)[:3] if param.channels == 3 else [value]
        edits[param.name] = ParamMap(np.clip(np.asarray(values, np.float32), param.lo, param.hi))
    return edits


def write_folder(folder: Path, mat: EnhancedMaterial, material: bpy.types.Material) -> dict[str, str]:
    """The material's folder (``core.material_folder``), claimed by its id; returns the textures' paths."""
    prefer_blender_bundled_modules()  # OpenImageIO and MaterialX: Blender's bundled copies
    return material_folder.write(folder, mat, {"material": material.name, "material_uid": material.richmat.uid,
                                               "blend_file": bpy.data.filepath})


def bake(obj: bpy.types.Object, all_slots: bool, root: Path, relink: bool = True) -> list[str]:
    """Bake every enhanced slot into ``root``; with ``relink`` the material then uses the files."""
    plans = [p for p in uplift.plan(obj, all_slots) if p.original.richmat.enhanced is not None]
    if not plans:
        raise InputProblem(f"{obj.name!r} has no enhanced material; run Uplift first")
    lines = []
    for p in plans:
        enhanced = p.original.richmat.enhanced
        mat = uplift.enhance_slot(p, _requested(enhanced), enhanced.richmat.seed, None, enhanced.richmat.amount,
                                  enhanced.richmat.auto_touch, json.loads(enhanced.richmat.record or "{}").get("words"))
        mat.params.update(edited_constants(enhanced))
        folder = claim_folder(root, p.original)
        files = write_folder(folder, mat, p.original)
        if relink:
            rebuilt = uplift.build_enhanced(p, mat, files, json.loads(enhanced.richmat.record or "{}"),
                                            cycles_builder.cycles_graph(enhanced) or "native")
            rebuilt.richmat.bake_dir = str(folder)
            rebuilt.richmat.neural_dir = enhanced.richmat.neural_dir
            uplift.install(p, rebuilt)
        else:
            enhanced.richmat.bake_dir = enhanced.richmat.bake_dir or str(folder)
        lines.append(f"{p.original.name}: {len(files)} maps -> {folder}")
    return lines


def _requested(enhanced: bpy.types.Material) -> str:
    """The type uplift resolved: bake repeats it exactly (never re-draws Auto; its amount and touch too)."""
    return str(enhanced.richmat.type)
