"""glTF 2.0 metal-rough materials as ``PbrInputs``, with numpy and the standard library only.

The materials are read from the parsed file (``gltf_container``) without torch, like the
rest of this package, and image decoding is injected (the backend passes PIL): a decoder takes the encoded
bytes and the MIME type and returns an ``(H, W)`` or ``(H, W, C)`` array (uint8,
uint16 or float in [0, 1]).

What is read, per material (glTF 2.0 section 3.9.2):
  base colour = sRGB->linear(baseColorTexture.rgb) * baseColorFactor.rgb
  roughness   = metallicRoughnessTexture.G * roughnessFactor
  metalness   = metallicRoughnessTexture.B * metallicFactor
A map without a texture (or with a zero factor) is a constant, never a texture.
Each image is decoded once, however many maps or materials share it (packed ORM).

KHR_texture_transform is recorded per texture slot (``TextureRef.transform``), not
baked: every enhanced parameter is a per-texel function of the input maps, so the
enhanced textures live in the same texture space as the inputs and whoever samples
them (MaterialX, Blender) applies the same transform. The UV rasteriser applies it to
UVs so that world-space data lands on the texels that are actually sampled.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

import numpy as np

from richmat_addon.core.colour import srgb_to_linear
from richmat_addon.core.maps import ParamMap, PbrInputs
from .gltf_container import GltfDocument, load_gltf, read_uri

ImageDecoder = Callable[[bytes, str], np.ndarray]


@dataclass(frozen=True)
class TextureTransform:
    """KHR_texture_transform: uv' = T(offset) R(rotation) S(scale) uv."""

    offset: tuple[float, float] = (0.0, 0.0)
    rotation: float = 0.0
    scale: tuple[float, float] = (1.0, 1.0)

    @property
    def is_identity(self) -> bool:
        return self.offset == (0.0, 0.0) and self.rotation == 0.0 and self.scale == (1.0, 1.0)

    def matrix(self) -> np.ndarray:
        """The 3x3 matrix of the extension specification (column-vector convention)."""
        c, s = np.cos(self.rotation), np.sin(self.rotation)
        return (np.array([[1, 0, self.offset[0]], [0, 1, self.offset[1]], [0, 0, 1]])
                @ np.array([[c, s, 0], [-s, c, 0], [0, 0, 1]])
                @ np.diag([self.scale[0], self.scale[1], 1.0]))

    def apply(self, uv: np.ndarray) -> np.ndarray:
        m = self.matrix()
        return (uv @ m[:2, :2].T + m[:2, 2]).astype(np.float32)

    def to_json(self) -> dict[str, Any]:
        return {"offset": list(self.offset), "rotation": self.rotation, "scale": list(self.scale)}


@dataclass(frozen=True)
class TextureRef:
    """One texture slot of a material: which image, which UV set, which transform."""

    texture: int
    image: int
    tex_coord: int = 0
    transform: TextureTransform | None = None


@dataclass
class GltfMaterial:
    """A material of the file: the PBR inputs plus what is needed to place them.

    ``index`` is None for glTF's default material (primitives without a material).
    ``textures`` maps slot names (base_color, metallic_roughness, normal, occlusion,
    emissive) to their references; only base colour and metal-rough are decoded here.
    """

    index: int | None
    pbr: PbrInputs
    textures: dict[str, TextureRef] = field(default_factory=dict)
    alpha_mode: str = "OPAQUE"
    double_sided: bool = False

    @property
    def resolution(self) -> tuple[int, int] | None:
        """The largest (H, W) among the textured PBR maps; None when all are constants."""
        shapes = [m.shape for m in (self.pbr.base_color, self.pbr.roughness, self.pbr.metalness)
                  if m.shape is not None]
        return max(shapes, key=lambda s: s[0] * s[1]) if shapes else None

    @property
    def placement(self) -> TextureRef | None:
        """The slot whose UV set and transform define the material's texture space."""
        return self.textures.get("base_color") or self.textures.get("metallic_roughness")


_SRGB_LUT = srgb_to_linear(np.arange(256) / 255.0)


def _to_float(img: np.ndarray, srgb: bool) -> np.ndarray:
    """Decoder output -> float32 (H, W, C) in [0, 1], linearised when ``srgb``."""
    img = np.asarray(img)
    if img.ndim == 2:
        img = img[:, :, None]
    if img.dtype == np.uint8 and srgb:
        return _SRGB_LUT[img]
    if img.dtype == np.uint8 or img.dtype == np.uint16:
        out = img.astype(np.float32) / float(np.iinfo(img.dtype).max)
    elif np.issubdtype(img.dtype, np.floating):
        out = img.astype(np.float32)
    else:
        raise TypeError(f"the image decoder returned {img.dtype}; expected uint8, uint16 or float")
    return srgb_to_linear(out) if srgb else out


def _sniff_mime(data: bytes) -> str | None:
    if data[:8] == b"\x89PNG\r\n\x1a\n":
        return "image/png"
    if data[:3] == b"\xff\xd8\xff":
        return "image/jpeg"
    return None


