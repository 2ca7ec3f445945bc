"""Lookup tables the Cycles closures read, regenerated here with Cycles' conventions.

Cycles ships these as arrays (``scene/shader.tables``, produced by
``app/cycles_precompute.cpp`` with Monte Carlo). We regenerate them from their
definitions with a deterministic Gauss-Legendre quadrature of the VNDF
(``vndf_quadrature``; fp64, cached per process: its cost is in docs/lobes.md)
and only check them against published values in the tests; nothing is copied.

Conventions (``kernel/util/lookup_table.h``, ``cycles_precompute.cpp``):

- node-centred grids: node i of n sits at i / (n - 1); the table's last axis is
  the first lookup coordinate (x), then y, then z;
- lookups are (bi/tri)linear with every coordinate clamped to [0, 1];
- the roughness coordinate is rough = sqrt(alpha); generation clamps rough and
  mu to >= 1e-4 and the IOR coordinate z to [1e-4, 0.99], with z^4 = F0.

Tables:

- ``ggx_E`` [mu 32][rough 32]: single-scatter GGX albedo E(mu) (no Fresnel).
- ``ggx_Eavg`` [rough 32]: the cosine-weighted mean 2 int E(mu) mu dmu.
- ``ggx_gen_schlick_ior_s`` [z 16][mu 16][rough 16]: mean over VNDF samples of
  the clamped interpolation factor (F(h.wi) - F0) / (1 - F0) of the exact dielectric
  Fresnel; samples mirrored below the surface count as 0 (Cycles' pdf == 0 case).
- ``sheen_ltc`` [A, B, R][roughness 32][mu 32]: Zeltner sheen LTC coefficients and
  albedo, measured from Cycles: bench/material/calibrate_sheen.py starts from Stephen
  Hill's closed-form fits (as MaterialX ships them) and fits the table to
  Cycles renders of the closure; the result ships as ``richmat_addon/core/data/sheen_ltc.npy``
  (Cycles' own table is a different fit than Hill's, see docs/lobes.md).
- ``ggx_fresnel_moments`` [16][mu 32][rough 32] (ours, not Cycles'): the
  single-scatter albedo with Fresnel replaced by each of 16 hat functions of
  c = h.wi, so any Fresnel's albedo is a linear combination of its node values.
"""
from __future__ import annotations

import functools
import itertools
import math
from pathlib import Path

import numpy as np
import torch
from torch import Tensor

from richmat_addon.core.sheen_table import sheen_table

from . import ggx
from .frame import cos_theta, dot, reflect
from .fresnel import fresnel_dielectric

E_SIZE = 32
S_SIZE = 16
SHEEN_SIZE = 32
QUADRATURE = 24  # Gauss-Legendre nodes per polar axis of the VNDF half disks
FRESNEL_NODES = 16  # hat functions in c = h.wi for the conductor albedo
S_QUADRATURE = 32  # the Fresnel ratio is steep at grazing mu: a finer rule for ``s``
TAU_MAX = 16.0  # graded radius reaches 1 - rho^2 = exp(-16): all mass that matters
BISECTIONS = 24  # horizon crossing along a ray, to TAU_MAX / 2^24
SHEEN_FIT_ROUGHNESS_MIN = 0.01  # MaterialX clamps the Hill fits' roughness here
_F64 = torch.float64


# ---- lookups (lookup_table.h) -------------------------------------------------
def lookup(table: Tensor, *coords: Tensor) -> Tensor:
    """Multilinear read of ``table`` at node-centred coordinates in [0, 1].

    ``coords`` are (x, y, z...) with x indexing the *last* table axis, as
    Cycles' ``lookup_table_read_{2D,3D}``. Coordinates are clamped, so any
    finite input reads the border. Returns the broadcast shape of the coords.
    """
    sizes = table.shape[::-1][:len(coords)]
    coords = torch.broadcast_tensors(*coords)
    flat = table.reshape(-1)
    strides = [math.prod(sizes[:d]) for d in range(len(sizes))]
    lo, hi, frac = [], [], []
    for c, n in zip(coords, sizes):
        x = c.clamp(0.0, 1.0) * (n - 1)
        i0 = x.floor().clamp(max=n - 1)
        lo.append(i0.long())
        hi.append((i0 + 1).clamp(max=n - 1).long())
        frac.append(x - i0)
    out = torch.zeros_like(coords[0])
    for corner in itertools.product((0, 1), repeat=len(sizes)):
        index = torch.zeros_like(lo[0])
        weight = torch.ones_like(coords[0])
        for d, bit in enumerate(corner):
            index = index + (hi[d] if bit else lo[d]) * strides[d]
            weight = weight * (frac[d] if bit else 1.0 - frac[d])
        out = out + weight * flat[index]
    return out


