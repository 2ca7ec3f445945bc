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
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import torch
from torch import Tensor

LENS_MM, SENSOR_MM = 35.0, 32.0
ELEVATION_DEG, ELEVATION_SWING_DEG = 25.0, 10.0
FRAMING_MARGIN = 1.08


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


def direction(azimuth: float, elevation: float) -> np.ndarray:
    """The unit vector from the target towards a camera at these angles (radians; Z up)."""
    return np.array([math.cos(elevation) * math.cos(azimuth), math.cos(elevation) * math.sin(azimuth),
                     math.sin(elevation)])


def look_at(directions: np.ndarray, resolution: int, radius: float = math.sqrt(3) / 2,
            centre: np.ndarray | None = None) -> Cameras:
    """Cameras looking at ``centre`` from the unit ``directions`` (N, 3), each far enough to frame
    a sphere of ``radius`` (default: the unit cube's bounding sphere, as batch frames)."""
    distance = FRAMING_MARGIN * radius / math.sin(math.atan(SENSOR_MM / 2 / LENS_MM))
    centre = np.zeros(3) if centre is None else centre
    mats = []
    for d in directions:
        back = d / np.linalg.norm(d)  # camera +Z points away from the target
        right = np.cross([0.0, 0.0, 1.0], back)
        if np.linalg.norm(right) < 1e-6:  # straight down or up: any horizontal right will do
            right = np.array([0.0, -1.0, 0.0]) * np.sign(back[2])
        right /= np.linalg.norm(right)
        m = np.eye(4)
        m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = right, np.cross(back, right), back, centre + distance * back
        mats.append(m)
    return Cameras(resolution, LENS_MM / SENSOR_MM * resolution, torch.tensor(np.stack(mats)))


def orbit_cameras(frames: int, resolution: int, azimuth0: float = 0.0) -> Cameras:
    """One closed turn around the origin, elevation 25 +- 10 deg, the unit cube's bounding sphere framed."""
    t = np.arange(frames) / frames
    return look_at(np.stack([direction(azimuth0 + 2 * math.pi * ti,
                                       math.radians(ELEVATION_DEG + ELEVATION_SWING_DEG * math.sin(2 * math.pi * ti)))
                             for ti in t]), resolution)


@dataclass
class Mesh:
    """A triangle mesh with per-vertex normals and UVs (seams already split).

    Each face belongs to a material (``face_material``, None: all to material 0) and its
    UVs address that material's textures: materials do not share a texture space."""

    positions: np.ndarray  # (N, 3) float32, world (normalised) space
    normals: np.ndarray  # (N, 3) float32
    uvs: np.ndarray  # (N, 2) float32, glTF convention
    faces: np.ndarray  # (T, 3) int64
    face_material: np.ndarray | None = None  # (T,) int64

    @property
    def materials(self) -> np.ndarray:
        """(T,) the material index of every face."""
        return np.zeros(len(self.faces), np.int64) if self.face_material is None else self.face_material


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

    def material(self, face_material: np.ndarray) -> Tensor:
        """(V, H, W) the material index of what each pixel sees, -1 on the background."""
        per_face = torch.from_numpy(np.asarray(face_material, np.int64))
        return torch.where(self.triangle >= 0, per_face[self.triangle.clamp(min=0)], -1)


def rasterize(mesh: Mesh, cameras: Cameras) -> Fragments:
    """Nearest triangle per pixel centre, perspective-correct barycentrics.

    Each triangle is tested only against the pixel centres inside its screen
    bounding box: (triangle, pixel) candidate pairs are enumerated at once, the
    depth test is a scatter-min per pixel, and ties go to the higher triangle id.
    """
    res = cameras.resolution
    world_to_camera = torch.linalg.inv(cameras.camera_to_world)
    pos = torch.from_numpy(mesh.positions).double()
    homo = torch.cat([pos, torch.ones(len(pos), 1, dtype=torch.float64)], 1)
    cam = torch.einsum("vij,nj->vni", world_to_camera, homo)[..., :3]  # (V, N, 3)
    depth = -cam[..., 2]  # positive in front of the camera
    f, c = cameras.focal_px, res / 2
    sx = c + f * cam[..., 0] / depth.clamp(min=1e-9)
    sy = c - f * cam[..., 1] / depth.clamp(min=1e-9)
    faces = torch.from_numpy(mesh.faces)
    triangles, barys = [], []
    for view in range(len(world_to_camera)):
        tri, bary = _rasterize_view(sx[view][faces], sy[view][faces], depth[view][faces], res)
        triangles.append(tri)
        barys.append(bary)
    return Fragments(torch.stack(triangles).reshape(-1, res, res), torch.stack(barys).reshape(-1, res, res, 3).float())


