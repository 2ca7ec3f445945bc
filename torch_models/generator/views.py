"""Intrinsic views of a textured mesh: the batch orbit cameras and a small z-buffer rasteriser.

The generator trains and samples on per-view maps of world normals, world
positions, base colour, coverage and the latent textures. ``batch/`` renders them
with Cycles (``passes/NNNN.exr``); this module makes the same maps in torch, so
generation can render its condition views without Blender and small corpora can
be made in seconds. ``orbit_cameras`` repeats ``batch/bl_render.orbit`` (same
lens, framing, elevation swing and the ``cameras.json`` layout); the two agree on a
batch-rendered asset (tests/test_generator_views.py).

Conventions: world Z up; the asset normalised into the cube [-0.5, 0.5]^3;
Blender camera (looks down -Z, +Y up); image row 0 at the top; UV (0, 0) at the
top-left texel (glTF, as ``core.uv_raster`` without ``flip_v``). One sample at
each pixel centre, or ``supersample`` x ``supersample`` samples averaged over the
covered ones (batch anti-aliases with 8 Cycles samples; its maps agree better with
supersampled ones, tests/test_generator_views.py). Coverage is then fractional.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import torch
from torch import Tensor

LENS_MM, SENSOR_MM = 35.0, 32.0
ELEVATION_DEG, ELEVATION_SWING_DEG = 25.0, 10.0
FRAMING_MARGIN = 1.08
_TRIANGLE_CHUNK = 512


@dataclass
class Cameras:
    """Pinhole cameras in the ``cameras.json`` layout: square images, camera_to_world (V, 4, 4)."""

    resolution: int
    focal_px: float
    camera_to_world: Tensor

    @classmethod
    def from_record(cls, record: dict) -> "Cameras":
        """From batch's ``cameras.json``."""
        intr = record["intrinsics"]
        c2w = torch.tensor([f["camera_to_world"] for f in record["frames"]], dtype=torch.float64)
        return cls(int(intr["width"]), float(intr["fx"]), c2w)

    @property
    def origins(self) -> Tensor:
        return self.camera_to_world[:, :3, 3]


def orbit_cameras(frames: int, resolution: int, azimuth0: float = 0.0) -> Cameras:
    """One closed turn around the origin, elevation 25 +- 10 deg, the unit cube's bounding sphere framed."""
    half_fov = math.atan(SENSOR_MM / 2 / LENS_MM)
    distance = FRAMING_MARGIN * (math.sqrt(3) / 2) / math.sin(half_fov)
    mats = []
    for i in range(frames):
        t = i / frames
        az = azimuth0 + 2 * math.pi * t
        el = math.radians(ELEVATION_DEG + ELEVATION_SWING_DEG * math.sin(2 * math.pi * t))
        eye = distance * np.array([math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), math.sin(el)])
        back = eye / np.linalg.norm(eye)  # camera +Z points away from the target
        right = np.cross([0.0, 0.0, 1.0], back)
        right /= np.linalg.norm(right)
        up = np.cross(back, right)
        m = np.eye(4)
        m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = right, up, back, eye
        mats.append(m)
    return Cameras(resolution, LENS_MM / SENSOR_MM * resolution, torch.tensor(np.stack(mats)))


@dataclass
class Mesh:
    """A triangle mesh with per-vertex normals and UVs (seams already split)."""

    positions: np.ndarray  # (N, 3) float32, world (normalised) space
    normals: np.ndarray  # (N, 3) float32
    uvs: np.ndarray  # (N, 2) float32, glTF convention
    faces: np.ndarray  # (T, 3) int64


@dataclass
class Fragments:
    """What each pixel of each view sees: (V, H, W) triangle id (-1 = background) and barycentrics (V, H, W, 3)."""

    triangle: Tensor
    bary: Tensor

    @property
    def coverage(self) -> Tensor:
        return (self.triangle >= 0).float()

    def interpolate(self, attribute: np.ndarray, faces: np.ndarray) -> Tensor:
        """Per-vertex ``attribute`` (N, C) at every pixel, (V, H, W, C); 0 on the background."""
        corners = torch.from_numpy(np.asarray(attribute, np.float32))[torch.from_numpy(faces)]  # (T, 3, C)
        tri = self.triangle.clamp(min=0)
        value = (corners[tri] * self.bary[..., None]).sum(-2)
        return value * (self.triangle >= 0)[..., None]