def nodes(n: int, lo: float = 1e-4, hi: float = 1.0) -> Tensor:
    """Cycles' node positions i / (n - 1), clamped as cycles_precompute does."""
    return (torch.arange(n, dtype=_F64) / (n - 1)).clamp(lo, hi)


def ior_from_z(z: Tensor) -> Tensor:
    """The IOR axis: z^4 = F0 (``ior_parametrization``)."""
    sqrt_f0 = z * z
    return (1.0 + sqrt_f0) / (1.0 - sqrt_f0)


def z_from_ior(ior: Tensor) -> Tensor:
    """Lookup coordinate of an IOR: sqrt(|ior - 1| / (ior + 1))."""
    return ((ior - 1.0).abs() / (ior + 1.0)).sqrt()


# ---- VNDF quadrature ----------------------------------------------------------
def _gauss_legendre(n: int, lo: float, hi: float) -> tuple[Tensor, Tensor]:
    x, w = np.polynomial.legendre.leggauss(n)
    half = 0.5 * (hi - lo)
    return torch.from_numpy(lo + half * (x + 1.0)), torch.from_numpy(half * w)


def _ray_point(frame: tuple[Tensor, Tensor, Tensor], alpha: Tensor, wi: Tensor,
               ray: tuple[Tensor, Tensor], tau: Tensor) -> tuple[Tensor, Tensor]:
    """(h, wo) at graded radius tau (1 - rho^2 = exp(-tau)) along a ray of the VNDF region."""
    rho = (1.0 - torch.exp(-tau)).sqrt()
    h = ggx.vndf_normal(frame, alpha, rho * ray[0], rho * ray[1])
    return h, reflect(wi, h)


def _valid_length(frame: tuple[Tensor, Tensor, Tensor], alpha: Tensor, wi: Tensor,
                  ray: tuple[Tensor, Tensor]) -> Tensor:
    """tau where the mirrored direction crosses the horizon along each ray (bisection).

    Going out along a ray tilts h away from wi, so wo sinks monotonically; rays
    that never cross it end at TAU_MAX.
    """
    lo = torch.zeros_like(ray[0])
    hi = torch.full_like(ray[0], TAU_MAX)
    for _ in range(BISECTIONS):
        mid = 0.5 * (lo + hi)
        above = cos_theta(_ray_point(frame, alpha, wi, ray, mid)[1]) > 0
        lo = torch.where(above, mid, lo)
        hi = torch.where(above, hi, mid)
    ends_above = cos_theta(_ray_point(frame, alpha, wi, ray, hi)[1]) > 0
    return torch.where(ends_above, hi, lo)


