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

from dataclasses import dataclass
from typing import Callable, Mapping

import torch
from torch import Tensor

from richmat_addon.core import graph as g
from richmat_addon.core.colour import LUMINANCE
from richmat_addon.core.schema import CHANNEL_SLICES, PARAM_BY_NAME

from .closures import TORCH
from .closures.kind import TorchClosure


def luminance(rgb: Tensor) -> Tensor:
    w = torch.tensor(LUMINANCE, dtype=rgb.dtype, device=rgb.device)
    return (rgb * w).sum(-1, keepdim=True)


# The Lambertian base is a graph node of its own kind; every material has one, pruned or not (then T = 0).
_BASE = g.Diffuse()
_BASE_KIND = TORCH[g.Diffuse.closure]


def _kind(node: g.Lobe | g.Diffuse) -> TorchClosure:
    return TORCH[node.closure]


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
        self._cached: dict[tuple[object, ...], object] = {}
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

    def cached(self, key: tuple[object, ...], compute: Callable[[], object]) -> object:
        """A value that depends on no direction (a conductor's (n, k)), computed once per material."""
        if key not in self._cached:
            self._cached[key] = compute()
        return self._cached[key]

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
                out.append(_Term(node, w * self.value(node.weight) * _kind(node).colour(self, node)))
            elif isinstance(node, g.Add):
                for t in node.terms:
                    walk(t, w)
            elif isinstance(node, g.Layer):
                tops = [node.top] if isinstance(node.top, g.Lobe) else list(node.top.terms)
                albedo = sum(self.value(t.weight) * _kind(t).colour(self, t) * _kind(t).albedo(self, t, cos_i)
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
            per_lobe = [t.coeff * _kind(t.lobe).albedo(self, t.lobe, cos_i) * _ones3(cos_i) for t in terms]
            return per_lobe, diffuse * _BASE_KIND.colour(self, _BASE) * _BASE_KIND.albedo(self, _BASE, cos_i)
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
        base = diffuse * _BASE_KIND.colour(self, _BASE) * _BASE_KIND.eval(self, _BASE, wi, wo)
        return self._sum_terms(terms, wi, wo) + base

    def _sum_terms(self, terms: list[_Term], wi: Tensor, wo: Tensor) -> Tensor:
        total = torch.zeros(wi.shape[:-1] + (3,), dtype=wi.dtype, device=wi.device)
        for t in terms:
            total = total + t.coeff * _kind(t.lobe).eval(self, t.lobe, wi, wo)
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
        pdf = probs[..., -1:] * _BASE_KIND.pdf(self, _BASE, wi, wo)
        for j, lobe in enumerate(self.lobes):
            pdf = pdf + probs[..., j:j + 1] * _kind(lobe).pdf(self, lobe, wi, wo)
        return pdf.squeeze(-1)

    def sample(self, wi: Tensor, u: Tensor) -> Tensor:
        """Pick a component with u[:, 0], then sample it with u[:, 1:3]."""
        probs = self.selection_probabilities(wi)
        cdf = probs.cumsum(-1)
        choice = (u[..., :1] >= cdf[..., :-1]).sum(-1)
        wo = _BASE_KIND.sample(self, _BASE, wi, u[..., 1:3], torch.arange(len(wi), device=wi.device))
        for j, lobe in enumerate(self.lobes):
            rows = (choice == j).nonzero(as_tuple=True)[0]
            if rows.numel():
                wo[rows] = _kind(lobe).sample(self, lobe, wi[rows], u[rows, 1:3], rows)
        return wo


def _ones3(like: Tensor) -> Tensor:
    return torch.ones(like.shape[:-1] + (3,), dtype=like.dtype, device=like.device)


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
