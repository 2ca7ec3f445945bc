"""The farm orchestrator without Blender: sharding, ids, ledger, publish, timeouts, crashes, resume.

The per-asset children are replaced by two small stand-in programs written
into tmp_path: a fake ``blender`` (called with Blender's command line, ``-b
... -P job.py -- STAGE ARGS``) and a fake torch ``python`` for the fit step.
What they do depends on the asset's file name: ``hang`` sleeps (and leaves a
grandchild that must die with it), ``crash`` segfaults, ``bad`` reports bad
input, ``flaky`` crashes once, anything else succeeds after RENDER_SECONDS.
"""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from batch import ledger, publish, runner
from batch.assets import asset_id, collect
from batch.cores import CoreShares, allowed_cores
from batch.orchestrator import main, run
from batch.options import build_parser, cpu_threads
from batch.pipeline import Commands
from batch.sharding import Shard, parse_shard, shard_from_environment, shard_of

REPO = Path(__file__).resolve().parents[1]

FAKE_BLENDER = '''#!{python}
import json, os, signal, subprocess, sys, time
from pathlib import Path
argv = sys.argv[sys.argv.index("--") + 1:]
stage, opts = argv[0], dict(zip(argv[1::2], argv[2::2]))
work = Path(opts["--work"])
if stage == "prepare":
    name = Path(opts["--asset"]).name
    if "hang" in name:
        child = subprocess.Popen(["sleep", "300"])
        Path(os.environ["FAKE_PIDS"]).open("a").write(f"{{child.pid}}\\n")
        time.sleep(300)
    if "crash" in name:
        os.kill(os.getpid(), signal.SIGSEGV)
    if "bad" in name:
        (work / "error.json").write_text(json.dumps({{"reason": "zero faces"}}))
        sys.exit(3)
    if "flaky" in name:
        marker = Path(os.environ["FAKE_PIDS"]).with_name("flaky-" + opts["--asset-id"])
        if not marker.exists():
            marker.touch()
            os.kill(os.getpid(), signal.SIGSEGV)
    print("fake stderr line", file=sys.stderr)
    (work / "asset.json").write_text(json.dumps({{"type": int(opts["--type"]), "materials": [], "notes": ["n"]}}))
else:
    time.sleep(float(os.environ.get("RENDER_SECONDS", "0")))
    (work / "rgb").mkdir()
    (work / "rgb" / "0000.png").write_text(opts["--asset-id"] + opts["--resolution"])
    (work / "render.json").write_text(json.dumps({{"frames": [], "timings_s": {{}}}}))
'''

FAKE_PYTHON = '''#!{python}
import json, sys
from pathlib import Path
if sys.argv[1] == "-c":  # the orchestrator's check that this Python has torch
    sys.exit(0)
opts = dict(zip(sys.argv[2::2], sys.argv[3::2]))
(Path(opts["--work"]) / "fit.json").write_text(json.dumps({{"materials": {{}}}}))
'''


