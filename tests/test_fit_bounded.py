"""The bounded fit: its decoder evaluations stop growing with the texture past the budget, and
its representatives keep apart what the decoder draws apart."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch

from richmat_addon.core import material_folder, neural_folder
from richmat_addon.core.enhance import enhance
from richmat_addon.core.folder_io import read_exr
from richmat_addon.core.maps import ParamMap, PbrInputs
from richmat_addon.core.schema import CHANNEL_SLICES
from richmat_addon.core.texel_vectors import read_vectors
from torch_models.neural import trained
from torch_models.neural.fit import representatives
from torch_models.neural.fit.material import FitSettings, fit_material

BUDGET, STEPS = 256, 2


@pytest.fixture(scope="module")
def model():  # type: ignore[no-untyped-def]
    return trained.load(trained.SHIPPED)


def noisy_material(folder: Path, size: int) -> Path:
    """A material whose every texel holds its own vector (random colour, roughness and metal)."""
    rng = np.random.default_rng(size)
    pbr = PbrInputs(f"noise_{size}", ParamMap(rng.uniform(0, 1, (size, size, 3))),
                    ParamMap(rng.uniform(0, 1, (size, size, 1))),
                    ParamMap((rng.uniform(0, 1, (size, size, 1)) < 0.5).astype(np.float32)))
    material_folder.write(folder, enhance(pbr, 2, 0), {"asset": "test"})
    return folder


def evaluations(model, material: Path, out: Path, budget: int) -> tuple[int, dict]:  # type: ignore[no-untyped-def]
    """Decoder rows evaluated by one whole fit (fit, energy check and error readout), and its record."""
    rows: list[int] = []
    hook = model.decoder.register_forward_pre_hook(lambda module, args: rows.append(len(args[0])))
    try:
        record = fit_material(model, material, out, FitSettings(steps=STEPS, budget=budget))
    finally:
        hook.remove()
    return sum(rows), record


def test_decoder_evaluations_do_not_grow_with_the_texture_past_the_budget(model, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    small, large = noisy_material(tmp_path / "small", 48), noisy_material(tmp_path / "large", 96)
    assert BUDGET < len(read_vectors(small).unique) < len(read_vectors(large).unique)
    counted = {name: evaluations(model, folder, tmp_path / f"{name}_fit", BUDGET)
               for name, folder in (("small", small), ("large", large))}
    assert counted["small"][0] == counted["large"][0] > 0  # four times the vectors, not one evaluation more
    record = counted["large"][1]
    assert record["fitted_vectors"] == BUDGET and record["merged_vectors"] > 4 * BUDGET
    latents = np.concatenate([read_exr(tmp_path / "large_fit" / name) for name in neural_folder.LATENT_FILES], -1)
    assert latents.shape == (96, 96, 6) and len(np.unique(latents.reshape(-1, 6), axis=0)) <= BUDGET
    error = neural_folder.read(tmp_path / "large_fit").fit_error
    assert error is not None and error.map is not None and np.isfinite(read_exr(error.map)).all()


def test_representatives_keep_metals_apart_from_dielectrics(model) -> None:  # type: ignore[no-untyped-def]
    """Two representatives of metals and dielectrics of every roughness: in the encoder's space each
    stands for one kind (a mean of both would be a half-metal, which neither is)."""
    rng = np.random.default_rng(0)
    vectors = np.zeros((400, 22), np.float32)
    vectors[:, CHANNEL_SLICES["alpha_core"]] = rng.uniform(0.01, 1.0, (400, 1))
    vectors[:, CHANNEL_SLICES["spec_color"]] = 0.9
    vectors[:, CHANNEL_SLICES["diel_ior"]] = 1.5
    metal = np.arange(400) < 200
    vectors[metal, CHANNEL_SLICES["metalness"]] = 1.0
    reps = representatives.choose(model, vectors, np.ones(400), 2)
    for r in range(2):
        members = metal[reps.of_vector == r]
        assert members.all() or not members.any()
    drawn = representatives.draw_members(reps, np.ones(400))
    assert list(reps.of_vector[drawn]) == [0, 1]  # one member of each, in order
    z = torch.randn(2, 6)
    assert torch.equal(representatives.transfer(model, vectors, reps, z), z[torch.from_numpy(reps.of_vector)])


def test_the_cli_says_what_it_does_before_its_steps(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The add-on's status line: a stage event names the representatives before the first step."""
    import json

    from torch_models.cli import main

    folder = noisy_material(tmp_path / "mat", 48)
    assert main(["fit", str(folder), "--out", str(tmp_path / "fit"), "--steps", "2", "--budget", str(BUDGET),
                 "--progress", "jsonl"]) == 0
    events = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    kinds = [e["event"] for e in events]
    choosing = next(i for i, e in enumerate(events) if e["event"] == "stage" and "representatives" in e["text"])
    assert choosing < kinds.index("progress") and kinds[-1] == "done"
    assert [e["step"] for e in events if e["event"] == "progress"] == [1, 2]
