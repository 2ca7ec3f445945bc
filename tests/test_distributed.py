"""Data-parallel decoder training under torchrun (two CPU processes, gloo)."""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

from safetensors.torch import load_file

from tests.test_neural_training import TINY

ROOT = Path(__file__).resolve().parents[1]


def test_torchrun_trains_the_decoder_on_two_ranks(tmp_path: Path) -> None:
    cfg = tmp_path / "tiny.json"
    cfg.write_text(json.dumps(dict(TINY, steps=20, sampler_steps=4, checkpoint_every=12)))
    out = tmp_path / "run"
    done = subprocess.run([sys.executable, "-m", "torch.distributed.run", "--standalone", "--nproc_per_node", "2",
                           "-m", "torch_models", "train-decoder",
                           "--config", str(cfg), "--out", str(out)],
                          cwd=ROOT, capture_output=True, text=True, timeout=300)
    # the ranks' own errors come first, the launcher's summary last
    assert done.returncode == 0, done.stderr[:4000] + "\n...\n" + done.stderr[-1000:]
    state = json.loads((out / "state.json").read_text())
    assert state["step"] == 24 and [h["step"] for h in state["config"]["history"]] == [12, 24]
    weights = load_file(str(out / "weights.safetensors"))
    assert any(k.startswith("decoder.") for k in weights)
    assert not list(out.glob("*.partial*"))  # rank 0 alone wrote, atomically
