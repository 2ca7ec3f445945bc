"""`make demo`'s command on tiny sizes: every stage runs and writes what the README promises."""
import json
from pathlib import Path

import numpy as np
from PIL import Image

from torch_models.cli import main


def test_demo_writes_types_neural_comparison_and_generated_materials(tmp_path: Path) -> None:
    out = tmp_path / "demo"
    assert main(["demo", "--out", str(out), "--size", "8", "--resolution", "16", "--spp", "2",
                 "--fit-steps", "1", "--generate-size", "16"]) == 0
    for k in range(6):
        assert (out / f"type_{k}" / "params.json").is_file() and (out / f"type_{k}" / "material.mtlx").is_file()
        assert (out / f"type_{k}" / "neural" / "latent_0.exr").is_file()
    flips = json.loads((out / "neural_vs_analytic.json").read_text())["flip"]
    assert set(flips) == {f"type_{k}" for k in range(6)} and all(0 <= f <= 1 for f in flips.values())
    generated = json.loads((out / "generated.json").read_text())
    assert generated["held_out"] and len(generated["rows"]) == 3
    assert len({row["type"] for row in generated["rows"]}) == 3  # the prompts name different enhancements
    for png in ("side_by_side.png", "neural_vs_analytic.png", "generated.png"):
        image = np.asarray(Image.open(out / png))
        assert image.ndim == 3 and image.max() > 0
