"""The generator's training corpus: one safetensors file per object.

A sample is an object seen from V orbit views at the working resolution:
``target`` (V, 6, H, W) latent channels, ``conditions`` (V, 19, H, W) = world
normal, world position, base colour, roughness, metalness, whether those two are
known, the uplift prior's latents (``prior.py``), coverage
(``views.CONDITION_LAYOUT``); ``unknown_prior`` (V, 6, H, W) the prior of the same
object uplifted without its roughness and metalness (what training puts in the
prior channels when it drops those maps); ``text`` (384,) the caption's MiniLM
embedding; ``type`` the enhancement type (an index of ``enhancement_types.TYPES``). The caption and asset id ride in
the file's metadata.

Two sources feed it:
- ``batch/`` outputs (``batch_samples``): the intrinsic EXRs Cycles rendered and the
  caption batch wrote, read through the output's dataset index (``torch_models/dataset.py``);
  the maps are read as they are (render batch at the working resolution).
- procedural assets (``from_procedural``): enhanced with ``core.enhance`` and
  encoded to latents with the shipped encoder (optionally refined by a few fit
  steps, ``encoding.py``), rendered with the torch rasteriser of ``views.py``. This is the fast
  path: batch's per-asset cost (its latent fit and Cycles, minutes per asset on 2
  cores, docs/batch.md) makes it too slow for a corpus of hundreds here.

Held-out objects: ``is_held_out`` hashes the asset id, so the split is stable
whatever order or subset the corpus is built in.
"""
from __future__ import annotations

import hashlib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch
from safetensors.torch import load_file, save_file
from torch import Tensor

from richmat_addon.core.captions import caption
from richmat_addon.core.enhance import enhance, is_metallic
from richmat_addon.core.maps import EnhancedMaterial, ParamMap
from ..assets.enhancement_plan import asset_type, material_type
from ..dataset import BatchDataset
from . import procedural, text
from .encoding import latent_texture
from .mesh_input import MaterialInput
from .prior import prior_latents
from .views import CONDITION_CHANNELS, Cameras, IntrinsicViews, orbit_cameras, render_intrinsics

HELD_OUT_FRACTION = 0.1


def is_held_out(asset_id: str, fraction: float = HELD_OUT_FRACTION) -> bool:
    digest = hashlib.sha256(f"{asset_id}\0split".encode()).digest()
    return int.from_bytes(digest[:8], "big") / 2.0 ** 64 < fraction


@dataclass
class Sample:
    asset_id: str
    caption: str
    type: int
    target: Tensor  # (V, 6, H, W)
    conditions: Tensor  # (V, CONDITION_CHANNELS, H, W)
    unknown_prior: Tensor  # (V, 6, H, W)
    text: Tensor  # (384,)

    def save(self, path: Path) -> None:
        tensors = {"target": self.target.half().contiguous(), "conditions": self.conditions.half().contiguous(),
                   "unknown_prior": self.unknown_prior.half().contiguous(), "text": self.text.float().contiguous()}
        save_file(tensors, str(path), metadata={"asset_id": self.asset_id, "caption": self.caption,
                                                "type": str(self.type)})

    @classmethod
    def load(cls, path: Path) -> "Sample":
        from safetensors import safe_open

        with safe_open(str(path), "pt") as f:
            meta = f.metadata()
        t = load_file(str(path))
        if "unknown_prior" not in t or t["conditions"].shape[1] != CONDITION_CHANNELS:
            raise ValueError(f"{path}: a corpus file of an older layout (no uplift prior); delete the corpus "
                             "folder and let train-generator rebuild it")
        return cls(meta["asset_id"], meta["caption"], int(meta["type"]), t["target"].float(),
                   t["conditions"].float(), t["unknown_prior"].float(), t["text"])


def caption_for(shape: str, material: EnhancedMaterial, metallic: bool) -> str:
    """The batch-rendered corpus's caption (colour, family, enhancement keywords with strength) for one
    procedural object."""
    return caption(shape, [{"name": material.name, "metallic": metallic, "settings": material.settings,
                            "mean_base_color": material.base_color.mean().tolist()}])


def _type_for(asset_id: str, metallic: bool, seed: int) -> int:
    return material_type(asset_type(asset_id, seed), metallic)[0]


def enhancement_seed(seed: int, index: int) -> int:
    """The enhancement draws of procedural object ``index``: its own, so settings and strengths
    vary across objects as their captions say (one seed for all made every "ceramic" of a
    type alike, which flattered retrieval)."""
    return seed * 1_000_003 + index + 1


