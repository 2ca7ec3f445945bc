"""Run the torch backend's ``fit`` and ``generate`` commands as child processes and follow their JSON lines.

Blender's own Python has numpy but no torch, so fitting and generation run in an interpreter
that has torch and richmat's ``torch_models``: Blender's own when both import
there (the pip ``bpy`` module in the project's venv), otherwise the one set in
the add-on preferences. A child process, not a thread, because a fit can be
cancelled at any step (terminate) and a crash in torch cannot take Blender
down. Protocol (stdout, one JSON object per line; docs/addon.md):

    {"event": "progress", "step": 12, "total": 300, "loss": 0.031}
    {"event": "done", "out": "/path/neural", "files": ["latent_0.exr", ...]}
    {"event": "error", "message": "..."}        (exit code 2)
"""
from __future__ import annotations

import importlib.util
import json
import os
import queue
import subprocess
import sys
import threading
from dataclasses import dataclass, field
from pathlib import Path

# The repository holding torch_models, when the add-on runs from a source checkout.
SOURCE_ROOT = Path(__file__).resolve().parents[2]


class BackendProblem(RuntimeError):
    """The backend cannot run; the message says how to fix it."""


def backend_root(configured: str) -> Path | None:
    """The folder that holds ``torch_models``: the preference, the source checkout, or sys.path."""
    candidates = [Path(configured)] if configured else []
    candidates.append(SOURCE_ROOT)
    spec = importlib.util.find_spec("torch_models")
    if spec is not None and spec.origin:
        candidates.append(Path(spec.origin).parents[1])
    return next((f for f in candidates if (f / "torch_models" / "__main__.py").is_file()), None)


def choose_python(configured: str) -> str:
    """The interpreter for the backend, or a BackendProblem naming the fix."""
    if importlib.util.find_spec("torch") is not None and backend_root("") is not None:
        return sys.executable
    if configured:
        if not Path(configured).is_file() or not os.access(configured, os.X_OK):
            raise BackendProblem(f"the backend Python {configured!r} does not exist or is not executable; "
                                 "fix it in Preferences > Add-ons > Richmat")
        return configured
    raise BackendProblem("no torch backend: Blender's Python has no torch. Set a Python with torch and "
                         "richmat installed (pip install -e <richmat checkout>) in Preferences > Add-ons > "
                         "Richmat > Backend Python")


@dataclass
class BackendJob:
    """One ``python -m torch_models <command> ... --progress jsonl`` run; subclasses name the command."""

    python: str
    source_root: Path | None = field(default=None, kw_only=True)
    events: "queue.Queue[dict]" = field(default_factory=queue.Queue, kw_only=True)
    stderr: list[str] = field(default_factory=list, kw_only=True)
    done: dict | None = field(default=None, kw_only=True)
    error: str | None = field(default=None, kw_only=True)
    process: subprocess.Popen | None = field(default=None, kw_only=True)
    readers: list[threading.Thread] = field(default_factory=list, kw_only=True)

    def arguments(self) -> list[str]:
        """The command and its arguments after ``python -m torch_models``."""
        raise NotImplementedError

    def start(self) -> None:
        cmd = [self.python, "-m", "torch_models", *self.arguments(), "--progress", "jsonl"]
        env = dict(os.environ)
        if self.source_root is not None:
            env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(self.source_root), env.get("PYTHONPATH")]))
        try:
            self.process = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                            stdin=subprocess.DEVNULL, text=True, env=env)
        except OSError as exc:
            raise BackendProblem(f"cannot start the backend Python {self.python!r} ({exc.strerror}); "
                                 "fix it in Preferences > Add-ons > Richmat") from None
        self.readers = [threading.Thread(target=self._read_stdout, daemon=True),
                        threading.Thread(target=self._read_stderr, daemon=True)]
        for reader in self.readers:
            reader.start()

    def _read_stdout(self) -> None:
        for line in self.process.stdout:
            try:
                event = json.loads(line)
            except ValueError:
                continue  # stray prints from libraries are not protocol lines
            if isinstance(event, dict) and "event" in event:
                self.events.put(event)

    def _read_stderr(self) -> None:
        for line in self.process.stderr:
            self.stderr.append(line.rstrip())
            del self.stderr[:-50]

    def poll(self) -> list[dict]:
        """Events received since the last call; records done/error."""
        out = []
        while True:
            try:
                event = self.events.get_nowait()
            except queue.Empty:
                break
            if event["event"] == "done":
                self.done = event
            elif event["event"] == "error":
                self.error = str(event.get("message"))
            out.append(event)
        return out

    @property
    def running(self) -> bool:
        return self.process is not None and self.process.poll() is None

    def finish(self) -> dict:
        """Wait for the process; the done event, or a BackendProblem explaining the failure."""
        code = self.process.wait()
        for reader in self.readers:  # let them drain the pipes
            reader.join(timeout=5.0)
        self.poll()
        if code == 0 and self.done is not None:
            return self.done
        raise BackendProblem(self.diagnose(code))

    def diagnose(self, code: int) -> str:
        if self.error:
            return f"{self.arguments()[0]} failed: {self.error}"
        text = "\n".join(self.stderr)
        if "No module named 'torch'" in text:
            return (f"the backend Python {self.python} has no torch: run `{self.python} -m pip install torch` "
                    "or choose another Python in Preferences > Add-ons > Richmat")
        if "No module named torch_models" in text or "No module named 'torch_models'" in text:
            return ("the backend Python cannot import richmat's torch_models: set the richmat source folder "
                    "in Preferences > Add-ons > Richmat, or pip install -e the checkout in that Python")
        last = next((ln for ln in reversed(self.stderr) if ln.strip()), "no message")
        return f"the backend stopped (exit code {code}): {last}"

    def cancel(self) -> None:
        if self.running:
            self.process.terminate()
            try:
                self.process.wait(timeout=5)
            except subprocess.TimeoutExpired:
                self.process.kill()


@dataclass
class FitJob(BackendJob):
    """Fit the latents of a baked material against the decoder (``weights``: empty for the shipped one)."""

    material_dir: Path
    out_dir: Path
    steps: int
    weights: str = ""

    def arguments(self) -> list[str]:
        args = ["fit", str(self.material_dir), "--out", str(self.out_dir), "--steps", str(self.steps)]
        return args + (["--weights", self.weights] if self.weights else [])


@dataclass
class GenerateJob(BackendJob):
    """Generate the latents of a mesh from a prompt, against a baked material's base colour
    (``checkpoint``: a generator run folder, empty for the shipped one)."""

    mesh: Path
    material_dir: Path
    out_dir: Path
    prompt: str
    steps: int
    seed: int = 0
    checkpoint: str = ""

    def arguments(self) -> list[str]:
        args = ["generate", str(self.mesh), "--prompt", self.prompt, "--material", str(self.material_dir),
                "--out", str(self.out_dir), "--steps", str(self.steps), "--seed", str(self.seed),
                "--no-preview"]  # Blender previews with its own OSL shader
        return args + (["--checkpoint", self.checkpoint] if self.checkpoint else [])
