"""Blender (the pip ``bpy`` module) in a fresh child process.

bpy keeps global state, and compiling OSL needs Blender's bundled OpenImageIO
imported before PyPI's, which a torch process has usually imported already: every
test and bench that needs Blender runs it in a child.
"""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import textwrap
from pathlib import Path
from typing import Any

from .paths import REPO


def run_blender(source: str, folder: Path, timeout: float = 300.0) -> Any:
    """Run Python source with the pip bpy module in a fresh process, inside ``folder``.

    The source may print one line ``RESULT <json>``; its decoded value is returned.
    Blender's user folder points into ``folder`` so nothing leaks into ~/.config.
    """
    script = folder / "blender_script.py"
    script.write_text(textwrap.dedent(source))
    env = dict(os.environ, BLENDER_USER_RESOURCES=str(folder / "blender_user"), PYTHONPATH=str(REPO))
    # its own session, so a timeout also ends the backend processes the add-on started
    proc = subprocess.Popen([sys.executable, str(script)], cwd=folder, env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, start_new_session=True)
    try:
        stdout, stderr = proc.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        stdout, stderr = proc.communicate()
        raise AssertionError(f"blender script ran past {timeout:.0f} s:\n{stdout[-3000:]}\n{stderr[-3000:]}")
    if proc.returncode != 0:
        raise AssertionError(f"blender script failed ({proc.returncode}):\n{stdout[-3000:]}\n{stderr[-3000:]}")
    results = [ln[len("RESULT "):] for ln in stdout.splitlines() if ln.startswith("RESULT ")]
    return json.loads(results[-1]) if results else None
