"""``python -m torch_models enhance``: outputs, name sanitising, bad input.

Uses the procedural GLB of test_gltf_io.py (a fresh clone needs nothing else) and,
when present, a few of the real sample assets (small ones: the whole suite must stay
fast on two CPU cores).
"""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from richmat_addon.core import material_folder, schema
from richmat_addon.core.folder_io import read_exr
from richmat_addon.core.mtlx import read_back
from tests.test_gltf_io import pil_decode, write_test_glb
from torch_models.assets.gltf_materials import read_materials
from torch_models.cli import main

REPO = Path(__file__).resolve().parents[1]


def check_outputs(out: Path) -> dict[str, dict]:
    """Every material folder is complete and consistent; returns params.json per folder."""
    found = {}
    for folder in sorted(p for p in out.iterdir() if p.is_dir()):
        params = material_folder.read(folder).record
        assert (folder / "material.mtlx").is_file()
        assert params["schema_version"].startswith("22ch-")
        assert set(params["constants"]) | set(params["textures"]) == {"base_color", *schema.PARAM_BY_NAME}
        for name, file in params["textures"].items():
            image = read_exr(folder / file)
            channels = 3 if name == "base_color" else schema.PARAM_BY_NAME[name].channels
            assert image.ndim == 3 and image.shape[2] == channels and np.isfinite(image).all()
        assert sorted(p.name for p in folder.glob("*.exr")) == sorted(params["textures"].values())
        assert read_back(folder / "material.mtlx")["textures"] == params["textures"]
        assert not list(folder.glob(".*")), "no temporary files left behind"
        found[folder.name] = params
    return found


@pytest.mark.parametrize("name", ["../../escape", "..", ".", "a/b\\c", "C:evil", "CON", "con.txt", "",
                                  "\x00\x1f\x7f", "\u202egnp.exe", "..\\..\\x", "a" * 500])
def test_safe_name_stays_inside(tmp_path: Path, name: str) -> None:
    safe = material_folder.safe_name(name, set())
    assert safe and safe not in (".", "..") and not safe.startswith(".")
    assert not set(safe) & set('/\\:*?"<>|') and safe.isprintable()
    assert len(safe.encode()) <= 120
    assert (tmp_path / safe).resolve().parent == tmp_path.resolve()


def test_safe_name_keeps_unicode_and_disambiguates() -> None:
    taken: set[str] = set()
    names = [material_folder.safe_name(n, taken) for n in ("Stoff 名前", "Mat", "mat", "MAT", "Mat_2")]
    assert names == ["Stoff 名前", "Mat", "mat_2", "MAT_3", "Mat_2_2"]


def test_enhance_procedural_glb(tmp_path: Path) -> None:
    glb = write_test_glb(tmp_path / "cube.glb", ("../../escape", "Plain", "plain"))
    out = tmp_path / "out"
    assert main(["enhance", str(glb), "--type", "1", "--seed", "7", "--out", str(out)]) == 0
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cube.glb", "out"]
    params = check_outputs(out)
    assert sorted(params) == ["Plain", "_.._escape", "plain_2"]

    cube = params["_.._escape"]
    assert cube["material"] == "../../escape" and cube["type"] == 1 and cube["seed"] == 7
    assert cube["world_maps"] == "rasterised"
    assert params["Plain"]["world_maps"] == "none: the mesh has no UVs"
    assert "tiled" in params["plain_2"]["world_maps"]
    assert params["plain_2"]["texture_transform"]["scale"] == [4.0, 4.0]
    assert params["Plain"]["textures"] == {}, "a factor-only material without UVs stays constant"
    assert cube["settings"]["dust_geometry"] == "world normals and positions"
    assert read_exr(out / "_.._escape" / "dust_weight.exr").shape == (8, 8, 1)

    source = read_materials(glb, pil_decode)[0].pbr.base_color.value
    np.testing.assert_allclose(read_exr(out / "_.._escape" / "base_color.exr"), source, rtol=2e-3, atol=1e-4)

    # A rerun with another type replaces the folder's contents, stale textures included.
    assert main(["enhance", str(glb), "--type", "0", "--out", str(out)]) == 0
    assert all(p["type"] == 0 and "dust_weight" not in p["textures"] for p in check_outputs(out).values())


