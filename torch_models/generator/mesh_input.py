"""A user's mesh file as the generator needs it: Z up, in the unit cube, every material with its own
UVs and maps (base colour, and roughness and metalness where the file has them).

glTF/GLB goes through the farm's readers (``assets.gltf_container``, ``assets.gltf_materials``, ``assets.gltf_mesh``):
per material, base colour = factor x sRGB->linear(texture), roughness and metalness = factors x the
metallicRoughness texture's G and B (glTF 2.0 3.9.2); the triangles of every primitive placed by
the node hierarchy in Blender's Z-up frame (as batch imports them), with the UV set the material's
textures use and its KHR_texture_transform applied, so that a face's UVs address its material's
texels. External files are read only inside the asset's folder (``read_uri``). Other formats
(OBJ, PLY, STL) go through trimesh, (x, y, z) -> (x, -z, y), each part a material with its base
colour; their roughness and metalness are unknown, which the generator was trained to handle.

The mesh is centred and scaled into [-0.5, 0.5]^3 as batch's prepare stage does. Only a material
whose faces have no UVs, or whose texture space is stacked or tiled (covered more than
``MAX_UV_OVERLAP`` times over: a texel there has no one place on the surface), is unwrapped with
xatlas; its maps are then baked into the new UVs through the old ones (a tiled map through the mip
level the new texels span), not averaged away. Overlapping or mirrored UVs below that are kept and
said: a texel used at several places takes the views' evidence from each.
"""
from __future__ import annotations

from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import torch

from richmat_addon.core.colour import srgb_to_linear
from richmat_addon.core.enhance import METALLIC_THRESHOLD
from richmat_addon.core.maps import ParamMap, PbrInputs
from richmat_addon.core.prompt import Reading, base_over, keeps_base
from richmat_addon.core.uv_raster import MAX_UV_OVERLAP, rasterize as uv_rasterize, uv_area

from ..assets.gltf_container import read_uri
from ..assets.gltf_materials import TextureTransform
from .views import Mesh, sample_texture

MIN_TEXTURE = 8  # smallest latent texture side
BAKE_SIDE = 1024  # largest side of the maps baked into new UVs
OVERLAP_NOTED = 1.05  # UVs covering their texels more than this many times over are said to overlap (the raster
# counts texel centres, so thin islands read a few per cent of overlap that is not there)
ANALYSIS_SIDE = 256  # texels a side of the rasters that measure UV overlap


@dataclass
class MaterialInput:
    """One material: its maps in its own texture space, (H, W, C) images or (1, 1, C) constants."""

    name: str
    base_color: np.ndarray  # (H, W, 3) linear
    roughness_metalness: np.ndarray | None = None  # (H, W, 2); None where the file does not say
    record: dict[str, Any] = field(default_factory=dict)  # where it came from, for neural.json
    unwrapped: bool = False  # its UVs are xatlas's, not the file's

    @classmethod
    def from_pbr(cls, pbr: PbrInputs) -> "MaterialInput":
        """A material whose full PBR inputs are known (procedural objects, the demo)."""
        return cls(pbr.name, as_image(pbr.base_color), stack_maps(as_image(pbr.roughness), as_image(pbr.metalness)))

    @property
    def metallic(self) -> bool:
        """Whether the enhancer's metal rules apply (known only with the PBR maps)."""
        rm = self.roughness_metalness
        return rm is not None and float(rm[..., 1].mean()) > METALLIC_THRESHOLD

    @property
    def shape(self) -> tuple[int, int] | None:
        """The largest (H, W) of its textured maps; None when every map is a constant."""
        maps = [m for m in (self.base_color, self.roughness_metalness) if m is not None and m.shape[:2] != (1, 1)]
        return max((m.shape[:2] for m in maps), key=lambda s: s[0] * s[1]) if maps else None

    def texture_shape(self, largest: int) -> tuple[int, int]:
        """Its latent texture's (H, W): its maps' size, scaled to at most ``largest`` a side (the energy
        guard measures every texel), at least ``MIN_TEXTURE``; ``largest`` square for constant maps."""
        shape = self.shape or (largest, largest)
        scale = min(1.0, largest / max(shape))
        return tuple(max(MIN_TEXTURE, round(s * scale)) for s in shape)  # type: ignore[return-value]

    def maps_at(self, shape: tuple[int, int]) -> tuple[np.ndarray, np.ndarray | None]:
        """(base colour, roughness and metalness) at ``shape`` (area means: a texel holds what it covers)."""
        rm = self.roughness_metalness
        return resize(self.base_color, shape), None if rm is None else resize(rm, shape)


