"""Shared test fixtures: Blender in a child process (``support.blender_child``, why there) inside the
test's tmp_path, and the external sample assets."""
from __future__ import annotations

from pathlib import Path
from typing import Any, Callable

import pytest

from support.blender_child import run_blender
from support.paths import shared_assets_or_skip


@pytest.fixture
def blender_run(tmp_path: Path) -> Callable[..., Any]:
    """``run_blender`` in the test's tmp_path."""

    def run(source: str, timeout: float = 300.0) -> Any:
        return run_blender(source, tmp_path, timeout)

    return run


@pytest.fixture
def shared_assets() -> Path:
    return shared_assets_or_skip()
