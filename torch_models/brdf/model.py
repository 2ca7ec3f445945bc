"""The enhanced BRDF evaluated by walking the material graph.

Layering follows Cycles' OSL ``layer()`` exactly (brdf-notes sec. 1): the base of a
layer is scaled by the scalar T = clamp(1 - max_c sum_i w_i a_i(mu_i), 0, 1),
where a_i is the albedo each top closure reports at the view direction. All such
weights depend on the view direction only, so they are computed once per
``wi`` and every lobe then contributes ``coefficient * lobe(wi, wo)``:

    f(wi, wo) cos = sum_j c_j(wi) f_j(wi, wo) cos + T(wi) base_color cos / pi

which is the paper's f = f_neu + T(wi) c / pi. Only the lobes left after
pruning by constant weights are ever evaluated.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Mapping

import torch
from torch import Tensor

from richmat_addon.core import graph as g
from richmat_addon.core.colour import LUMINANCE
from richmat_addon.core.schema import CHANNEL_SLICES, PARAM_BY_NAME

from . import lobes


def luminance(rgb: Tensor) -> Tensor:
    w = torch.tensor(LUMINANCE, dtype=rgb.dtype, device=rgb.device)
    return (rgb * w).sum(-1, keepdim=True)


@dataclass
class _Term:
    """A lobe with its view-dependent coefficient (product of weights and Ts above)."""

    lobe: g.Lobe
    coeff: Tensor  # (N, 1) or (N, 3)


class LayeredBsdf:
    """The enhanced material at N shading points (one parameter row per point).

    ``params`` maps schema names to tensors shaped (N, C) or (1, C); ``base_color``
    is (N, 3) or (1, 3). Directions are local (z = shading normal), (N, 3).
    Implements the renderer's BSDF protocol: eval returns f * cos(theta_o).
    """

    def __init__(self, params: Mapping[str, Tensor], base_color: Tensor,
                 node: g.Node = g.SURFACE) -> None:
        self.params = dict(params)
        self.base_color = base_color
        pruned = g.prune(node, constant_scalars(self.params))
        if pruned is None:
            raise ValueError("the material graph pruned to nothing")
        self.node = pruned
        # iter_lobes visits tops before bases and fg before bg, the order terms() uses.
        self.lobes = list(g.iter_lobes(self.node))
        self._nk: tuple[Tensor, Tensor] | None = None
        # View-dependent weights of the last view-direction tensor: a renderer calls
        # eval, pdf and sample with one ``wi`` and should pay for the layering once.
        self._memo: dict[str, tuple[Tensor, object]] = {}

    def _per_view(self, key: str, wi: Tensor, compute):  # type: ignore[no-untyped-def]
        hit = self._memo.get(key)
        if hit is not None and hit[0] is wi:
            return hit[1]
        value = compute()
        self._memo[key] = (wi, value)
        return value

    # ---- inputs -------------------------------------------------------------
    def value(self, v: g.Value) -> Tensor:
        ref_tensor = next(iter(self.params.values()))
        if isinstance(v, g.Ref):
            x = self.params[v.name]
            return 1.0 - x if v.one_minus else x
        return torch.as_tensor(v, dtype=ref_tensor.dtype, device=ref_tensor.device).reshape(1, -1)

    def conductor_ior(self) -> tuple[Tensor, Tensor]:
        """(n, k) from Gulbrandsen, computed once: it depends on no direction."""
        if self._nk is None:
            self._nk = lobes.gulbrandsen(self.params["spec_color"],
                                         self.params["edge_tint"].expand_as(self.params["spec_color"]))
        return self._nk

    # ---- per-lobe dispatch ----------------------------------------------------
    def _lobe_eval(self, lobe: g.Lobe, wi: Tensor, wo: Tensor) -> Tensor:
        i = lobe.inputs
        if lobe.closure == "sheen":
            return lobes.sheen_eval(wi, wo, self.value(i["roughness"]))
        if lobe.closure == "dielectric":
            return lobes.dielectric_eval(wi, wo, self.value(i["alpha"]), self.value(i["ior"]),
                                         self.value(i["tint"]))
        n, k = self.conductor_ior()
        return lobes.conductor_eval(wi, wo, self.value(i["alpha"]), n, k)

    def _lobe_albedo(self, lobe: g.Lobe, cos_i: Tensor) -> Tensor:
        i = lobe.inputs
        if lobe.closure == "sheen":
            return lobes.sheen_albedo(cos_i, self.value(i["roughness"]))
        if lobe.closure == "dielectric":
            return lobes.dielectric_albedo(cos_i, self.value(i["alpha"]), self.value(i["ior"]),
                                           self.value(i["tint"]))
        n, k = self.conductor_ior()
        return lobes.conductor_albedo(cos_i, self.value(i["alpha"]), n, k)

    def _lobe_sample(self, lobe: g.Lobe, wi: Tensor, u: Tensor, rows: Tensor) -> Tensor:
        i = lobe.inputs
        if lobe.closure == "sheen":
            return lobes.sheen_sample(wi, _rows(self.value(i["roughness"]), rows), u)
        return lobes.ggx_sample(wi, _rows(self.value(i["alpha"]), rows), u)

    def _lobe_pdf(self, lobe: g.Lobe, wi: Tensor, wo: Tensor) -> Tensor:
        if lobe.closure == "sheen":
            return lobes.sheen_pdf(wi, wo, self.value(lobe.inputs["roughness"]))
        return lobes.ggx_pdf(wi, wo, self.value(lobe.inputs["alpha"]))

    def _colour(self, lobe: g.Lobe) -> Tensor:
        """Sheen colour multiplies the closure (as ``w * c * sheen_bsdf(N, 1, r)``)."""
        return self.value(lobe.inputs["color"]) if lobe.closure == "sheen" else self.value(1.0)

    # ---- view-dependent weights --------------------------------------------------
    def terms(self, wi: Tensor) -> tuple[list[_Term], Tensor]:
        """Every lobe's coefficient at ``wi`` and the diffuse weight T(wi) (N, 1)."""
        return self._per_view("terms", wi, lambda: self._terms(wi))

    def _terms(self, wi: Tensor) -> tuple[list[_Term], Tensor]:
        cos_i = wi[..., 2:3].clamp(min=0.0)
        out: list[_Term] = []
        diffuse = torch.zeros_like(cos_i)

        def walk(node: g.Node, w: Tensor) -> None:
            nonlocal diffuse
            if isinstance(node, g.Diffuse):
                diffuse = diffuse + w
            elif isinstance(node, g.Lobe):
                out.append(_Term(node, w * self.value(node.weight) * self._colour(node)))
            elif isinstance(node, g.Add):
                for t in node.terms:
                    walk(t, w)
            elif isinstance(node, g.Layer):
                tops = [node.top] if isinstance(node.top, g.Lobe) else list(node.top.terms)
                albedo = sum(self.value(t.weight) * self._colour(t) * self._lobe_albedo(t, cos_i)
                             for t in tops)
                walk(node.top, w)
                transmit = (1.0 - albedo.amax(-1, keepdim=True)).clamp(0.0, 1.0)
                walk(node.base, w * transmit)
            elif isinstance(node, g.Mix):
                m = self.value(node.mix)
                walk(node.fg, w * m)
                walk(node.bg, w * (1.0 - m))

        walk(self.node, torch.ones_like(cos_i))
        return out, diffuse

    # ---- the quantities the paper names ----------------------------------------------
    def transmission(self, wi: Tensor) -> Tensor:
        """T(wi): the weight of the Lambertian base, (N, 1)."""
        return self.terms(wi)[1]

    def lobe_albedos(self, wi: Tensor) -> tuple[list[Tensor], Tensor]:
        """Per lobe, its weighted directional albedo at wi (N, 3); and T * base colour."""
        def compute() -> tuple[list[Tensor], Tensor]:
            cos_i = wi[..., 2:3].clamp(min=0.0)
            terms, diffuse = self.terms(wi)
            per_lobe = [t.coeff * self._lobe_albedo(t.lobe, cos_i) * _ones3(cos_i) for t in terms]
            return per_lobe, diffuse * self.base_color
        return self._per_view("albedos", wi, compute)

    def reflectance(self, wi: Tensor) -> Tensor:
        """R(wi): luminance of the non-diffuse part's directional albedo, (N, 1)."""
        per_lobe, _ = self.lobe_albedos(wi)
        if not per_lobe:
            return torch.zeros_like(wi[..., :1])
        return luminance(sum(per_lobe))

    def eval_neural_part(self, wi: Tensor, wo: Tensor) -> Tensor:
        """f_neu(wi, wo) * cos(theta_o), (N, 3): everything except the diffuse base."""
        terms, _ = self.terms(wi)
        return self._sum_terms(terms, wi, wo)

    def eval(self, wi: Tensor, wo: Tensor) -> Tensor:
        """Full f(wi, wo) * cos(theta_o), (N, 3)."""
        terms, diffuse = self.terms(wi)
        cos_o = wo[..., 2:3].clamp(min=0.0) * (wi[..., 2:3] > 0)
        return self._sum_terms(terms, wi, wo) + diffuse * self.base_color * cos_o / math.pi

    def _sum_terms(self, terms: list[_Term], wi: Tensor, wo: Tensor) -> Tensor:
        total = torch.zeros(wi.shape[:-1] + (3,), dtype=wi.dtype, device=wi.device)
        for t in terms:
            total = total + t.coeff * self._lobe_eval(t.lobe, wi, wo)
        return total

    # ---- importance sampling -------------------------------------------------------
    def selection_probabilities(self, wi: Tensor) -> Tensor:
        """(N, L + 1): probability of sampling each lobe, last column the diffuse.

        Proportional to each component's albedo luminance, so sampling follows
        where the energy is; uniform where a point reflects nothing.
        """
        per_lobe, diffuse = self.lobe_albedos(wi)
        lum = torch.cat([luminance(a) for a in per_lobe] + [luminance(diffuse)], dim=-1)
        lum = lum.clamp(min=0.0)
        total = lum.sum(-1, keepdim=True)
        uniform = torch.full_like(lum, 1.0 / lum.shape[-1])
        return torch.where(total > 0, lum / total.clamp(min=1e-30), uniform)

    def pdf(self, wi: Tensor, wo: Tensor) -> Tensor:
        """Solid-angle pdf of ``sample``, (N,)."""
        probs = self.selection_probabilities(wi)
        pdf = probs[..., -1:] * wo[..., 2:3].clamp(min=0.0) / math.pi
        for j, lobe in enumerate(self.lobes):
            pdf = pdf + probs[..., j:j + 1] * self._lobe_pdf(lobe, wi, wo)
        return pdf.squeeze(-1)

    def sample(self, wi: Tensor, u: Tensor) -> Tensor:
        """Pick a component with u[:, 0], then sample it with u[:, 1:3]."""
        probs = self.selection_probabilities(wi)
        cdf = probs.cumsum(-1)
        choice = (u[..., :1] >= cdf[..., :-1]).sum(-1)
        wo = _cosine_sample(u[..., 1:3])
        for j, lobe in enumerate(self.lobes):
            rows = (choice == j).nonzero(as_tuple=True)[0]
            if rows.numel():
                wo[rows] = self._lobe_sample(lobe, wi[rows], u[rows, 1:3], rows)
        return wo


