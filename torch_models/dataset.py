"""A ``batch/render_dataset.py`` output as a torch ``Dataset``, read through its index.

The index (``assets/dataset_index.py``) lists the published assets, so
nothing here walks folders or guesses the layout. An item is a dict: ``record``, the
asset's index line, plus the kinds of array asked for at construction, read when the
item is: ``frames`` (V, H, W, C) uint8 beauty frames; ``intrinsics`` the layers of the
multilayer EXRs by name, each (V, H, W, C) float32; ``latents`` per material its
(H, W, 6) latent texture or its constant (6,) vector; ``cameras`` the cameras.json
record. Numpy arrays, so a ``DataLoader`` with its default collate makes tensors of
them; assets differ in materials and sizes, so batch with ``batch_size=None`` or a
collate of your own.
"""
from __future__ import annotations

import json
from pathlib import Path
from typing import Any, Callable, Sequence

import numpy as np
from PIL import Image
from torch.utils.data import Dataset

from richmat_addon.core import neural_folder
from richmat_addon.core.folder_io import read_exr
from .assets import dataset_index
from .assets.dataset_index import DatasetIndex


def read_passes(exr: Path) -> dict[str, np.ndarray]:
    """Layers of one ``passes/NNNN.exr`` frame as (H, W, C) arrays, keyed by layer name.

    Blender writes one EXR part (subimage) per layer, named after it."""
    import OpenImageIO as oiio

    layers = {}
    probe = oiio.ImageBuf(str(exr))
    if probe.has_error:
        raise ValueError(f"{exr}: cannot read ({probe.geterror().strip()})")
    for sub in range(max(probe.nsubimages, 1)):
        buf = oiio.ImageBuf(str(exr), sub, 0)
        name = buf.spec().getattribute("name") or buf.spec().channelnames[0].split(".")[0]
        layers[str(name)] = np.asarray(buf.get_pixels(oiio.FLOAT), np.float32)
    return layers


def _frames(index: DatasetIndex, record: dict[str, Any]) -> np.ndarray:
    frames = []
    for path in index.files(record, "frames"):
        with Image.open(path) as image:
            frames.append(np.asarray(image))
    return np.stack(frames)


def _intrinsics(index: DatasetIndex, record: dict[str, Any]) -> dict[str, np.ndarray]:
    frames = [read_passes(p) for p in index.files(record, "intrinsics")]
    return {name: np.stack([f[name] for f in frames]) for name in frames[0]} if frames else {}


def _latents(index: DatasetIndex, record: dict[str, Any]) -> list[np.ndarray]:
    out = []
    for mat in record["materials"]:
        neural = neural_folder.read(index.root / mat["neural"])
        if neural.latent_paths is None:
            out.append(np.asarray(neural.latent, np.float32))
        else:
            out.append(np.concatenate([read_exr(p) for p in neural.latent_paths], -1))
    return out


def _cameras(index: DatasetIndex, record: dict[str, Any]) -> dict[str, Any]:
    return json.loads(index.files(record, "cameras")[0].read_text(encoding="utf-8"))


_LOADERS: dict[str, Callable[[DatasetIndex, dict[str, Any]], Any]] = {
    "frames": _frames, "intrinsics": _intrinsics, "latents": _latents, "cameras": _cameras}


class BatchDataset(Dataset):
    """The assets of one index; ``load`` names the kinds of array each item carries.

    Every asset's files of those kinds are checked when the dataset is made, so a
    missing file stops the run before training, naming the assets that lack one.
    """

    def __init__(self, index: Path, load: Sequence[str] = ()) -> None:
        self.index = dataset_index.read(index)
        self.index.check_files(load)
        self.load = tuple(load)

    def __len__(self) -> int:
        return len(self.index.records)

    def __getitem__(self, i: int) -> dict[str, Any]:
        record = self.index.records[i]
        return {"record": record, **{kind: _LOADERS[kind](self.index, record) for kind in self.load}}
