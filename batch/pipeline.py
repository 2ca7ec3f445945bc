"""One asset through its stages, each a child process: prepare (bpy), fit (torch), render (bpy).

The split follows what each stage needs: a stock ``blender -b`` has no torch,
and the pip venv's Python has both; running the fit as its own process keeps
one recipe for both cases. Stages exchange files in the asset's ``.partial``
folder. A stage that meets bad input writes ``error.json`` and exits with
``BAD_INPUT_EXIT``: that is recorded and never retried; a crash or a timeout is
retried from scratch up to ``--retries`` times.
"""
from __future__ import annotations

import json
import os
import platform
import shutil
import subprocess
import sys
import tempfile
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, Sequence

from richmat_addon.core import captions
from torch_models.assets.enhancement_plan import asset_type

from . import publish, runner
from .assets import Asset
from .cores import CoreShares
from .options import REPO, Settings, cpu_threads, file_sha256

BAD_INPUT_EXIT = 3
ERROR_FILE = "error.json"
LOGS_DIR = "_logs"
SCENE_FILE = "scene.blend"
JOB_SCRIPT = REPO / "batch" / "blender_job.py"
FIT_SCRIPT = REPO / "batch" / "fit_job.py"


@dataclass
class Commands:
    """How to start the two kinds of child: a Blender with bpy, a Python with torch."""

    blender: str  # a Blender executable, or a Python with the bpy module
    python: str  # a Python with torch
    job_script: Path = JOB_SCRIPT
    fit_script: Path = FIT_SCRIPT

    def blender_job(self, args: Sequence[str]) -> list[str]:
        if Path(self.blender).name.startswith("python"):
            return [self.blender, str(self.job_script), *args]
        return [self.blender, "-b", "-Y", "--factory-startup", "--python-exit-code", "1",
                "-P", str(self.job_script), "--", *args]

    def fit_job(self, args: Sequence[str]) -> list[str]:
        return [self.python, str(self.fit_script), *args]


VENV_PYTHON = REPO / ".venv" / "bin" / "python"


def default_commands(blender: str | None, python: str | None) -> Commands:
    """Children like the parent: the same Blender under ``blender -P``, else this Python (pip bpy).

    The fit's Python: ``--python``, else ``$RICHMAT_PYTHON``, else under a Blender binary the
    checkout's ``.venv/bin/python`` (Blender's own Python has no torch), else this Python.
    """
    bpy = sys.modules.get("bpy")  # present (not imported here) only when running inside Blender
    inside_blender = bpy is not None and bool(getattr(bpy.app, "binary_path", ""))
    blender_cmd = blender or (bpy.app.binary_path if inside_blender else sys.executable)
    python_cmd = python or os.environ.get("RICHMAT_PYTHON")
    if python_cmd is None and inside_blender:
        if not VENV_PYTHON.exists():
            raise ValueError(f"the fit step needs a Python with torch, and Blender's has none: found no "
                             f"--python, no $RICHMAT_PYTHON and no {VENV_PYTHON} (`make env` makes it)")
        python_cmd = str(VENV_PYTHON)
    return Commands(blender_cmd, python_cmd or sys.executable)


# Looks torch up without importing it: the import costs 2 CPU s, as much again as the fit child's own.
FIND_TORCH = "import importlib.util, sys; importlib.util.find_spec('torch') or sys.exit(\"No module named 'torch'\")"


def check_fit_python(python: str) -> None:
    """Refuse a fit interpreter without torch before any asset is started. A torch that is there but does
    not import fails each asset's fit instead, with its traceback in the ledger."""
    try:
        proc = subprocess.run([python, "-c", FIND_TORCH], capture_output=True, text=True, timeout=600)
    except OSError as exc:
        raise ValueError(f"the fit's Python {python} cannot be run ({exc.strerror}); the fit step needs a Python "
                         f"with torch, such as {VENV_PYTHON} (`make env` makes it)") from None
    if proc.returncode != 0:
        last = (proc.stderr.strip().splitlines() or [f"exit code {proc.returncode}"])[-1]
        raise ValueError(f"the fit's Python {python} has no torch ({last}); the fit step needs a Python "
                         f"with torch, such as {VENV_PYTHON} (`make env` makes it)")