class _Images:
    """Decodes each image once (raw and linearised) however often it is referenced."""

    def __init__(self, doc: GltfDocument, decode: ImageDecoder) -> None:
        self.doc = doc
        self.decode = decode
        self.decoded: dict[int, np.ndarray] = {}
        self.floats: dict[tuple[int, bool], np.ndarray] = {}

    def get(self, index: int, srgb: bool) -> np.ndarray:
        key = (index, srgb)
        if key not in self.floats:
            if index not in self.decoded:
                self.decoded[index] = self._decode(index)
            self.floats[key] = _to_float(self.decoded[index], srgb)
        return self.floats[key]

    def _decode(self, index: int) -> np.ndarray:
        doc = self.doc
        image = doc.item("images", index, "a texture")
        what = f"images[{index}] ({image.get('name') or image.get('uri') or 'unnamed'})"
        if "bufferView" in image:
            data = bytes(doc.buffer_view(image["bufferView"], what))
        elif "uri" in image:
            data = read_uri(doc.path, image["uri"], what)
        else:
            raise doc.error(f"{what} has neither a bufferView nor a URI")
        mime = _sniff_mime(data)
        if mime is None:
            hint = " (a Git LFS pointer, not the image)" if data.startswith(b"version https://git-lfs") else ""
            raise doc.error(f"{what} is not a PNG or JPEG image{hint}")
        try:
            return self.decode(data, mime)
        except Exception as exc:  # decoders raise anything; report which image broke
            raise doc.error(f"{what} cannot be decoded ({type(exc).__name__}: {exc})") from None


def _texture_ref(doc: GltfDocument, info: dict[str, Any] | None, referrer: str) -> TextureRef | None:
    if info is None:
        return None
    tex_index = info.get("index")
    texture = doc.item("textures", tex_index, referrer)
    if "source" not in texture:
        raise doc.error(f"textures[{tex_index}] has no PNG/JPEG source "
                        f"(extensions: {', '.join(texture.get('extensions', {})) or 'none'})")
    doc.item("images", texture["source"], f"textures[{tex_index}]")
    tex_coord = int(info.get("texCoord", 0))
    ext = info.get("extensions", {}).get("KHR_texture_transform")
    transform = None
    if ext is not None:
        tex_coord = int(ext.get("texCoord", tex_coord))
        transform = TextureTransform(tuple(map(float, ext.get("offset", (0.0, 0.0)))),  # type: ignore[arg-type]
                                     float(ext.get("rotation", 0.0)),
                                     tuple(map(float, ext.get("scale", (1.0, 1.0)))))  # type: ignore[arg-type]
        transform = None if transform.is_identity else transform
    return TextureRef(tex_index, texture["source"], tex_coord, transform)


def _scaled(texture: np.ndarray | None, factor: np.ndarray) -> ParamMap:
    """texture * factor, a constant when there is no texture or the factor is zero."""
    if texture is None or not np.any(factor):
        return ParamMap(factor.astype(np.float32))
    return ParamMap(texture * factor).collapse()


def _material(doc: GltfDocument, images: _Images, index: int | None) -> GltfMaterial:
    mat = doc.item("materials", index, "a primitive") if index is not None else {}
    name = str(mat.get("name") or (f"material_{index}" if index is not None else "default"))
    referrer = f"materials[{index}] ({name})"
    pbr = mat.get("pbrMetallicRoughness", {})
    refs = {slot: _texture_ref(doc, info, referrer) for slot, info in (
        ("base_color", pbr.get("baseColorTexture")),
        ("metallic_roughness", pbr.get("metallicRoughnessTexture")),
        ("normal", mat.get("normalTexture")),
        ("occlusion", mat.get("occlusionTexture")),
        ("emissive", mat.get("emissiveTexture")))}
    textures = {k: v for k, v in refs.items() if v is not None}

    base_factor = np.asarray(pbr.get("baseColorFactor", (1.0, 1.0, 1.0, 1.0)), np.float32)[:3]
    bc = textures.get("base_color")
    bc_tex = _rgb(images.get(bc.image, srgb=True)) if bc else None
    mr = textures.get("metallic_roughness")
    mr_tex = _rgb(images.get(mr.image, srgb=False)) if mr else None
    return GltfMaterial(
        index=index,
        pbr=PbrInputs(
            name=name,
            base_color=_scaled(bc_tex, base_factor),
            roughness=_scaled(None if mr_tex is None else mr_tex[:, :, 1:2],
                              np.float32([pbr.get("roughnessFactor", 1.0)])),
            metalness=_scaled(None if mr_tex is None else mr_tex[:, :, 2:3],
                              np.float32([pbr.get("metallicFactor", 1.0)])),
        ),
        textures=textures,
        alpha_mode=str(mat.get("alphaMode", "OPAQUE")),
        double_sided=bool(mat.get("doubleSided", False)),
    )


def _rgb(img: np.ndarray) -> np.ndarray:
    """Grey, grey+alpha, RGB or RGBA -> RGB (a grey PNG is read as R = G = B)."""
    c = img.shape[2]
    return np.repeat(img[:, :, :1], 3, axis=2) if c < 3 else img[:, :, :3]


def uses_default_material(doc: GltfDocument) -> bool:
    """Whether some primitive has no material (glTF then uses the default material)."""
    return any("material" not in p for m in doc.json.get("meshes", []) for p in m.get("primitives", []))


def read_materials(source: str | Path | GltfDocument, decode: ImageDecoder) -> list[GltfMaterial]:
    """Every material of the file, in file order, plus glTF's default material when used."""
    doc = source if isinstance(source, GltfDocument) else load_gltf(source)
    images = _Images(doc, decode)
    with doc.checked():
        indices: list[int | None] = list(range(len(doc.json.get("materials", []))))
        if uses_default_material(doc):
            indices.append(None)
        return [_material(doc, images, i) for i in indices]
