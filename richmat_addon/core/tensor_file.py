"""Trained networks read without torch: the add-on's OSL preview and its numpy encoder
both run inside a stock Blender, whose Python has numpy only."""
from __future__ import annotations

import json
import struct
from pathlib import Path

import numpy as np

_DTYPES = {"F32": np.float32, "F16": np.float16, "F64": np.float64}


def read_safetensors(path: str | Path) -> dict[str, np.ndarray]:
    """Tensors of a .safetensors file (8-byte header size, JSON header, raw data) as float32."""
    raw = Path(path).read_bytes()
    (size,) = struct.unpack("<Q", raw[:8])
    header = json.loads(raw[8:8 + size])
    data = raw[8 + size:]
    out = {}
    for name, info in header.items():
        if name == "__metadata__":
            continue
        start, end = info["data_offsets"]
        out[name] = np.frombuffer(data[start:end], dtype=_DTYPES[info["dtype"]]).reshape(info["shape"]).astype(np.float32)
    return out


def linear_layers(tensors: dict[str, np.ndarray], prefix: str) -> list[tuple[np.ndarray, np.ndarray]]:
    """(weight (out, in), bias) of each Linear of the ``mlp`` named prefix (``decoder.net``: indices 0, 2, ...)."""
    keys = sorted({int(k[len(prefix) + 1:].split(".")[0]) for k in tensors if k.startswith(prefix + ".")})
    return [(tensors[f"{prefix}.{i}.weight"], tensors[f"{prefix}.{i}.bias"]) for i in keys]
