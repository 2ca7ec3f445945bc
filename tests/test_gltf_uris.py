"""External glTF URIs are read only inside the asset's folder, from regular files under a size cap.

Every reader of buffers and images by URI goes through ``gltf_container.resolve_uri``:
the material/geometry reader, the generator's mesh input (trimesh's resolver) and
batch's check before Blender's importer. Each crafted file below must be refused
with an error naming the URI, and the file it points at must never be opened.
"""
from __future__ import annotations

import base64
import json
import os
from pathlib import Path
from typing import Any, Callable

import numpy as np
import pytest

from batch.gltf_import import checked_files, prepare
from tests.test_gltf_io import base_color_image, pil_decode, png
from torch_models.assets import gltf_container
from torch_models.assets.gltf_container import GltfError, load_gltf, parse_file
from torch_models.assets.gltf_materials import read_materials

Craft = Callable[[Path], str]  # makes what the URI points at inside tmp_path; returns the URI


def _outside(tmp: Path) -> Path:
    """A readable PNG outside the asset's folder: what a crafted URI is after."""
    secret = tmp / "outside" / "secret.png"
    secret.parent.mkdir(exist_ok=True)
    secret.write_bytes(png(base_color_image()))
    return secret


def _symlink_out(tmp: Path) -> str:
    (tmp / "asset" / "link.png").symlink_to(_outside(tmp))
    return "link.png"


def _symlinked_folder_out(tmp: Path) -> str:
    (tmp / "asset" / "textures").symlink_to(_outside(tmp).parent, target_is_directory=True)
    return "textures/secret.png"


def _fifo(tmp: Path) -> str:
    os.mkfifo(tmp / "asset" / "pipe.png")  # opening it for reading would block until a writer comes
    return "pipe.png"


CRAFTED: dict[str, Craft] = {
    "absolute path": lambda tmp: str(_outside(tmp)),
    "file: URI": lambda tmp: _outside(tmp).as_uri(),
    "../ escape": lambda tmp: (_outside(tmp), "../outside/secret.png")[1],
    "escape hidden in a subfolder": lambda tmp: (_outside(tmp), "sub/../../outside/secret.png")[1],
    "percent-encoded ../": lambda tmp: (_outside(tmp), "%2E%2E/outside/secret.png")[1],
    "/dev/zero": lambda tmp: "/dev/zero",
    "symlink leading outside": _symlink_out,
    "symlinked folder leading outside": _symlinked_folder_out,
    "fifo": _fifo,
}


