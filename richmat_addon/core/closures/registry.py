"""A table of implementations keyed by closure kind, one per floor.

The core table (``core.closures.KINDS``) defines each kind: its inputs and its
OSL and MaterialX emitters. The torch floor (``torch_models.brdf.closures``) and
the Blender floor (``blender.native_closures``) keep their own tables keyed by
the same names, because core may import neither torch nor bpy. Each table fills
itself from the modules of its package (``discover``), so a new kind is one new
module per floor and no edit elsewhere.
"""
from __future__ import annotations

import importlib
import pkgutil
from contextlib import contextmanager
from typing import Generic, Iterator, TypeVar

T = TypeVar("T")


class Registry(Generic[T]):
    """Closure-kind name -> this floor's implementation of it."""

    def __init__(self, floor: str) -> None:
        self.floor = floor
        self._entries: dict[str, T] = {}

    def register(self, name: str, entry: T) -> None:
        if name in self._entries:
            raise ValueError(f"closure kind {name!r} already has a {self.floor} implementation")
        self._entries[name] = entry

    def unregister(self, name: str) -> None:
        del self._entries[name]

    @contextmanager
    def registered(self, name: str, entry: T) -> Iterator[T]:
        """``entry`` registered for the duration of a ``with`` block (a toy kind in a test)."""
        self.register(name, entry)
        try:
            yield entry
        finally:
            self.unregister(name)

    def __getitem__(self, name: str) -> T:
        try:
            return self._entries[name]
        except KeyError:
            raise KeyError(f"closure kind {name!r} has no {self.floor} implementation "
                           f"(known: {', '.join(sorted(self._entries))})") from None

    def __contains__(self, name: object) -> bool:
        return name in self._entries

    def names(self) -> tuple[str, ...]:
        return tuple(self._entries)

    def discover(self, package: str, path: list[str]) -> None:
        """Register ``IMPLEMENTATION`` of every module of ``package`` under its module name."""
        for info in sorted(pkgutil.iter_modules(path), key=lambda i: i.name):
            module = importlib.import_module(f"{package}.{info.name}")
            if hasattr(module, "IMPLEMENTATION"):
                self.register(info.name, module.IMPLEMENTATION)
