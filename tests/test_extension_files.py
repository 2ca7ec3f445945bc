"""The extension zip is the whole ``richmat_addon`` package, and the package needs nothing the zip lacks.

What only the farm, the torch backend, the tests or the benches read lives outside the package
(``torch_models/assets/``, ``support/``), so every module of it ships. The installed add-on then works
only if no module imports beyond the package and a stock Blender: the standard library, the modules
Blender bundles and Blender's own. An absolute ``richmat_addon`` import counts as beyond: the installed
package is named ``bl_ext.user_default.richmat``, so it reaches itself by relative imports only.
"""
from __future__ import annotations

import ast
import sys
import zipfile
from pathlib import Path

from tests.stock_blender.sitecustomize import BUNDLED
from tools.extension_files import PACKAGE, package_files

from .test_addon_extension import extension_zip  # noqa: F401  (session fixture)

BLENDER = frozenset({"bpy", "bmesh", "mathutils", "cycles", "addon_utils"})  # Blender's own modules
# Imported where present, with a fallback where not: xatlas (else Smart UV Project unwraps) and matplotlib
# (only for the maintainer's command that rewrites the named-colour table from it).
OPTIONAL = frozenset({"xatlas", "matplotlib"})


def absolute_imports(path: Path) -> set[str]:
    """The top-level names a module imports absolutely, inside functions too (relative imports stay in its
    package)."""
    found = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            found |= {alias.name.split(".")[0] for alias in node.names}
        elif isinstance(node, ast.ImportFrom) and node.level == 0:
            found.add(node.module.split(".")[0])
    return found


def test_the_zip_is_the_whole_package(extension_zip: Path) -> None:  # noqa: F811
    carried = {name for name in zipfile.ZipFile(extension_zip).namelist() if not name.endswith("/")}
    package = {p.as_posix() for p in package_files()}
    assert carried - package == {"blender_manifest.toml", "decoder/weights.safetensors", "decoder/state.json"}
    assert package <= carried, f"the zip lacks {sorted(package - carried)}"
    modules = {p.relative_to(PACKAGE).as_posix() for p in PACKAGE.rglob("*.py") if "__pycache__" not in p.parts}
    assert modules <= package and "core/data/sheen_ltc.npy" in package


def test_the_package_imports_only_itself_and_what_a_stock_blender_has() -> None:
    imported = {rel.as_posix(): absolute_imports(PACKAGE / rel) for rel in package_files() if rel.suffix == ".py"}
    allowed = set(sys.stdlib_module_names) | BUNDLED | BLENDER | OPTIONAL
    assert {module: sorted(names - allowed) for module, names in imported.items() if names - allowed} == {}
    assert "bpy" in imported["blender/addon.py"] and "numpy" in imported["core/maps.py"]  # the reader sees them


def test_the_reader_counts_absolute_imports_only(tmp_path: Path) -> None:
    module = tmp_path / "m.py"
    module.write_text("from .maps import ParamMap\nimport numpy as np\n\n\ndef f():\n"
                      "    from torch_models.assets import gltf_container\n    import richmat_addon.core.maps\n")
    assert absolute_imports(module) == {"numpy", "torch_models", "richmat_addon"}
