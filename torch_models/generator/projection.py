"""Generated views back into texture space (paper sec. 5.2: splatting, view averaging, inpainting).

1. Splat: every covered pixel of every view adds its value to the four texels
   around its UV with bilinear weights, times cos^2 of the angle between the
   surface normal and the direction to the camera: a view that sees the
   surface squarely samples its texture densely and counts most.
2. Average: the weighted sum over the weight sum, where some view saw the texel.
3. Erode: seen texels within ``erode`` texels of an unseen texel of the UV charts
   are dropped; silhouettes and grazing views leave thin, unreliable rims there.
4. Inpaint: unseen chart texels take the mean of their known 8-neighbours, ring
   by ring, never crossing outside the charts.
5. Fallback: chart texels that inpainting cannot reach (an island no view saw)
   get the diffuse fallback value (a plain diffuse material's latent).
6. Pad: ``padding`` rings around the charts, so bilinear lookups at island
   borders never read the empty background.
"""
from __future__ import annotations

from dataclasses import dataclass

import torch
from torch import Tensor

from .views import Cameras, IntrinsicViews

SEEN_WEIGHT = 1e-3  # weight below which a texel counts as unseen


@dataclass
class Projection:
    texture: Tensor  # (H, W, C)
    seen: Tensor  # (H, W) bool: averaged from the views and kept after erosion
    inpainted: Tensor  # (H, W) bool
    fallback: Tensor  # (H, W) bool

    def stats(self, charts: Tensor) -> dict[str, float]:
        """Shares of the chart texels that were seen, inpainted, given the fallback."""
        total = max(int(charts.sum()), 1)
        return {k: int((getattr(self, k) & charts).sum()) / total for k in ("seen", "inpainted", "fallback")}


def view_weights(views: IntrinsicViews, cameras: Cameras) -> Tensor:
    """(V, H, W) cos^2 between the normal and the direction to the camera (0 off the object)."""
    to_camera = cameras.origins.float()[:, None, None, :] - views.positions
    to_camera = to_camera / to_camera.norm(dim=-1, keepdim=True).clamp(min=1e-12)
    cos = (views.normals * to_camera).sum(-1).clamp(min=0.0)
    return cos ** 2 * (views.coverage > 0.5)


def splat(values: Tensor, uvs: Tensor, weights: Tensor, size: tuple[int, int]) -> tuple[Tensor, Tensor]:
    """Bilinear splatting of (V, H, W, C) values at (V, H, W, 2) UVs: weighted sums (h, w, C) and weights (h, w)."""
    h, w = size
    sel = weights > 0
    val, uv, wt = values[sel], uvs[sel], weights[sel]
    x, y = uv[:, 0] * w - 0.5, uv[:, 1] * h - 0.5
    x0, y0 = x.floor(), y.floor()
    fx, fy = x - x0, y - y0
    acc = torch.zeros(h * w, values.shape[-1])
    wsum = torch.zeros(h * w)
    for dx, dy, bw in ((0, 0, (1 - fx) * (1 - fy)), (1, 0, fx * (1 - fy)), (0, 1, (1 - fx) * fy), (1, 1, fx * fy)):
        index = ((y0.long() + dy) % h) * w + (x0.long() + dx) % w
        acc.index_add_(0, index, val * (wt * bw)[:, None])
        wsum.index_add_(0, index, wt * bw)
    return acc.reshape(h, w, -1), wsum.reshape(h, w)


def _neighbour_sum(x: Tensor) -> Tensor:
    """3 x 3 box sum of (h, w, C) without wrapping."""
    k = torch.ones(x.shape[-1], 1, 3, 3, dtype=x.dtype)
    return torch.nn.functional.conv2d(x.permute(2, 0, 1)[None], k, padding=1, groups=x.shape[-1])[0].permute(1, 2, 0)


def _grow(mask: Tensor, rings: int) -> Tensor:
    out = mask.float()[..., None]
    for _ in range(rings):
        out = (_neighbour_sum(out) > 0).float()
    return out[..., 0] > 0


def fill(texture: Tensor, known: Tensor, allowed: Tensor, rings: int) -> tuple[Tensor, Tensor]:
    """Grow known texels into ``allowed`` unknown ones by 8-neighbour means, ``rings`` steps at most.

    Returns the texture and the new known mask."""
    texture, known = texture * known[..., None], known.clone()
    for _ in range(rings):
        total = _neighbour_sum(texture)
        count = _neighbour_sum(known.float()[..., None])[..., 0]
        new = allowed & ~known & (count > 0)
        if not bool(new.any()):
            break
        texture = torch.where(new[..., None], total / count.clamp(min=1)[..., None], texture)
        known = known | new
    return texture, known


def project(values: Tensor, views: IntrinsicViews, cameras: Cameras, charts: Tensor, fallback: Tensor,
            erode: int = 4, padding: int = 4) -> Projection:
    """Bake per-view values (V, H, W, C) into a texture over the UV ``charts`` (h, w) bool mask."""
    size = (int(charts.shape[0]), int(charts.shape[1]))
    acc, wsum = splat(values, views.uvs, view_weights(views, cameras), size)
    seen = (wsum > SEEN_WEIGHT) & charts
    texture = torch.where(seen[..., None], acc / wsum.clamp(min=1e-12)[..., None], torch.zeros_like(acc))
    if erode:
        seen = seen & ~_grow(charts & ~seen, erode)
    texture, known = fill(texture, seen, charts, rings=sum(size))
    inpainted = known & ~seen
    fallback_mask = charts & ~known
    texture = torch.where(fallback_mask[..., None], fallback.to(texture.dtype), texture)
    texture, _ = fill(texture, charts, ~charts, rings=padding)
    return Projection(texture, seen, inpainted, fallback_mask)
