"""The hybrid's training config: the shared fields plus its lobes, its networks' sizes and its floor's annealing."""
from __future__ import annotations

from dataclasses import dataclass

from ..config import TrainConfig
from .networks import HybridDecoder


@dataclass
class HybridConfig(TrainConfig):
    kind: str = HybridDecoder.kind
    lobes: int = 3  # GGX lobes
    head_width: int = 32  # the lobe head
    gate_width: int = 32  # the gate network
    gate_depth: int = 2
    lobe_alpha_floor: tuple[float, float] = (0.05, 1e-3)  # the lobes' alpha floor, annealed from, to
    unit_lobes: bool = False  # GGX lobes normalised to unit albedo (networks.HybridDecoder)
    sheen: bool = False  # a unit-albedo LTC sheen lobe beside the GGX and diffuse lobes
    anneal: float = 0.6  # share of the decoder phase over which the floor falls (geometrically)
    view_gates: bool = False  # gates from (latent, view cosine) only: the lobes are exact closures
