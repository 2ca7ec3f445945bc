"""Isotropic GGX microfacet pieces as in Cycles' kernel/closure/bsdf_microfacet.h.

D, the height-correlated Smith G2 = 1 / (1 + Lambda_i + Lambda_o), visible-normal
sampling (Heitz 2018, with Cycles' concentric disk) and the pdf of the mirrored
direction. Angles enter as unit vectors so that sin^2 comes from x and y, not
from 1 - cos^2: at alpha = 1e-4 the peak of D lives in a region float32 1 - cos^2
cannot resolve.
"""
from __future__ import annotations

import math

import torch
from torch import Tensor

from .frame import cos_theta, reflect, safe_normalize, sample_uniform_disk, sin2_theta

ALPHA_MIN = 1e-4  # = richmat_addon.core.schema.ALPHA_MIN (a non-singular lobe in Cycles)
_COS_MIN = 1e-12  # keeps tan(theta) finite at exactly grazing directions


def clamp_alpha(alpha: Tensor) -> Tensor:
    """GGX alpha as Cycles uses it: saturated, and above our non-singular floor."""
    return alpha.clamp(ALPHA_MIN, 1.0)


def ggx_d(h: Tensor, alpha: Tensor) -> Tensor:
    """Normal distribution D(h) = a^2 / (pi (sin^2 + a^2 cos^2)^2), (..., 1)."""
    a2 = alpha * alpha
    return a2 / (math.pi * (sin2_theta(h) + a2 * cos_theta(h) ** 2) ** 2)


def ggx_lambda(w: Tensor, alpha: Tensor) -> Tensor:
    """Smith Lambda(w) = (sqrt(1 + a^2 tan^2) - 1) / 2 (Heitz 2014 eq. 72)."""
    tan2 = sin2_theta(w) / cos_theta(w).clamp(min=_COS_MIN) ** 2
    return 0.5 * ((1.0 + alpha * alpha * tan2).sqrt() - 1.0)


def ggx_g1(w: Tensor, alpha: Tensor) -> Tensor:
    """Smith masking 1 / (1 + Lambda)."""
    return 1.0 / (1.0 + ggx_lambda(w, alpha))


def ggx_g2(wi: Tensor, wo: Tensor, alpha: Tensor) -> Tensor:
    """Height-correlated masking-shadowing 1 / (1 + Lambda_i + Lambda_o)."""
    return 1.0 / (1.0 + ggx_lambda(wi, alpha) + ggx_lambda(wo, alpha))


def both_above(wi: Tensor, wo: Tensor) -> Tensor:
    """Where a reflection pair can be evaluated (Cycles: cos_NI > 0, cos_NO > 0)."""
    return (cos_theta(wi) > 0) & (cos_theta(wo) > 0)


def half_vector(wi: Tensor, wo: Tensor) -> Tensor:
    return safe_normalize(wi + wo)


def ggx_single_scatter(wi: Tensor, wo: Tensor, alpha: Tensor) -> tuple[Tensor, Tensor]:
    """(D G2 / (4 cos_i), h): the Fresnel-free single-scatter f * cos_o and its half vector.

    Zero unless both directions are above the surface.
    """
    h = half_vector(wi, wo)
    value = ggx_d(h, alpha) * ggx_g2(wi, wo, alpha) / (4.0 * cos_theta(wi).clamp(min=_COS_MIN))
    return torch.where(both_above(wi, wo), value, torch.zeros_like(value)), h


def vndf_frame(wi: Tensor, alpha: Tensor) -> tuple[Tensor, Tensor, Tensor]:
    """(wi_s, t1, t2): the stretched view direction and an orthonormal basis around it."""
    wi_s = safe_normalize(torch.cat([alpha * wi[..., :2], wi[..., 2:3]], -1))
    lensq = sin2_theta(wi_s)
    inv_len = lensq.clamp(min=1e-7).rsqrt()
    zero = torch.zeros_like(lensq)
    t1 = torch.where(lensq > 1e-7,
                     torch.cat([-wi_s[..., 1:2] * inv_len, wi_s[..., 0:1] * inv_len, zero], -1),
                     torch.cat([torch.ones_like(lensq), zero, zero], -1))
    return wi_s, t1, torch.linalg.cross(wi_s, t1, dim=-1)


def vndf_normal(frame: tuple[Tensor, Tensor, Tensor], alpha: Tensor, tx: Tensor, ty: Tensor) -> Tensor:
    """The microfacet normal of a point (tx, ty) of the projected-area region.

    The region is the upper half disk plus the lower half disk squashed by wi_s.z;
    a uniform point in it gives a VNDF-distributed normal (Heitz 2018 sec. 4.3, 3.4).
    """
    wi_s, t1, t2 = frame
    tz = (1.0 - tx * tx - ty * ty).clamp(min=0.0).sqrt()
    h_s = tx * t1 + ty * t2 + tz * wi_s
    return safe_normalize(torch.cat([alpha * h_s[..., :2], h_s[..., 2:3].clamp(min=0.0)], -1))


def ggx_sample_vndf(wi: Tensor, alpha: Tensor, u: Tensor) -> Tensor:
    """A microfacet normal distributed as D_wi(h) = G1(wi) max(0, wi.h) D(h) / cos_i.

    Heitz 2018 in Cycles' form (``microfacet_ggx_sample_vndf``): stretch wi,
    sample the projected hemisphere with the concentric disk, unstretch.
    """
    frame = vndf_frame(wi, alpha)
    disk = sample_uniform_disk(u)
    tx, ty = disk[..., 0:1], disk[..., 1:2]
    s = 0.5 * (1.0 + cos_theta(frame[0]))
    ty = (1.0 - s) * (1.0 - tx * tx).clamp(min=0.0).sqrt() + s * ty
    return vndf_normal(frame, alpha, tx, ty)


def ggx_sample(wi: Tensor, alpha: Tensor, u: Tensor) -> Tensor:
    """wo mirrored about a VNDF normal. May point below the surface (z <= 0): Cycles
    rejects such samples; here their pdf and eval are 0, so estimators stay unbiased."""
    return reflect(wi, ggx_sample_vndf(wi, clamp_alpha(alpha), u))


def ggx_pdf(wi: Tensor, wo: Tensor, alpha: Tensor) -> Tensor:
    """Solid-angle density of ``ggx_sample``: D G1(wi) / (4 cos_i), (..., 1).

    Zero for wo below the surface, so it integrates to the valid fraction (<= 1).
    """
    alpha = clamp_alpha(alpha)
    h = half_vector(wi, wo)
    value = ggx_d(h, alpha) * ggx_g1(wi, alpha) / (4.0 * cos_theta(wi).clamp(min=_COS_MIN))
    return torch.where(both_above(wi, wo), value, torch.zeros_like(value))
