"""Fit Neural Material: the JSON-lines backend protocol, its failures, and the operator."""
from __future__ import annotations

import json
import stat
import sys
import time
from pathlib import Path

import pytest

from richmat_addon.blender import neural_backend

from support.extension import script
from .test_addon_extension import extension_zip  # noqa: F401  (session fixture)

REPO = Path(__file__).resolve().parents[1]
SHIPPED_WEIGHTS = REPO / "torch_models" / "neural" / "weights"


def fake_python(tmp_path: Path, body: str, name: str = "fake_python") -> str:
    """An executable standing in for the backend interpreter."""
    exe = tmp_path / name
    exe.write_text("#!/bin/sh\n" + body)
    exe.chmod(exe.stat().st_mode | stat.S_IXUSR)
    return str(exe)


def job(python: str, tmp_path: Path, steps: int = 3) -> neural_backend.FitJob:
    return neural_backend.FitJob(python, tmp_path / "material", tmp_path / "neural", steps)


def test_progress_and_done_events_are_read_and_stray_output_ignored(tmp_path: Path):
    lines = [json.dumps({"event": "progress", "step": k, "total": 2, "loss": 0.5 / k}) for k in (1, 2)]
    lines += ["some library chatter", json.dumps({"event": "done", "out": "X", "files": ["latent_0.exr"]})]
    python = fake_python(tmp_path, "".join(f"echo '{ln}'\n" for ln in lines))
    j = job(python, tmp_path)
    j.start()
    done = j.finish()
    assert done["out"] == "X"
    assert [e["step"] for e in j.poll()] == []  # already consumed by finish
    assert j.done == done and j.error is None


@pytest.mark.parametrize("stderr, fix", [
    ("ModuleNotFoundError: No module named 'torch'", "-m pip install torch"),
    ("/x/python: No module named torch_models", "richmat source folder"),
])
def test_a_broken_backend_is_a_message_with_the_fix(tmp_path: Path, stderr: str, fix: str):
    j = job(fake_python(tmp_path, f"echo \"{stderr}\" >&2\nexit 1\n"), tmp_path)
    j.start()
    with pytest.raises(neural_backend.BackendProblem, match=fix.replace(".", r"\.")):
        j.finish()


def test_missing_interpreter_names_the_preference(tmp_path: Path):
    with pytest.raises(neural_backend.BackendProblem, match="Preferences > Add-ons > Richmat"):
        job(str(tmp_path / "no_python"), tmp_path).start()


def test_cancel_stops_the_backend(tmp_path: Path):
    j = job(fake_python(tmp_path, "while true; do echo '{\"event\": \"progress\", \"step\": 1, "
                                  "\"total\": 9, \"loss\": 1}'; sleep 0.05; done\n"), tmp_path)
    j.start()
    time.sleep(0.3)
    assert j.running and j.poll()
    j.cancel()
    assert not j.running


def test_the_fit_command_speaks_the_protocol_on_bad_input(tmp_path: Path):
    """The real backend: a folder that is not a baked material is an error event, exit code 2."""
    j = job(sys.executable, tmp_path)
    j.source_root = REPO
    j.start()
    with pytest.raises(neural_backend.BackendProblem, match="not an enhanced material folder"):
        j.finish()


FIT = r'''
obj = procedural_asset(TMP, size=16)
scene = bpy.context.scene
scene.richmat.enhancement_type = "0"
scene.richmat.output_dir = TMP + "/baked"
scene.richmat.fit_steps = 5
assert run_op("uplift_material")[0] == {"FINISHED"}
polls_before_bake = bpy.ops.richmat.fit_neural.poll()
assert run_op("bake_parameters")[0] == {"FINISHED"}
prefs = bpy.context.preferences.addons[MODULE].preferences
prefs.weights_dir = WEIGHTS
res, err = run_op("fit_neural")
enhanced = obj.active_material
latents = sorted(n.image.name for n in enhanced.node_tree.nodes if n.name.startswith("neural_latent"))
print("RESULT " + json.dumps(dict(res=list(res), err=err, polls_before_bake=polls_before_bake,
                                  neural_dir=enhanced.richmat.neural_dir, latents=latents)))
'''


def test_fit_reports_missing_weights_with_the_fix(blender_run, extension_zip: Path, tmp_path: Path):  # noqa: F811
    result = blender_run(script(f"TMP = {str(tmp_path)!r}\nWEIGHTS = {str(tmp_path / 'none')!r}\n" + FIT,
                                extension_zip))
    assert result["polls_before_bake"] is False
    assert result["res"] == ["CANCELLED"]
    assert "no trained decoder" in result["err"] and "train-decoder" in result["err"]
    assert "Traceback" not in result["err"]


def test_fit_writes_and_assigns_the_latent_textures(blender_run, extension_zip: Path, tmp_path: Path):  # noqa: F811
    result = blender_run(script(f"TMP = {str(tmp_path)!r}\nWEIGHTS = ''\n" + FIT, extension_zip))
    assert result["res"] == ["FINISHED"], result["err"]
    neural = Path(result["neural_dir"])
    assert (neural / "latent_0.exr").is_file() and (neural / "latent_1.exr").is_file()
    assert result["latents"] == ["latent_0.exr", "latent_1.exr"]


def fake_venv(root: Path, body: str) -> Path:
    """``root/.venv/bin/python``: a shell script standing in for a venv's interpreter."""
    (root / ".venv" / "bin").mkdir(parents=True)
    return Path(fake_python(root / ".venv" / "bin", body, "python"))


def test_a_checkout_venv_above_the_blend_is_found_and_runs_the_backend(tmp_path: Path, monkeypatch):
    """A .venv without torch is passed over; a checkout's (torch_models beside it) above the .blend's
    folder is found, checked by importing, and runs the fit command from its source root."""
    monkeypatch.setattr(neural_backend, "blender_has_torch", lambda: False)  # as in a stock Blender
    fake_venv(tmp_path / "projects", "exit 1\n")  # no torch there
    checkout = tmp_path / "projects" / "richmat"
    python = fake_venv(checkout, f'exec {sys.executable} "$@"\n')
    (checkout / "torch_models").symlink_to(REPO / "torch_models")
    blend_dir = tmp_path / "projects" / "shots" / "a"
    blend_dir.mkdir(parents=True)
    assert [c.python for c in neural_backend.venv_candidates([blend_dir])] == [
        str(tmp_path / "projects" / ".venv" / "bin" / "python"), str(python)]
    found = neural_backend.find_backend("", "", [blend_dir])
    assert found == neural_backend.Backend(str(python), checkout)
    j = neural_backend.FitJob(found.python, tmp_path / "material", tmp_path / "neural", 3,
                              source_root=found.source_root)
    j.start()
    with pytest.raises(neural_backend.BackendProblem, match="not an enhanced material folder"):
        j.finish()


def test_no_backend_anywhere_says_what_to_install_and_where(tmp_path: Path, monkeypatch):
    monkeypatch.setattr(neural_backend, "blender_has_torch", lambda: False)
    with pytest.raises(neural_backend.BackendProblem, match=r"no torch backend: clone richmat and run `make env`"):
        neural_backend.find_backend("", "", [tmp_path])
