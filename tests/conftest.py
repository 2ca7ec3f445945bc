"""Shared test fixtures.

Blender (the pip ``bpy`` module) runs in a child process for every test that needs
it: bpy keeps global state, and compiling OSL needs Blender's bundled
OpenImageIO imported before PyPI's, which the torch side of a test session has
usually imported already.
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path
from typing import Any, Callable

import pytest

REPO = Path(__file__).resolve().parents[1]
SHARED_ASSETS = REPO.parent / "shared" / "assets"


def run_blender(source: str, folder: Path, timeout: float = 300.0) -> Any:
    """Run Python source with the pip bpy module in a fresh process, inside ``folder``.

    The source may print one line ``RESULT <json>``; its decoded value is returned.
    Blender's user folder points into ``folder`` so nothing leaks into ~/.config.
    Also used by bench/addon_assets.py.
    """
    script = folder / "blender_script.py"
    script.write_text(textwrap.dedent(source))
    env = dict(os.environ, BLENDER_USER_RESOURCES=str(folder / "blender_user"), PYTHONPATH=str(REPO))
    proc = subprocess.run([sys.executable, str(script)], cwd=folder, env=env,
                          capture_output=True, text=True, timeout=timeout)
    if proc.returncode != 0:
        raise AssertionError(f"blender script failed ({proc.returncode}):\n"
                             f"{proc.stdout[-3000:]}\n{proc.stderr[-3000:]}")
    results = [ln[len("RESULT "):] for ln in proc.stdout.splitlines() if ln.startswith("RESULT ")]
    return json.loads(results[-1]) if results else None


@pytest.fixture
def blender_run(tmp_path: Path) -> Callable[..., Any]:
    """``run_blender`` in the test's tmp_path."""

    def run(source: str, timeout: float = 300.0) -> Any:
        return run_blender(source, tmp_path, timeout)

    return run


@pytest.fixture
def shared_assets() -> Path:
    if not SHARED_ASSETS.is_dir():
        pytest.skip("../shared/assets is not beside this clone")
    return SHARED_ASSETS
