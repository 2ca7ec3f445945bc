"""What the core floor knows of a closure kind: its inputs and its two text emitters.

An emitter receives the backend's writer (the OSL ``_Writer`` or the MaterialX
``_Builder``) and a graph node whose ``closure`` names the kind; the protocols
below are the part of each writer an emitter may use.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable, Protocol

from ..graph import Lobe, Value

# Every GGX lobe compensates its multiple scattering, so that Cycles' layer albedo is the lobe's true one.
GGX_DISTRIBUTION = "multi_ggx"


class OslWriter(Protocol):
    def value(self, value: Value) -> str: ...
    def as_color(self, value: Value) -> str: ...
    def clamped(self, value: Value, lo: float) -> str: ...
    def local(self, name: str) -> str: ...
    def declare(self, line: str) -> None: ...
    def once(self, key: tuple[Any, ...], make: Callable[[], str]) -> str: ...


class MtlxBuilder(Protocol):
    def node(self, category: str, name: str, out_type: str, **inputs: tuple[str, Any]) -> Any: ...
    def value(self, value: Value) -> Any: ...
    def param(self, name: str) -> Any: ...
    def clamped(self, value: Value, lo: float) -> Any: ...
    def alpha2(self, value: Value) -> Any: ...
    def as_color(self, value: Value) -> Any: ...
    def coloured_weight(self, lobe: Lobe, color_input: str) -> tuple[Any, Any]: ...
    def memo(self, key: tuple[Any, ...], make: Callable[[], Any]) -> Any: ...


@dataclass(frozen=True)
class ClosureKind:
    """One closure kind as the text backends see it.

    ``inputs`` are the keys a ``Lobe`` of this kind carries; ``colour_input`` is the
    one that colours its layering albedo (the terms of one layer top must share it).
    ``osl`` returns the closure expression (the lobe weight included), ``mtlx`` the
    BSDF node.
    """

    inputs: tuple[str, ...]
    osl: Callable[[OslWriter, Any], str]
    mtlx: Callable[[MtlxBuilder, Any], Any]
    colour_input: str | None = None