@dataclass
class MeshInput:
    """A mesh file's parts as one mesh, Z up in the unit cube, and its materials."""

    mesh: Mesh  # every part; face_material indexes ``materials``
    materials: list[MaterialInput]
    notes: list[str] = field(default_factory=list)  # what reading did (unwraps, unknown maps)
    warnings: list[str] = field(default_factory=list)  # what a user should know (overlapping UVs)

    @classmethod
    def from_pbr(cls, mesh: Mesh, pbr: PbrInputs) -> "MeshInput":
        """A one-material mesh whose full PBR material is known (procedural objects, the demo)."""
        return cls(mesh, [MaterialInput.from_pbr(pbr)])

    @property
    def metallic(self) -> bool:
        """Every material is a metal: the prompt's type then keeps off dielectric-only lobes."""
        return all(m.metallic for m in self.materials)

    @property
    def pbr_known(self) -> bool:
        return all(m.roughness_metalness is not None for m in self.materials)

    @property
    def unwrapped(self) -> bool:
        return any(m.unwrapped for m in self.materials)


def as_image(pmap: ParamMap) -> np.ndarray:
    """A parameter map's value as an (H, W, C) image; constants are 1 x 1."""
    value = pmap.value
    return (value if value.ndim == 3 else value.reshape(1, 1, -1)).astype(np.float32)


def resize(image: np.ndarray, size: tuple[int, int]) -> np.ndarray:
    """(h, w, C) image at ``size``: the mean of the texels each new texel covers when shrinking, the
    nearest texel when growing; a (1, 1, C) constant stays constant."""
    if image.shape[:2] in (tuple(size), (1, 1)):
        return image
    t = torch.from_numpy(np.ascontiguousarray(image, np.float32)).permute(2, 0, 1)[None]
    return torch.nn.functional.adaptive_avg_pool2d(t, size)[0].permute(1, 2, 0).numpy()


def stack_maps(roughness: np.ndarray, metalness: np.ndarray) -> np.ndarray:
    """(H, W, 2) from two single-channel images (H, W, 1) or (1, 1, 1); a smaller texture is
    resampled to the larger one's size."""
    size = max((m.shape[:2] for m in (roughness, metalness)), key=lambda s: s[0] * s[1])
    resized = [np.broadcast_to(resize(m, size), (*size, 1)) for m in (roughness, metalness)]
    return np.concatenate(resized, -1).astype(np.float32)


@dataclass
class _Part:
    """One material's triangles as read, before normalisation (Z up; UVs None where the file has none,
    and the texture transform that takes them to its maps' texels)."""

    material: MaterialInput
    positions: np.ndarray
    normals: np.ndarray
    uvs: np.ndarray | None
    faces: np.ndarray
    transform: TextureTransform | None = None


def load_mesh(path: Path) -> MeshInput:
    """The mesh file's parts and materials (module docstring)."""
    path = Path(path)
    gltf = path.suffix.lower() in (".glb", ".gltf")
    parts, notes = _gltf_parts(path) if gltf else _trimesh_parts(path)
    if not parts:
        raise ValueError(f"{path}: no triangles")
    return _assemble(parts, notes)


