"""The closures of the enhanced material, as Cycles 5.0 evaluates their OSL forms.

- ``sheen``: Cycles' ``sheen(N, r)`` / ``sheen_bsdf`` (Zeltner 2022 LTC,
  closure/bsdf_sheen.h).
- ``dielectric``: ``dielectric_bsdf(N, T, a, a, ior, tint, 0, "multi_ggx")``,
  reflection only (closure/bsdf_microfacet.h, osl/closures_setup.h).
- ``conductor``: ``conductor_bsdf(N, T, a, a, n, k, "multi_ggx")``.

All directions are unit vectors in the local frame (z = shading normal), shaped
(..., 3); wi points to the viewer, wo to the light. Parameters broadcast as (..., 1)
or (..., 3). ``*_eval`` returns f * cos(theta_o) for a unit closure weight, zero
unless wi.z > 0 and wo.z > 0. ``*_albedo`` is what the layering uses (see each).
"""
from __future__ import annotations

import math

import torch
from torch import Tensor

from richmat_addon.core.schema import SHEEN_ROUGHNESS_MIN  # Cycles' clamp

from . import tables
from .frame import cos_theta, from_local, sample_uniform_disk, tangent_frame, to_local
from .fresnel import (conductor_fss, dielectric_fss, f0_from_ior, fresnel_conductor,
                      fresnel_dielectric, gulbrandsen)
from .ggx import both_above, clamp_alpha, ggx_pdf, ggx_sample, ggx_single_scatter

__all__ = [
    "sheen_eval", "sheen_albedo", "sheen_sample", "sheen_pdf", "sheen_pdf_setup", "sheen_pdf_at",
    "dielectric_eval", "dielectric_albedo", "conductor_eval", "conductor_albedo",
    "ggx_sample", "ggx_pdf", "gulbrandsen", "multi_ggx_factor",
]

_SHEEN_DROP = 1e-5  # Cycles drops the closure when |A| or R falls below this
_E_MIN = 1e-4  # E >= 0.3 on the whole table; the clamp only guards the division


# ---- sheen (Zeltner LTC) ---------------------------------------------------------
def _sheen_setup(wi: Tensor, roughness: Tensor) -> tuple[Tensor, Tensor, Tensor, Tensor]:
    """(A, B, R, kept) as ``bsdf_sheen_setup``: roughness clamped, table read at mu."""
    r = roughness.clamp(SHEEN_ROUGHNESS_MIN, 1.0)
    a, b, albedo = tables.sheen_ltc(cos_theta(wi), r)
    kept = (a.abs() >= _SHEEN_DROP) & (albedo >= _SHEEN_DROP)
    return a, b, albedo, kept


def _ltc_density(local: Tensor, a: Tensor, b: Tensor) -> Tensor:
    """The LTC distribution (1/pi) z (A / |M^-1 w|^2)^2 with M^-1 = [[A,0,B],[0,A,0],[0,0,1]]."""
    x, y, z = local[..., 0:1], local[..., 1:2], local[..., 2:3]
    len_sq = (a * x + b * z) ** 2 + (a * y) ** 2 + z * z
    value = z * (a / len_sq.clamp(min=1e-30)) ** 2 / math.pi
    return torch.where(z > 0, value, torch.zeros_like(value))


def _sampling_a(a: Tensor) -> Tensor:
    """A for sampling and pdf: a dropped closure is never sampled by Cycles; we keep
    a valid (if degenerate) distribution so sample and pdf stay consistent."""
    return a.clamp(min=_SHEEN_DROP)


def sheen_eval(wi: Tensor, wo: Tensor, roughness: Tensor) -> Tensor:
    """R * LTC(wo) in the frame whose x axis is wi's tangential direction, (..., 1).

    Integrates over wo to exactly R(mu_i, r); not reciprocal (the frame and the
    table follow wi). Zero where Cycles drops the closure.
    """
    a, b, albedo, kept = _sheen_setup(wi, roughness)
    t, bt = tangent_frame(wi)
    value = albedo * _ltc_density(to_local(wo, t, bt), a, b)
    return torch.where(kept & both_above(wi, wo), value, torch.zeros_like(value))


def sheen_albedo(cos_i: Tensor, roughness: Tensor) -> Tensor:
    """R(mu, r): the layering albedo of ``sheen(N, r)`` (0 where the closure is dropped).

    As Cycles' table read, mu is clamped to [0, 1].
    """
    r = roughness.clamp(SHEEN_ROUGHNESS_MIN, 1.0)
    a, _, albedo = tables.sheen_ltc(cos_i, r)
    kept = (a.abs() >= _SHEEN_DROP) & (albedo >= _SHEEN_DROP)
    return torch.where(kept, albedo, torch.zeros_like(albedo))


def sheen_sample(wi: Tensor, roughness: Tensor, u: Tensor) -> Tensor:
    """LTC sampling (``bsdf_sheen_sample``): a cosine sample pushed through M."""
    a, b, _, _ = _sheen_setup(wi, roughness)
    a = _sampling_a(a)
    disk = sample_uniform_disk(u)
    dx, dy = disk[..., 0:1], disk[..., 1:2]
    dz = (1.0 - dx * dx - dy * dy).clamp(min=0.0).sqrt()
    local = torch.cat([dx - dz * b, dy, dz * a], -1)
    local = local / local.norm(dim=-1, keepdim=True).clamp(min=1e-30)
    t, bt = tangent_frame(wi)
    return from_local(local, t, bt)


def sheen_pdf(wi: Tensor, wo: Tensor, roughness: Tensor) -> Tensor:
    """Solid-angle density of ``sheen_sample``, (..., 1); integrates to 1."""
    return sheen_pdf_at(wo, sheen_pdf_setup(wi, roughness))


