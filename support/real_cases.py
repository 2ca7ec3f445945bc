"""Ball cases drawn from real sample assets, uplifted as the add-on and the farm do.

Each asset is enhanced at the defaults (type auto, seed 0), its texel vectors merged at the
fit's cluster step, and ``per_material`` of each material's vectors drawn with probability
proportional to the texels they cover (what a viewer of the asset sees most), each with the
base colour of one of its texels. The cases are constant materials, like the agreement
cases, so a ball measures a decoder's reach on vectors real assets hold.
"""
from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np

from richmat_addon.core import material_folder
from richmat_addon.core.schema import CHANNEL_SLICES
from richmat_addon.core.texel_vectors import nearest_resize, read_vectors
from support.agreement_cases import Case
from support.paths import SHARED_ASSETS
from torch_models.neural.real_vectors import enhanced_folders


def case_of(name: str, vector: np.ndarray, base: np.ndarray) -> Case:
    params = {k: [float(x) for x in np.atleast_1d(vector[sl])] for k, sl in CHANNEL_SLICES.items()}
    return Case(name, "surface", params, [float(x) for x in base])


def material_cases(folder: Path, label: str, per_material: int, rng: np.random.Generator) -> list[Case]:
    """``per_material`` cases of one enhanced material folder (fewer when it has fewer vectors)."""
    tv = read_vectors(folder)
    base = material_folder.read(folder).map("base_color").value
    if tv.shape is None:
        return [case_of(f"{label}_0", tv.unique[0], base.reshape(-1, 3)[0])]
    counts = np.bincount(tv.inverse, minlength=len(tv.unique))
    picks = rng.choice(len(tv.unique), min(per_material, len(tv.unique)), replace=False, p=counts / counts.sum())
    _, first_texel = np.unique(tv.inverse, return_index=True)  # every vector covers at least one texel
    colours = (nearest_resize(base, tv.shape) if base.ndim == 3 else np.broadcast_to(base, (*tv.shape, 3)))
    colours = colours.reshape(-1, 3)
    return [case_of(f"{label}_{k}", tv.unique[i], colours[first_texel[i]]) for k, i in enumerate(picks)]


def real_cases(assets: list[str], per_material: int, seed: int = 0) -> list[Case]:
    """Cases of every material of the named sample assets (names in ``../shared/assets/models``)."""
    rng = np.random.default_rng(seed)
    out: list[Case] = []
    with tempfile.TemporaryDirectory() as tmp:
        for asset in assets:
            for material in enhanced_folders(SHARED_ASSETS / "models" / f"{asset}.glb", Path(tmp) / asset):
                out += material_cases(material, f"{asset}_{material.name}", per_material, rng)
    return out
