"""Parameter maps that stay constant when they are constant.

A map is either one value (shape ``(C,)``) or a texture (shape ``(H, W, C)``),
float32, linear. Keeping constants as constants is how an untextured material
costs nothing: no 4K image of a single roughness value is ever made.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np


@dataclass(frozen=True)
class ParamMap:
    value: np.ndarray

    def __post_init__(self) -> None:
        v = np.asarray(self.value, dtype=np.float32)
        if v.ndim not in (1, 3):
            raise ValueError(f"a parameter map is (C,) or (H, W, C), got shape {v.shape}")
        object.__setattr__(self, "value", v)

    @classmethod
    def constant(cls, *values: float) -> "ParamMap":
        return cls(np.asarray(values, dtype=np.float32))

    @property
    def is_constant(self) -> bool:
        return self.value.ndim == 1

    @property
    def channels(self) -> int:
        return int(self.value.shape[-1])

    @property
    def shape(self) -> tuple[int, int] | None:
        """(H, W) of a texture, None for a constant."""
        return None if self.is_constant else (int(self.value.shape[0]), int(self.value.shape[1]))

    def collapse(self, atol: float = 0.0) -> "ParamMap":
        """Turn a texture whose texels are all equal (within atol) into a constant."""
        if self.is_constant:
            return self
        flat = self.value.reshape(-1, self.channels)
        if np.all(np.abs(flat - flat[0]) <= atol):
            return ParamMap(flat[0].copy())
        return self

    def mean(self) -> np.ndarray:
        return self.value.reshape(-1, self.channels).mean(axis=0)


@dataclass
class PbrInputs:
    """A simple metal-rough PBR material; base colour is linear (not sRGB)."""

    name: str
    base_color: ParamMap
    roughness: ParamMap
    metalness: ParamMap


@dataclass
class EnhancedMaterial:
    """The diffuse base colour plus every schema parameter as a map.

    ``params`` is keyed by ``schema.PARAMS`` names; ``settings`` holds the
    per-material scalars the maps were made from (p, q, s, seeds, type), which go
    into params.json.
    """

    name: str
    type: int
    seed: int
    base_color: ParamMap
    params: dict[str, ParamMap]
    settings: dict[str, Any] = field(default_factory=dict)

    def constants(self) -> dict[str, float]:
        """Scalar parameters that are constant over the material (for graph pruning)."""
        return {k: float(m.value[0]) for k, m in self.params.items()
                if m.is_constant and m.channels == 1}
