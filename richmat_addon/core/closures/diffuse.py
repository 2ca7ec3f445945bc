"""The Lambertian base (``graph.Diffuse``): the PBR base colour, kept outside f_neu.

It has no weight or inputs of its own: the layers above scale it, and its colour
is the shader's ``base_color``. OSL ``diffuse()``; MaterialX
``oren_nayar_diffuse_bsdf`` with roughness 0, the same lobe.
"""
from __future__ import annotations

from typing import Any

from .. import graph
from .kind import ClosureKind, MtlxBuilder, OslWriter


def _osl(w: OslWriter, node: graph.Diffuse) -> str:
    return "base_color * diffuse(Nn)"


def _mtlx(b: MtlxBuilder, node: graph.Diffuse) -> Any:
    return b.node("oren_nayar_diffuse_bsdf", node.name, "BSDF", weight=("float", 1.0),
                  color=("color3", b.param("base_color")), roughness=("float", 0.0))


IMPLEMENTATION = ClosureKind(inputs=(), osl=_osl, mtlx=_mtlx)