def rasterize(mesh: Mesh, cameras: Cameras) -> Fragments:
    """Nearest triangle per pixel centre, perspective-correct barycentrics (brute force, chunked)."""
    res = cameras.resolution
    v = len(cameras.camera_to_world)
    world_to_camera = torch.linalg.inv(cameras.camera_to_world)
    pos = torch.from_numpy(mesh.positions).double()
    homo = torch.cat([pos, torch.ones(len(pos), 1, dtype=torch.float64)], 1)
    cam = torch.einsum("vij,nj->vni", world_to_camera, homo)[..., :3]  # (V, N, 3)
    depth = -cam[..., 2]  # positive in front of the camera
    f, c = cameras.focal_px, res / 2
    sx = c + f * cam[..., 0] / depth.clamp(min=1e-9)
    sy = c - f * cam[..., 1] / depth.clamp(min=1e-9)
    faces = torch.from_numpy(mesh.faces)
    centres = torch.arange(res, dtype=torch.float64) + 0.5
    py, px = torch.meshgrid(centres, centres, indexing="ij")
    px, py = px.reshape(1, -1), py.reshape(1, -1)
    best_depth = torch.full((v, res * res), math.inf, dtype=torch.float64)
    best_tri = torch.full((v, res * res), -1, dtype=torch.int64)
    best_bary = torch.zeros(v, res * res, 3, dtype=torch.float64)
    for view in range(v):
        for t0 in range(0, len(faces), _TRIANGLE_CHUNK):
            tri = faces[t0:t0 + _TRIANGLE_CHUNK]
            x, y, z = sx[view][tri], sy[view][tri], depth[view][tri]  # (t, 3)
            area = (x[:, 1] - x[:, 0]) * (y[:, 2] - y[:, 0]) - (x[:, 2] - x[:, 0]) * (y[:, 1] - y[:, 0])
            ok = (area.abs() > 1e-12) & (z > 1e-6).all(1)
            safe = torch.where(ok, area, torch.ones_like(area))[:, None]
            w0 = ((x[:, 1:2] - px) * (y[:, 2:3] - py) - (x[:, 2:3] - px) * (y[:, 1:2] - py)) / safe
            w1 = ((x[:, 2:3] - px) * (y[:, 0:1] - py) - (x[:, 0:1] - px) * (y[:, 2:3] - py)) / safe
            w2 = 1.0 - w0 - w1
            inside = (w0 >= 0) & (w1 >= 0) & (w2 >= 0) & ok[:, None]
            # perspective correction: screen barycentrics / depth, renormalised
            b = torch.stack([w0 / z[:, 0:1], w1 / z[:, 1:2], w2 / z[:, 2:3]], -1)
            inv_z = b.sum(-1)
            b = b / inv_z[..., None]
            pix_depth = torch.where(inside, 1.0 / inv_z, torch.full_like(inv_z, math.inf))
            d, k = pix_depth.min(0)
            closer = d < best_depth[view]
            best_depth[view] = torch.where(closer, d, best_depth[view])
            best_tri[view] = torch.where(closer, t0 + k, best_tri[view])
            chosen = b.gather(0, k[None, :, None].expand(1, -1, 3))[0]
            best_bary[view] = torch.where(closer[:, None], chosen, best_bary[view])
    return Fragments(best_tri.reshape(v, res, res), best_bary.reshape(v, res, res, 3).float())


def sample_texture(texture: np.ndarray, uv: Tensor) -> Tensor:
    """Bilinear lookup of an (H, W, C) texture at UVs (..., 2), wrapping like glTF's REPEAT."""
    tex = torch.from_numpy(np.asarray(texture, np.float32))
    h, w, ch = tex.shape
    x = uv[..., 0] * w - 0.5
    y = uv[..., 1] * h - 0.5
    x0, y0 = x.floor(), y.floor()
    fx, fy = (x - x0)[..., None], (y - y0)[..., None]
    x0, y0 = x0.long(), y0.long()

    def at(yy: Tensor, xx: Tensor) -> Tensor:
        return tex[yy % h, xx % w]

    return ((1 - fy) * ((1 - fx) * at(y0, x0) + fx * at(y0, x0 + 1))
            + fy * ((1 - fx) * at(y0 + 1, x0) + fx * at(y0 + 1, x0 + 1)))


@dataclass
class IntrinsicViews:
    """Per-view maps (V, H, W, C): normal 3, position 3, base colour 3, coverage 1, uv 2, latent 6 (if known)."""

    normals: Tensor
    positions: Tensor
    base_color: Tensor
    coverage: Tensor
    uvs: Tensor
    latents: Tensor | None

    def conditions(self) -> Tensor:
        """The generator's condition channels, (V, 10, H, W)."""
        return torch.cat([self.normals, self.positions, self.base_color, self.coverage[..., None]],
                         -1).permute(0, 3, 1, 2).contiguous()


def render_intrinsics(mesh: Mesh, cameras: Cameras, base_color: np.ndarray,
                      latents: np.ndarray | None = None, supersample: int = 1) -> IntrinsicViews:
    """Normals, positions, base colour (and latents) as seen by each camera; 0 on the background.

    With supersampling every map is the mean over the covered subsamples of a pixel
    (not premultiplied by coverage) and coverage is the covered fraction.
    """
    fine = Cameras(cameras.resolution * supersample, cameras.focal_px * supersample, cameras.camera_to_world)
    frags = rasterize(mesh, fine)
    cover = frags.coverage[..., None]
    n = frags.interpolate(mesh.normals, mesh.faces)
    uv = frags.interpolate(mesh.uvs, mesh.faces)
    maps = [n / n.norm(dim=-1, keepdim=True).clamp(min=1e-12), frags.interpolate(mesh.positions, mesh.faces),
            sample_texture(base_color, uv) * cover, uv]
    if latents is not None:
        maps.append(sample_texture(latents, uv) * cover)
    if supersample > 1:
        pooled_cover = torch.nn.functional.avg_pool2d(cover.permute(0, 3, 1, 2), supersample)
        maps = [(torch.nn.functional.avg_pool2d(m.permute(0, 3, 1, 2), supersample)
                 / pooled_cover.clamp(min=1e-6)).permute(0, 2, 3, 1) for m in maps]
        cover = pooled_cover.permute(0, 2, 3, 1)
        maps[0] = maps[0] / maps[0].norm(dim=-1, keepdim=True).clamp(min=1e-12)
    return IntrinsicViews(maps[0], maps[1], maps[2], cover[..., 0], maps[3], maps[4] if latents is not None else None)
