"""The enhanced material as a small graph: the single source of truth.

Like a MaterialX nodegraph, the structure is data: closures (each kind defined
by one module of ``core/closures/`` and its twins on the other floors) combined by ``Layer`` (albedo-scaled coating), ``Mix`` and
``Add``. The torch evaluator, the Cycles OSL generator and the MaterialX
exporter each walk this graph; none of them hard-codes the lobe stack.

The nesting is right-leaning on purpose: Cycles' OSL ``layer()`` must not appear
inside the *top* of another layer, and conductors report an albedo of 1 when
used as a top (see docs/material-model.md). So

    layer(dust, layer(coat, mix(bg = layer(diel_core + diel_haze,
                                           layer(inner, layer(subsurf, diffuse))),
                                fg = cond_core + cond_haze,
                                mix = metalness)))

which gives T(wi) = T_dust * T_coat * (1 - m) * T_diel * T_inner * T_subsurf.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import ClassVar, Iterator, Mapping, Union

from .schema import PARAM_BY_NAME

@dataclass(frozen=True)
class Ref:
    """A parameter reference, optionally as ``1 - value`` (core = 1 - haze)."""

    name: str
    one_minus: bool = False

    def __post_init__(self) -> None:
        if self.name not in PARAM_BY_NAME:
            raise KeyError(f"unknown parameter {self.name!r}")


Value = Union[Ref, float, tuple[float, float, float]]

WHITE: tuple[float, float, float] = (1.0, 1.0, 1.0)


@dataclass(frozen=True)
class Lobe:
    """One weighted closure; ``closure`` names its kind in ``core.closures.KINDS``, which lists its inputs."""

    name: str
    closure: str
    weight: Ref
    inputs: Mapping[str, Value] = field(default_factory=dict)


@dataclass(frozen=True)
class Diffuse:
    """The Lambertian base with the PBR base colour; kept outside f_neu."""

    name: str = "diffuse"
    closure: ClassVar[str] = "diffuse"


@dataclass(frozen=True)
class Add:
    terms: tuple[Lobe, ...]


@dataclass(frozen=True)
class Layer:
    """``top`` coated over ``base``: base is scaled by T = 1 - max_c(albedo(top))."""

    top: Union[Lobe, Add]
    base: "Node"


@dataclass(frozen=True)
class Mix:
    """(1 - mix) * bg + mix * fg."""

    fg: "Node"
    bg: "Node"
    mix: Ref


Node = Union[Lobe, Add, Layer, Mix, Diffuse]

_CORE = Ref("haze_weight", one_minus=True)
_HAZE = Ref("haze_weight")


def _dielectric(name: str, weight: Ref, alpha: str, ior: str = "diel_ior",
                tint: Value = WHITE) -> Lobe:
    return Lobe(name, "dielectric", weight, {"ior": Ref(ior), "alpha": Ref(alpha), "tint": tint})


def _conductor(name: str, weight: Ref, alpha: str) -> Lobe:
    return Lobe(name, "conductor", weight, {"reflectivity": Ref("spec_color"),
                                            "edge_tint": Ref("edge_tint"),
                                            "alpha": Ref(alpha)})


DUST = Lobe("dust", "sheen", Ref("dust_weight"),
            {"roughness": Ref("dust_roughness"), "color": WHITE})
COAT = _dielectric("coat", Ref("coat_weight"), "coat_alpha", ior="coat_ior")
COND_CORE = _conductor("cond_core", _CORE, "alpha_core")
COND_HAZE = _conductor("cond_haze", _HAZE, "alpha_haze")
DIEL_CORE = _dielectric("diel_core", _CORE, "alpha_core")
DIEL_HAZE = _dielectric("diel_haze", _HAZE, "alpha_haze")
INNER = Lobe("inner", "sheen", Ref("inner_weight"),
             {"roughness": Ref("inner_roughness"), "color": Ref("scatter_color")})
SUBSURF = _dielectric("subsurf", Ref("subsurf_weight"), "subsurf_alpha", ior="subsurf_ior",
                      tint=Ref("scatter_color"))

SURFACE: Node = Layer(
    DUST,
    Layer(
        COAT,
        Mix(
            fg=Add((COND_CORE, COND_HAZE)),
            bg=Layer(Add((DIEL_CORE, DIEL_HAZE)),
                     Layer(INNER, Layer(SUBSURF, Diffuse()))),
            mix=Ref("metalness"),
        ),
    ),
)


def iter_lobes(node: Node) -> Iterator[Lobe]:
    """All lobes of a graph, top to bottom."""
    if isinstance(node, Lobe):
        yield node
    elif isinstance(node, Add):
        yield from node.terms
    elif isinstance(node, Layer):
        yield from iter_lobes(node.top)
        yield from iter_lobes(node.base)
    elif isinstance(node, Mix):
        yield from iter_lobes(node.fg)
        yield from iter_lobes(node.bg)


def _known(ref: Ref, constants: Mapping[str, float]) -> float | None:
    if ref.name not in constants:
        return None
    v = float(constants[ref.name])
    return 1.0 - v if ref.one_minus else v


def prune(node: Node, constants: Mapping[str, float]) -> Node | None:
    """Drop what a material cannot show, given its constant (scalar) parameters.

    A lobe whose weight is a constant 0 disappears, a layer without a top becomes its
    base, a mix with a constant 0 or 1 becomes one branch. Backends evaluate the
    pruned graph, so a Type 0 material never pays for dust, coat or scattering.
    Returns None when nothing is left (cannot happen for SURFACE: the diffuse stays).
    """
    if isinstance(node, Diffuse):
        return node
    if isinstance(node, Lobe):
        return None if _known(node.weight, constants) == 0.0 else node
    if isinstance(node, Add):
        kept = tuple(t for t in node.terms if prune(t, constants) is not None)
        if not kept:
            return None
        return kept[0] if len(kept) == 1 else replace(node, terms=kept)
    if isinstance(node, Layer):
        top = prune(node.top, constants)
        base = prune(node.base, constants)
        if top is None:
            return base
        if base is None:
            return top
        return Layer(top, base)  # type: ignore[arg-type]
    if isinstance(node, Mix):
        m = _known(node.mix, constants)
        fg = None if m == 0.0 else prune(node.fg, constants)
        bg = None if m == 1.0 else prune(node.bg, constants)
        if fg is None:
            return bg
        if bg is None:
            return fg
        return Mix(fg, bg, node.mix)
    raise TypeError(f"not a graph node: {node!r}")
