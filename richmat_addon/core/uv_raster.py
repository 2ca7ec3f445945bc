"""Rasterise a triangle mesh into texture space (numpy only).

Dust is driven by world-space normals (upward faces get dust) and its masks are
triplanar-mapped with world positions, but the enhanced parameters are textures.
So each texel needs the normal and position of the surface point that samples it.

UV convention: glTF puts UV (0, 0) at the top-left of the image, so texel row
``y = v * H`` counts down from the first stored row: no flip for glTF UVs. Blender
(and OpenGL) put v = 0 at the bottom; pass ``flip_v=True`` for UVs from Blender,
whose glTF importer stores ``v_blender = 1 - v_gltf``.

A texel is covered when its centre lies in a triangle (texel (x, y) has its centre at
uv = ((x + 0.5) / W, (y + 0.5) / H)). Where UV islands overlap, the triangle drawn last
wins. Uncovered texels next to covered ones get the mean of their covered neighbours,
``padding`` rings deep, so bilinear lookups at island borders do not pull in zeros.
UVs outside [0, 1] wrap (glTF's default REPEAT sampler).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

# Candidate texels evaluated at once (tiles x tile texels): bounds memory (~0.5 GB peak).
_CHUNK_TEXELS = 1 << 22
_TILE = 64
# Barycentric tolerance (float32 evaluation): texel centres on a shared edge belong to both sides.
_EDGE_EPS = -1e-6
# A texture space covered more than this many times over is tiled or stacked: a
# texel then stands for many surface points and has no single world position.
MAX_UV_OVERLAP = 2.0


@dataclass
class UvRaster:
    """Per-texel world-space data; texels outside every island (and the padding) are 0."""

    normals: np.ndarray  # (H, W, 3) float32, unit length where ``filled``
    positions: np.ndarray  # (H, W, 3) float32
    coverage: np.ndarray  # (H, W) bool: texel centre inside a triangle
    filled: np.ndarray  # (H, W) bool: covered or padded
    skipped: int = 0  # triangles left out: non-finite UVs, or wider than two texture widths


def uv_area(uvs: np.ndarray, indices: np.ndarray) -> float:
    """Total |area| of the triangles in UV space (1.0 = the texture covered once)."""
    a, b, c = (uvs[indices[:, k]].astype(np.float64) for k in range(3))
    cross = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (c[:, 0] - a[:, 0]) * (b[:, 1] - a[:, 1])
    return float(np.abs(cross).sum() / 2)


def rasterize(positions: np.ndarray, normals: np.ndarray, uvs: np.ndarray | None,
              indices: np.ndarray, size: tuple[int, int], padding: int = 4,
              flip_v: bool = False) -> tuple[UvRaster | None, str | None]:
    """World normals, positions and coverage per texel of an (H, W) map.

    Returns ``(raster, None)``, or ``(None, reason)`` when the texture space cannot
    hold world-space data (no UVs, zero UV area, a tiled/stacked texture space).
    """
    if uvs is None:
        return None, "the mesh has no UVs"
    h, w = size
    uv = uvs.astype(np.float64)
    if flip_v:
        uv[:, 1] = 1.0 - uv[:, 1]
    tri_xy = (uv * (w, h) - 0.5)[indices]  # (T, 3, 2); texel centres at integer coordinates
    finite = np.isfinite(tri_xy).all(axis=(1, 2))
    area = uv_area(uvs, indices[finite])
    if area <= 1e-12:
        return None, "the UVs have zero area"
    if area > MAX_UV_OVERLAP:
        return None, (f"the texture space is tiled or stacked (triangles cover {area:.1f}x the "
                      f"texture), so a texel has no single world position")
    tri_xy = np.where(finite[:, None, None], tri_xy, 0.0)
    lo = np.ceil(tri_xy.min(axis=1))
    extent = np.floor(tri_xy.max(axis=1)) - lo + 1  # texel centres spanned per axis
    (x0, y0), (x1, y1), (x2, y2) = (tri_xy[:, k].T for k in range(3))
    det = (y1 - y2) * (x0 - x2) + (x2 - x1) * (y0 - y2)
    bounded = finite & np.all(extent <= (2 * w, 2 * h), axis=1)
    tris = np.flatnonzero(bounded & np.all(extent > 0, axis=1) & (np.abs(det) > 1e-12))

    # Cut each triangle's texel box into tiles of at most _TILE^2 and process tiles of
    # equal (power-of-two) shape together: work follows the boxes' area, memory is capped.
    lo_t, ext_t = lo[tris].astype(np.int64), extent[tris].astype(np.int64)
    n_tiles = -(-ext_t // _TILE)  # (T, 2)
    count = n_tiles[:, 0] * n_tiles[:, 1]
    owner = np.repeat(np.arange(len(tris)), count)
    k = np.arange(int(count.sum())) - np.repeat(np.cumsum(count) - count, count)
    tile = np.stack([k % n_tiles[owner, 0], k // n_tiles[owner, 0]], axis=1) * _TILE
    origin = lo_t[owner] + tile
    tile_ext = np.minimum(_TILE, ext_t[owner] - tile)
    shape_log2 = np.ceil(np.log2(tile_ext)).astype(np.int64)
    keys = shape_log2[:, 0] * 64 + shape_log2[:, 1]

    # Barycentrics are affine in the texel offset within a tile: l = c + gx * dx + gy * dy,
    # with c, gx, gy per tile in float64 and the per-texel part in float32.
    t_all = tris[owner]
    inv = 1.0 / det[t_all]
    ox, oy = origin[:, 0], origin[:, 1]
    coeffs = np.stack([
        ((y1 - y2)[t_all] * (ox - x2[t_all]) + (x2 - x1)[t_all] * (oy - y2[t_all])) * inv,
        (y1 - y2)[t_all] * inv, (x2 - x1)[t_all] * inv,
        ((y2 - y0)[t_all] * (ox - x2[t_all]) + (x0 - x2)[t_all] * (oy - y2[t_all])) * inv,
        (y2 - y0)[t_all] * inv, (x0 - x2)[t_all] * inv,
    ], axis=1).astype(np.float32)

    flat_n = np.zeros((h * w, 3), np.float32)
    flat_p = np.zeros((h * w, 3), np.float32)
    covered = np.zeros(h * w, bool)
    for key in np.unique(keys):
        bw, bh = 1 << int(key // 64), 1 << int(key % 64)
        sel = np.flatnonzero(keys == key)
        offs = np.arange(bw * bh)
        dx, dy = (offs % bw).astype(np.float32), (offs // bw).astype(np.float32)
        per_chunk = max(1, _CHUNK_TEXELS // (bw * bh))
        for start in range(0, len(sel), per_chunk):
            p = sel[start:start + per_chunk]
            c = coeffs[p]
            l0 = c[:, 0, None] + c[:, 1, None] * dx + c[:, 2, None] * dy
            l1 = c[:, 3, None] + c[:, 4, None] * dx + c[:, 5, None] * dy
            l2 = 1.0 - l0 - l1
            # Padding texels of a tile's power-of-two box lie outside the triangle's
            # texel box, hence outside the triangle: no extent test is needed.
            ti, ci = np.nonzero((l0 >= _EDGE_EPS) & (l1 >= _EDGE_EPS) & (l2 >= _EDGE_EPS))
            weights = np.stack([l0[ti, ci], l1[ti, ci], l2[ti, ci]], axis=1)
            corners = indices[t_all[p[ti]]]  # (K, 3)
            texel = ((oy[p[ti]] + offs[ci] // bw) % h) * w + (ox[p[ti]] + offs[ci] % bw) % w
            flat_n[texel] = np.einsum("kcj,kc->kj", normals[corners], weights)
            flat_p[texel] = np.einsum("kcj,kc->kj", positions[corners], weights)
            covered[texel] = True

    nrm, pos, cov = flat_n.reshape(h, w, 3), flat_p.reshape(h, w, 3), covered.reshape(h, w)
    if not cov.any():
        return None, "no texel centre falls inside a triangle (UVs too small for this resolution)"
    data, filled = _dilate(np.concatenate([nrm, pos], axis=2), cov, padding)
    return UvRaster(normals=_normalise(data[:, :, :3]), positions=data[:, :, 3:].copy(),
                    coverage=cov, filled=filled, skipped=int(len(indices) - bounded.sum())), None


def _normalise(v: np.ndarray) -> np.ndarray:
    length = np.sqrt(np.einsum("hwc,hwc->hw", v, v))[:, :, None]
    return (v / np.where(length > 0, length, 1.0)).astype(np.float32)


def _grow(mask: np.ndarray) -> np.ndarray:
    """3 x 3 binary dilation of a boolean mask."""
    rows = mask.copy()
    rows[1:] |= mask[:-1]
    rows[:-1] |= mask[1:]
    out = rows.copy()
    out[:, 1:] |= rows[:, :-1]
    out[:, :-1] |= rows[:, 1:]
    return out


def _dilate(data: np.ndarray, mask: np.ndarray, rings: int) -> tuple[np.ndarray, np.ndarray]:
    """Grow ``data`` into unmasked texels by ``rings`` 8-neighbour mean steps.

    Only the frontier texels of each ring are gathered, so the cost follows the
    islands' perimeter, not the texture area.
    """
    data, mask = data * mask[:, :, None], mask.copy()
    h, w = mask.shape
    for _ in range(rings):
        gy, gx = np.nonzero(_grow(mask) & ~mask)
        if not len(gy):
            break
        total = np.zeros((len(gy), data.shape[2]), np.float32)
        count = np.zeros(len(gy), np.float32)
        for oy in (-1, 0, 1):
            for ox in (-1, 0, 1):
                ny, nx = gy + oy, gx + ox
                inside = (ny >= 0) & (ny < h) & (nx >= 0) & (nx < w)
                ny, nx = np.clip(ny, 0, h - 1), np.clip(nx, 0, w - 1)
                valid = mask[ny, nx] & inside
                total += data[ny, nx] * valid[:, None]
                count += valid
        data[gy, gx] = total / count[:, None]
        mask[gy, gx] = True
    return data, mask
