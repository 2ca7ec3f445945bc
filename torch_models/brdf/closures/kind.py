"""What the torch floor implements for a closure kind, and what it may ask of the material.

The layered model (``brdf/model.py``) walks the pruned graph and calls these per
closure; a kind reads its inputs through ``Material.value``, so constants and
per-point parameters come to it alike.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Protocol

from torch import Tensor

from richmat_addon.core import graph

from .. import lobes


class Material(Protocol):
    """The part of ``LayeredBsdf`` a closure kind uses."""

    base_color: Tensor

    def value(self, value: graph.Value) -> Tensor: ...
    def cached(self, key: tuple[object, ...], compute: Callable[[], object]) -> object: ...


Node = graph.Lobe | graph.Diffuse


def white(material: Material, node: Node) -> Tensor:
    """The colour multiplier of a kind whose colour, if any, is inside its eval (1, 1)."""
    return material.value(1.0)


@dataclass(frozen=True)
class TorchClosure:
    """One closure kind for a unit weight, at N points; directions local, (N, 3).

    ``eval(m, node, wi, wo)``: f * cos(theta_o), (N, 1) or (N, 3);
    ``albedo(m, node, cos_i)``: the albedo the kind reports to the layering;
    ``sample(m, node, wi, u, rows)``: wo from uniforms u (N', 2) at the points ``rows``
    (per-point parameters are taken at those rows with ``at_rows``);
    ``pdf(m, node, wi, wo)``: the solid-angle density of ``sample``, (N, 1);
    ``colour(m, node)``: what multiplies the closure weight (sheen's colour, the
    diffuse base colour; 1 where the colour is inside the eval).
    """

    eval: Callable[[Material, Node, Tensor, Tensor], Tensor]
    albedo: Callable[[Material, Node, Tensor], Tensor]
    sample: Callable[[Material, Node, Tensor, Tensor, Tensor], Tensor]
    pdf: Callable[[Material, Node, Tensor, Tensor], Tensor]
    colour: Callable[[Material, Node], Tensor] = white


def at_rows(x: Tensor, rows: Tensor) -> Tensor:
    """Per-point rows of a parameter, leaving broadcast (1, C) parameters as they are."""
    return x if x.shape[0] == 1 else x[rows]


def ggx_sample(m: Material, lobe: graph.Lobe, wi: Tensor, u: Tensor, rows: Tensor) -> Tensor:
    """Visible-normal sampling of a lobe's ``alpha`` input (every GGX kind samples the same way)."""
    return lobes.ggx_sample(wi, at_rows(m.value(lobe.inputs["alpha"]), rows), u)


def ggx_pdf(m: Material, lobe: graph.Lobe, wi: Tensor, wo: Tensor) -> Tensor:
    return lobes.ggx_pdf(wi, wo, m.value(lobe.inputs["alpha"]))