@pytest.fixture
def fakes(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Commands:
    tools = tmp_path / "tools"
    tools.mkdir()
    for name, text in (("blender", FAKE_BLENDER), ("torch-python", FAKE_PYTHON)):
        (tools / name).write_text(text.format(python=sys.executable))
        (tools / name).chmod(0o755)
    monkeypatch.setenv("FAKE_PIDS", str(tmp_path / "pids.txt"))
    return Commands(str(tools / "blender"), str(tools / "torch-python"))


@pytest.fixture
def decoder(tmp_path: Path) -> Path:
    folder = tmp_path / "decoder"
    folder.mkdir()
    (folder / "weights.safetensors").write_bytes(b"stand-in weights")
    return folder


def make_assets(folder: Path, names: list[str]) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    for name in names:
        (folder / name).parent.mkdir(parents=True, exist_ok=True)
        (folder / name).write_bytes(b"asset " + name.encode())
    return folder


def args_for(inp: Path, out: Path, decoder: Path, *extra: str):  # type: ignore[no-untyped-def]
    return build_parser().parse_args(["--input", str(inp), "--output", str(out), "--decoder", str(decoder),
                                      "--resolution", "8", *extra])


def ledger_records(out: Path) -> list[dict]:
    return [r for path in sorted((out / "_ledger").glob("*.jsonl")) for r in ledger.read(path)]


# --- sharding ---------------------------------------------------------------------------------------

def test_shards_partition_the_assets_and_do_not_move_when_the_list_grows() -> None:
    ids = [asset_id(f"obj_{i}.glb") for i in range(400)]
    owners = {i: [s for s in range(4) if Shard(s, 4).owns(i)] for i in ids}
    assert all(len(o) == 1 for o in owners.values())
    counts = [sum(o == [s] for o in owners.values()) for s in range(4)]
    assert min(counts) > 60  # roughly even
    more = ids + [asset_id(f"new_{i}.glb") for i in range(100)]
    assert all(shard_of(i, 4) == owners[i][0] for i in more[:400])


def test_shard_from_slurm_environment_and_argument() -> None:
    assert shard_from_environment({"SLURM_ARRAY_TASK_ID": "3", "SLURM_ARRAY_TASK_COUNT": "8"}) == Shard(3, 8)
    assert shard_from_environment({"SLURM_ARRAY_TASK_ID": "4", "SLURM_ARRAY_TASK_COUNT": "4",
                                   "SLURM_ARRAY_TASK_MIN": "1"}) == Shard(3, 4)
    assert shard_from_environment({}) is None
    assert parse_shard("2/5") == Shard(2, 5)
    for bad in ("5/5", "x", "1/0"):
        with pytest.raises(ValueError):
            parse_shard(bad)


def test_slurm_variables_pick_the_shard(tmp_path: Path, fakes: Commands, decoder: Path,
                                        monkeypatch: pytest.MonkeyPatch) -> None:
    inp = make_assets(tmp_path / "in", [f"a{i}.glb" for i in range(12)])
    mine = [a.id for a in collect(inp) if shard_of(a.id, 3) == 1]
    monkeypatch.setenv("SLURM_ARRAY_TASK_ID", "1")
    monkeypatch.setenv("SLURM_ARRAY_TASK_COUNT", "3")
    assert run(args_for(inp, tmp_path / "out", decoder), fakes) == 0
    done = sorted(p.name for p in (tmp_path / "out").iterdir() if (p / "manifest.json").exists())
    assert done == sorted(mine)
    assert (tmp_path / "out" / "_ledger" / "shard-0001-of-0003.jsonl").is_file()


# --- names ------------------------------------------------------------------------------------------

def test_render_threads_split_the_cores_the_task_may_use_not_the_node(monkeypatch: pytest.MonkeyPatch) -> None:
    # a SLURM task with --cpus-per-task=16 on a 64-core node: its affinity mask holds 16 cores
    monkeypatch.setattr(os, "cpu_count", lambda: 64)
    monkeypatch.setattr(os, "sched_getaffinity", lambda pid: set(range(16)), raising=False)
    assert [cpu_threads(k) for k in (1, 2, 3, 32)] == [16, 8, 5, 1]


def test_each_worker_lends_its_children_its_own_cores() -> None:
    shares = CoreShares(2, cores=[0, 1, 2, 3, 4])
    with shares.lend() as first, shares.lend() as second:
        assert {first, second} == {frozenset({0, 1}), frozenset({2, 3})}
    with CoreShares(1, cores=[0, 1]).lend() as one, CoreShares(3, cores=[0, 1]).lend() as crowded:
        assert one is None and crowded is None  # one worker, or more workers than cores: every core


def test_a_child_runs_on_the_cores_it_is_lent(tmp_path: Path) -> None:
    core = allowed_cores()[-1]
    show = [sys.executable, "-c", "import os; print(sorted(os.sched_getaffinity(0)))"]
    assert runner.run(show, 60, tmp_path / "lent", cores=frozenset({core})).ok
    assert runner.run(show, 60, tmp_path / "all").ok
    assert (tmp_path / "lent.out").read_text().strip() == f"[{core}]"
    assert (tmp_path / "all.out").read_text().strip() == str(allowed_cores())


def test_hostile_names_stay_inside_the_output_folder(tmp_path: Path) -> None:
    for key in ("../../etc/passwd", "a b/ünï côde.glb", "..", "CON.glb", "x/\x00y.glb", "/abs/path.obj"):
        folder = publish.final_dir(tmp_path, asset_id(key))
        assert folder.resolve().parent == tmp_path.resolve() and folder.name not in ("", ".", "..")
    assert asset_id("a/chair.glb") != asset_id("b/chair.glb")
    with pytest.raises(ValueError):
        publish.final_dir(tmp_path, "../escape")


def test_list_file_with_parent_paths_and_spaces(tmp_path: Path, fakes: Commands, decoder: Path) -> None:
    make_assets(tmp_path / "assets", ["with space.glb", "ünïcode.obj"])
    listing = tmp_path / "lists" / "assets.txt"
    listing.parent.mkdir()
    listing.write_text("# comment\n../assets/with space.glb\n../assets/ünïcode.obj\n\n")
    out = tmp_path / "out"
    assert run(args_for(listing, out, decoder), fakes) == 0
    names = sorted(p.name for p in out.iterdir() if not p.name.startswith("_"))
    assert len(names) == 2 and all((out / n / "manifest.json").is_file() for n in names)
    assert not list(tmp_path.glob("*.partial")) and not (tmp_path / "assets" / "out").exists()


# --- ledger, publish --------------------------------------------------------------------------------

def test_ledger_appends_and_skips_a_torn_last_line(tmp_path: Path) -> None:
    path = tmp_path / "l" / "shard.jsonl"
    book = ledger.Ledger(path)
    book.append({"asset_id": "a", "status": "done"})
    book.append({"asset_id": "b", "status": "failed"})
    with path.open("a") as f:
        f.write('{"asset_id": "c", "sta')  # a run killed mid-write
    assert [r["asset_id"] for r in ledger.read(path)] == ["a", "b"]


def test_publish_is_atomic_and_replaces_an_older_render(tmp_path: Path) -> None:
    work = publish.fresh_partial(tmp_path, "asset-1")
    (work / "a.txt").write_text("one")
    assert not (tmp_path / "asset-1").exists()
    final = publish.publish(tmp_path, "asset-1", {"settings_hash": "h1"})
    assert publish.is_done(tmp_path, "asset-1", "h1") and not publish.is_done(tmp_path, "asset-1", "h2")
    manifest = publish.read_manifest(final)
    assert manifest["files"] == {"a.txt": publish.file_hashes(final)["a.txt"]}
    work = publish.fresh_partial(tmp_path, "asset-1")
    (work / "b.txt").write_text("two")
    publish.publish(tmp_path, "asset-1", {"settings_hash": "h2"})
    assert sorted(p.name for p in tmp_path.iterdir()) == ["asset-1"]
    assert sorted(p.name for p in final.iterdir()) == ["b.txt", "manifest.json"]


# --- child processes --------------------------------------------------------------------------------

def test_timeout_kills_the_whole_process_group(tmp_path: Path) -> None:
    script = "import subprocess, sys, time; p = subprocess.Popen(['sleep', '300']); print(p.pid, flush=True); time.sleep(300)"
    start = time.monotonic()
    out = runner.run([sys.executable, "-c", script], 1.0, tmp_path / "logs" / "x")
    # ended at its 1 s timeout, not by waiting out the 300 s grandchild: a margin no load closes
    assert out.timed_out and not out.ok and time.monotonic() - start < 100
    grandchild = int((tmp_path / "logs" / "x.out").read_text().split()[0])
    assert _dies(grandchild)


def test_segfault_is_recorded_with_signal_and_stderr(tmp_path: Path) -> None:
    script = "import os, signal, sys; print('about to crash', file=sys.stderr, flush=True); os.kill(os.getpid(), signal.SIGSEGV)"
    out = runner.run([sys.executable, "-c", script], 30, tmp_path / "crash")
    assert out.signal == "SIGSEGV" and out.exit_code is None and "about to crash" in out.stderr_tail


def _alive(pid: int) -> bool:
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().split()[2] != "Z"
    except FileNotFoundError:
        return False


def _dies(pid: int, within: float = 30.0) -> bool:
    """Whether a process sent SIGKILL is gone within ``within`` seconds: the kernel ends it
    asynchronously, which on a loaded machine takes longer than a fixed short sleep."""
    deadline = time.monotonic() + within
    while _alive(pid):
        if time.monotonic() > deadline:
            return False
        time.sleep(0.05)
    return True


def test_bad_hanging_and_crashing_assets_do_not_stop_the_batch(tmp_path: Path, fakes: Commands,
                                                               decoder: Path) -> None:
    inp = make_assets(tmp_path / "in", ["good.glb", "hang.glb", "crash.glb", "bad.glb", "flaky.glb",
                                        "notes.txt.xyz", "sub/good2.obj"])
    out = tmp_path / "out"
    code = run(args_for(inp, out, decoder, "--timeout", "3", "--retries", "1", "--workers", "2"), fakes)
    assert code == 1
    by_source = {r["source"]: r for r in ledger_records(out)}
    assert by_source["good.glb"]["status"] == by_source["sub/good2.obj"]["status"] == "done"
    assert by_source["flaky.glb"]["status"] == "done" and by_source["flaky.glb"]["attempts"] == 2
    hang, crash, bad = by_source["hang.glb"], by_source["crash.glb"], by_source["bad.glb"]
    assert hang["status"] == "failed" and "timed out" in hang["reason"] and hang["attempts"] == 2
    assert crash["signal"] == "SIGSEGV" and "SIGSEGV" in crash["reason"] and crash["attempts"] == 2
    assert bad["reason"] == "prepare: zero faces" and bad["attempts"] == 1 and bad["exit_code"] == 3
    assert "unsupported format" in by_source["notes.txt.xyz"]["reason"]
    assert by_source["good.glb"]["notes"] == ["n"]
    for pid in map(int, (tmp_path / "pids.txt").read_text().split()):
        assert _dies(pid)  # the hanging asset's grandchildren died with it
    assert not list(out.glob("*.partial"))
    assert (out / "_logs").is_dir()  # failed assets keep their child logs
    published = [p for p in out.iterdir() if not p.name.startswith("_")]
    assert len(published) == 3 and all((p / "manifest.json").is_file() for p in published)


def test_resume_skips_finished_assets_unless_settings_change(tmp_path: Path, fakes: Commands,
                                                             decoder: Path) -> None:
    inp = make_assets(tmp_path / "in", ["a.glb", "b.glb"])
    out = tmp_path / "out"
    assert run(args_for(inp, out, decoder), fakes) == 0
    first = {p.name: publish.read_manifest(p)["files"] for p in out.iterdir() if not p.name.startswith("_")}
    assert run(args_for(inp, out, decoder), fakes) == 0
    assert [r["status"] for r in ledger_records(out)][-2:] == ["skipped", "skipped"]
    assert run(args_for(inp, out, decoder, "--resolution", "16"), fakes) == 0
    assert [r["status"] for r in ledger_records(out)][-2:] == ["done", "done"]
    again = {p.name: publish.read_manifest(p)["files"] for p in out.iterdir() if not p.name.startswith("_")}
    assert again.keys() == first.keys() and again != first


@pytest.mark.parametrize("kill", [signal.SIGTERM, signal.SIGKILL])
def test_killed_run_restarts_to_identical_results(tmp_path: Path, fakes: Commands, decoder: Path,
                                                  kill: signal.Signals) -> None:
    names = [f"asset{i}.glb" for i in range(6)]
    inp = make_assets(tmp_path / "in", names)
    cmd = [sys.executable, str(REPO / "batch" / "render_dataset.py"), "--input", str(inp), "--decoder",
           str(decoder), "--resolution", "8", "--workers", "2", "--blender", fakes.blender, "--python", fakes.python]
    env = dict(os.environ, RENDER_SECONDS="0.6")
    reference = tmp_path / "reference"
    subprocess.run([*cmd, "--output", str(reference)], env=env, check=True, capture_output=True, timeout=120)

    out = tmp_path / "out"
    proc = subprocess.Popen([*cmd, "--output", str(out)], env=env, stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)
    deadline = time.monotonic() + 60
    while not any((p / "manifest.json").exists() for p in out.glob("asset*")) and time.monotonic() < deadline:
        time.sleep(0.05)
    time.sleep(0.3)
    proc.send_signal(kill)
    proc.wait(timeout=30)
    finished = {p.name for p in out.iterdir() if (p / "manifest.json").exists()}
    assert 0 < len(finished) < len(names)
    for folder in out.iterdir():  # nothing half-written is visible: only complete folders, .partial or bookkeeping
        assert folder.name.startswith("_") or folder.name.endswith(".partial") or folder.name in finished
    time.sleep(1.0)  # children killed with the run must not write any more
    subprocess.run([*cmd, "--output", str(out)], env=env, check=True, capture_output=True, timeout=120)
    statuses = [r["status"] for r in ledger_records(out)]
    assert statuses.count("skipped") >= len(finished)

    def content(root: Path) -> dict[str, dict[str, str]]:
        return {p.name: {k: v for k, v in publish.read_manifest(p)["files"].items() if not k.startswith("logs/")}
                for p in root.iterdir() if not p.name.startswith("_")}

    assert content(out) == content(reference)
    assert not list(out.glob("*.partial"))


def test_help_documents_every_option_with_its_default() -> None:
    text = subprocess.run([sys.executable, str(REPO / "batch" / "render_dataset.py"), "--help"],
                          capture_output=True, text=True, check=True).stdout
    for option in ("--input", "--output", "--frames", "--resolution", "--samples", "--probe", "--shard",
                   "--workers", "--timeout", "--seed", "--decoder", "--retries"):
        assert option in text
    assert "(default: 16)" in text and "(default: 512)" in text


def test_missing_decoder_is_a_clear_usage_error(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit):
        main(["--input", str(tmp_path), "--output", str(tmp_path / "o"), "--decoder", str(tmp_path / "none")])
    assert "no weights.safetensors" in capsys.readouterr().err


def test_children_match_the_parent_blender_or_python(monkeypatch: pytest.MonkeyPatch) -> None:
    from types import SimpleNamespace

    from batch.pipeline import default_commands

    monkeypatch.delenv("RICHMAT_PYTHON", raising=False)
    pip = default_commands(None, None)
    assert pip.blender == pip.python == sys.executable
    assert pip.blender_job(["prepare"])[:2] == [sys.executable, str(pip.job_script)]
    monkeypatch.setitem(sys.modules, "bpy", SimpleNamespace(app=SimpleNamespace(binary_path="/opt/blender/blender")))
    inside = default_commands(None, "/env/python")
    assert inside.blender_job(["render", "--x"]) == [
        "/opt/blender/blender", "-b", "-Y", "--factory-startup", "--python-exit-code", "1", "-P",
        str(inside.job_script), "--", "render", "--x"]
    assert inside.fit_job(["--work", "w"]) == ["/env/python", str(inside.fit_script), "--work", "w"]


def test_fit_python_is_the_checkouts_venv_under_blender_or_a_clear_error(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from types import SimpleNamespace

    from batch import pipeline

    monkeypatch.delenv("RICHMAT_PYTHON", raising=False)
    monkeypatch.setitem(sys.modules, "bpy", SimpleNamespace(app=SimpleNamespace(binary_path="/opt/blender/blender")))
    venv = tmp_path / "venv" / "bin" / "python"
    monkeypatch.setattr(pipeline, "VENV_PYTHON", venv)
    with pytest.raises(ValueError, match=r"needs a Python with torch.*no --python, no \$RICHMAT_PYTHON.*make env"):
        pipeline.default_commands(None, None)
    venv.parent.mkdir(parents=True)
    venv.symlink_to(sys.executable)
    assert pipeline.default_commands(None, None).python == str(venv)
    assert pipeline.default_commands(None, "/env/python").python == "/env/python"
    # a Python without torch (isolated, no site-packages) is refused before any asset starts
    bare = tmp_path / "bare-python"
    bare.write_text(f"#!/bin/sh\nexec {sys.executable} -I -S \"$@\"\n")
    bare.chmod(0o755)
    with pytest.raises(ValueError, match="has no torch.*No module named 'torch'"):
        pipeline.check_fit_python(str(bare))
    with pytest.raises(ValueError, match="cannot be run"):
        pipeline.check_fit_python(str(tmp_path / "no-such-python"))
    pipeline.check_fit_python(sys.executable)


def test_device_and_its_graph_are_in_the_settings_hash(decoder: Path, tmp_path: Path) -> None:
    from batch import options

    def settings(*extra: str) -> options.Settings:
        args = args_for(tmp_path, tmp_path / "out", decoder, *extra)
        options.validate(args)
        return options.settings_of(args)

    cpu, optix, cuda = settings(), settings("--device", "OPTIX"), settings("--device", "CUDA")
    assert [(s.device, s.graph) for s in (cpu, optix, cuda)] == [("CPU", "native"), ("OPTIX", "native"),
                                                                 ("CUDA", "native")]
    osl = settings("--graph", "osl")
    assert osl.graph == "osl" and settings("--device", "OPTIX", "--graph", "osl").graph == "osl"
    assert len({cpu.hash(), optix.hash(), cuda.hash(), osl.hash()}) == 4
    for gpu in ("CUDA", "HIP", "METAL", "ONEAPI"):
        with pytest.raises(ValueError, match="--graph osl renders only on CPU and OPTIX"):
            settings("--device", gpu, "--graph", "osl")


def test_input_files_the_farm_does_not_take_are_listed_with_why(tmp_path: Path, fakes: Commands, decoder: Path,
                                                                capsys: pytest.CaptureFixture[str]) -> None:
    inp = make_assets(tmp_path / "in", ["good.glb", "..name.glb", ".hidden/inside.glb", "sub/.DS_Store",
                                        "paint.png", "points.xyz"])
    out = tmp_path / "out"
    assert run(args_for(inp, out, decoder), fakes) == 1  # points.xyz failed
    by_source = {r["source"]: r for r in ledger_records(out)}
    assert by_source["good.glb"]["status"] == "done"
    xyz = by_source["points.xyz"]
    assert xyz["status"] == "failed" and "unsupported format '.xyz'" in xyz["reason"]
    ignored = {k: r["reason"] for k, r in by_source.items() if r["status"] == "ignored"}
    assert set(ignored) == {"..name.glb", ".hidden/", "sub/.DS_Store", "paint.png"}
    assert "starts with a dot" in ignored["..name.glb"] and "rename it" in ignored["..name.glb"]
    assert "hidden folder" in ignored[".hidden/"] and "not searched" in ignored[".hidden/"]
    assert "read by the asset that refers to it" in ignored["paint.png"]
    err = capsys.readouterr().err
    assert "ignored 4 (not assets)" in err and "IGNORED ..name.glb: the name starts with a dot" in err
    assert "IGNORED 1 texture, buffer or material file(s)" in err and "FAILED points.xyz" in err


def test_progress_is_a_plain_line_per_asset_without_tqdm(monkeypatch: pytest.MonkeyPatch) -> None:
    import io

    from batch import progress

    monkeypatch.setitem(sys.modules, "tqdm", None)  # as in a stock Blender: `import tqdm` fails
    assert isinstance(progress.progress(2, "shard 0000-of-0001"), progress.Lines)
    stream = io.StringIO()
    lines = progress.Lines(2, "shard 0000-of-0001", stream)
    lines.step("done", "chair-0123456789")
    lines.step("failed", "lamp-9876543210")
    first, second = stream.getvalue().splitlines()
    assert first.startswith("shard 0000-of-0001 [1/2] done chair-0123456789 (ETA ")
    assert second.startswith("shard 0000-of-0001 [2/2] failed lamp-9876543210 (ETA 00:00:00")


CRASHING_RUN = """
import runpy, sys
from batch import index
def full_disk(output):
    raise OSError(28, "No space left on device")
index.write = full_disk  # the index is written after the assets: a crash of the run itself, not of an asset
sys.argv = [sys.argv[0], "--", *sys.argv[1:]]  # as Blender passes them
runpy.run_path({entry!r}, run_name="__main__")
"""


def test_a_crash_inside_the_entry_script_exits_non_zero_with_a_ledger_line(tmp_path: Path, fakes: Commands,
                                                                           decoder: Path) -> None:
    inp = make_assets(tmp_path / "in", ["good.glb"])
    out = tmp_path / "out"
    script = CRASHING_RUN.format(entry=str(REPO / "batch" / "render_dataset.py"))
    proc = subprocess.run([sys.executable, "-c", script, "--input", str(inp), "--output", str(out), "--decoder",
                           str(decoder), "--resolution", "8", "--blender", fakes.blender, "--python", fakes.python],
                          capture_output=True, text=True, timeout=120, env=dict(os.environ, PYTHONPATH=str(REPO)))
    assert proc.returncode == 70, proc.stderr[-2000:]
    assert "Traceback" in proc.stderr and "No space left on device" in proc.stderr
    records = ledger_records(out)
    assert [r["status"] for r in records] == ["done", "aborted"]
    assert records[-1]["reason"] == "the run crashed: OSError: [Errno 28] No space left on device"
    assert records[-1]["asset_id"] is None and records[-1]["settings_hash"] == records[0]["settings_hash"]