def _gltf_parts(path: Path) -> tuple[list[_Part], list[str]]:
    from ..assets.gltf_container import load_gltf
    from ..assets.gltf_materials import read_materials
    from ..assets.gltf_mesh import read_geometry

    from ..cli_enhance import pil_decode

    doc = load_gltf(path)
    materials = read_materials(doc, pil_decode)
    geometry = read_geometry(doc, {m.index: m.placement.tex_coord for m in materials if m.placement})
    parts, notes = [], []
    for mat in materials:
        geo = geometry.get(mat.index)
        if geo is None:
            continue  # no triangle uses it
        notes += [f"material {mat.pbr.name!r}: {n}" for n in geo.notes]
        record = {"material_index": mat.index, "uv_set": mat.placement.tex_coord if mat.placement else 0}
        pbr = mat.pbr
        material = MaterialInput(pbr.name, as_image(pbr.base_color),
                                 stack_maps(as_image(pbr.roughness), as_image(pbr.metalness)), record)
        parts.append(_Part(material, geo.positions, geo.normals, geo.uvs, geo.indices,
                           mat.placement.transform if mat.placement else None))
    return parts, notes


def _base_colour(part) -> np.ndarray:  # part: trimesh.Trimesh
    """(H, W, 3) or (1, 1, 3) linear base colour of a trimesh part: factor times texture."""
    material = getattr(part.visual, "material", None)
    if material is None:
        return np.full((1, 1, 3), 0.8, np.float32)
    factor = np.ones(3)
    if getattr(material, "baseColorFactor", None) is not None:
        factor = np.asarray(material.baseColorFactor[:3], np.float64) / 255.0
    texture = getattr(material, "baseColorTexture", None) or getattr(material, "image", None)
    if texture is None:
        return factor.reshape(1, 1, 3).astype(np.float32)
    return (factor * srgb_to_linear(np.asarray(texture.convert("RGB"), np.float64) / 255.0)).astype(np.float32)


def _trimesh_parts(path: Path) -> tuple[list[_Part], list[str]]:
    import trimesh

    scene = trimesh.load(str(path), force="scene", resolver=_MeshFolder(path))
    z_up = lambda a: np.stack([a[:, 0], -a[:, 2], a[:, 1]], 1)
    parts = []
    for i, part in enumerate(g for g in scene.dump() if isinstance(g, trimesh.Trimesh) and len(g.faces)):
        uv = getattr(part.visual, "uv", None)
        if uv is not None and len(uv) == len(part.vertices):
            uv = np.asarray(uv, np.float32).copy()
            uv[:, 1] = 1.0 - uv[:, 1]  # trimesh keeps v up; views.py counts v down (glTF)
        else:
            uv = None
        name = getattr(getattr(part.visual, "material", None), "name", None) or f"part_{i}"
        parts.append(_Part(MaterialInput(name, _base_colour(part)), z_up(np.asarray(part.vertices, np.float64)),
                           z_up(np.asarray(part.vertex_normals, np.float64)), uv,
                           np.asarray(part.faces, np.int64)))
    return parts, ["no roughness or metalness in the file: the prompt's material family and finish give them "
                   "where it names them, else they are unknown to the generator"]


class _MeshFolder(Mapping[str, bytes]):
    """trimesh's resolver for the files a mesh refers to (OBJ materials and textures): each is read
    by ``read_uri``, so a crafted file reads nothing outside its folder and nothing over the size cap."""

    def __init__(self, path: Path) -> None:
        self.path = path

    def __getitem__(self, name: str) -> bytes:
        return read_uri(self.path, name, "the mesh file")

    def __iter__(self) -> Iterator[str]:  # the folder is not listed: only named files are read
        return iter(())

    def __len__(self) -> int:
        return 0


def _assemble(parts: list[_Part], notes: list[str]) -> MeshInput:
    """Every part into the unit cube, in the texture space its latents will live in, concatenated."""
    lo = np.min([p.positions.min(0) for p in parts], 0)
    hi = np.max([p.positions.max(0) for p in parts], 0)
    centre, scale = (hi + lo) / 2, 1.0 / max(float((hi - lo).max()), 1e-12)
    meshes, warnings = [], []
    for part in parts:
        part.positions = (part.positions - centre) * scale
        note = _texture_space(part)
        if note:
            notes.append(f"material {part.material.name!r}: {note}")
        if not part.material.unwrapped:
            warnings += [f"material {part.material.name!r}: {w}" for w in _overlap(part.uvs, part.faces)]
        meshes.append(Mesh(part.positions.astype(np.float32), part.normals.astype(np.float32),
                           part.uvs.astype(np.float32), part.faces.astype(np.int64)))
    offsets = np.cumsum([0] + [len(m.positions) for m in meshes[:-1]])
    mesh = Mesh(np.concatenate([m.positions for m in meshes]), np.concatenate([m.normals for m in meshes]),
                np.concatenate([m.uvs for m in meshes]), np.concatenate([m.faces + o for m, o in zip(meshes, offsets)]),
                np.concatenate([np.full(len(m.faces), i, np.int64) for i, m in enumerate(meshes)]))
    return MeshInput(mesh, [p.material for p in parts], notes, warnings)


