"""Blender (the pip ``bpy`` module) in a fresh child process.

bpy keeps global state, and compiling OSL needs Blender's bundled OpenImageIO
imported before PyPI's, which a torch process has usually imported already: every
test and bench that needs Blender runs it in a child.
"""
from __future__ import annotations

import functools
import json
import os
import signal
import subprocess
import sys
import tempfile
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


EEVEE_PROBE = '''
import bpy
bpy.ops.wm.read_factory_settings(use_empty=False)
scene = bpy.context.scene
scene.render.engine = "BLENDER_EEVEE"
scene.render.resolution_x = scene.render.resolution_y = 4
scene.eevee.taa_render_samples = 1
bpy.ops.render.render()
'''


@functools.cache
def eevee_failure() -> str | None:
    """None where EEVEE renders with the pip bpy module here; else why not.

    Headless, EEVEE draws through EGL: Mesa's software OpenGL (llvmpipe) on a machine without a GPU.
    Where EGL finds no OpenGL, Blender aborts the whole process, so a child renders a 4 px frame first.
    """
    with tempfile.TemporaryDirectory(prefix="richmat_eevee_probe_") as user:
        proc = subprocess.run([sys.executable, "-c", EEVEE_PROBE], capture_output=True, text=True, timeout=300,
                              env=dict(os.environ, BLENDER_USER_RESOURCES=user))
    if proc.returncode == 0:
        return None
    said = [line for line in proc.stderr.splitlines() if line.strip() and "EGL_BAD_MATCH" not in line]
    return (f"EEVEE cannot start here (Blender exited {proc.returncode}: {said[-1] if said else 'no message'}); "
            "headless it needs Mesa's EGL and OpenGL drivers (Debian: libegl-mesa0 libgl1-mesa-dri)")