def _rows(x: Tensor, rows: Tensor) -> Tensor:
    """Select per-point rows of a parameter, leaving broadcast (1, C) parameters as they are."""
    return x if x.shape[0] == 1 else x[rows]


def _ones3(like: Tensor) -> Tensor:
    return torch.ones(like.shape[:-1] + (3,), dtype=like.dtype, device=like.device)


def _cosine_sample(u: Tensor) -> Tensor:
    r = u[..., 0].sqrt()
    phi = 2.0 * math.pi * u[..., 1]
    z = (1.0 - u[..., 0]).clamp(min=0.0).sqrt()
    return torch.stack([r * phi.cos(), r * phi.sin(), z], dim=-1)


def constant_scalars(params: Mapping[str, Tensor]) -> dict[str, float]:
    """Scalar parameters equal at every point: what graph pruning may rely on."""
    out: dict[str, float] = {}
    for name, x in params.items():
        if PARAM_BY_NAME[name].channels == 1 and bool((x == x.reshape(-1)[0]).all()):
            out[name] = float(x.reshape(-1)[0])
    return out


def params_from_vectors(vectors: Tensor) -> dict[str, Tensor]:
    """Split packed (N, 22) parameter vectors into named (N, C) tensors."""
    return {name: vectors[:, sl] for name, sl in CHANNEL_SLICES.items()}
