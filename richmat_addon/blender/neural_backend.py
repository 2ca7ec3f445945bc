"""Run the torch backend's ``fit`` and ``generate`` commands as child processes and follow their JSON lines.

Blender's own Python has numpy but no torch, so fitting and generation run in an interpreter
that has torch and richmat's ``torch_models``: Blender's own when both import
there (the pip ``bpy`` module in the project's venv), else the one set in the
add-on preferences, else one found by itself: a ``.venv`` (or ``richmat/.venv``)
in the add-on's folder or the current .blend's folder or any folder above them,
whose Python imports torch and torch_models. Without any, Fit still writes the
encoder's latents (core/neural_encoder.py, numpy) and Generate says what to
install. A child process, not a thread, because a fit can be
cancelled at any step (terminate) and a crash in torch cannot take Blender
down. Protocol (stdout, one JSON object per line; docs/addon.md):

    {"event": "progress", "step": 12, "total": 300, "loss": 0.031}
    {"event": "stage", "text": "choosing 4096 representatives of 409590 distinct vectors"}
    {"event": "done", "out": "/path/neural", "files": ["latent_0.exr", ...]}
    {"event": "error", "message": "..."}        (exit code 2)
"""
from __future__ import annotations

import functools
import importlib.util
import json
import os
import queue
import subprocess
import sys
import threading
from dataclasses import dataclass, field
from pathlib import Path

ADDON_ROOT = Path(__file__).resolve().parents[1]  # the add-on package: the extension's folder when installed
# The repository holding torch_models, when the add-on runs from a source checkout.
SOURCE_ROOT = ADDON_ROOT.parent
# `make extension` ships the decoder (weights.safetensors, state.json) here: the numpy encoder and
# the OSL preview need it in a stock Blender, where no torch_models is at hand.
BUNDLED_DECODER = ADDON_ROOT / "decoder"
SHIPPED_DECODER = Path("torch_models") / "neural" / "weights"  # below a backend root
VENV_PYTHONS = (Path(".venv") / "bin" / "python", Path(".venv") / "Scripts" / "python.exe")
INSTALL_HINT = ("clone richmat and run `make env` in it (a .venv with torch) in the folder of your .blend or "
                "one above it, or set Backend Python in Preferences > Add-ons > Richmat")


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


def decoder_dir(configured_weights: str, configured_source: str) -> Path | None:
    """The decoder the add-on encodes, fits and previews with: the preference, the one shipped in
    the extension, else torch_models' shipped one; None when there is none at all."""
    if configured_weights:
        return Path(configured_weights)
    if BUNDLED_DECODER.is_dir():
        return BUNDLED_DECODER
    root = backend_root(configured_source)
    return root / SHIPPED_DECODER if root is not None else None


@dataclass(frozen=True)
class Backend:
    """An interpreter that runs ``python -m torch_models`` and the folder to put on its path (if any)."""

    python: str
    source_root: Path | None


def venv_candidates(search_from: list[Path]) -> list[Backend]:
    """Each ``.venv`` Python in, or in a ``richmat`` folder in, the given folders and those above them."""
    found = []
    for start in search_from:
        for folder in (start, *start.parents):
            for root in (folder, folder / "richmat"):
                python = next((root / p for p in VENV_PYTHONS if (root / p).is_file()), None)
                if python is not None and Backend(str(python), root) not in found:
                    found.append(Backend(str(python), root))
    return found


@functools.lru_cache(maxsize=16)
def runs_torch_models(backend: Backend) -> bool:
    """Whether the interpreter imports torch and torch_models (with its root on the path). Cached:
    importing torch takes seconds, and panels ask on every redraw."""
    env = dict(os.environ, PYTHONPATH=str(backend.source_root or ""))
    try:
        return subprocess.run([backend.python, "-c", "import torch, torch_models"], env=env, timeout=120,
                              stdin=subprocess.DEVNULL, capture_output=True).returncode == 0
    except (OSError, subprocess.TimeoutExpired):
        return False


def blender_has_torch() -> bool:
    """Blender's own Python runs the backend (the pip bpy module in richmat's venv)."""
    return importlib.util.find_spec("torch") is not None and backend_root("") is not None


def find_backend(configured: str, configured_source: str, search_from: list[Path]) -> Backend:
    """The backend to run, or a BackendProblem naming the fix: Blender's own Python, the preference,
    else the first ``.venv`` found from ``search_from`` that imports torch and torch_models."""
    source = backend_root(configured_source)
    if blender_has_torch():
        return Backend(sys.executable, source)
    if configured:
        if not Path(configured).is_file() or not os.access(configured, os.X_OK):
            raise BackendProblem(f"the backend Python {configured!r} does not exist or is not executable; "
                                 "fix it in Preferences > Add-ons > Richmat")
        return Backend(configured, source)
    found = next((b for b in venv_candidates(search_from) if runs_torch_models(b)), None)
    if found is None:
        raise BackendProblem(f"no torch backend: {INSTALL_HINT}")
    return Backend(found.python, backend_root(str(found.source_root)))


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
    budget: int | None = None  # the fit's vector budget; None: the backend's default

    def arguments(self) -> list[str]:
        args = ["fit", str(self.material_dir), "--out", str(self.out_dir), "--steps", str(self.steps)]
        args += ["--budget", str(self.budget)] if self.budget is not None else []
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
                "--no-preview",  # Blender previews with its own OSL shader
                "--base", "mesh"]  # the bake already holds the base the words asked for
        return args + (["--checkpoint", self.checkpoint] if self.checkpoint else [])
