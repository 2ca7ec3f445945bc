"""What the Blender extension carries: the add-on modules ``richmat_addon/__init__.py`` reaches by imports.

Modules that only the farm and the torch side import (the glTF readers, the
caption vocabulary, ...) stay in the repository, out of the zip a user
installs. ``make extension`` runs ``python tools/extension_files.py DEST`` to
copy the modules and the data they read under DEST, keeping their paths inside the package.
"""
from __future__ import annotations

import modulefinder
import shutil
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
PACKAGE = "richmat_addon"


def addon_modules(root: Path = REPO) -> list[Path]:
    """The package's module files reached from its ``__init__``, relative to the package folder.

    ``modulefinder`` reads the imports from byte code, those inside functions too,
    without running anything; it searches ``root`` only, so bpy, numpy and the
    standard library are left out.
    """
    finder = modulefinder.ModuleFinder(path=[str(root)])
    finder.import_hook(PACKAGE)
    for name in _discovered_modules(root, finder):
        finder.import_hook(name)
    return sorted(Path(module.__file__).relative_to(root / PACKAGE) for name, module in finder.modules.items()
                  if name == PACKAGE or name.startswith(PACKAGE + "."))


def _discovered_modules(root: Path, finder: modulefinder.ModuleFinder) -> list[str]:
    """The modules a reached package imports at run time by listing itself (a closure registry's
    ``Registry.discover(__name__, __path__)``): no import statement names them."""
    found = []
    for name, module in list(finder.modules.items()):
        path = Path(module.__file__ or "")
        if name.startswith(PACKAGE) and path.name == "__init__.py" and \
                ".discover(__name__, __path__)" in path.read_text(encoding="utf-8"):
            found += [f"{name}.{p.stem}" for p in sorted(path.parent.glob("*.py")) if p.name != "__init__.py"]
    return found


def addon_data(root: Path = REPO) -> list[Path]:
    """The data files the modules read (``core/data``: the sheen table of the neural preview), relative
    to the package folder."""
    return sorted(p.relative_to(root / PACKAGE) for p in (root / PACKAGE / "core" / "data").iterdir() if p.is_file())


def copy_modules(dest: Path) -> None:
    for rel in addon_modules() + addon_data():
        (dest / rel).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(REPO / PACKAGE / rel, dest / rel)


if __name__ == "__main__":
    copy_modules(Path(sys.argv[1]))