def from_procedural(index: int, cameras: Cameras, texture_size: int = 64, seed: int = 0,
                    fit_steps: int = 0, supersample: int = 1) -> Sample:
    asset = procedural.make_asset(index, texture_size, seed)
    metallic = is_metallic(asset.pbr)
    type_ = _type_for(asset.asset_id, metallic, seed)
    material = enhance(asset.pbr, type_, enhancement_seed(seed, index), ParamMap(asset.world_normals),
                       ParamMap(asset.world_positions))
    latents = latent_texture(material, (texture_size, texture_size), fit_steps)
    inp = MaterialInput.from_pbr(asset.pbr)
    rm = inp.roughness_metalness
    priors = [prior_latents(inp.base_color, known, type_, asset.world_normals, asset.world_positions)
              for known in (rm, None)]
    views = render_intrinsics(asset.mesh, cameras, inp.base_color, np.concatenate([latents, *priors], -1),
                              supersample, rm)
    cap = caption_for(asset.shape, material, metallic)
    return sample_from_views(asset.asset_id, cap, type_, views)


def sample_from_views(asset_id: str, caption: str, type_: int, views: IntrinsicViews) -> Sample:
    """A sample from rendered views whose latents hold the target, the prior and the unknown-PBR prior
    (6 channels each); pixels count as covered from half coverage on, as in ``from_batch``."""
    assert views.latents is not None and views.latents.shape[-1] == 18
    inside = (views.coverage > 0.5).float()[:, None]
    target, prior, unknown = (views.latents[..., k:k + 6].permute(0, 3, 1, 2) * inside for k in (0, 6, 12))
    return Sample(asset_id, caption, type_, target.contiguous(), views.conditions(prior.permute(0, 2, 3, 1)),
                  unknown.contiguous(), text.embed([caption])[0])


def batch_samples(output: Path) -> list[Sample]:
    """A sample per asset of a ``batch/`` output, as its dataset index lists them (only published
    assets: batch renames ``<id>.partial`` to ``<id>`` when an asset is complete)."""
    assets = BatchDataset(output, load=("intrinsics",))
    return [from_batch(assets[i]) for i in range(len(assets))]


def from_batch(item: dict[str, Any]) -> Sample:
    """A sample from one batch asset: a ``BatchDataset`` item with its intrinsic passes.

    batch renders no roughness or metalness pass, so these samples say the two are unknown,
    and their prior is the unknown-PBR uplift, made per pixel of the views (batch keeps no
    texture-space maps) from their base colour, normals and positions."""
    record, layers = item["record"], item["intrinsics"]
    cover = layers["coverage"][..., :1]
    # Cycles averages its AA samples with the black background: undo that premultiplication
    unmix = np.where(cover > 0.5, 1.0 / np.maximum(cover, 1e-6), 0.0)
    normal = layers["Normal"][..., :3] * unmix
    normal /= np.maximum(np.linalg.norm(normal, axis=-1, keepdims=True), 1e-12)
    position, base = layers["Position"][..., :3] * unmix, layers["basecolor"][..., :3] * unmix
    latents = np.concatenate([layers["latent_a"][..., :3], layers["latent_b"][..., :3]], -1) * unmix
    cover = cover[..., 0]
    type_ = int(record["enhancement_type"])
    v, h, w = cover.shape
    flat = lambda m: m.reshape(v * h, w, -1)  # the views stacked as one image: the prior is per pixel here
    prior = prior_latents(flat(base), None, type_, flat(normal), flat(position)).reshape(v, h, w, 6)
    views = IntrinsicViews(*(torch.from_numpy(m).float() for m in (normal, position, base, cover)),
                           torch.zeros((v, h, w, 2)),
                           torch.from_numpy(np.concatenate([latents, prior, prior], -1)).float())
    return sample_from_views(record["asset_id"], record["caption"], type_, views)


def build_procedural(out: Path, count: int, views: int, resolution: int, seed: int = 0,
                     texture_size: int = 64, fit_steps: int = 0, supersample: int = 1,
                     progress: bool = True) -> list[Path]:
    """Write ``count`` procedural samples into ``out`` (existing files are kept: resumable)."""
    from tqdm import tqdm

    out.mkdir(parents=True, exist_ok=True)
    cameras = orbit_cameras(views, resolution)
    paths = []
    for index in tqdm(range(count), desc="procedural corpus", disable=not progress):
        path = out / f"proc-{seed}-{index:05d}.safetensors"
        if not path.exists():
            from_procedural(index, cameras, texture_size, seed, fit_steps, supersample).save(path)
        paths.append(path)
    return paths
