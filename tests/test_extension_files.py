"""The extension zip carries exactly the add-on modules that ``richmat_addon/__init__.py`` reaches by imports.

A module no add-on module imports (a reader only the farm or torch uses) must
not ship to users; a module an add-on module imports must, or the installed
add-on fails on first use.
"""
from __future__ import annotations

import zipfile
from pathlib import Path

from tools.extension_files import addon_modules

from .test_addon_extension import extension_zip  # noqa: F401  (session fixture)


def test_the_zip_carries_the_modules_the_addon_imports_and_no_others(extension_zip: Path):  # noqa: F811
    carried = {Path(name) for name in zipfile.ZipFile(extension_zip).namelist() if name.endswith(".py")}
    imported = set(addon_modules())
    assert not carried - imported, f"the zip carries modules no add-on module imports: {sorted(carried - imported)}"
    assert not imported - carried, f"the zip lacks modules the add-on imports: {sorted(imported - carried)}"