def sheen_pdf_setup(wi: Tensor, roughness: Tensor) -> Tensor:
    """(..., 8) what ``sheen_pdf`` reads at wi: the LTC's A and B and wi's tangent frame.
    It depends on wi alone, so a shading point computes it once for all its wo."""
    a, b, _, _ = _sheen_setup(wi, roughness)
    return torch.cat([_sampling_a(a), b, *tangent_frame(wi)], -1)


def sheen_pdf_at(wo: Tensor, setup: Tensor) -> Tensor:
    """``sheen_pdf`` at wo from its ``sheen_pdf_setup``, (..., 1)."""
    return _ltc_density(to_local(wo, setup[..., 2:5], setup[..., 5:8]), setup[..., 0:1], setup[..., 1:2])


# ---- multi_ggx energy preservation -------------------------------------------------
def multi_ggx_factor(cos_i: Tensor, alpha: Tensor, fss: Tensor) -> Tensor:
    """k = 1 + Fms (1 - E) / E with Fms = Fss Eavg / (1 - Fss (1 - Eavg)).

    Cycles' ``microfacet_ggx_preserve_energy`` splits this into ``energy_scale``
    = 1/E (applied in eval) and a weight ``darkening`` = k E; their product k
    multiplies the single-scatter lobe. Depends on wi only (not reciprocal).
    """
    e = tables.ggx_e(alpha, cos_i).clamp(min=_E_MIN)
    e_avg = tables.ggx_eavg(alpha)
    fms = fss * e_avg / (1.0 - fss * (1.0 - e_avg))
    return 1.0 + fms * (1.0 - e) / e


def _darkened_weight(cos_i: Tensor, alpha: Tensor, fss: Tensor) -> Tensor:
    """What multi_ggx multiplies ``sc->weight`` by: k E = E + Fms (1 - E)."""
    return multi_ggx_factor(cos_i, alpha, fss) * tables.ggx_e(alpha, cos_i).clamp(min=_E_MIN)


# ---- dielectric_bsdf, reflection only ---------------------------------------------
def _dielectric_fss(ior: Tensor, tint: Tensor) -> Tensor:
    """Fss of a reflection-only ``dielectric_bsdf``: fit(eta) * reflection tint."""
    return dielectric_fss(ior) * tint


def dielectric_eval(wi: Tensor, wo: Tensor, alpha: Tensor, ior: Tensor, tint: Tensor) -> Tensor:
    """tint F(h.wi) D G2 / (4 mu_i) * k(mu_i), (..., 3): exact Fresnel, multi_ggx."""
    alpha = clamp_alpha(alpha)
    single, h = ggx_single_scatter(wi, wo, alpha)
    fresnel = fresnel_dielectric((wi * h).sum(-1, keepdim=True), ior)
    k = multi_ggx_factor(cos_theta(wi), alpha, _dielectric_fss(ior, tint))
    return tint * fresnel * single * k


def dielectric_albedo(cos_i: Tensor, alpha: Tensor, ior: Tensor, tint: Tensor) -> Tensor:
    """The layering albedo Cycles reports for this closure, per unit weight, (..., 3).

    ``bsdf_albedo`` = ``sc->weight`` (carrying the multi_ggx darkening k E) times
    ``bsdf_microfacet_estimate_albedo``: tint [F0 + (1 - F0) s(sqrt(a), mu, z)] for
    ior > 1, tint F(mu) (a smooth-surface guess) otherwise.
    """
    alpha = clamp_alpha(alpha)
    f0 = f0_from_ior(ior)
    rough_estimate = f0 + (1.0 - f0) * tables.gen_schlick_ior_s(alpha, cos_i, ior)
    estimate = torch.where(ior > 1.0, rough_estimate, fresnel_dielectric(cos_i, ior))
    return tint * estimate * _darkened_weight(cos_i, alpha, _dielectric_fss(ior, tint))


# ---- conductor_bsdf --------------------------------------------------------------------
def conductor_eval(wi: Tensor, wo: Tensor, alpha: Tensor, n: Tensor, k: Tensor) -> Tensor:
    """F_conductor(h.wi) D G2 / (4 mu_i) * k(mu_i), (..., 3); Fss from the F82 fit."""
    alpha = clamp_alpha(alpha)
    single, h = ggx_single_scatter(wi, wo, alpha)
    fresnel = fresnel_conductor((wi * h).sum(-1, keepdim=True), n, k)
    return fresnel * single * multi_ggx_factor(cos_theta(wi), alpha, conductor_fss(n, k))


def conductor_albedo(cos_i: Tensor, alpha: Tensor, n: Tensor, k: Tensor) -> Tensor:
    """Directional albedo of ``conductor_eval`` at mu = cos_i, (..., 3).

    Cycles never uses a conductor's albedo for layering (it reports 1); this is
    our estimate of the true albedo, for lobe selection and the reflectance R:
    the exact Fresnel sampled at the nodes c_j of ``tables.fresnel_nodes``,
    weighted by the tabulated single-scatter albedos of the hat functions, times
    k(mu). Agreement with the integral of the eval is checked in the tests.
    """
    alpha = clamp_alpha(alpha)
    knots = tables.fresnel_nodes(n.dtype, n.device)
    fresnel = fresnel_conductor(knots[:, None], n[..., None, :], k[..., None, :])  # (..., J, 3)
    moments = tables.ggx_fresnel_moments(alpha, cos_i)  # (..., J)
    single = (moments[..., None] * fresnel).sum(-2)
    return single * multi_ggx_factor(cos_i, alpha, conductor_fss(n, k))
