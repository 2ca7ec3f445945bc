"""The parts of bench/farm/slurm_e2e.py that need no SLURM: its slurm.conf, its parsing of SLURM's
output, the ledger merge it compares with a single-process run, and the sbatch file's
argument pass-through (run with bash against a stand-in Python). Collected by ``make test``
beside tests/: a bench's own tests live beside it, since tests/ never imports bench/."""
from __future__ import annotations

import os
import subprocess
from pathlib import Path

import pytest

from bench.farm import slurm_e2e
from bench.farm.slurm_e2e import (BAD, SBATCH, SBATCH_ARGS, expand_tasks, key_values, merged_outcomes,
                                  outcome_differences, slurm_conf)
from support.paths import shared_assets_or_skip

SLURMD_C = ("NodeName=vm CPUs=2 Boards=1 SocketsPerBoard=1 CoresPerSocket=2 ThreadsPerCore=1 "
            "RealMemory=24105")


def test_slurm_conf_declares_this_node_and_keeps_every_file_in_its_folder(tmp_path: Path) -> None:
    text = slurm_conf(tmp_path, key_values(SLURMD_C), (16817, 16818), tmp_path / "munge" / "munge.sock")
    conf = dict(line.split("=", 1) for line in text.splitlines() if not line.startswith(("NodeName", "Partition")))
    node = next(line for line in text.splitlines() if line.startswith("NodeName="))
    assert "CPUs=2" in node and "RealMemory=24105" in node and "CoresPerSocket=2" in node
    assert conf["SlurmctldHost"] == "vm(127.0.0.1)"
    assert (conf["SlurmctldPort"], conf["SlurmdPort"]) == ("16817", "16818")
    assert conf["ProctrackType"] == "proctrack/linuxproc" and conf["TaskPlugin"] == "task/none"
    assert "cgroup" not in text
    assert conf["AuthInfo"] == f"socket={tmp_path / 'munge' / 'munge.sock'}"
    for key in ("StateSaveLocation", "SlurmdSpoolDir", "SlurmctldPidFile", "SlurmdPidFile", "SlurmctldLogFile",
                "SlurmdLogFile", "JobCompLoc"):
        assert Path(conf[key]).is_relative_to(tmp_path), key


def test_key_values_keeps_a_command_line_with_spaces_in_one_value() -> None:
    line = ("JobId=6 ArrayJobId=4 ArrayTaskId=1 JobState=CANCELLED Reason=None Restarts=1 ExitCode=130:0 "
            "Command=/x/run.sbatch /in /out --frames 2 WorkDir=/x")
    record = key_values(line)
    assert record["JobState"] == "CANCELLED" and record["Restarts"] == "1" and record["ExitCode"] == "130:0"
    assert record["Command"] == "/x/run.sbatch /in /out --frames 2" and record["WorkDir"] == "/x"
    assert key_values(SLURMD_C)["NodeName"] == "vm"


def test_expand_tasks_reads_a_pending_group() -> None:
    assert expand_tasks("1") == [1]
    assert expand_tasks("0-2,5%2") == [0, 1, 2, 5]


def _record(asset: str, status: str, shard: str, reason: str = "", seconds: float = 1.0) -> dict:
    return {"asset_id": asset, "source": f"{asset}.glb", "status": status, "reason": reason, "shard": shard,
            "settings_hash": "h", "seconds": seconds, "attempts": 1}


def test_a_cancelled_and_requeued_shard_merges_to_the_single_process_result() -> None:
    array = [_record("a", "done", "0000-of-0002"),  # then cancelled inside b: no record for b
             _record("a", "skipped", "0000-of-0002", "finished with the same settings hash"),  # requeued
             _record("b", "done", "0000-of-0002", seconds=9.0),
             _record("c", "failed", "0001-of-0002", "prepare: import failed: x")]
    single = [_record("a", "done", "0000-of-0001", seconds=2.0), _record("b", "done", "0000-of-0001"),
              _record("c", "failed", "0000-of-0001", "prepare: import failed: x")]
    merged = merged_outcomes(array)
    assert {k: (v["status"], v["done_records"]) for k, v in merged.items()} == {
        "a": ("done", 1), "b": ("done", 1), "c": ("failed", 0)}
    assert outcome_differences(merged, merged_outcomes(single)) == []  # timings and shards do not count


def test_outcome_differences_names_a_changed_reason_and_a_lost_asset() -> None:
    array = merged_outcomes([_record("a", "failed", "0000-of-0002", "timed out")])
    single = merged_outcomes([_record("a", "failed", "0000-of-0001", "killed by SIGSEGV"),
                              _record("b", "done", "0000-of-0001")])
    diffs = outcome_differences(array, single)
    assert diffs == ["b: only in the second", "a: reason 'timed out' != 'killed by SIGSEGV'"]


def test_a_missing_slurm_says_how_to_install_it_and_installs_nothing(monkeypatch: pytest.MonkeyPatch) -> None:
    assert slurm_e2e.missing_tools(path="") == list(slurm_e2e.TOOLS)
    monkeypatch.setattr(slurm_e2e, "missing_tools", lambda: ["munged", "slurmctld"])
    monkeypatch.setattr("sys.argv", ["slurm_e2e"])
    with pytest.raises(SystemExit, match="apt-get install -y slurm-wlm munge"):
        slurm_e2e.main()


def _sbatch_argv(tmp_path: Path, *args: str, workers: str | None = None) -> list[str]:
    """What the sbatch file hands to the repository's Python (a stand-in that prints its arguments)."""
    python = tmp_path / ".venv" / "bin" / "python"
    python.parent.mkdir(parents=True, exist_ok=True)
    python.write_text('#!/bin/bash\nprintf "%s\\n" "$@"\n')
    python.chmod(0o755)
    env = {k: v for k, v in os.environ.items() if not k.startswith(("RICHMAT_", "SLURM_"))}
    env |= {"RICHMAT_REPO": str(tmp_path)} | ({"RICHMAT_WORKERS": workers} if workers else {})
    proc = subprocess.run(["bash", str(SBATCH), *args], env=env, capture_output=True, text=True, check=True)
    return proc.stdout.splitlines()


def test_sbatch_passes_arguments_after_output_to_render_dataset(tmp_path: Path) -> None:
    fixed = ["batch/render_dataset.py", "--input", "IN", "--output", "OUT", "--workers", "2", "--timeout", "3600",
             "--retries", "1", "--seed", "0"]
    assert _sbatch_argv(tmp_path, "IN", "OUT") == fixed
    assert _sbatch_argv(tmp_path, "IN", "OUT", "--frames", "2", "--timeout", "60") == [
        *fixed, "--frames", "2", "--timeout", "60"]
    # the bench's single-process reference repeats the file's own arguments (with 1 worker per task)
    assert _sbatch_argv(tmp_path, "IN", "OUT", workers="1")[5:] == SBATCH_ARGS


def test_inputs_give_the_cancelled_task_two_good_assets(tmp_path: Path) -> None:
    shared_assets_or_skip()  # the inputs copy the sample assets
    slurm_e2e.build_inputs(tmp_path / "inputs")
    layout = slurm_e2e.plan(tmp_path / "inputs", 3)
    assert set(BAD) <= set(layout["assets"])
    assert len(layout["good_by_task"][layout["target"]]) >= 2
    assert sorted(k for keys in layout["shards"].values() for k in keys) == sorted(layout["assets"])
    assert not (tmp_path / "inputs" / "triangle.bin").exists()  # the missing buffer is missing
    assert (tmp_path / "outside" / "triangle.bin").is_file()  # what the escaping URI names exists
