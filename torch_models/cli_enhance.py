"""Enhance every metal-rough material of a glTF asset and write textures + MaterialX.

For each material: read its PBR inputs, rasterise world normals and positions into its
texture space when the type has dust, enhance, and write into OUT/<material>/:
  <param>.exr     one per *textured* schema parameter (and base_color.exr when textured),
                  half float (ZIP): 11 mantissa bits, below the 8-bit inputs' quantisation;
  material.mtlx   the MaterialX graph, textures referenced by relative path;
  params.json     constants, settings, type (and any remap note), texture list,
                  schema version; written last, so its presence marks a complete material.
Material names are sanitised so nothing can be written outside OUT.
"""
from __future__ import annotations

import argparse
import hashlib
import io
import json
import unicodedata
from pathlib import Path
from typing import Any

import numpy as np
from tqdm import tqdm

from richmat_addon.core import schema
from richmat_addon.core.enhance import enhance, resolve_type
from richmat_addon.core.enhancement_types import DIELECTRIC_ONLY, DUST_TYPES, TYPES, index_ranges
from richmat_addon.core.gltf_materials import GltfMaterial, load_gltf, read_materials
from richmat_addon.core.gltf_mesh import MeshGeometry, read_geometry
from richmat_addon.core.maps import EnhancedMaterial, ParamMap
from richmat_addon.core.mtlx import write_materialx
from richmat_addon.core.uv_raster import rasterize

from .cli import InputError, atomic_path

HELP = "enhance the materials of a .glb/.gltf asset (textures, params.json, MaterialX)"

TYPE_CHOICES = tuple(str(t.index) for t in TYPES) + ("auto",)
# World-space data of a material whose PBR maps are all constants (but which has UVs):
# this size then sets the dust texture's resolution.
UNTEXTURED_RASTER_SIZE = (512, 512)
PARAMS_FORMAT = 1


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("asset", type=Path, help="a .glb or .gltf file")
    parser.add_argument("--type", choices=TYPE_CHOICES, default="auto",
                        help=f"enhancement type {index_ranges(range(len(TYPES)))}, "
                             "or auto (sampled from the dataset mix)")
    parser.add_argument("--seed", type=int, default=0,
                        help="seed; enhance mixes in the material name, as the add-on does")
    parser.add_argument("--out", type=Path, required=True, help="output folder")
    parser.add_argument("--on-metal", choices=("refuse", "remap"), default="refuse",
                        help=f"when a dielectric-only type ({index_ranges(DIELECTRIC_ONLY)}) meets a metallic "
                             "material: fail (default) or use the type resolve_type picks instead")


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


def pil_decode(data: bytes, mime: str) -> np.ndarray:
    """PNG/JPEG bytes -> uint8 or uint16 array, for ``read_materials``."""
    from PIL import Image

    img = Image.open(io.BytesIO(data))
    if img.mode.startswith("I"):  # 16-bit grey
        return np.asarray(img).astype(np.uint16)
    if img.mode not in ("L", "LA", "RGB", "RGBA"):
        img = img.convert("RGBA" if "A" in img.mode or "transparency" in img.info else "RGB")
    return np.asarray(img)


def write_exr(path: Path, value: np.ndarray) -> None:
    """An (H, W, C) float map as a half-float ZIP EXR, atomically."""
    import OpenImageIO as oiio

    h, w, c = value.shape
    spec = oiio.ImageSpec(w, h, c, "half")
    spec.channelnames = ("Y",) if c == 1 else ("R", "G", "B", "A")[:c]
    spec.attribute("compression", "zip")
    with atomic_path(path) as tmp:
        out = oiio.ImageOutput.create(str(tmp))
        if out is None or not out.open(str(tmp), spec) or not out.write_image(np.ascontiguousarray(value)):
            raise OSError(f"cannot write {path}: {oiio.geterror() or (out and out.geterror())}")
        out.close()


def _jsonable(value: Any) -> Any:
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, Path):
        return str(value)
    raise TypeError(f"not JSON serialisable: {type(value).__name__}")


