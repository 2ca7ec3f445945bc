"""Procedural training assets: varied shapes with UVs and plausible PBR textures by family.

The real asset folder holds a handful of objects; the generator needs many. Each
asset is drawn from a seed: a primitive (sphere, box, cylinder, capsule, torus,
cone), optionally a second one beside it, stretched and bent by smooth noise,
normalised into [-0.5, 0.5]^3 like batch's prepare stage and unwrapped with xatlas.
Its textures are solid (3D) patterns evaluated at each texel's world position
(``core.uv_raster``), so they run seamlessly across UV seams: metals, paints,
plastics, ceramics, wood and fabric, each with its own colour palette, roughness
range and pattern.
"""
from __future__ import annotations

import colorsys
from dataclasses import dataclass

import numpy as np

from richmat_addon.core.base_materials import CORPUS_METALS, FAMILIES as MATERIAL_FAMILIES, METALS
from richmat_addon.core.colour import gamma_to_linear
from richmat_addon.core.maps import PbrInputs, ParamMap
from richmat_addon.core.uv_raster import rasterize as uv_rasterize
from .views import Mesh

FAMILIES = tuple(MATERIAL_FAMILIES)  # metal, paint, plastic, ceramic, wood, fabric: the draws index this order
ROUGHNESS = {f.name: f.roughness for f in MATERIAL_FAMILIES.values()}
SHAPES = ("sphere", "box", "cylinder", "capsule", "torus", "cone")


@dataclass
class ProceduralAsset:
    asset_id: str
    shape: str
    family: str
    mesh: Mesh
    pbr: PbrInputs  # textures (H, W, C) in the mesh's UV space
    world_normals: np.ndarray  # (H, W, 3) per texel, for dust
    world_positions: np.ndarray  # (H, W, 3)


def _primitive(kind: str, rng: np.random.Generator):  # -> trimesh.Trimesh
    import trimesh

    c = trimesh.creation
    if kind == "sphere":
        return c.icosphere(subdivisions=3)
    if kind == "box":
        return c.box(extents=rng.uniform(0.6, 1.4, 3)).subdivide().subdivide().subdivide()
    if kind == "cylinder":
        return c.cylinder(radius=rng.uniform(0.3, 0.7), height=rng.uniform(0.6, 1.6), sections=32)
    if kind == "capsule":
        return c.capsule(height=rng.uniform(0.4, 1.2), radius=rng.uniform(0.25, 0.5), count=[24, 24])
    if kind == "torus":
        return c.torus(major_radius=0.6, minor_radius=rng.uniform(0.15, 0.35), major_sections=40, minor_sections=16)
    return c.cone(radius=rng.uniform(0.4, 0.8), height=rng.uniform(0.8, 1.6), sections=32).subdivide()


def _smooth_noise(p: np.ndarray, rng: np.random.Generator, octaves: int = 4, base: float = 2.0) -> np.ndarray:
    """A cheap solid noise in about [-1, 1]: a sum of random plane waves, amplitude halving per octave."""
    out = np.zeros(len(p))
    for k in range(octaves):
        direction = rng.normal(size=3)
        direction /= np.linalg.norm(direction)
        out += 0.5 ** k * np.sin(base * 2 ** k * (p @ direction) * np.pi + rng.uniform(0, 2 * np.pi))
    return out / (2 - 0.5 ** (octaves - 1))


def make_mesh(shape: str, rng: np.random.Generator) -> Mesh:
    """A deformed primitive (sometimes two), normalised into the unit cube, unwrapped with xatlas."""
    import trimesh

    parts = [_primitive(shape, rng)]
    if rng.uniform() < 0.3:  # a second part beside the first
        extra = _primitive(SHAPES[rng.integers(len(SHAPES))], rng)
        extra.apply_scale(rng.uniform(0.3, 0.6))
        extra.apply_translation(rng.uniform(-0.6, 0.6, 3))
        parts.append(extra)
    mesh = trimesh.util.concatenate(parts)
    mesh.apply_transform(trimesh.transformations.random_rotation_matrix(rng.uniform(size=3)))
    v = mesh.vertices * rng.uniform(0.6, 1.3, 3)
    v = v + 0.08 * _smooth_noise(v, rng, octaves=2, base=1.0)[:, None] * mesh.vertex_normals
    v = v - (v.max(0) + v.min(0)) / 2
    return unwrapped(trimesh.Trimesh(v / (v.max(0) - v.min(0)).max(), mesh.faces, process=False))


def unwrapped(mesh) -> Mesh:  # mesh: trimesh.Trimesh
    """The mesh with a UV map from xatlas (vertices split along the seams)."""
    import xatlas

    vmap, faces, uvs = xatlas.parametrize(mesh.vertices.astype(np.float32), mesh.faces.astype(np.uint32))
    return Mesh(mesh.vertices[vmap].astype(np.float32), np.asarray(mesh.vertex_normals[vmap], np.float32),
                uvs.astype(np.float32), faces.astype(np.int64))


