"""Local-frame vector helpers shared by the lobes (z = shading normal).

Directions are tensors shaped (..., 3); scalar results keep a trailing
dimension of 1 so they broadcast against (..., 1) and (..., 3) parameters.
"""
from __future__ import annotations

import math

import torch
from torch import Tensor

# Smallest length a vector may have before normalising it: keeps 0/0 out of
# half vectors and frames without changing any non-degenerate direction.
_TINY = 1e-30


def dot(a: Tensor, b: Tensor) -> Tensor:
    """Dot product over the last axis, keeping it: (..., 1)."""
    return (a * b).sum(-1, keepdim=True)


def cos_theta(w: Tensor) -> Tensor:
    """Cosine to the normal (the z component), (..., 1)."""
    return w[..., 2:3]


def sin2_theta(w: Tensor) -> Tensor:
    """Squared sine to the normal from x and y: exact near the pole, where 1 - z^2 cancels."""
    return w[..., 0:1] ** 2 + w[..., 1:2] ** 2


def safe_normalize(v: Tensor) -> Tensor:
    """Unit vector along v; a zero vector stays zero instead of becoming NaN."""
    return v / v.norm(dim=-1, keepdim=True).clamp(min=_TINY)


def reflect(wi: Tensor, h: Tensor) -> Tensor:
    """Mirror wi about the unit vector h."""
    return 2.0 * dot(wi, h) * h - wi


def tangent_frame(w: Tensor) -> tuple[Tensor, Tensor]:
    """(T, B): T the tangential direction of w, B = z x T.

    Cycles' ``make_orthonormals_safe_tangent(N, wi)`` (sample/mapping.h): B =
    normalize(N x wi), T = B x N. When w is (nearly) the normal any frame is
    valid; like Cycles we fall back to a fixed one, here T = x.
    """
    x, y = w[..., 0:1], w[..., 1:2]
    length = (x * x + y * y).sqrt()
    usable = length > 1e-7
    scale = 1.0 / length.clamp(min=1e-7)
    tx = torch.where(usable, x * scale, torch.ones_like(x))
    ty = torch.where(usable, y * scale, torch.zeros_like(y))
    zero = torch.zeros_like(x)
    return torch.cat([tx, ty, zero], -1), torch.cat([-ty, tx, zero], -1)


def to_local(v: Tensor, t: Tensor, b: Tensor) -> Tensor:
    """Coordinates of v in the frame (t, b, z)."""
    return torch.cat([dot(v, t), dot(v, b), v[..., 2:3]], -1)


def from_local(v: Tensor, t: Tensor, b: Tensor) -> Tensor:
    """Inverse of ``to_local`` for a tangential frame (t and b have z = 0)."""
    xy = v[..., 0:1] * t[..., :2] + v[..., 1:2] * b[..., :2]
    return torch.cat([xy, v[..., 2:3]], -1)


def sample_uniform_disk(u: Tensor) -> Tensor:
    """Shirley-Chiu concentric map of u in [0,1)^2 to the unit disk, (..., 2).

    The same map as Cycles' ``sample_uniform_disk`` so that stratified inputs
    stay stratified.
    """
    a = 2.0 * u[..., 0] - 1.0
    b = 2.0 * u[..., 1] - 1.0
    first = a * a > b * b
    r = torch.where(first, a, b)
    safe_a = torch.where(a == 0, torch.ones_like(a), a)
    safe_b = torch.where(b == 0, torch.ones_like(b), b)
    phi = torch.where(first, (math.pi / 4) * (b / safe_a),
                      math.pi / 2 - (math.pi / 4) * (a / safe_b))
    return torch.stack([r * phi.cos(), r * phi.sin()], -1)
