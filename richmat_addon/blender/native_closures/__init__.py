"""The Blender-node half of each closure kind, one module per kind named as in ``core/closures/``.

Each module defines ``IMPLEMENTATION``, a ``native_nodes.NativeClosure``: the
nodes Cycles' SVM and EEVEE render for the kind, and the layering albedo a top
reports (from the kind's fit in core). ``native_builder`` looks a lobe's kind up
here and never branches on it.
"""
from __future__ import annotations

from ...core.closures.registry import Registry
from ..native_nodes import NativeClosure

NATIVE: Registry[NativeClosure] = Registry("native")
NATIVE.discover(__name__, __path__)
