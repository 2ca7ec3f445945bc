"""Run Blender's extension CLI (``blender_ext.py``, shipped inside the bpy wheel).

``make extension`` runs ``python tools/blender_ext.py build ...``: the script is
looked up when it runs, inside the virtual environment make has just made, not
when make reads the Makefile (on a fresh clone the environment does not exist yet).
"""
from __future__ import annotations

import importlib.util
import subprocess
import sys
from pathlib import Path

CLI = "5.0/scripts/addons_core/bl_pkg/cli/blender_ext.py"


def cli_path() -> Path:
    """Path of ``blender_ext.py`` inside the installed bpy wheel."""
    spec = importlib.util.find_spec("bpy")
    if spec is None or spec.origin is None:
        raise SystemExit(f"{sys.executable} cannot import bpy: run make inside the repository so it installs .venv")
    return Path(spec.origin).parent / CLI


if __name__ == "__main__":
    sys.exit(subprocess.run([sys.executable, str(cli_path()), *sys.argv[1:]]).returncode)
