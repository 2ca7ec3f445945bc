"""What the Blender extension carries: the whole ``richmat_addon`` package, its modules and ``core/data``.

What only the farm, the torch backend, the tests or the benches use lives outside the package
(``torch_models/assets/``, ``support/``, ...), so the package is the add-on and nothing needs
pruning. ``make extension`` runs ``python tools/extension_files.py DEST`` to copy it under DEST,
keeping the paths inside the package.
"""
from __future__ import annotations

import shutil
import sys
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "richmat_addon"


def package_files(package: Path = PACKAGE) -> list[Path]:
    """The package's modules and the data they read (``core/data``: the sheen table, the named colours),
    relative to the package folder; byte-code caches stay behind."""
    modules = [p for p in package.rglob("*.py") if "__pycache__" not in p.parts]
    data = [p for p in (package / "core" / "data").iterdir() if p.is_file()]
    return sorted(p.relative_to(package) for p in modules + data)


def copy_package(dest: Path) -> None:
    for rel in package_files():
        (dest / rel).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(PACKAGE / rel, dest / rel)


if __name__ == "__main__":
    copy_package(Path(sys.argv[1]))
