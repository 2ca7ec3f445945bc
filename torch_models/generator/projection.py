"""Generated views back into texture space (paper sec. 5.2: splatting, view averaging, inpainting).

1. Splat: every covered pixel of every view adds its value to the four texels
   around its UV with bilinear weights, times cos^2 of the angle between the
   surface normal and the direction to the camera: a view that sees the
   surface squarely samples its texture densely and counts most.
2. Average: the weighted sum over the weight sum, where some view saw the texel.
   Pixels near a silhouette or an occlusion boundary of their view count
   ``RIM_TRUST`` times as much (``rim_trust``): the views are upsampled from the
   model's coarser pixels, which mix the surfaces on both sides there. They still
   make a texel seen; its value then comes from wherever a view sees it away
   from such rims, if one does.
3. Inpaint: unseen chart texels take the mean of their known 8-neighbours, ring
   by ring, never crossing outside the charts. Only texels no view sees are
   inpainted.
4. Fallback: chart texels that inpainting cannot reach (an island no view saw)
   get the diffuse fallback value (a plain diffuse material's latent).
5. Pad: ``padding`` rings around the charts, so bilinear lookups at island
   borders never read the empty background.
"""
from __future__ import annotations

from dataclasses import dataclass

import torch
from torch import Tensor

from .views import Cameras, IntrinsicViews

SEEN_WEIGHT = 1e-3  # weight below which a texel counts as unseen
RIM_TRUST = 0.01  # what a pixel near a silhouette or an occlusion boundary counts for in a texel's average
DEPTH_STEP = 3.0  # a step in depth between neighbouring pixels of more than this many pixel footprints is an edge


@dataclass
class Projection:
    texture: Tensor  # (H, W, C)
    seen: Tensor  # (H, W) bool: averaged from the views
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


def rim_trust(views: IntrinsicViews, cameras: Cameras, width: int) -> Tensor:
    """(V, H, W) ``RIM_TRUST`` within ``width`` pixels of the view's silhouette or of an occlusion
    boundary (neighbouring pixels more than ``DEPTH_STEP`` pixel footprints apart), 1 elsewhere."""
    covered = views.coverage > 0.5
    footprint = (views.positions - cameras.origins.float()[:, None, None, :]).norm(dim=-1) / cameras.focal_px
    edge = ~covered
    for dy, dx in ((0, 1), (1, 0)):
        h, w = covered.shape[1] - dy, covered.shape[2] - dx
        apart = (views.positions[:, :h, :w] - views.positions[:, dy:, dx:]).norm(dim=-1)
        step = (apart > DEPTH_STEP * footprint[:, dy:, dx:]) & covered[:, :h, :w] & covered[:, dy:, dx:]
        edge[:, :h, :w] |= step
        edge[:, dy:, dx:] |= step
    near = torch.nn.functional.max_pool2d(edge.float()[:, None], 2 * width + 1, 1, width)[:, 0] > 0
    return torch.where(near, RIM_TRUST, 1.0)


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
            padding: int = 4, pixels: Tensor | None = None, trust: Tensor | None = None) -> Projection:
    """Bake per-view values (V, H, W, C) into a texture over the UV ``charts`` (h, w) bool mask.

    ``pixels`` (V, H, W) bool keeps only those pixels (a material's, when materials have their own
    textures); ``trust`` (V, H, W) scales what each pixel counts for in the average (``rim_trust``),
    not whether it makes a texel seen."""
    size = (int(charts.shape[0]), int(charts.shape[1]))
    weights = view_weights(views, cameras)
    if pixels is not None:
        weights = weights * pixels
    acc, wsum = splat(values, views.uvs, weights if trust is None else weights * trust, size)
    _, visible = splat(values[..., :0], views.uvs, weights, size)
    seen = (visible > SEEN_WEIGHT) & charts
    texture = torch.where(seen[..., None], acc / wsum.clamp(min=1e-30)[..., None], torch.zeros_like(acc))
    texture, known = fill(texture, seen, charts, rings=sum(size))
    inpainted = known & ~seen
    fallback_mask = charts & ~known
    texture = torch.where(fallback_mask[..., None], fallback.to(texture.dtype), texture)
    texture, _ = fill(texture, charts, ~charts, rings=padding)
    return Projection(texture, seen, inpainted, fallback_mask)
