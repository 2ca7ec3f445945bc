"""Which enhancement type an asset gets: the paper's dataset mix, fixed by asset id and seed.

One type per asset (the paper assigns types per object); a metallic material
in an asset drawn as Type 4 or 5 gets the dielectric-free remap of
``enhancement_types.METAL_REMAP`` (4 -> 1, 5 -> 3), noted in its params.json. Drawn from a hash,
not from a shared random stream, so a shard or a retry gives the same answer.
"""
from __future__ import annotations

import hashlib

from richmat_addon.core.enhancement_types import DIELECTRIC_ONLY, METAL_REMAP, TYPE_MIX


def asset_type(asset_id: str, seed: int) -> int:
    """The asset's type, drawn from the shares of ``TYPE_MIX`` relative to their sum (a type added with a
    share of its own is drawn too; the paper's mix sums to 1, so its draws are unchanged)."""
    digest = hashlib.sha256(f"{seed}\0{asset_id}\0type".encode("utf-8")).digest()
    u = int.from_bytes(digest[:8], "big") / 2.0 ** 64 * sum(TYPE_MIX)
    edge = 0.0
    for type_, share in enumerate(TYPE_MIX):
        edge += share
        if u < edge:
            return type_
    return len(TYPE_MIX) - 1


def material_type(asset_type_: int, metallic: bool) -> tuple[int, str]:
    """The type a material gets and a note when it differs from the asset's."""
    if metallic and asset_type_ in DIELECTRIC_ONLY:
        return METAL_REMAP[asset_type_], (f"asset type {asset_type_} is for dielectrics; metallic material "
                                          f"got type {METAL_REMAP[asset_type_]}")
    return asset_type_, ""
