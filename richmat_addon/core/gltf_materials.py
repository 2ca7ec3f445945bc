"""glTF 2.0 metal-rough materials as ``PbrInputs``, with numpy and the standard library only.

The same code runs inside Blender (no pip packages there) and in the torch backend,
so the GLB container and the JSON are parsed here, and image decoding is injected:
Blender passes its own loader, the backend passes PIL. A decoder takes the encoded
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

import base64
import json
import os
import stat
import struct
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path, PurePosixPath, PureWindowsPath
from typing import Any, Callable, ContextManager, Iterator
from urllib.parse import unquote

import numpy as np

from .colour import srgb_to_linear
from .maps import ParamMap, PbrInputs

ImageDecoder = Callable[[bytes, str], np.ndarray]

_GLB_MAGIC = b"glTF"
_CHUNK_JSON = 0x4E4F534A
_CHUNK_BIN = 0x004E4942

# Required extensions whose absence from this reader still gives a correct base
# material: the transform is recorded, quantised accessors are read as normalised
# integers, and KHR_materials_* only add lobes on top of metal-rough.
_UNDERSTOOD_REQUIRED = frozenset({"KHR_texture_transform", "KHR_mesh_quantization"})
_NOT_METAL_ROUGH = frozenset({"KHR_materials_pbrSpecularGlossiness"})
# The largest external buffer or image read by URI: far above any real texture or
# mesh buffer, and a bound on what a crafted file can make a reader load.
MAX_URI_BYTES = 1 << 31


class GltfError(ValueError):
    """A glTF file this reader cannot use; the message names the file and the problem."""

    def __init__(self, path: str | Path, problem: str) -> None:
        super().__init__(f"{path}: {problem}")
        self.path = str(path)
        self.problem = problem


class MissingFile(GltfError):
    """An external file the glTF names (inside its folder) does not exist."""


@contextmanager
def checked(path: Path) -> Iterator[None]:
    """Turn what malformed JSON makes the readers trip over into a ``GltfError``.

    The readers index the JSON as the specification lays it out; a file that does
    not (a string where a number belongs, a missing required field) must still end
    in a clear error about the file, not a traceback.
    """
    try:
        yield
    except GltfError:
        raise
    except (KeyError, IndexError, TypeError, AttributeError, ValueError) as exc:
        raise GltfError(path, f"malformed glTF ({type(exc).__name__}: {exc})") from None


@dataclass
class GltfDocument:
    """The parsed JSON plus the raw bytes of every buffer."""

    path: Path
    json: dict[str, Any]
    buffers: list[bytes]

    def error(self, problem: str) -> GltfError:
        return GltfError(self.path, problem)

    def checked(self) -> ContextManager[None]:
        return checked(self.path)

    def item(self, kind: str, index: Any, referrer: str) -> dict[str, Any]:
        """``json[kind][index]``, with a clear error for a dangling reference."""
        items = self.json.get(kind, [])
        if not isinstance(index, int) or not 0 <= index < len(items):
            raise self.error(f"{referrer} refers to {kind}[{index}], which does not exist")
        return items[index]

    def buffer_view(self, index: int, referrer: str) -> memoryview:
        view = self.item("bufferViews", index, referrer)
        buf_index = view.get("buffer")
        self.item("buffers", buf_index, f"bufferViews[{index}]")
        data = self.buffers[buf_index]
        start = int(view.get("byteOffset", 0))
        end = start + int(view["byteLength"])
        if end > len(data):
            raise self.error(f"bufferViews[{index}] ends at byte {end} but buffer {buf_index} "
                             f"has {len(data)} bytes (truncated file?)")
        return memoryview(data)[start:end]


def load_gltf(path: str | Path) -> GltfDocument:
    """Parse a .glb or .gltf file and load its buffers (GLB chunk, data: URIs, files)."""
    path = Path(path)
    doc_json, bin_chunk = parse_file(path)
    with checked(path):
        _check_asset(path, doc_json)
        buffers = [_load_buffer(path, i, b, bin_chunk) for i, b in enumerate(doc_json.get("buffers", []))]
    return GltfDocument(path, doc_json, buffers)


def parse_file(path: Path) -> tuple[dict[str, Any], bytes | None]:
    """The JSON of a .gltf or .glb, and the GLB binary chunk if there is one (no URI is read)."""
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise GltfError(path, f"cannot read the file ({exc.strerror or exc})") from None
    if raw[:4] == _GLB_MAGIC:
        return _parse_glb(path, raw)
    return _parse_json(path, raw), None


def _parse_json(path: Path, raw: bytes) -> dict[str, Any]:
    try:
        doc = json.loads(raw.decode("utf-8-sig"))
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise GltfError(path, f"not a glTF file: neither the GLB magic nor valid JSON ({exc})") from None
    if not isinstance(doc, dict):
        raise GltfError(path, "the glTF JSON is not an object")
    return doc


def _parse_glb(path: Path, raw: bytes) -> tuple[dict[str, Any], bytes | None]:
    if len(raw) < 20:
        raise GltfError(path, f"truncated GLB: {len(raw)} bytes, shorter than its header")
    _, version, length = struct.unpack_from("<4sII", raw, 0)
    if version != 2:
        raise GltfError(path, f"unsupported GLB container version {version} (only 2 is supported)")
    if length != len(raw):
        kind = "truncated" if length > len(raw) else "corrupt"
        raise GltfError(path, f"{kind} GLB: the header says {length} bytes, the file has {len(raw)}")
    chunks: list[tuple[int, bytes]] = []
    offset = 12
    while offset < length:
        if offset + 8 > length:
            raise GltfError(path, f"corrupt GLB: chunk header at byte {offset} runs past the end")
        size, kind = struct.unpack_from("<II", raw, offset)
        if offset + 8 + size > length:
            raise GltfError(path, f"truncated GLB: chunk at byte {offset} needs {size} bytes, "
                                  f"only {length - offset - 8} remain")
        chunks.append((kind, raw[offset + 8: offset + 8 + size]))
        offset += 8 + size
    if not chunks or chunks[0][0] != _CHUNK_JSON:
        raise GltfError(path, "corrupt GLB: the first chunk is not JSON")
    bin_chunk = chunks[1][1] if len(chunks) > 1 and chunks[1][0] == _CHUNK_BIN else None
    return _parse_json(path, chunks[0][1].rstrip(b" \x00")), bin_chunk


def glb_bytes(doc: dict[str, Any], binary: bytes | None) -> bytes:
    """A GLB container of the JSON and the binary chunk (both padded to 4 bytes)."""
    js = json.dumps(doc).encode()
    js += b" " * (-len(js) % 4)
    chunks = struct.pack("<II", len(js), _CHUNK_JSON) + js
    if binary is not None:
        binary += b"\0" * (-len(binary) % 4)
        chunks += struct.pack("<II", len(binary), _CHUNK_BIN) + binary
    return struct.pack("<4sII", _GLB_MAGIC, 2, 12 + len(chunks)) + chunks


def _check_asset(path: Path, doc: dict[str, Any]) -> None:
    version = str(doc.get("asset", {}).get("version", ""))
    if not version.startswith("2."):
        raise GltfError(path, f"unsupported glTF version {version or '(missing)'!r} (only 2.x is supported)")
    required = set(doc.get("extensionsRequired", []))
    unsupported = sorted(e for e in required if e not in _UNDERSTOOD_REQUIRED
                         and (e in _NOT_METAL_ROUGH or not e.startswith("KHR_materials_")))
    if unsupported:
        raise GltfError(path, f"requires unsupported extension(s): {', '.join(unsupported)}")


def resolve_uri(path: Path, uri: str, what: str) -> Path:
    """The file an external URI of the glTF at ``path`` names, if the file may be read.

    A glTF is untrusted input: its URIs may only name regular files of at most
    ``MAX_URI_BYTES`` inside the asset's folder. Absolute paths, other schemes,
    ``..`` or symlinks leading out of the folder, devices and fifos are refused, so
    a crafted file can neither read other local files nor hang on /dev/zero."""
    name = unquote(uri)
    if (PurePosixPath(name).is_absolute() or PureWindowsPath(name).drive or PureWindowsPath(name).root
            or ":" in name.split("/")[0]):
        raise _refused(path, uri, what, "only relative paths inside the asset's folder are read")
    folder = path.parent.resolve()
    target = (folder / name).resolve()
    if not target.is_relative_to(folder):
        raise _refused(path, uri, what, f"it leads out of the asset's folder {folder} (to {target})")
    try:
        info = target.stat()
    except OSError:
        raise MissingFile(path, f"{what} refers to external file {uri!r}, which is missing "
                                f"(looked for {target})") from None
    if not stat.S_ISREG(info.st_mode):
        raise _refused(path, uri, what, f"{target} is not a regular file")
    if info.st_size > MAX_URI_BYTES:
        raise _refused(path, uri, what, f"{target} has {info.st_size} bytes, over the {MAX_URI_BYTES} byte cap")
    return target


def _refused(path: Path, uri: str, what: str, why: str) -> GltfError:
    return GltfError(path, f"{what} refers to {uri!r}, which is refused: {why}")


def read_uri(path: Path, uri: str, what: str) -> bytes:
    """Bytes of a data: URI, or of the file ``resolve_uri`` allows.

    The file is opened without following a final symlink or blocking on a fifo and
    checked again once open, so a swap after ``resolve_uri`` reads nothing either."""
    if uri.startswith("data:"):
        header, _, payload = uri.partition(",")
        if not header.endswith(";base64"):
            raise GltfError(path, f"{what} has a data: URI that is not base64")
        try:
            return base64.b64decode(payload, validate=True)
        except ValueError:
            raise GltfError(path, f"{what} has a corrupt base64 data: URI") from None
    target = resolve_uri(path, uri, what)
    flags = os.O_RDONLY | getattr(os, "O_BINARY", 0) | getattr(os, "O_NOFOLLOW", 0) | getattr(os, "O_NONBLOCK", 0)
    try:
        fd = os.open(target, flags)
    except OSError as exc:
        raise GltfError(path, f"{what}: cannot open {uri!r} ({exc.strerror or exc})") from None
    with os.fdopen(fd, "rb") as f:
        if not stat.S_ISREG(os.fstat(fd).st_mode):
            raise _refused(path, uri, what, f"{target} is not a regular file")
        data = f.read(MAX_URI_BYTES + 1)
    if len(data) > MAX_URI_BYTES:
        raise _refused(path, uri, what, f"{target} grew over the {MAX_URI_BYTES} byte cap")
    return data


def _load_buffer(path: Path, index: int, buf: dict[str, Any], bin_chunk: bytes | None) -> bytes:
    what = f"buffers[{index}]"
    if "uri" in buf:
        data = read_uri(path, buf["uri"], what)
    elif index == 0 and bin_chunk is not None:
        data = bin_chunk
    else:
        raise GltfError(path, f"{what} has no URI and there is no GLB binary chunk")
    if len(data) < int(buf.get("byteLength", 0)):
        raise GltfError(path, f"truncated {what}: {len(data)} bytes, byteLength says {buf['byteLength']}")
    return data


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
