"""The torch half of each closure kind, one module per kind named as in ``richmat_addon/core/closures/``.

Each module defines ``IMPLEMENTATION``, a ``kind.TorchClosure`` built on the
Cycles-matching formulas of ``brdf/lobes.py``; ``brdf/model.py`` looks a lobe's
kind up here and never branches on it.
"""
from __future__ import annotations

from richmat_addon.core.closures.registry import Registry

from .kind import TorchClosure

TORCH: Registry[TorchClosure] = Registry("torch")
TORCH.discover(__name__, __path__)
