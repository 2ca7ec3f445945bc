"""The real sample assets the generator never trained on, as the generator benches evaluate them.

The corpus configuration names them (``corpus.held_out``: none of the ten sample assets
hashes into the held-out split). Each is read as ``generate`` reads a user's file
(``mesh_input.load_mesh``: every part with its UVs and its material's maps), prompted
with the caption batch wrote for it, and its reference is what batch made of it for the
corpus: each material uplifted with the caption's parameters and fitted (the latents of
``corpus.batch_dirs``' output), in the same texture space, matched by material name.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from support.paths import SHARED_ASSETS
from richmat_addon.core.captions import caption
from richmat_addon.core.enhance import baseline
from torch_models.dataset import BatchDataset
from torch_models.generator.encoding import latent_texture
from torch_models.generator.generate import texture_rasters
from torch_models.generator.mesh_input import MeshInput, load_mesh
from torch_models.generator.prior import pbr_inputs, prior_material
from torch_models.generator.train import GeneratorTrainConfig

SAMPLE_MODELS = SHARED_ASSETS / "models"


@dataclass
class RealHeldOut:
    """A held-out sample asset: its mesh as ``generate`` reads it, batch's caption and fitted latents."""

    asset_id: str
    name: str  # the file's stem, as captions name the object
    prompt: str
    type: int
    inp: MeshInput
    fitted: list[np.ndarray]  # per material (``inp.materials``), batch's latents: (H, W, 6) or constant (6,)

    def shapes(self, size: int) -> list[tuple[int, int]]:
        """Each material's latent texture shape as ``generate`` makes it with ``size`` the largest side."""
        return [m.texture_shape(size) for m in self.inp.materials]

    def reference(self, size: int) -> list[np.ndarray]:
        """batch's fitted latents; a constant material's vector filled to its texture."""
        return [lat if lat.ndim == 3 else np.broadcast_to(lat, (*shape, 6)).copy()
                for lat, shape in zip(self.fitted, self.shapes(size))]

    def plain_pbr(self, size: int) -> list[np.ndarray]:
        """The encoder's latents of each material's PBR maps, not enhanced (``core.enhance.baseline``)."""
        out = []
        for material, shape in zip(self.inp.materials, self.shapes(size)):
            base, rm = material.maps_at(shape)
            out.append(latent_texture(baseline(pbr_inputs(base, rm, shape, material.name)), shape))
        return out

    def uplifted(self, type_: int, size: int, seed: int = 0) -> tuple[list[np.ndarray], str]:
        """Each material uplifted with ``type_`` and its own draws (``seed``, its name), encoded, and the
        caption batch would write for that uplift: a reference for a prompt naming ``type_``."""
        latents, described = [], []
        for material, raster in zip(self.inp.materials, texture_rasters(self.inp, size)):
            shape = raster.coverage.shape
            base, rm = material.maps_at(shape)
            enhanced = prior_material(base, rm, type_, raster.normals, raster.positions, seed, material.name)
            latents.append(latent_texture(enhanced, shape))
            described.append({"name": material.name, "metallic": material.metallic,
                              "settings": enhanced.settings, "mean_base_color": base.reshape(-1, 3).mean(0).tolist()})
        return latents, caption(self.name, described)


def real_held_out(cfg: GeneratorTrainConfig, models: Path = SAMPLE_MODELS) -> list[RealHeldOut]:
    """The assets of ``cfg.corpus.held_out`` found in its batch outputs, in the config's order."""
    if not cfg.corpus.held_out:
        raise SystemExit("the checkpoint's corpus holds no real asset out (corpus.held_out is empty): "
                         "it trained on every sample asset, so none can be evaluated as unseen")
    found: dict[str, RealHeldOut] = {}
    for folder in cfg.corpus.batch_dirs:
        assets = BatchDataset(Path(folder), load=("latents",))
        for i, record in enumerate(assets.index.records):
            if record["asset_id"] not in cfg.corpus.held_out:
                continue
            item = assets[i]
            inp = load_mesh(models / record["source"])
            by_name = {m["name"]: lat for m, lat in zip(record["materials"], item["latents"])}
            missing = [m.name for m in inp.materials if m.name not in by_name]
            if missing:
                raise ValueError(f"{record['asset_id']}: batch fitted no latents for materials {missing}")
            found[record["asset_id"]] = RealHeldOut(
                record["asset_id"], Path(record["source"]).stem, record["caption"], int(record["enhancement_type"]),
                inp, [by_name[m.name] for m in inp.materials])
    absent = [a for a in cfg.corpus.held_out if a not in found]
    if absent:
        raise SystemExit(f"held-out assets {absent} are in none of the batch outputs {cfg.corpus.batch_dirs}")
    return [found[a] for a in cfg.corpus.held_out]