@dataclass
class Job:
    """Everything a worker needs, shared by all assets of a run."""

    settings: Settings
    settings_hash: str
    output: Path
    probe: Path
    decoder: Path
    timeout: float
    retries: int
    workers: int
    max_triangles: int  # not in the settings: it decides which assets are refused, not what one's output is
    commands: Commands
    cores: CoreShares = field(default_factory=lambda: CoreShares(1))  # one share per worker


@dataclass
class Result:
    asset: Asset
    status: str  # "done", "failed"
    reason: str = ""
    attempts: int = 0
    seconds: float = 0.0
    outcome: dict[str, Any] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)  # what was repaired on the way (done assets)


def _child_env(blender_home: Path, threads: int) -> dict[str, str]:
    path = os.pathsep.join(p for p in (str(REPO), os.environ.get("PYTHONPATH", "")) if p)
    return dict(os.environ, PYTHONPATH=path, BLENDER_USER_RESOURCES=str(blender_home),
                OMP_NUM_THREADS=str(threads), PYTHONUNBUFFERED="1")


def _stage_commands(asset: Asset, job: Job, work: Path) -> list[tuple[str, list[str]]]:
    s, threads = job.settings, cpu_threads(job.workers)
    prepare = ["prepare", "--asset", str(asset.path), "--work", str(work), "--asset-id", asset.id,
               "--type", str(asset_type(asset.id, s.seed)), "--seed", str(s.seed),
               "--max-texture", str(s.max_texture), "--max-triangles", str(job.max_triangles)]
    fit = ["--work", str(work), "--decoder", str(job.decoder), "--steps", str(s.fit_steps),
           "--cluster-step", repr(s.cluster_step), "--budget", str(s.fit_budget), "--threads", str(threads)]
    render = ["render", "--work", str(work), "--asset-id", asset.id, "--frames", str(s.frames),
              "--resolution", str(s.resolution), "--samples", str(s.samples),
              "--adaptive-threshold", str(s.adaptive_threshold), "--denoise-prefilter", s.denoise_prefilter,
              "--denoise-quality", s.denoise_quality, "--aov-samples", str(s.aov_samples), "--device", s.device,
              "--graph", s.graph, "--probe", str(job.probe), "--seed", str(s.seed), "--threads", str(threads)]
    return [("prepare", job.commands.blender_job(prepare)), ("fit", job.commands.fit_job(fit)),
            ("render", job.commands.blender_job(render))]


def device_problem(job: Job) -> str | None:
    """Why ``--device`` cannot render here (None when it can): one Blender asked before any asset starts,
    so a missing GPU fails the run at once instead of every asset after its prepare and fit."""
    device = job.settings.device
    if device == "CPU":
        return None
    with tempfile.TemporaryDirectory(prefix="richmat-device-") as folder:
        work = Path(folder)
        out = runner.run(job.commands.blender_job(["device", "--device", device, "--work", str(work)]), 600,
                         work / "logs" / "device", env=_child_env(work / "home", 1), cwd=work)
        if out.ok:
            return None
        reason = _bad_input_reason(work)
        if out.exit_code == BAD_INPUT_EXIT and reason:
            return reason
        return f"--device {device}: the device check failed ({out.describe()}): {out.stderr_tail[-500:]}"


def _bad_input_reason(work: Path) -> str | None:
    try:
        return str(json.loads((work / ERROR_FILE).read_text(encoding="utf-8"))["reason"])
    except (OSError, ValueError, KeyError):
        return None


