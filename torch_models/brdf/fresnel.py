"""Fresnel terms as Cycles 5.0 evaluates them (kernel/closure/bsdf_util.h).

- ``fresnel_dielectric``: exact unpolarised dielectric Fresnel, 1 under TIR.
- ``fresnel_conductor``: exact complex-IOR Fresnel per channel, ambient IOR 1.
- ``dielectric_fss`` / ``conductor_fss``: the average single-scattering Fresnel
  that Cycles' multi_ggx energy preservation uses (fits, not integrals).
- ``gulbrandsen``: the artist-friendly (r, g) -> (n, k) metal mapping.
"""
from __future__ import annotations

import torch
from torch import Tensor

# F82 model constants: the fit point cos = 1/7 (~82 deg), f = 1 - 1/7.
_F82_F = 6.0 / 7.0
_F82_F5 = _F82_F ** 5


def f0_from_ior(ior: Tensor) -> Tensor:
    """Normal-incidence reflectance of a dielectric interface."""
    return ((ior - 1.0) / (ior + 1.0)) ** 2


def fresnel_dielectric(cos_i: Tensor, eta: Tensor) -> Tensor:
    """Unpolarised reflectance (Rs + Rp) / 2 for relative IOR eta; 1 under TIR.

    Written as Cycles' ``fresnel_dielectric_cos`` (no refracted direction needed).
    """
    c = cos_i.abs()
    g2 = eta * eta - 1.0 + c * c
    g = g2.clamp(min=0.0).sqrt()
    a = (g - c) / (g + c).clamp(min=1e-30)
    b = (c * (g + c) - 1.0) / (c * (g - c) + 1.0)
    return torch.where(g2 > 0, 0.5 * a * a * (1.0 + b * b), torch.ones_like(a * b))


def fresnel_conductor(cos_i: Tensor, n: Tensor, k: Tensor) -> Tensor:
    """Unpolarised reflectance of a conductor n + ik seen from IOR 1 (Born & Wolf).

    ``cos_i`` (..., 1) broadcasts against per-channel ``n``, ``k`` (..., 3).
    """
    c = cos_i
    n2, k2 = n * n, k * k
    t1 = n2 - k2 - (1.0 - c * c)
    t2 = (t1 * t1 + (2.0 * n * k) ** 2).sqrt()
    u2 = (0.5 * (t2 + t1)).clamp(min=0.0)
    v2 = (0.5 * (t2 - t1)).clamp(min=0.0)
    u, v = u2.sqrt(), v2.sqrt()
    rs = ((c - u) ** 2 + v2) / ((c + u) ** 2 + v2).clamp(min=1e-30)
    t3 = (n2 - k2) * c
    t4 = 2.0 * n * k * c
    rp = ((t3 - u) ** 2 + (t4 - v) ** 2) / ((t3 + u) ** 2 + (t4 + v) ** 2).clamp(min=1e-30)
    return 0.5 * (rs + rp)


def dielectric_fss(eta: Tensor) -> Tensor:
    """Kulla-Conty fit of the cosine-weighted mean Fresnel, Cycles' ``fresnel_dielectric_Fss``."""
    above = (eta - 1.0) / (4.08567 + 1.00071 * eta)
    below = 0.997118 + eta * (0.1014 - eta * (0.965241 + eta * 0.130607))
    return torch.where(eta < 1.0, below, above)


def f82_b(f0: Tensor, f82: Tensor) -> Tensor:
    """B of the F82 model whose value at cos = 1/7 is ``f82`` (``fresnel_f82_B``)."""
    schlick = f0 + (1.0 - f0) * _F82_F5
    return (7.0 / (_F82_F5 * _F82_F)) * (schlick - f82)


def f82_fss(f0: Tensor, b: Tensor) -> Tensor:
    """Closed-form cosine-weighted mean of the F82 model (``fresnel_f82_Fss``)."""
    return f0 + (1.0 - f0) / 21.0 - b / 126.0


def conductor_f82_fit(n: Tensor, k: Tensor) -> tuple[Tensor, Tensor]:
    """(F0, B): the F82 model through the exact conductor Fresnel at 0 deg and ~82 deg."""
    one = torch.ones_like(n[..., :1])
    f0 = fresnel_conductor(one, n, k)
    return f0, f82_b(f0, fresnel_conductor(one / 7.0, n, k))


def conductor_fss(n: Tensor, k: Tensor) -> Tensor:
    """Cycles' ``fresnel_conductor_Fss``: the F82 fit's mean, saturated."""
    return f82_fss(*conductor_f82_fit(n, k)).clamp(0.0, 1.0)


def gulbrandsen(r: Tensor, g: Tensor) -> tuple[Tensor, Tensor]:
    """Gulbrandsen 2014 reflectivity r and edge tint g -> complex IOR (n, k).

    As OSL's ``artistic_ior`` / MaterialX ``mx_artistic_ior``: r clamped to
    [0, 0.99], n = mix(n_max, n_min, g), k from F(0) = r. So the exact conductor
    Fresnel at normal incidence returns r for every g.
    """
    r = r.clamp(0.0, 0.99)
    sqrt_r = r.sqrt()
    n_min = (1.0 - r) / (1.0 + r)
    n_max = (1.0 + sqrt_r) / (1.0 - sqrt_r)
    n = g * n_min + (1.0 - g) * n_max
    k2 = (r * (n + 1.0) ** 2 - (n - 1.0) ** 2) / (1.0 - r)
    return n, k2.clamp(min=0.0).sqrt()
