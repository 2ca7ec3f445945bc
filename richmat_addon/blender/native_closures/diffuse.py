"""The Lambertian base in nodes: a Diffuse BSDF of the material's base colour."""
from __future__ import annotations

from typing import Optional

from ...core import graph
from ..native_nodes import Socket, Walker


class _Diffuse:
    """The base: no group of its own, since it has no weight or albedo to report."""

    def build(self, walker: Walker, node: graph.Diffuse) -> tuple[Socket, Optional[Socket]]:
        diffuse = walker.b.bsdf("ShaderNodeBsdfDiffuse", walker.inputs, label=node.name)
        walker.b.feed(diffuse.inputs["Color"], walker.inputs["base_color"])
        return diffuse.outputs[0], None


IMPLEMENTATION = _Diffuse()
