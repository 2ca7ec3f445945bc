"""Entry point: ``python batch/render_dataset.py ARGS`` or
``blender -b -Y --factory-startup --python-exit-code 1 -P batch/render_dataset.py -- ARGS``.

Only finds the repository and hands the arguments to the orchestrator, which
never imports bpy; see docs/batch.md. Without ``--python-exit-code 1`` Blender
ends with exit code 0 after an uncaught exception in a ``-P`` script, and a
farm would record a crashed task as done; so every exception is caught here
and ends the process with ``CRASH_EXIT`` through ``sys.exit``, which Blender
passes on as its own exit code.
"""
from __future__ import annotations

import sys
import traceback
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
CRASH_EXIT = 70  # the run itself crashed (sysexits' EX_SOFTWARE); 1 is "some assets failed"


def script_arguments(argv: list[str]) -> list[str]:
    """The arguments meant for this script: after ``--`` under Blender, else all of them."""
    return argv[argv.index("--") + 1:] if "--" in argv else argv[1:]


def entry(argv: list[str]) -> int:
    """The orchestrator's exit status, or ``CRASH_EXIT`` with the traceback on stderr."""
    if str(REPO) not in sys.path:
        sys.path.insert(0, str(REPO))
    try:
        from batch.orchestrator import main

        return main(script_arguments(argv))
    except Exception:
        traceback.print_exc()
        print(f"render_dataset.py: the run crashed (exit code {CRASH_EXIT})", file=sys.stderr)
        return CRASH_EXIT


if __name__ == "__main__":
    sys.exit(entry(sys.argv))