def vndf_quadrature(rough: Tensor, mu: Tensor, n: int = QUADRATURE) -> tuple[Tensor, Tensor, Tensor]:
    """Per (mu, rough) cell: the (G2/G1 weight, c = h.wi, rule weight) of VNDF nodes.

    Shapes (len(mu), len(rough), nodes). The VNDF is uniform on the upper unit
    half disk plus the lower half disk squashed by wi_s.z (Heitz 2018). We
    integrate it in polar coordinates, Gauss-Legendre in the angle and in the
    graded radius tau = -log(1 - rho^2) (GGX tails of small alpha live in a thin
    ring at the rim), each ray cut where the mirrored direction leaves the upper
    hemisphere: beyond it Cycles' sampler returns pdf = 0 (the sample counts as
    zero), and cutting there keeps the integrand smooth. The single-scatter albedo
    with Fresnel F(c) is sum(rule * F(c) * weight).
    """
    alpha = (rough * rough).reshape(1, -1, 1, 1)
    cos_i = mu.reshape(-1, 1, 1, 1)
    wi = torch.cat([(1.0 - cos_i ** 2).clamp(min=0.0).sqrt(), torch.zeros_like(cos_i), cos_i], -1)
    wi = wi.expand(len(mu), len(rough), 1, 3)
    frame = ggx.vndf_frame(wi, alpha)
    squash = cos_theta(frame[0])  # (mu, rough, 1, 1)
    phi, w_phi = _gauss_legendre(n, 0.0, math.pi)
    ones = torch.ones_like(squash)
    ray = (torch.cat([phi.cos(), phi.cos()])[:, None] * ones,
           torch.cat([phi.sin()[:, None] * ones, -phi.sin()[:, None] * squash], -2))
    ray_weight = torch.cat([w_phi[:, None] * ones, w_phi[:, None] * squash], -2)
    length = _valid_length(frame, alpha, wi, ray)  # (mu, rough, 2n, 1)
    v, w_v = _gauss_legendre(n, 0.0, 1.0)
    tau = length * v  # (mu, rough, 2n, n)
    per_node = tuple(f[..., None, :] for f in frame)
    h, wo = _ray_point(per_node, alpha[..., None], wi[..., None, :],
                       (ray[0][..., None], ray[1][..., None]), tau[..., None])
    rule = 0.5 * torch.exp(-tau) * length * w_v * ray_weight / (0.5 * math.pi * (1.0 + squash))
    lambda_i = ggx.ggx_lambda(wi[..., None, :], alpha[..., None])
    g2_over_g1 = (1.0 + lambda_i) / (1.0 + lambda_i + ggx.ggx_lambda(wo, alpha[..., None]))
    weight = torch.where(cos_theta(wo) > 0, g2_over_g1, torch.zeros_like(g2_over_g1))
    c = dot(wi[..., None, :], h)
    cells = (len(mu), len(rough), -1)
    return weight.reshape(cells), c.reshape(cells), rule.reshape(cells)


# ---- generation ---------------------------------------------------------------
def generate_ggx_e(n: int = QUADRATURE) -> Tensor:
    """E[mu][rough]: VNDF mean of G2/G1, 0 for invalid samples (``precompute_ggx_E``)."""
    weight, _, rule = vndf_quadrature(nodes(E_SIZE), nodes(E_SIZE), n)
    return (rule * weight).sum(-1).clamp(0.0, 1.0)


UPPER_SUBDIVISION = 8  # quadrature points per table cell and axis that the upper table must cover
UPPER_MARGIN = 5e-4  # absolute, over the quadrature's error (2e-4 relative against 64 nodes) and between points


def generate_ggx_e_upper(sub: int = UPPER_SUBDIVISION, margin: float = UPPER_MARGIN) -> Tensor:
    """E[mu][rough] raised just enough that its bilinear read is >= the single-scatter GGX albedo
    everywhere, not only at the nodes (``lookup`` of ``ggx_E`` falls up to 0.86 % short between them).

    E is evaluated on ``sub`` x ``sub`` points per cell; each node is raised by the largest
    shortfall of the bilinear read over the cells it touches, plus ``margin``. A read is a
    convex combination of its cell's four nodes, each raised by at least that cell's largest
    shortfall, so the read covers every evaluated point. The raise averages 0.1 % (0.9 % at
    most). About 30 s on one thread, hence stored (``tools/ggx_e_upper.py``)."""
    import torch.nn.functional as F

    table = generate_ggx_e()
    n = (E_SIZE - 1) * sub + 1
    fine = (torch.arange(n, dtype=_F64) / (n - 1)).clamp(1e-4, 1.0)
    rows = []
    for k in range(0, n, 16):
        weight, _, rule = vndf_quadrature(fine, fine[k:k + 16])
        rows.append((rule * weight).sum(-1))
    rough, mu = torch.meshgrid(fine, fine, indexing="xy")
    short = (torch.cat(rows) - lookup(table, rough, mu)).clamp(min=0.0)
    per_cell = short.unfold(0, sub + 1, sub).unfold(1, sub + 1, sub).amax((-1, -2))  # (E_SIZE - 1)^2
    per_node = F.max_pool2d(F.pad(per_cell[None, None], (1, 1, 1, 1)), 2, 1)[0, 0]
    return table + per_node + margin


