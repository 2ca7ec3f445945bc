"""The cases of the agreement benchmark, as plain data both renderers rebuild.

A case is a constant material (every map collapsed to its mean) drawn with the
enhancement rules, and the part of the graph to render: the whole surface, or
one lobe alone at full weight. Kept free of torch and bpy so the Blender child
process and the torch side read the very same cases.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from richmat_addon.core import graph
from richmat_addon.core.enhance import enhance, is_metallic
from richmat_addon.core.enhancement_types import METAL_TYPES, TYPES
from richmat_addon.core.maps import EnhancedMaterial, ParamMap, PbrInputs
from richmat_addon.core.schema import CHANNEL_SLICES

# Lobe alone -> the type whose materials have it, and whether the base is metal.
LOBE_SOURCES: dict[str, tuple[int, bool]] = {
    "dust": (1, False), "coat": (3, False), "cond_core": (0, True), "cond_haze": (2, True),
    "diel_core": (0, False), "diel_haze": (2, False), "inner": (4, False), "subsurf": (5, False),
}


@dataclass(frozen=True)
class Case:
    name: str
    node: str  # "surface" or a lobe name
    params: dict[str, list[float]]
    base_color: list[float]

    def material(self) -> EnhancedMaterial:
        params = {k: ParamMap.constant(*v) for k, v in self.params.items()}
        return EnhancedMaterial(self.name, -1, 0, ParamMap.constant(*self.base_color), params)

    def vector(self) -> np.ndarray:
        """The packed parameter vector (schema order), as the neural side takes it."""
        return np.concatenate([np.atleast_1d(self.params[k]) for k in CHANNEL_SLICES]).astype(np.float32)

    def graph_node(self) -> graph.Node:
        if self.node == "surface":
            return graph.SURFACE
        return next(lobe for lobe in graph.iter_lobes(graph.SURFACE) if lobe.name == self.node)


def _drawn(rng: np.random.Generator, type_: int, metal: bool, name: str) -> Case:
    """A constant material of ``type_`` with random PBR inputs (mean of every enhanced map)."""
    base = rng.uniform(0.05, 0.9, 3)
    pbr = PbrInputs(name, ParamMap.constant(*base), ParamMap.constant(rng.uniform(0.05, 0.8)),
                    ParamMap.constant(1.0 if metal else 0.0))
    assert is_metallic(pbr) == metal
    mat = enhance(pbr, type_, int(rng.integers(1 << 30)))
    params = {k: [float(x) for x in np.atleast_1d(m.mean())] for k, m in mat.params.items()}
    return Case(name, "surface", params, [float(x) for x in base])


def _full_weight(case: Case, lobe: graph.Lobe) -> Case:
    """The lobe alone, its weight parameter set so that the lobe's weight is 1."""
    params = dict(case.params)
    params[lobe.weight.name] = [0.0 if lobe.weight.one_minus else 1.0]
    return Case(f"lobe_{lobe.name}_{case.name.rsplit('_', 1)[-1]}", lobe.name, params, case.base_color)


def cases(seed: int, per_type: int, per_lobe: int) -> list[Case]:
    """``per_type`` surface cases for each of Types 0-5, ``per_lobe`` isolated cases per lobe."""
    rng = np.random.default_rng(seed)
    out = []
    for type_ in range(len(TYPES)):
        for k in range(per_type):
            metal = type_ in METAL_TYPES and k % 2 == 1  # metals where the type allows them
            out.append(_drawn(rng, type_, metal, f"type{type_}_{'metal' if metal else 'diel'}_{k}"))
    lobes = {lobe.name: lobe for lobe in graph.iter_lobes(graph.SURFACE)}
    for name, (type_, metal) in LOBE_SOURCES.items():
        for k in range(per_lobe):
            out.append(_full_weight(_drawn(rng, type_, metal, f"src_{k}"), lobes[name]))
    return out
