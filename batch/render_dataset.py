"""Entry point: ``python batch/render_dataset.py ARGS`` or ``blender -b -P batch/render_dataset.py -- ARGS``.

Only finds the repository and hands the arguments to the orchestrator, which
never imports bpy; see docs/batch.md.
"""
from __future__ import annotations

import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def script_arguments(argv: list[str]) -> list[str]:
    """The arguments meant for this script: after ``--`` under Blender, else all of them."""
    return argv[argv.index("--") + 1:] if "--" in argv else argv[1:]


if __name__ == "__main__":
    if str(REPO) not in sys.path:
        sys.path.insert(0, str(REPO))
    from batch.orchestrator import main

    sys.exit(main(script_arguments(sys.argv)))