def _hsv(h: float, s: float, v: float) -> np.ndarray:
    """Linear RGB of an sRGB-space HSV colour, decoded with the corpus's 2.2 power (``colour.gamma_to_linear``)
    rather than the exact sRGB curve (``colour.srgb_to_linear``, at most 0.0085 apart): the corpus the shipped generator trained on and the
    benches' held-out procedural objects were made with it."""
    return gamma_to_linear(np.asarray(colorsys.hsv_to_rgb(h % 1.0, s, v)))


def family_textures(family: str, p: np.ndarray,
                    rng: np.random.Generator) -> tuple[str, np.ndarray, np.ndarray, np.ndarray]:
    """A material name, base colour (N, 3), roughness (N,), metalness (N,) at world points p (N, 3).

    Metals are named by their metal ("copper"), others by their family, so captions read naturally.
    """
    n = _smooth_noise(p, rng)
    fine = _smooth_noise(p, rng, base=8.0)
    metal, name = np.zeros(len(p)), family
    if family == "metal":
        name = CORPUS_METALS[rng.integers(len(CORPUS_METALS))]
        base = np.asarray(METALS[name])[None] * (1 + 0.05 * n[:, None])
        rough = rng.uniform(*ROUGHNESS["metal"]) + 0.08 * fine  # brushed/worn variation
        metal[:] = 1.0
    elif family == "paint":
        base = np.tile(_hsv(rng.uniform(), rng.uniform(0.6, 1.0), rng.uniform(0.4, 0.9)), (len(p), 1))
        rough = rng.uniform(*ROUGHNESS["paint"]) + 0.03 * fine
    elif family == "plastic":
        c0 = _hsv(rng.uniform(), rng.uniform(0.3, 0.9), rng.uniform(0.3, 0.95))
        base = c0[None] * (1 + 0.05 * fine[:, None])
        rough = rng.uniform(*ROUGHNESS["plastic"]) + 0.05 * n
    elif family == "ceramic":
        c0 = _hsv(rng.uniform(), rng.uniform(0.0, 0.35), rng.uniform(0.75, 0.98))
        base = c0[None] * (1 + 0.08 * n[:, None])  # mottled glaze
        rough = rng.uniform(*ROUGHNESS["ceramic"]) + 0.02 * fine
    elif family == "wood":
        axis = rng.normal(size=3)
        axis /= np.linalg.norm(axis)
        radial = np.linalg.norm(p - (p @ axis)[:, None] * axis, axis=1)
        rings = 0.5 + 0.5 * np.sin(2 * np.pi * rng.uniform(6, 14) * radial + 2.0 * n)
        light, dark = _hsv(rng.uniform(0.06, 0.1), 0.55, 0.75), _hsv(rng.uniform(0.05, 0.09), 0.7, 0.4)
        base = light[None] * (1 - rings[:, None]) + dark[None] * rings[:, None]
        rough = rng.uniform(*ROUGHNESS["wood"]) + 0.1 * rings
    else:  # fabric: a weave of two thread directions
        f = rng.uniform(20, 40)
        weave = np.sin(f * np.pi * p[:, 0]) * np.sin(f * np.pi * (p[:, 1] + p[:, 2]))
        c0 = _hsv(rng.uniform(), rng.uniform(0.2, 0.8), rng.uniform(0.3, 0.8))
        base = c0[None] * (1 + 0.15 * weave[:, None])
        rough = rng.uniform(*ROUGHNESS["fabric"]) + 0.05 * weave
    return name, np.clip(base, 0, 1), np.clip(rough, 0.02, 1.0), metal


def make_asset(index: int, texture_size: int = 64, seed: int = 0) -> ProceduralAsset:
    """Asset number ``index`` of the procedural corpus (deterministic per index and seed)."""
    rng = np.random.default_rng([seed, index])
    shape, family = SHAPES[rng.integers(len(SHAPES))], FAMILIES[rng.integers(len(FAMILIES))]
    mesh = make_mesh(shape, rng)
    raster, reason = uv_rasterize(mesh.positions, mesh.normals, mesh.uvs, mesh.faces, (texture_size, texture_size))
    if raster is None:
        raise ValueError(f"procedural asset {index}: {reason}")
    hw = (texture_size, texture_size)
    name, base, rough, metal = family_textures(family, raster.positions.reshape(-1, 3).astype(np.float64), rng)
    pbr = PbrInputs(name, ParamMap(base.reshape(*hw, 3)), ParamMap(rough.reshape(*hw, 1)),
                    ParamMap(metal.reshape(*hw, 1)))
    return ProceduralAsset(f"proc-{seed}-{index:05d}", shape, family, mesh, pbr, raster.normals, raster.positions)

