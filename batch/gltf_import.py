"""What Blender's glTF importer is given: the asset, or a copy without what Blender cannot use.

Blender's importer reads external URIs unchecked, refuses a file that requires
KHR_texture_basisu (it cannot decode KTX2), turns a texture whose image file is
missing into a blank image, and plays the file's animations, leaving each object
where the current frame puts it. So before Blender sees a .gltf/.glb:

* every external URI goes through ``resolve_uri``: one leading out of the asset's
  folder refuses the asset before anything is read, and so does a missing buffer;
* textures Blender cannot read (KTX2 without a PNG/JPEG fallback, missing image
  files) are dropped from the materials, which then use their factors;
* animations are left out: the file's own node transforms are the rest pose;
* the triangles the file's mesh nodes draw are counted from the JSON, so a huge
  mesh is refused without importing it.

When something has to go, Blender imports a copy written to a scratch folder
(external URIs made absolute, to the files already checked). Every change is a
note for the asset's manifest.
"""
from __future__ import annotations

import copy
import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any
from urllib.parse import quote

from torch_models.assets.gltf_container import MissingFile, checked, glb_bytes, parse_file, resolve_uri

BASISU = "KHR_texture_basisu"
TRIANGLES, TRIANGLE_STRIP, TRIANGLE_FAN = 4, 5, 6  # primitive modes that draw triangles


@dataclass
class GltfImport:
    path: Path  # the file for Blender's importer: the asset itself, or the copy
    triangles: int  # drawn by all mesh nodes (each instance counted)
    notes: list[str]


def _texture_infos(item: Any, path: str = "") -> list[tuple[str, dict[str, Any], str]]:
    """Every textureInfo under a material, as (its location, the dict holding it, its key)."""
    found = []
    if isinstance(item, dict):
        for key, value in item.items():
            if key.endswith("Texture") and isinstance(value, dict) and "index" in value:
                found.append((path + key, item, key))
            else:
                found += _texture_infos(value, f"{path}{key}.")
    return found


def checked_files(asset: Path, doc: dict[str, Any]) -> tuple[dict[tuple[str, int], Path], dict[int, str]]:
    """External files by (kind, index), and why each missing image is missing; raises for the rest."""
    files, missing = {}, {}
    for kind in ("buffers", "images"):
        for i, item in enumerate(doc.get(kind, [])):
            uri = item.get("uri")
            if uri is None or uri.startswith("data:"):
                continue
            try:
                files[kind, i] = resolve_uri(asset, uri, f"{kind}[{i}]")
            except MissingFile as error:
                if kind == "buffers":  # no geometry without it
                    raise
                missing[i] = error.problem
    return files, missing


def _unreadable_textures(doc: dict[str, Any], missing: dict[int, str], notes: list[str]) -> dict[int, str]:
    """Why each texture Blender cannot read is unreadable; notes the KTX2 ones a fallback replaces."""
    images = doc.get("images", [])
    unreadable = {}
    for t, texture in enumerate(doc.get("textures", [])):
        source = texture.get("source")
        if source in missing:
            unreadable[t] = missing[source]
        elif BASISU in texture.get("extensions", {}):
            if source is None:
                unreadable[t] = f"{BASISU} texture {t}: Blender cannot read KTX2 and the file has no PNG/JPEG fallback"
            else:
                name = images[source].get("name") or images[source].get("uri") or "unnamed"
                notes.append(f"{BASISU} texture {t}: Blender cannot read KTX2; used the fallback image "
                             f"images[{source}] ({name!r})")
    return unreadable


def triangle_count(doc: dict[str, Any]) -> int:
    """Triangles the mesh nodes draw: each node instancing a mesh counts all its primitives."""
    accessors, meshes = doc.get("accessors", []), doc.get("meshes", [])
    total = 0
    for node in doc.get("nodes", []):
        for prim in meshes[node["mesh"]]["primitives"] if "mesh" in node else []:
            source = prim["indices"] if "indices" in prim else prim["attributes"]["POSITION"]
            count, mode = accessors[source]["count"], prim.get("mode", TRIANGLES)
            if mode == TRIANGLES:
                total += count // 3
            elif mode in (TRIANGLE_STRIP, TRIANGLE_FAN):
                total += max(count - 2, 0)
    return total


def prepare(asset: Path, scratch: Path) -> GltfImport:
    """Check the asset's URIs and count its triangles; write the copy Blender imports when one is needed.

    Raises ``GltfError`` for a refused or missing external file (nothing read) and a
    malformed file.
    """
    doc, binary = parse_file(asset)
    notes: list[str] = []
    with checked(asset):
        files, missing = checked_files(asset, doc)
        unreadable = _unreadable_textures(doc, missing, notes)
        triangles = triangle_count(doc)
        patched = copy.deepcopy(doc)
        for material in patched.get("materials", []):
            for where, holder, key in _texture_infos(material):
                texture = holder[key]["index"]
                if texture in unreadable:
                    del holder[key]
                    notes.append(f"{unreadable[texture]}: dropped from {where} of material "
                                 f"{material.get('name', 'unnamed')!r} (its factor is used)")
        animations = patched.pop("animations", [])
    needed = bool(unreadable or animations or BASISU in doc.get("extensionsRequired", []))
    if animations:
        notes.append(f"{len(animations)} animation(s) in the file not imported: rendered in the rest pose")
    if not needed:
        return GltfImport(asset, triangles, notes)
    patched["extensionsRequired"] = [e for e in patched.get("extensionsRequired", []) if e != BASISU]
    for (kind, i), path in files.items():
        patched[kind][i]["uri"] = quote(str(path))
    copy_path = scratch / ("asset.glb" if binary is not None or asset.suffix.lower() == ".glb" else "asset.gltf")
    if copy_path.suffix == ".glb":
        copy_path.write_bytes(glb_bytes(patched, binary))
    else:
        copy_path.write_text(json.dumps(patched), encoding="utf-8")
    return GltfImport(copy_path, triangles, notes)