def _unusable_uvs(uvs: np.ndarray | None, faces: np.ndarray) -> str | None:
    """Why a part's UVs cannot hold its latents (None when they can)."""
    if uvs is None:
        return "no UVs"
    area = uv_area(uvs, faces)
    if not np.isfinite(area) or area <= 1e-12:
        return "UVs of zero or undefined area"
    if area > MAX_UV_OVERLAP:
        return f"its texture space is tiled or stacked ({area:.0f}x covered)"
    return None


def _overlap(uvs: np.ndarray, faces: np.ndarray) -> list[str]:
    """What to say about UVs that use texels more than once: the share, and whether mirrored
    halves share them (triangles of both windings on one texel)."""
    size = (ANALYSIS_SIDE, ANALYSIS_SIDE)
    covered = _uv_coverage(uvs, faces, size)
    if covered is None:
        return []
    times = uv_area(uvs, faces) * covered.size / max(int(covered.sum()), 1)
    if times <= OVERLAP_NOTED:
        return []
    a, b, c = (uvs[faces[:, k]].astype(np.float64) for k in range(3))
    winding = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (c[:, 0] - a[:, 0]) * (b[:, 1] - a[:, 1]) > 0
    halves = [_uv_coverage(uvs, faces[w], size) for w in (winding, ~winding)]
    both = 0.0 if any(h is None for h in halves) else float((halves[0] & halves[1]).sum() / covered.sum())
    mirrored = f"; {both:.0%} of them are used by mirrored halves" if both > 0.01 else ""
    return [f"its UVs overlap: they cover their texels {times:.2f} times over{mirrored}; such a texel "
            "takes the views' evidence from every place that uses it"]


def _uv_coverage(uvs: np.ndarray, faces: np.ndarray, size: tuple[int, int]) -> np.ndarray | None:
    """(H, W) bool: texels some triangle covers; None when none does."""
    if not len(faces):
        return None
    zeros = np.zeros((len(uvs), 3), np.float32)
    raster, _ = uv_rasterize(zeros, zeros, uvs, faces, size, padding=0)
    return None if raster is None else raster.coverage


def _texture_space(part: _Part) -> str:
    """Put ``part``'s UVs in the texture space its latents will live in; returns a note, or "".

    The maps' own texture space (the transformed UVs) where it can hold them; else the file's
    UVs, with the maps baked through the transform (a material tiled by KHR_texture_transform);
    else xatlas's, with the maps baked through whatever UVs there were."""
    transformed = None if part.uvs is None or part.transform is None else part.transform.apply(part.uvs)
    problem = _unusable_uvs(part.uvs if transformed is None else transformed, part.faces)
    if problem is None:
        if transformed is not None:
            part.uvs = transformed
            part.material.record["texture_transform"] = part.transform.to_json()
        return ""
    lookup = part.uvs if transformed is None else transformed
    if transformed is not None and _unusable_uvs(part.uvs, part.faces) is None:
        return problem + _bake(part, lookup, "the file's own UVs")
    import xatlas

    vmap, faces, uvs = xatlas.parametrize(part.positions.astype(np.float32), part.faces.astype(np.uint32))
    part.positions, part.normals, part.faces = part.positions[vmap], part.normals[vmap], faces.astype(np.int64)
    part.uvs = uvs.astype(np.float32)
    part.material.unwrapped = True
    return f"{problem}: unwrapped with xatlas" + _bake(part, None if lookup is None else lookup[vmap], "the new UVs")


