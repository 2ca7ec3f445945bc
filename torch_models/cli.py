"""``python -m torch_models <command>``: one argparse front end, one small module per command.

A command module (listed in ``COMMANDS``) provides ``HELP`` (one line), a module
docstring (the long description), ``add_arguments(parser)`` and ``run(args) -> int``.
Command modules keep heavy imports (torch, OpenImageIO) inside ``run`` so that
``--help`` and the other commands stay fast.

Exit codes: 0 success, 2 bad input (one line on stderr naming the file and the
problem, no traceback), anything else is a bug and keeps its traceback.
"""
from __future__ import annotations

import argparse
import importlib
import sys
from pathlib import Path
from typing import Sequence

from richmat_addon.core.folder_io import FormatError, atomic_path  # noqa: F401  (atomic_path: for the commands)
from .assets.gltf_container import GltfError

PROG = "python -m torch_models"

COMMANDS: dict[str, str] = {
    "enhance": "torch_models.cli_enhance",
    "demo": "torch_models.cli_demo",
    "train-decoder": "torch_models.cli_train_decoder",
    "fit": "torch_models.cli_fit",
    "train-generator": "torch_models.cli_train_generator",
    "generate": "torch_models.cli_generate",
}


class InputError(ValueError):
    """Bad input that the user can fix; reported in one line with exit code 2."""


BAD_INPUT: tuple[type[Exception], ...] = (InputError, GltfError, FormatError)  # FormatError: a folder to write again


def emit(event: str, **fields: object) -> None:
    """One JSON-lines protocol event on stdout (the Blender add-on reads them, docs/addon.md)."""
    import json

    print(json.dumps({"event": event, **fields}), flush=True)


def emit_done(out: Path, **fields: object) -> None:
    """The protocol's last event: the output folder and the files in it."""
    emit("done", out=str(out), files=sorted(f.name for f in out.iterdir() if f.is_file()), **fields)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog=PROG, description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for name, module_name in COMMANDS.items():
        module = importlib.import_module(module_name)
        cmd = sub.add_parser(name, help=module.HELP, description=module.__doc__,
                             formatter_class=argparse.RawDescriptionHelpFormatter)
        module.add_arguments(cmd)
        cmd.set_defaults(run=module.run)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return int(args.run(args))
    except BAD_INPUT as exc:
        print(f"{PROG} {args.command}: error: {exc}", file=sys.stderr)
        return 2