def generate_ggx_eavg(n: int = QUADRATURE, n_mu: int = 32) -> Tensor:
    """Eavg[rough] = int_0^1 2 mu E(mu) dmu by Gauss-Legendre in mu."""
    mu, w = _gauss_legendre(n_mu, 0.0, 1.0)
    weight, _, rule = vndf_quadrature(nodes(E_SIZE), mu, n)
    e = (rule * weight).sum(-1)
    return (2.0 * (w * mu)[:, None] * e).sum(0).clamp(0.0, 1.0)


def generate_gen_schlick_ior_s(n: int = S_QUADRATURE) -> Tensor:
    """s[z][mu][rough]: VNDF mean of saturate((F(c) - F0) / (1 - F0)), 0 for invalid samples."""
    weight, c, rule = vndf_quadrature(nodes(S_SIZE), nodes(S_SIZE), n)
    slices = []
    for ior in ior_from_z(nodes(S_SIZE, 1e-4, 0.99)).tolist():
        f0 = ((ior - 1.0) / (ior + 1.0)) ** 2
        ratio = ((fresnel_dielectric(c, torch.tensor(ior, dtype=_F64)) - f0) / (1.0 - f0)).clamp(0.0, 1.0)
        slices.append((rule * ratio * (weight > 0)).sum(-1))
    return torch.stack(slices).clamp(0.0, 1.0)


def fresnel_nodes(dtype: torch.dtype = _F64, device: torch.device | None = None) -> Tensor:
    """Nodes c_j = (j / (J - 1))^2 of the hat basis in c = h.wi: dense at grazing c,
    where a metal's Fresnel bends towards 1."""
    return (torch.arange(FRESNEL_NODES, dtype=dtype, device=device) / (FRESNEL_NODES - 1)) ** 2


def _hat_weights(c: Tensor) -> Tensor:
    """Piecewise-linear interpolation weights of c on ``fresnel_nodes``, (..., J)."""
    knots = fresnel_nodes(c.dtype, c.device)
    c = c.clamp(0.0, 1.0)
    hi = torch.bucketize(c, knots).clamp(1, FRESNEL_NODES - 1)
    lo = hi - 1
    t = (c - knots[lo]) / (knots[hi] - knots[lo])
    weights = torch.zeros(c.shape + (FRESNEL_NODES,), dtype=c.dtype, device=c.device)
    weights.scatter_(-1, lo[..., None], (1.0 - t)[..., None])
    return weights.scatter_add_(-1, hi[..., None], t[..., None])


def generate_ggx_fresnel_moments(n: int = QUADRATURE) -> Tensor:
    """M_j[mu][rough] = single-scatter albedo with Fresnel = the j-th hat function of c.

    Any Fresnel F(c) then gives the albedo sum_j F(c_j) M_j, exact up to the
    piecewise-linear interpolation of F on the nodes. Shape [J][mu][rough].
    """
    weight, c, rule = vndf_quadrature(nodes(E_SIZE), nodes(E_SIZE), n)
    return torch.einsum("...n,...nj->j...", rule * weight, _hat_weights(c))


def hill_sheen_fit(mu: Tensor, roughness: Tensor) -> tuple[Tensor, Tensor, Tensor]:
    """Stephen Hill's fits of Zeltner's sheen LTC (A, B) and albedo R.

    The formulas of MaterialX ``mx_microfacet_sheen.glsl`` (``mx_zeltner_sheen_*``),
    roughness clamped to [0.01, 1] as MaterialX does.
    """
    x = mu
    y = roughness.clamp(SHEEN_FIT_ROUGHNESS_MIN, 1.0)
    a = (2.58126 * x + 0.813703 * y) * y / (1.0 + 0.310327 * x * x + 2.60994 * x * y)
    b = ((1.0 - x).clamp(min=0.0).sqrt() * (y - 1.0) * y ** 3
         / (0.0000254053 + 1.71228 * x - 1.71506 * x * y + 1.34174 * y * y))
    s = y * (0.0206607 + 1.58491 * y) / (0.0379424 + y * (1.32227 + y))
    mean = y * (-0.193854 + y * (-1.14885 + y * (1.7932 - 0.95943 * y * y))) / (0.046391 + y)
    offset = y * (0.000654023 + (-0.0207818 + 0.119681 * y) * y) / (1.26264 + y * (-1.92021 + y))
    r = torch.exp(-0.5 * ((x - mean) / s) ** 2) / (s * math.sqrt(2.0 * math.pi)) + offset
    return a, b, r


