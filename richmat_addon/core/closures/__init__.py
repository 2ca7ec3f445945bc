"""The closure kinds of the material graph: one module per kind, found by ``KINDS.discover``.

Each module here defines ``IMPLEMENTATION``, a ``kind.ClosureKind``, and is the
kind's home on the core floor: its inputs, its OSL and MaterialX emitters and,
where the native node graph needs one, its layering-albedo fit. The torch and
Blender floors keep their halves under the same module name
(``torch_models/brdf/closures/``, ``richmat_addon/blender/native_closures/``).
"""
from __future__ import annotations

from .kind import ClosureKind
from .registry import Registry

KINDS: Registry[ClosureKind] = Registry("core")
KINDS.discover(__name__, __path__)