def _bake(part: _Part, lookup: np.ndarray | None, into: str) -> str:
    """Bake the material's maps into ``part.uvs`` (``into`` names them for the note), read through
    ``lookup`` (the UVs per vertex that address the maps, None where there are none); returns what to
    add to the note."""
    material = part.material
    if material.shape is None:
        return ""  # constant maps: nothing to bake
    maps = (material.base_color, material.roughness_metalness)
    if lookup is None:
        material.base_color, material.roughness_metalness = (
            None if m is None else m.reshape(-1, m.shape[-1]).mean(0).reshape(1, 1, -1) for m in maps)
        return "; its textures had no UVs to be read through: their means are used"
    shape = tuple(min(s, BAKE_SIDE) for s in material.shape)
    carried = np.concatenate([lookup, np.zeros((len(lookup), 1), np.float32)], 1)  # rasterised as "positions"
    raster, reason = uv_rasterize(carried, part.normals, part.uvs, part.faces, shape)
    if raster is None:
        raise ValueError(f"cannot bake the maps of material {material.name!r}: {reason}")
    texels = torch.from_numpy(raster.positions[..., :2].copy())
    # the map's texels one new texel spans: a tiled map is read at the mip level of that footprint
    span = max(1.0, np.sqrt(uv_area(lookup, part.faces) / max(uv_area(part.uvs, part.faces), 1e-12))
               * max(material.shape) / max(shape))

    def bake(m: np.ndarray | None) -> np.ndarray | None:
        if m is None or m.shape[:2] == (1, 1):
            return m
        level = resize(m, tuple(max(1, round(s / span)) for s in m.shape[:2]))
        baked = sample_texture(level, texels).numpy()
        return np.where(raster.filled[..., None], baked, m.reshape(-1, m.shape[-1]).mean(0)).astype(np.float32)

    material.base_color, material.roughness_metalness = (bake(m) for m in maps)
    return f"; its maps baked into {into} at {shape[1]} x {shape[0]}"


def use_baked_material(inp: MeshInput, folder: Path) -> None:
    """Take the base colour, roughness and metalness of a baked enhanced-material folder (params.json).

    The add-on bakes the material it previews; generating against that same base
    colour keeps the latents and the preview's diffuse base in agreement, and its
    metalness lets the prompt's type follow the enhancer's rule for metals."""
    from richmat_addon.core import material_folder
    from richmat_addon.core.folder_io import FormatError

    if len(inp.materials) != 1:
        raise ValueError(f"--material is one baked material, and the mesh has {len(inp.materials)} materials")
    baked = material_folder.read(folder)
    exponent = baked.record["settings"].get("p")
    if exponent is None:
        raise FormatError(f"{folder}: params.json has no settings.p (roughness exponent); bake the material again")
    base, alpha, metal = (as_image(baked.map(name)) for name in ("base_color", "alpha_core", "metalness"))
    material = inp.materials[0]
    material.base_color = base[..., :3]
    # enhance: alpha_core = roughness^p
    material.roughness_metalness = stack_maps(alpha[..., :1] ** (1.0 / exponent), metal[..., :1])


def put_words_base(inp: MeshInput, reading: Reading, choice: str = "auto") -> None:
    """Put the base material the prompt names on each material (``prompt.base_over``): ``choice`` "auto"
    keeps a textured base colour and takes the words' on a one-colour (or absent) one, "mesh" and "words"
    decide for every material. Each change is noted (neural.json's notes)."""
    for material in inp.materials:
        keep = keeps_base(material.base_color, choice)
        rm = material.roughness_metalness
        rough0, metal0 = (None, None) if rm is None else (rm[..., :1], rm[..., 1:])
        base, rough, metal = base_over(reading, material.base_color, rough0, metal0, keep)
        said = []
        if base is not material.base_color:
            said.append(f"base colour {reading.colour_name}")
        if rough is not rough0 or metal is not metal0:
            said.append(f"roughness {float(rough.mean()):.2f} and metalness {float(metal.mean()):g}")
            material.roughness_metalness = stack_maps(rough, metal)
        material.base_color = base
        if said:
            inp.notes.append(f"material {material.name!r}: {' and '.join(said)} from the prompt's words")