def world_maps(material: GltfMaterial, geometry: MeshGeometry | None
               ) -> tuple[ParamMap | None, ParamMap | None, str | None]:
    """World normals/positions in the material's texture space, or a reason why not."""
    if geometry is None:
        return None, None, "no mesh uses this material"
    uvs = geometry.uvs
    placement = material.placement
    if uvs is not None and placement is not None and placement.transform is not None:
        uvs = placement.transform.apply(uvs)
    raster, reason = rasterize(geometry.positions, geometry.normals, uvs, geometry.indices,
                               material.resolution or UNTEXTURED_RASTER_SIZE)
    if raster is None:
        return None, None, reason
    return ParamMap(raster.normals), ParamMap(raster.positions), None


def _output_maps(mat: EnhancedMaterial) -> dict[str, ParamMap]:
    """Base colour then the schema parameters, in schema order."""
    return {"base_color": mat.base_color, **{p.name: mat.params[p.name] for p in schema.PARAMS}}


def write_material(folder: Path, mat: EnhancedMaterial, record: dict[str, Any]) -> None:
    """Textures, then material.mtlx, then params.json; stale EXRs of a previous run go."""
    folder.mkdir(parents=True, exist_ok=True)
    textures: dict[str, str] = {}
    constants: dict[str, Any] = {}
    for name, pmap in _output_maps(mat).items():
        file = folder / f"{name}.exr"
        if pmap.is_constant:
            values = [float(str(v)) for v in pmap.value]  # shortest float32 repr: 0.01, not 0.0099999
            constants[name] = values[0] if pmap.channels == 1 else values
            file.unlink(missing_ok=True)
        else:
            write_exr(file, pmap.value)
            textures[name] = file.name
    with atomic_path(folder / "material.mtlx") as tmp:  # written relative to the .mtlx folder
        write_materialx(mat, {k: str(folder / v) for k, v in textures.items()}, tmp)
    params = {"format": PARAMS_FORMAT, "schema_version": schema_version(), **record,
              "type": mat.type, "seed": mat.seed, "constants": constants, "textures": textures,
              "settings": mat.settings}
    with atomic_path(folder / "params.json") as tmp:
        tmp.write_text(json.dumps(params, indent=2, ensure_ascii=False, default=_jsonable) + "\n",
                       encoding="utf-8")


def run(args: argparse.Namespace) -> int:
    asset: Path = args.asset
    if not asset.is_file():
        raise InputError(f"{asset}: no such file")
    doc = load_gltf(asset)
    materials = read_materials(doc, pil_decode)
    if not materials:
        raise InputError(f"{asset}: the file has no materials")
    requested: int | str = args.type if args.type == "auto" else int(args.type)

    plan = []  # resolve every type first: a refusal must come before anything is written
    for material in materials:
        type_, note = resolve_type(material.pbr, requested, args.seed)
        if requested != "auto" and type_ != requested and args.on_metal == "refuse":
            raise InputError(f"{asset}: material {material.pbr.name!r}: type {requested} cannot be "
                             f"applied ({note}); pass --on-metal remap to accept type {type_}")
        plan.append((material, type_, note))

    geometry = None
    if any(type_ in DUST_TYPES for _, type_, _ in plan):
        geometry = read_geometry(doc, {m.index: m.placement.tex_coord for m in materials if m.placement})

    out: Path = args.out
    out.mkdir(parents=True, exist_ok=True)
    root = out.resolve()
    taken: set[str] = set()
    for material, type_, note in tqdm(plan, desc=asset.name, unit="material", disable=None):
        folder = root / safe_name(material.pbr.name, taken)
        assert folder.parent == root, folder  # safe_name guarantees one plain component
        record: dict[str, Any] = {"asset": asset.name, "material": material.pbr.name,
                                  "material_index": material.index, "requested_type": requested,
                                  "type_note": note, "alpha_mode": material.alpha_mode,
                                  "texture_transform": (material.placement.transform.to_json()
                                                        if material.placement and material.placement.transform
                                                        else None)}
        normals = positions = None
        if type_ in DUST_TYPES:
            geo = geometry.get(material.index) if geometry else None
            normals, positions, reason = world_maps(material, geo)
            record["world_maps"] = "rasterised" if reason is None else f"none: {reason}"
            record["geometry_notes"] = geo.notes if geo else []
        mat = enhance(material.pbr, type_, args.seed, world_normals=normals, world_positions=positions)
        write_material(folder, mat, record)
    return 0
