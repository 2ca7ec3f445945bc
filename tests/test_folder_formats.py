"""The material and neural folder formats: one writer each, versioned, and clear about foreign folders."""
from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest

from richmat_addon.core import material_folder, neural_folder
from richmat_addon.core.enhance import enhance
from richmat_addon.core.folder_io import FormatError
from torch_models.cli import main
from tests import test_neural_fit
from torch_models.demo_material import chipped_paint, sphere_texel_geometry

REPO = Path(__file__).resolve().parents[1]
SOURCES = ("richmat_addon", "torch_models", "batch", "bench", "tests")
OWNERS = {"richmat_addon/core/material_folder.py", "richmat_addon/core/neural_folder.py"}
textured = test_neural_fit.textured  # fixture: an enhanced material folder (Type 1, seed 3)


def edit_record(path: Path, **changes: object) -> None:
    """Rewrite a record as an older or foreign writer would have left it (None drops a field)."""
    record = json.loads(path.read_text())
    for key, value in changes.items():
        record.pop(key) if value is None else record.__setitem__(key, value)
    path.write_text(json.dumps(record))


def test_a_material_folder_reads_back_what_was_written(textured: Path) -> None:
    mat = enhance(chipped_paint(8), 1, 3, *sphere_texel_geometry(8, 8))  # what the fixture wrote
    back = material_folder.read(textured)
    assert back.record["format"] == material_folder.FORMAT
    assert back.record["schema_version"] == material_folder.schema_version()
    loaded = back.material()
    assert (loaded.name, loaded.type, loaded.seed) == ("mat", 1, 3)  # no material name given: the folder's
    for name, pmap in mat.params.items():  # half floats: 11 mantissa bits
        np.testing.assert_allclose(loaded.params[name].value, pmap.value, rtol=1e-3, atol=1e-4)
    assert set(back.texture_paths) == set(back.record["textures"]) and "base_color" in back.texture_paths


@pytest.mark.parametrize("changes, named", [
    ({"format": None}, "'format'"),
    ({"format": 0}, "format is 0"),
    ({"schema_version": None}, "'schema_version'"),  # what the add-on's Bake wrote before it had one
    ({"schema_version": "21ch-000000000000"}, "schema_version is '21ch-"),
    ({"settings": None}, "'settings'"),
    ({"constants": {}}, "coat_weight"),
    ({"textures": []}, "'textures' is not an object"),
])
def test_an_old_or_foreign_material_folder_is_named_not_a_key_error(textured: Path, changes: dict,
                                                                    named: str) -> None:
    edit_record(textured / material_folder.RECORD, **changes)
    with pytest.raises(FormatError, match=re.escape(named)):
        material_folder.read(textured)


def test_a_folder_without_a_record_or_with_broken_json_is_a_format_error(tmp_path: Path) -> None:
    with pytest.raises(FormatError, match="no params.json"):
        material_folder.read(tmp_path)
    (tmp_path / neural_folder.RECORD).write_text("{not json")
    with pytest.raises(FormatError, match="not a JSON record"):
        neural_folder.read(tmp_path)


def test_neural_folders_round_trip_textured_and_constant(tmp_path: Path) -> None:
    latents = np.linspace(-1, 1, 4 * 4 * 6, dtype=np.float32).reshape(4, 4, 6)
    scale = np.ones((4, 4), np.float32)
    scale[0, 0] = 0.5
    neural_folder.write(tmp_path, latents, scale, "d" * 64, {"steps": 3})
    back = neural_folder.read(tmp_path)
    assert back.decoder_sha256 == "d" * 64 and back.record["steps"] == 3 and back.latent is None
    assert back.energy_scale == tmp_path / neural_folder.ENERGY_FILE
    assert [p.name for p in back.latent_paths] == list(neural_folder.LATENT_FILES)

    neural_folder.write(tmp_path, latents[0, 0], np.ones(1), "d" * 64, {})  # refit as a constant
    back = neural_folder.read(tmp_path)
    assert back.latent == pytest.approx(latents[0, 0].tolist()) and back.energy_scale == 1.0
    assert back.latent_paths is None and not list(tmp_path.glob("*.exr")), "stale textures would win in Blender"


@pytest.mark.parametrize("changes, named", [
    ({"format": None}, "'format'"),  # neural.json before it was versioned
    ({"decoder_sha256": None}, "'decoder_sha256'"),
    ({"energy_scale": "gone.exr"}, "gone.exr"),
    ({"latent": [0.0, 1.0]}, "'latent' is not a list of 6"),
])
def test_an_old_or_foreign_neural_folder_is_named_not_a_key_error(tmp_path: Path, changes: dict,
                                                                  named: str) -> None:
    neural_folder.write(tmp_path, np.zeros(6, np.float32), np.ones(1), "d" * 64, {})
    edit_record(tmp_path / neural_folder.RECORD, **changes)
    with pytest.raises(FormatError, match=re.escape(named)):
        neural_folder.read(tmp_path)


def test_fit_refuses_an_old_folder_in_one_line(textured: Path, tmp_path: Path,
                                               capsys: pytest.CaptureFixture[str]) -> None:
    edit_record(textured / material_folder.RECORD, schema_version=None)
    assert main(["fit", str(textured), "--out", str(tmp_path / "fit")]) == 2
    err = capsys.readouterr().err
    assert "'schema_version'" in err and "Traceback" not in err


# A write: json.dump(s), write_text/write_bytes, or open(..., "w"/"a"/"x").
WRITE = re.compile(r"json\.dumps?\(|\.write_(text|bytes)\(|open\([^)]*[\"'][wax]")
RECORD_NAMES = re.compile(r"params\.json|neural\.json|\bRECORD\b")


def record_writes(text: str) -> list[int]:
    """Lines that name a folder record within two lines of a write."""
    lines = text.splitlines()
    return [i + 1 for i, line in enumerate(lines) if RECORD_NAMES.search(line)
            and any(WRITE.search(near) for near in lines[max(0, i - 2):i + 3])]


def test_the_format_modules_are_the_only_writers_of_their_records() -> None:
    offenders = []
    for top in SOURCES:
        for path in sorted((REPO / top).rglob("*.py")):
            relative = path.relative_to(REPO).as_posix()
            if relative in OWNERS or path == Path(__file__):
                continue
            offenders += [f"{relative}:{n}" for n in record_writes(path.read_text(encoding="utf-8"))]
    assert not offenders, "params.json / neural.json written outside core/material_folder.py and " \
                          "core/neural_folder.py (use their write): " + ", ".join(offenders)


def test_the_writer_check_sees_the_writers_it_replaced() -> None:
    """The shapes the second writers had before the format modules owned the records."""
    assert record_writes('(folder / "params.json").write_text(json.dumps(record, indent=2) + "\\n")')
    assert record_writes('with atomic_path(args.out / "neural.json") as tmp:\n'
                         '    tmp.write_text(json.dumps(record, indent=1))')
    assert record_writes('record = write_latents(folder / "neural", vectors, bounded)\n'
                         '(folder / "neural" / "neural.json").write_text(json.dumps(dict(record), indent=1))')
    assert not record_writes('record = json.loads((folder / "neural" / "neural.json").read_text())')