def hill_sheen_ltc() -> Tensor:
    """[A, B, R][roughness][mu] sampled from the Hill fits at the grid nodes: the
    starting point of bench/material/calibrate_sheen.py."""
    grid = torch.arange(SHEEN_SIZE, dtype=_F64) / (SHEEN_SIZE - 1)
    rough, mu = torch.meshgrid(grid, grid, indexing="ij")
    return torch.stack(hill_sheen_fit(mu, rough))


GGX_E_UPPER_FILE = Path(__file__).with_name("data") / "ggx_e_upper.npy"


def calibrated_sheen_ltc() -> Tensor:
    """[A, B, R][roughness][mu] fitted to Cycles' sheen by bench/material/calibrate_sheen.py."""
    return torch.from_numpy(sheen_table()).to(_F64)


def stored_ggx_e_upper() -> Tensor:
    """``generate_ggx_e_upper()`` as ``tools/ggx_e_upper.py`` stored it."""
    return torch.from_numpy(np.load(GGX_E_UPPER_FILE)).to(_F64)


_GENERATORS = {
    "ggx_E": generate_ggx_e,
    "ggx_E_upper": stored_ggx_e_upper,
    "ggx_Eavg": generate_ggx_eavg,
    "ggx_gen_schlick_ior_s": generate_gen_schlick_ior_s,
    "ggx_fresnel_moments": generate_ggx_fresnel_moments,
    "sheen_ltc": calibrated_sheen_ltc,
}


@functools.cache
def _cpu_table(name: str) -> Tensor:
    with torch.no_grad():
        return _GENERATORS[name]()


@functools.cache
def table(name: str, device: torch.device, dtype: torch.dtype) -> Tensor:
    """A generated table, computed once per process and cached per device and dtype."""
    return _cpu_table(name).to(device=device, dtype=dtype)


def _table_like(name: str, like: Tensor) -> Tensor:
    return table(name, like.device, like.dtype)


# ---- the reads the closures make ----------------------------------------------
def ggx_e(alpha: Tensor, mu: Tensor) -> Tensor:
    """E(sqrt(alpha), mu) as ``microfacet_ggx_preserve_energy`` reads it."""
    return lookup(_table_like("ggx_E", mu), alpha.sqrt(), mu)


def ggx_eavg(alpha: Tensor) -> Tensor:
    return lookup(_table_like("ggx_Eavg", alpha), alpha.sqrt())


def gen_schlick_ior_s(alpha: Tensor, mu: Tensor, ior: Tensor) -> Tensor:
    """s(sqrt(alpha), mu, z(ior)) as ``bsdf_microfacet_estimate_albedo`` reads it."""
    return lookup(_table_like("ggx_gen_schlick_ior_s", mu), alpha.sqrt(), mu, z_from_ior(ior))


def ggx_fresnel_moments(alpha: Tensor, mu: Tensor) -> Tensor:
    """The J hat-function albedos at (sqrt(alpha), mu), shape broadcast(alpha, mu)[:-1] + (J,)
    when alpha and mu end in a singleton axis."""
    t = _table_like("ggx_fresnel_moments", mu)
    return torch.cat([lookup(t[j], alpha.sqrt(), mu) for j in range(FRESNEL_NODES)], -1)


def sheen_ltc(mu: Tensor, roughness: Tensor) -> tuple[Tensor, Tensor, Tensor]:
    """(A, B, R) at (mu, roughness) as ``bsdf_sheen_setup`` reads them."""
    t = _table_like("sheen_ltc", mu)
    return lookup(t[0], mu, roughness), lookup(t[1], mu, roughness), lookup(t[2], mu, roughness)
