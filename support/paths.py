"""Where the repository and the external sample assets are."""
from __future__ import annotations

from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
SHARED_ASSETS = REPO.parent / "shared" / "assets"  # not shipped with the repo: beside a clone


def shared_assets_or_skip() -> Path:
    """``SHARED_ASSETS``, or a pytest skip saying they are not beside this clone."""
    import pytest

    if not SHARED_ASSETS.is_dir():
        pytest.skip("the external sample assets (../shared/assets, not shipped with the repo) are not beside this clone")
    return SHARED_ASSETS