def _attempt(asset: Asset, job: Job) -> tuple[str, str, dict[str, Any], dict[str, float]]:
    """One try: ``("done" | "bad" | "crash", reason, outcome, stage seconds)``."""
    work = publish.fresh_partial(job.output, asset.id)
    deadline = time.monotonic() + job.timeout
    timings: dict[str, float] = {}
    with tempfile.TemporaryDirectory(prefix="richmat-blender-") as home, job.cores.lend() as cores:
        env = _child_env(Path(home), cpu_threads(job.workers))
        for stage, cmd in _stage_commands(asset, job, work):
            left = deadline - time.monotonic()
            out = runner.run(cmd, max(left, 0.001), work / "logs" / stage, env=env, cwd=work, cores=cores)
            timings[stage] = round(out.seconds, 3)
            info = {"stage": stage, "exit_code": out.exit_code, "signal": out.signal,
                    "timed_out": out.timed_out, "stderr_tail": out.stderr_tail}
            if out.ok:
                continue
            reason = _bad_input_reason(work)
            if out.exit_code == BAD_INPUT_EXIT and reason:
                return "bad", f"{stage}: {reason}", info, timings
            if out.timed_out:
                return "crash", f"{stage}: timed out (limit {job.timeout:g} s per asset, process group killed)", \
                    info, timings
            return "crash", f"{stage}: {out.describe()}", info, timings
    return "done", "", {}, timings


def _manifest(asset: Asset, job: Job, timings: dict[str, float], attempts: int) -> dict[str, Any]:
    work = publish.partial_dir(job.output, asset.id)
    (work / SCENE_FILE).unlink(missing_ok=True)  # an intermediate: the render stage's input
    prepared = json.loads((work / "asset.json").read_text(encoding="utf-8"))
    rendered = json.loads((work / "render.json").read_text(encoding="utf-8"))
    fitted = json.loads((work / "fit.json").read_text(encoding="utf-8"))
    children = {"prepare": prepared, "fit": fitted, "render": rendered}
    text = captions.caption(asset.path.name.rsplit(".", 1)[0], prepared["materials"])
    (work / "caption.txt").write_text(text + "\n", encoding="utf-8")
    return {"asset_id": asset.id, "source": asset.key, "source_sha256": file_sha256(asset.path),
            "settings_hash": job.settings_hash, "settings": asdict(job.settings), "caption": text,
            "enhancement_type": prepared["type"], "autoexec_fail": prepared.get("autoexec_fail", False),
            "notes": prepared.get("notes", []), "normalisation": prepared.get("normalisation"),
            "materials": prepared["materials"], "fit": fitted, "frames": rendered.get("frames"),
            "cycles": rendered.get("cycles"),
            "versions": {"blender": prepared.get("blender_version"), "torch": fitted.get("torch_version"),
                         "python": platform.python_version(), "pipeline": job.settings.pipeline},
            "timings_s": {**timings, **_stage_times(children, "timings_s")},
            "cpu_s": _stage_times(children, "cpu_s"),
            "attempts": attempts}


def _stage_times(children: dict[str, dict[str, Any]], kind: str) -> dict[str, Any]:
    """The children's own ``kind`` records (``timings_s``: wall, ``cpu_s``: CPU), each key prefixed with
    its stage: ``render_beauty``. The orchestrator's wall seconds per child are the unprefixed keys."""
    return {f"{stage}_{k}": v for stage, record in children.items() for k, v in record.get(kind, {}).items()}


def process(asset: Asset, job: Job) -> Result:
    """Render one asset into ``output/<id>/``, or say why not; never raises for a bad asset."""
    start = time.monotonic()
    if not asset.supported:
        return Result(asset, "failed", f"unsupported format {asset.path.suffix or '(no extension)'!r}")
    if not asset.path.is_file():
        return Result(asset, "failed", "no such file")
    for attempt in range(1, job.retries + 2):
        kind, reason, outcome, timings = _attempt(asset, job)
        if kind != "crash":
            break
    seconds = time.monotonic() - start
    if kind == "done":
        manifest = _manifest(asset, job, timings, attempt)
        publish.publish(job.output, asset.id, manifest)
        return Result(asset, "done", "", attempt, seconds, notes=manifest["notes"])
    _keep_logs(job.output, asset.id)
    return Result(asset, "failed", reason, attempt, seconds, outcome)


def _keep_logs(output: Path, asset_id: str) -> None:
    """Move a failed asset's child logs to ``_logs/<id>/`` and drop its partial folder."""
    work = publish.partial_dir(output, asset_id)
    logs = output / LOGS_DIR / asset_id
    if (work / "logs").is_dir():
        shutil.rmtree(logs, ignore_errors=True)
        logs.parent.mkdir(parents=True, exist_ok=True)
        os.replace(work / "logs", logs)
    shutil.rmtree(work, ignore_errors=True)
