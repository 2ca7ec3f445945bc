"""Import guard: this Python imports only what a stock Blender 5.0's Python has (tests only).

Put this folder first on PYTHONPATH and set ``RICHMAT_STOCK_BLENDER`` to a file:
every Python started so imports the standard library, the modules Blender 5.0
bundles (``BUNDLED``), Blender's own scripts and add-ons, and the project's
Blender side (``PROJECT``); any other top-level import fails as in a stock
Blender (``ModuleNotFoundError``) and, when this Python has it, its name is
appended to that file, so a test sees what was refused even where the code
catches the error.

``BUNDLED``: what the pip ``bpy`` 5.0.1 wheel carries in
``bpy/5.0/python/lib/python3.11/site-packages`` (MaterialX, OpenImageIO,
PyOpenColorIO, oslquery, openvdb, pxr) and requires (numpy < 2, requests and its
idna, charset_normalizer, urllib3, certifi, zstandard, cython), all of which
Blender's own build bundles too (``build_files/build_environment``); docs/batch.md.
"""
from __future__ import annotations

import importlib.machinery
import os
import sys
from pathlib import Path

BUNDLED = frozenset({"numpy", "requests", "idna", "charset_normalizer", "urllib3", "certifi", "zstandard",
                     "cython", "Cython", "pyximport", "MaterialX", "OpenImageIO", "PyOpenColorIO", "oslquery",
                     "openvdb", "pxr"})
# The Blender side of this repository: the add-on, the farm, and the torch-free formats and clock of torch_models
# (assets/, stage_clock.py) the farm imports; torch itself is refused, so a torch import on that side is caught.
PROJECT = frozenset({"richmat_addon", "batch", "torch_models"})
ALLOWED = BUNDLED | PROJECT | frozenset(sys.stdlib_module_names) | {"sitecustomize"}


class StockBlenderGuard:
    """A ``sys.meta_path`` finder that refuses top-level modules a stock Blender lacks."""

    def __init__(self, log: Path) -> None:
        self.log = log
        spec = importlib.machinery.PathFinder.find_spec("bpy")
        # Blender's own scripts and add-ons (bpy_extras, cycles, io_scene_gltf2, ...) live in the bpy package
        self.blender_dir = Path(spec.submodule_search_locations[0]).resolve() if spec else None

    def find_spec(self, name: str, path: object = None, target: object = None) -> None:
        if "." in name or name in ALLOWED or name.startswith("_"):  # submodules of allowed packages, builtins
            return None
        found = importlib.machinery.PathFinder.find_spec(name)
        if found is None:  # not here either: the import fails as it would in Blender, nothing to refuse
            return None
        if (self.blender_dir is not None and found.origin
                and self.blender_dir in Path(found.origin).resolve().parents):
            return None
        with self.log.open("a") as f:
            f.write(f"{Path(sys.argv[0]).name if sys.argv and sys.argv[0] else '-'} {name}\n")
        raise ModuleNotFoundError(f"No module named {name!r} (not in a stock Blender 5.0: import guard)", name=name)


if os.environ.get("RICHMAT_STOCK_BLENDER"):
    sys.meta_path.insert(0, StockBlenderGuard(Path(os.environ["RICHMAT_STOCK_BLENDER"])))
