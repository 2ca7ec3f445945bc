"""MaterialX's own OSL generator (genosl) applied to the add-on's MaterialX export, made compilable by Cycles.

Used by bench/material/mtlx_osl_agreement.py and tests/test_mtlx.py; support/osl_script.py renders the result.

An outside check of the export: the document goes through the reference code
generator of the ``materialx`` wheel, not through anything of ours, and the OSL it
writes is what Cycles renders. Two things stop Cycles from compiling genosl's
output as it comes, and both are undone here without touching the shader code:

* genosl starts with ``#include "mx_funcs.h"``, which lives in the wheel's
  ``libraries/stdlib/genosl/include`` folder (with the ``color4.h``, ``vector2.h``,
  ``vector4.h`` and ``matrix33.h`` it includes). Cycles compiles a Script node with
  only its own shader folder on the include path, so the headers are inlined,
  each once, from the wheel.
* Those headers start with ``#pragma once``; once inlined it sits in the main
  file, and Blender 5.0's oslc crashes the whole process (SIGSEGV) on a
  ``#pragma once`` in the main file. The inlining does what the pragma did, so the
  lines are dropped.

Every closure genosl calls for our documents (``dielectric_bsdf``,
``conductor_bsdf``, ``sheen_bsdf``, ``oren_nayar_diffuse_bsdf``, ``layer``,
``transparent``) is one Cycles declares in its stdosl.h.
"""
from __future__ import annotations

import re
from pathlib import Path

import MaterialX as mx
from MaterialX import PyMaterialXGenOsl as genosl
from MaterialX import PyMaterialXGenShader as genshader

from richmat_addon.core import mtlx

SHADER_NAME = "richmat_mtlx"
_INCLUDE = re.compile(r'^[ \t]*#include[ \t]+"([^"]+)"[ \t]*$', re.M)
_PRAGMA_ONCE = re.compile(r"^[ \t]*#pragma[ \t]+once[ \t]*$\n?", re.M)


def include_folder() -> Path:
    """The wheel's genosl headers (``mx_funcs.h`` and what it includes)."""
    return Path(mx.__file__).parent / "libraries" / "stdlib" / "genosl" / "include"


def generate(doc: mx.Document, name: str = SHADER_NAME) -> str:
    """genosl's source for the document's (first) material, as MaterialX writes it."""
    full = mx.createDocument()
    full.copyContentFrom(doc)
    full.setDataLibrary(mtlx.standard_libraries())
    generator = genosl.OslShaderGenerator.create()
    context = genshader.GenContext(generator)
    context.registerSourceCodeSearchPath(mx.getDefaultDataSearchPath())
    shader = generator.generate(name, full.getMaterialNodes()[0], context)
    return shader.getSourceCode(genshader.PIXEL_STAGE)


def inline_includes(source: str, folder: Path | None = None) -> str:
    """``source`` with every quoted include found in ``folder`` (default: the wheel's) inlined once,
    and no ``#pragma once`` left (see the module docstring)."""
    folder = folder or include_folder()
    seen: set[str] = set()

    def expand(text: str) -> str:
        def one(match: re.Match[str]) -> str:
            name = match.group(1)
            if not (folder / name).is_file():
                return match.group(0)  # not genosl's: left for Cycles' own include path
            if name in seen:
                return ""
            seen.add(name)
            return expand((folder / name).read_text())

        return _INCLUDE.sub(one, _PRAGMA_ONCE.sub("", text))

    return expand(source)


def cycles_source(doc: mx.Document, name: str = SHADER_NAME) -> str:
    """The OSL text a Cycles Script node compiles for ``doc``: genosl's output, includes inlined."""
    return inline_includes(generate(doc, name))


def with_distribution(source: str, distribution: str) -> str:
    """``source`` with every ``*_distribution`` shader parameter defaulting to ``distribution``.

    genosl hands the MaterialX ``distribution`` input (``"ggx"``, the only value
    its enum has) to the closures as a shader parameter. Cycles' ``"ggx"`` is
    single scattering: rough lobes lose energy, and its layer albedo of a
    dielectric top is inflated. MaterialX's own GLSL renders GGX with energy
    compensation; in Cycles that is ``"multi_ggx"``. Setting the parameter is what
    an artist would do on the Script node's ``*_distribution`` inputs; the shader
    code is unchanged.
    """
    return re.sub(r'(\bstring[ \t]+\w+_distribution[ \t]*=[ \t]*)"[^"]*"', rf'\1"{distribution}"', source)