def _asset(tmp: Path, image_uri: str | None = None, buffer_uri: str | None = None) -> Path:
    """A .gltf with one material whose base colour image, or one buffer, has the given URI."""
    doc: dict[str, Any] = {"asset": {"version": "2.0"}}
    if image_uri is not None:
        doc.update(materials=[{"name": "m", "pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}],
                   textures=[{"source": 0}], images=[{"uri": image_uri}])
    if buffer_uri is not None:
        doc["buffers"] = [{"uri": buffer_uri, "byteLength": 4}]
    gltf = tmp / "asset" / "crafted.gltf"
    gltf.write_text(json.dumps(doc))
    return gltf


@pytest.fixture
def opened(monkeypatch: pytest.MonkeyPatch) -> list[str]:
    """Every path the reader opens with ``os.open`` (how ``read_uri`` opens files)."""
    paths: list[str] = []
    real_open = os.open

    def spy(path: Any, *args: Any, **kwargs: Any) -> int:
        paths.append(os.fspath(path))
        return real_open(path, *args, **kwargs)

    monkeypatch.setattr(os, "open", spy)
    return paths


@pytest.fixture
def asset_dir(tmp_path: Path) -> Path:
    (tmp_path / "asset").mkdir()
    return tmp_path


@pytest.mark.parametrize("craft", CRAFTED.values(), ids=CRAFTED.keys())
def test_crafted_image_uri_is_refused_and_nothing_read(asset_dir: Path, craft: Craft, opened: list[str]) -> None:
    uri = craft(asset_dir)
    gltf = _asset(asset_dir, image_uri=uri)
    with pytest.raises(GltfError, match="which is refused") as err:
        read_materials(gltf, pil_decode)
    assert repr(uri) in str(err.value) and str(gltf) in str(err.value)
    assert opened == []
    with pytest.raises(GltfError, match="which is refused"):
        prepare(gltf, asset_dir)  # what batch checks before Blender's importer
    assert opened == []


@pytest.mark.parametrize("craft", CRAFTED.values(), ids=CRAFTED.keys())
def test_crafted_buffer_uri_is_refused_and_nothing_read(asset_dir: Path, craft: Craft, opened: list[str]) -> None:
    uri = craft(asset_dir)
    with pytest.raises(GltfError, match=r"buffers\[0\] refers to .*which is refused"):
        load_gltf(_asset(asset_dir, buffer_uri=uri))
    assert opened == []


def test_file_over_the_cap_is_refused(asset_dir: Path, opened: list[str], monkeypatch: pytest.MonkeyPatch) -> None:
    (asset_dir / "asset" / "big.bin").write_bytes(bytes(64))
    gltf = _asset(asset_dir, buffer_uri="big.bin")
    assert len(load_gltf(gltf).buffers[0]) == 64
    opened.clear()
    monkeypatch.setattr(gltf_container, "MAX_URI_BYTES", 63)
    with pytest.raises(GltfError, match=r"'big.bin', which is refused: .* 64 bytes, over the 63 byte cap"):
        load_gltf(gltf)
    assert opened == []


def test_files_inside_the_folder_and_data_uris_are_read(asset_dir: Path) -> None:
    image = png(base_color_image())
    (asset_dir / "asset" / "textures").mkdir()
    (asset_dir / "asset" / "textures" / "base colour.png").write_bytes(image)
    (asset_dir / "asset" / "buf.bin").write_bytes(b"\x01\x02\x03\x04")
    gltf = _asset(asset_dir, image_uri="textures/../textures/base%20colour.png", buffer_uri="buf.bin")
    (mat,) = read_materials(gltf, pil_decode)
    assert mat.pbr.base_color.shape == (8, 8)
    assert load_gltf(gltf).buffers == [b"\x01\x02\x03\x04"]
    assert checked_files(gltf, parse_file(gltf)[0]) == ({("buffers", 0): asset_dir / "asset" / "buf.bin",
                                                         ("images", 0): asset_dir / "asset" / "textures" /
                                                         "base colour.png"}, {})
    inline = _asset(asset_dir, image_uri="data:image/png;base64," + base64.b64encode(image).decode())
    (mat,) = read_materials(inline, pil_decode)
    np.testing.assert_allclose(mat.pbr.base_color.value, read_materials(gltf, pil_decode)[0].pbr.base_color.value)
    assert checked_files(inline, parse_file(inline)[0]) == ({}, {})


@pytest.mark.parametrize("name", ["../ escape", "/dev/zero", "fifo"])
def test_generator_mesh_input_refuses_crafted_buffers(asset_dir: Path, name: str, opened: list[str]) -> None:
    """trimesh reads the mesh's files through the same resolver."""
    from torch_models.generator.mesh_input import load_mesh

    uri = CRAFTED[name](asset_dir)
    gltf = _asset(asset_dir, buffer_uri=uri)
    with pytest.raises(GltfError, match="which is refused"):
        load_mesh(gltf)
    assert opened == []


def test_batch_refuses_before_blenders_importer(asset_dir: Path, blender_run: Callable[..., Any]) -> None:
    """Blender's glTF importer resolves URIs itself: batch checks them first and reports the asset."""
    gltf = _asset(asset_dir, image_uri=CRAFTED["../ escape"](asset_dir))
    reason = blender_run(f"""
import json
from pathlib import Path
from batch import bl_scene
bl_scene.empty_scene()
try:
    bl_scene.import_asset(Path({str(gltf)!r}), max_triangles=1000)
    print("RESULT " + json.dumps("imported"))
except bl_scene.BadAsset as exc:
    print("RESULT " + json.dumps(str(exc)))
""")
    assert reason.startswith("import failed: images[0] refers to '../outside/secret.png', which is refused"), reason
