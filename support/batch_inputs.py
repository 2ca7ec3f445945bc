"""A small folder of farm inputs, good and deliberately broken: an OBJ with a unicode name, a texture far over
--max-texture and a missing roughness texture; an STL without UVs; a .blend whose driver and registered text
block would write marker files if they ever ran; a truncated GLB; an ASCII FBX; an OBJ with no faces; an
unsupported format."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
from PIL import Image

CUBE_OBJ = """mtllib {mtl}
v -1 -1 -1\nv 1 -1 -1\nv 1 1 -1\nv -1 1 -1\nv -1 -1 1\nv 1 -1 1\nv 1 1 1\nv -1 1 1
vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1
usemtl painted
f 1/1 4/4 3/3 2/2\nf 5/1 6/2 7/3 8/4\nf 1/1 2/2 6/3 5/4\nf 2/1 3/2 7/3 6/4\nf 3/1 4/2 8/3 7/4\nf 4/1 1/2 5/3 8/4
"""
TETRA_STL = """solid t
facet normal 0 0 -1\n outer loop\n  vertex 0 0 0\n  vertex 0 1 0\n  vertex 1 0 0\n endloop\nendfacet
facet normal 0 -1 0\n outer loop\n  vertex 0 0 0\n  vertex 1 0 0\n  vertex 0 0 1\n endloop\nendfacet
facet normal -1 0 0\n outer loop\n  vertex 0 0 0\n  vertex 0 0 1\n  vertex 0 1 0\n endloop\nendfacet
facet normal 1 1 1\n outer loop\n  vertex 1 0 0\n  vertex 0 1 0\n  vertex 0 0 1\n endloop\nendfacet
endsolid t
"""
TRAP_BLEND = """
import bpy, sys
marker = sys.argv[-2]
bpy.ops.wm.read_factory_settings(use_empty=True)
bpy.ops.mesh.primitive_cube_add()
cube = bpy.context.active_object
text = bpy.data.texts.new("autorun.py")
text.from_string(f"import pathlib; pathlib.Path({marker + '.text'!r}).touch()")
text.use_module = True
fcurve = cube.driver_add("location", 0)
fcurve.driver.type = "SCRIPTED"
fcurve.driver.expression = f"__import__('pathlib').Path({marker + '.driver'!r}).touch() or 0.0"
bpy.ops.wm.save_as_mainfile(filepath=sys.argv[-1])
"""


def make_inputs(folder: Path, marker: Path, env: dict[str, str]) -> None:
    folder.mkdir()
    rng = np.random.default_rng(0)
    Image.fromarray(rng.integers(0, 255, (1024, 1024, 3), np.uint8)).save(folder / "huge.png")
    (folder / "cube.mtl").write_text("newmtl painted\nKd 0.8 0.3 0.1\nmap_Kd huge.png\nPr 0.5\nmap_Pr gone.png\n")
    (folder / "painted cube ünï.obj").write_text(CUBE_OBJ.format(mtl="cube.mtl"))
    (folder / "no_uvs.stl").write_text(TETRA_STL)
    script = folder.parent / "make_trap.py"
    script.write_text(TRAP_BLEND)
    subprocess.run([sys.executable, str(script), str(marker), str(folder / "trap.blend")], check=True,
                   env=env, capture_output=True, timeout=120)
    import trimesh

    glb = trimesh.creation.box().export(file_type="glb")
    (folder / "truncated.glb").write_bytes(glb[: len(glb) // 2])
    (folder / "ascii.fbx").write_text('; FBX 7.4.0 project file\nFBXHeaderExtension:  {\n FBXHeaderVersion: 1003\n}\n')
    (folder / "zero_faces.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\n")
    (folder / "points.xyz").write_text("0 0 0\n")
