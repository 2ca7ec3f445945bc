"""The glTF 2.0 container: a .gltf's JSON or a .glb's chunks, and the buffers and files its URIs name.

Everything that reads a glTF (materials, meshes, the farm's import) starts here, with
the standard library only, so the farm's import in a stock Blender and the torch backend
parse files the same way. A glTF is untrusted input: every error names the file
(``GltfError``), and a URI may only name a regular file inside the asset's folder.
"""
from __future__ import annotations

import base64
import json
import os
import stat
import struct
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path, PurePosixPath, PureWindowsPath
from typing import Any, ContextManager, Iterator
from urllib.parse import unquote

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
