"""Make OSL compilation work in the pip ``bpy`` module.

Cycles' Script node compiles through ``oslquery``, which is linked against
Blender's own OpenImageIO. The pip ``bpy`` module ships both in
``<bpy>/5.0/python/lib/python3.11/site-packages`` but does not put that folder
on ``sys.path``; if PyPI's OpenImageIO is imported first, ``oslquery`` fails with
"Unregistered type OpenImageIO_v3_0::TypeDesc". The Blender application has the
right modules on its path already, so there this is a no-op.
"""
from __future__ import annotations

import importlib
import sys
from pathlib import Path

import bpy


def bundled_site_packages() -> Path:
    """Blender's bundled site-packages (holds oslquery, OpenImageIO, MaterialX, ...)."""
    major, minor = sys.version_info[:2]
    return Path(bpy.utils.system_resource("PYTHON")) / "lib" / f"python{major}.{minor}" / "site-packages"


def prefer_blender_bundled_modules() -> None:
    """Put Blender's bundled modules first on sys.path and import its OpenImageIO and oslquery.

    Raises RuntimeError when another OpenImageIO was imported already: a Python
    process cannot hold two builds of the module, so the caller must run Blender
    work in a process that has not imported PyPI's (tests use a child process).
    """
    if bpy.app.binary_path:  # the Blender application: its own Python is set up
        return
    site = bundled_site_packages().resolve()
    if not site.is_dir():
        raise RuntimeError(f"Blender's bundled site-packages not found at {site}")
    loaded = sys.modules.get("OpenImageIO")
    if loaded is not None and site not in Path(loaded.__file__ or "").resolve().parents:
        raise RuntimeError(
            f"OpenImageIO was already imported from {loaded.__file__}; OSL compilation "
            "needs Blender's bundled copy. Call prefer_blender_bundled_modules() before "
            "anything imports OpenImageIO, or run the Blender work in a fresh process.")
    if str(site) in sys.path:
        sys.path.remove(str(site))
    sys.path.insert(0, str(site))
    importlib.import_module("OpenImageIO")
    importlib.import_module("oslquery")