def run_cli(*args: str) -> subprocess.CompletedProcess[str]:
    env = dict(os.environ, PYTHONPATH=str(REPO))
    return subprocess.run([sys.executable, "-m", "torch_models", *args], cwd=REPO, env=env,
                          capture_output=True, text=True, timeout=120)


def test_bad_input_exit_code_2(tmp_path: Path) -> None:
    glb = write_test_glb(tmp_path / "cube.glb")
    bad = tmp_path / "truncated.glb"
    bad.write_bytes(glb.read_bytes()[:-64])
    proc = run_cli("enhance", str(bad), "--out", str(tmp_path / "out"))
    assert proc.returncode == 2, proc.stderr
    message = proc.stderr.strip()
    assert "\n" not in message and "Traceback" not in message
    assert str(bad) in message and "truncated GLB" in message
    assert not (tmp_path / "out").exists() or not any((tmp_path / "out").iterdir())


@pytest.mark.parametrize("name", ["../../escape", "..", "sub/dir"])
def test_output_folder_guard_survives_python_O(tmp_path: Path, name: str) -> None:
    """Were safe_name ever to let a path through, enhance must refuse it, under ``python -O`` too."""
    (tmp_path / "in").mkdir()
    glb = write_test_glb(tmp_path / "in" / "cube.glb", (name,))
    out = tmp_path / "in" / "out"
    code = ("import sys; from richmat_addon.core import material_folder; "
            "material_folder.safe_name = lambda name, taken, **kw: name; "
            "from torch_models.cli import main; sys.exit(main(sys.argv[1:]))")
    proc = subprocess.run([sys.executable, "-O", "-c", code, "enhance", str(glb), "--type", "0", "--out", str(out)],
                          cwd=REPO, env=dict(os.environ, PYTHONPATH=str(REPO)), capture_output=True, text=True,
                          timeout=120)
    assert proc.returncode == 2, proc.stderr
    assert f"material {name!r} would be written to" in proc.stderr and "outside the output folder" in proc.stderr
    assert sorted(p.name for p in tmp_path.rglob("*")) == ["cube.glb", "in", "out"]


def test_missing_file_exit_code_2(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["enhance", str(tmp_path / "nope.glb"), "--out", str(tmp_path / "out")]) == 2
    assert "nope.glb: no such file" in capsys.readouterr().err


# --- real sample assets ------------------------------------------------------------

def test_real_factor_only_box(shared_assets: Path, tmp_path: Path) -> None:
    out = tmp_path / "out"
    assert main(["enhance", str(shared_assets / "models" / "Box.glb"), "--type", "3", "--out", str(out)]) == 0
    (red,) = check_outputs(out).values()
    assert red["material"] == "Red" and red["world_maps"] == "none: the mesh has no UVs"
    assert red["textures"] == {}
    np.testing.assert_allclose(red["constants"]["base_color"], [0.8, 0.0, 0.0], atol=1e-6)


def test_real_avocado_dust(shared_assets: Path, tmp_path: Path) -> None:
    out = tmp_path / "out"
    assert main(["enhance", str(shared_assets / "models" / "Avocado.glb"), "--type", "1",
                 "--seed", "1", "--out", str(out)]) == 0
    (avocado,) = check_outputs(out).values()
    assert avocado["world_maps"] == "rasterised"
    assert read_exr(out / "2256_Avocado_d" / "base_color.exr").shape == (1024, 1024, 3)


def test_real_on_metal(shared_assets: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    suzanne = str(shared_assets / "models" / "Suzanne.glb")
    out = tmp_path / "out"
    assert main(["enhance", suzanne, "--type", "4", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "Suzanne" in err and "--on-metal remap" in err and not out.exists()
    assert main(["enhance", suzanne, "--type", "4", "--on-metal", "remap", "--out", str(out)]) == 0
    (params,) = check_outputs(out).values()
    assert params["requested_type"] == 4 and params["type"] != 4 and params["type_note"]