def _rasterize_view(x: Tensor, y: Tensor, z: Tensor, res: int) -> tuple[Tensor, Tensor]:
    """x, y (T, 3) pixel coordinates and z (T, 3) depths of the corners -> triangle id and barycentrics per pixel."""
    n_pix = res * res
    area = (x[:, 1] - x[:, 0]) * (y[:, 2] - y[:, 0]) - (x[:, 2] - x[:, 0]) * (y[:, 1] - y[:, 0])
    ok = (area.abs() > 1e-12) & (z > 1e-6).all(1)
    i0 = (x.min(1).values - 0.5).ceil().clamp(0, res).long()
    i1 = (x.max(1).values - 0.5).floor().clamp(-1, res - 1).long()
    j0 = (y.min(1).values - 0.5).ceil().clamp(0, res).long()
    j1 = (y.max(1).values - 0.5).floor().clamp(-1, res - 1).long()
    w, h = (i1 - i0 + 1).clamp(min=0) * ok, (j1 - j0 + 1).clamp(min=0) * ok
    count = w * h
    t = torch.repeat_interleave(torch.arange(len(x)), count)
    k = torch.arange(len(t)) - torch.repeat_interleave(count.cumsum(0) - count, count)
    px = (i0[t] + k % w[t].clamp(min=1)).double() + 0.5
    py = (j0[t] + k // w[t].clamp(min=1)).double() + 0.5
    xt, yt, zt = x[t], y[t], z[t]
    w0 = ((xt[:, 1] - px) * (yt[:, 2] - py) - (xt[:, 2] - px) * (yt[:, 1] - py)) / area[t]
    w1 = ((xt[:, 2] - px) * (yt[:, 0] - py) - (xt[:, 0] - px) * (yt[:, 2] - py)) / area[t]
    w2 = 1.0 - w0 - w1
    inside = (w0 >= 0) & (w1 >= 0) & (w2 >= 0)
    b = torch.stack([w0 / zt[:, 0], w1 / zt[:, 1], w2 / zt[:, 2]], -1)[inside]  # perspective correction
    inv_z = b.sum(-1)
    b = b / inv_z[:, None]
    t, pix = t[inside], (py[inside].long() * res + px[inside].long())
    d = 1.0 / inv_z
    nearest = torch.full((n_pix,), math.inf, dtype=torch.float64).scatter_reduce(0, pix, d, "amin")
    front = d == nearest[pix]
    winner = torch.full((n_pix,), -1, dtype=torch.int64).scatter_reduce(0, pix[front], t[front], "amax")
    chosen = front & (t == winner[pix])
    bary = torch.zeros(n_pix, 3, dtype=torch.float64)
    bary[pix[chosen]] = b[chosen]
    return winner, bary


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


Textures = np.ndarray | Sequence[np.ndarray]  # one (H, W, C) texture per material, or one for a one-material mesh


def per_material(textures: Textures) -> list[np.ndarray]:
    """Textures as a list with one entry per material."""
    return [textures] if isinstance(textures, np.ndarray) else list(textures)


def sample_materials(textures: Textures, uv: Tensor, material: Tensor) -> Tensor:
    """Each pixel's lookup in its own material's texture (``sample_texture``); 0 where ``material`` is -1."""
    textures = per_material(textures)
    out = torch.zeros((*uv.shape[:-1], textures[0].shape[-1]))
    for index, texture in enumerate(textures):
        where = material == index
        out[where] = sample_texture(texture, uv[where])
    return out


@dataclass
class IntrinsicViews:
    """Per-view maps (V, H, W, C): normal 3, position 3, base colour 3, coverage 1, uv 2, latent 6 (if known),
    roughness and metalness 2 (if known); ``material`` (V, H, W): the material index of each pixel
    (of its first subsample when supersampled), -1 on the background."""

    normals: Tensor
    positions: Tensor
    base_color: Tensor
    coverage: Tensor
    uvs: Tensor
    latents: Tensor | None
    roughness_metalness: Tensor | None = None
    material: Tensor | None = None

    def conditions(self, prior: Tensor) -> Tensor:
        """The generator's condition channels (V, CONDITION_CHANNELS, H, W), in ``CONDITION_LAYOUT`` order;
        ``prior`` (V, H, W, 6) is the uplift prior's latents as these views see them (``prior.py``).

        Pixels below half coverage count as background: their maps are 0 and their
        coverage channel is 0 (1 inside), as the denoiser's output mask expects."""
        inside = (self.coverage > 0.5).float()[..., None]
        if self.roughness_metalness is None:
            pbr = torch.zeros((*self.coverage.shape, 3))
        else:
            pbr = torch.cat([self.roughness_metalness, torch.ones((*self.coverage.shape, 1))], -1)
        maps = torch.cat([self.normals, self.positions, self.base_color, pbr, prior], -1) * inside
        return torch.cat([maps, inside], -1).permute(0, 3, 1, 2).contiguous()


CONDITION_LAYOUT = (("normal", 3), ("position", 3), ("base_color", 3), ("roughness", 1), ("metalness", 1),
                    ("pbr_known", 1), ("prior", 6), ("coverage", 1))
CONDITION_CHANNELS = sum(c for _, c in CONDITION_LAYOUT)
PBR_CHANNELS = slice(9, 12)  # roughness, metalness, pbr_known: zeroed together where the maps are unknown
PRIOR_CHANNELS = slice(12, 18)  # the uplift prior's latents; swapped for the unknown-PBR prior with the maps


def render_intrinsics(mesh: Mesh, cameras: Cameras, base_color: Textures,
                      latents: Textures | None = None, supersample: int = 1,
                      roughness_metalness: Textures | None = None) -> IntrinsicViews:
    """Normals, positions, base colour (and latents, roughness and metalness) as seen by each camera;
    0 on the background. Each texture argument holds one texture per material of the mesh.

    With supersampling every map is the mean over the covered subsamples of a pixel
    (not premultiplied by coverage) and coverage is the covered fraction.
    """
    fine = Cameras(cameras.resolution * supersample, cameras.focal_px * supersample, cameras.camera_to_world)
    frags = rasterize(mesh, fine)
    material = frags.material(mesh.materials)
    cover = frags.coverage[..., None]
    n = frags.interpolate(mesh.normals, mesh.faces)
    uv = frags.interpolate(mesh.uvs, mesh.faces)
    maps = [n / n.norm(dim=-1, keepdim=True).clamp(min=1e-12), frags.interpolate(mesh.positions, mesh.faces),
            sample_materials(base_color, uv, material), uv]
    optional = [t for t in (latents, roughness_metalness) if t is not None]
    maps += [sample_materials(t, uv, material) for t in optional]
    if supersample > 1:
        pooled_cover = torch.nn.functional.avg_pool2d(cover.permute(0, 3, 1, 2), supersample)
        maps = [(torch.nn.functional.avg_pool2d(m.permute(0, 3, 1, 2), supersample)
                 / pooled_cover.clamp(min=1e-6)).permute(0, 2, 3, 1) for m in maps]
        cover = pooled_cover.permute(0, 2, 3, 1)
        maps[0] = maps[0] / maps[0].norm(dim=-1, keepdim=True).clamp(min=1e-12)
    rest = iter(maps[4:])
    return IntrinsicViews(maps[0], maps[1], maps[2], cover[..., 0], maps[3],
                          next(rest) if latents is not None else None,
                          next(rest) if roughness_metalness is not None else None,
                          material[:, ::supersample, ::supersample])
