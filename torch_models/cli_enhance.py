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
import io
from pathlib import Path
from typing import Any

import numpy as np
from tqdm import tqdm

from richmat_addon.core import material_folder
from richmat_addon.core.enhance import enhance, resolve_type
from richmat_addon.core.enhancement_types import DIELECTRIC_ONLY, DUST_TYPES, TYPES, index_ranges
from richmat_addon.core.maps import ParamMap
from richmat_addon.core.uv_raster import rasterize

from .assets.gltf_container import load_gltf
from .assets.gltf_materials import GltfMaterial, read_materials
from .assets.gltf_mesh import MeshGeometry, read_geometry
from .cli import InputError

HELP = "enhance the materials of a .glb/.gltf asset (textures, params.json, MaterialX)"

TYPE_CHOICES = tuple(str(t.index) for t in TYPES) + ("auto",)
# World-space data of a material whose PBR maps are all constants (but which has UVs):
# this size then sets the dust texture's resolution.
UNTEXTURED_RASTER_SIZE = (512, 512)


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


def pil_decode(data: bytes, mime: str) -> np.ndarray:
    """PNG/JPEG bytes -> uint8 or uint16 array, for ``read_materials``."""
    from PIL import Image

    img = Image.open(io.BytesIO(data))
    if img.mode.startswith("I"):  # 16-bit grey
        return np.asarray(img).astype(np.uint16)
    if img.mode not in ("L", "LA", "RGB", "RGBA"):
        img = img.convert("RGBA" if "A" in img.mode or "transparency" in img.info else "RGB")
    return np.asarray(img)


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
        folder = root / material_folder.safe_name(material.pbr.name, taken)
        if folder.resolve().parent != root:  # safe_name makes one plain component; `python -O` drops asserts
            raise InputError(f"{asset}: material {material.pbr.name!r} would be written to {folder}, "
                             f"outside the output folder {root}")
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
        material_folder.write(folder, mat, record)
    return 0
