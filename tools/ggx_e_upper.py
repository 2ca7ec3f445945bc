"""Store the upper GGX albedo table the hybrid decoder's unit lobes divide by.

    python tools/ggx_e_upper.py   # rewrites torch_models/brdf/data/ggx_e_upper.npy

``tables.generate_ggx_e_upper`` takes about 30 s, too long to run in every process
that builds a hybrid decoder; ``tests/test_tables.py`` checks the stored table
against it.
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import torch

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from torch_models.brdf import tables  # noqa: E402


def main() -> None:
    torch.set_num_threads(1)
    with torch.no_grad():
        upper = tables.generate_ggx_e_upper()
    np.save(tables.GGX_E_UPPER_FILE, upper.numpy())
    print(f"wrote {tables.GGX_E_UPPER_FILE}: raised by {float((upper - tables.generate_ggx_e()).mean()):.5f} on average")


if __name__ == "__main__":
    main()
