"""Command-line options of render_dataset.py and the settings that decide an asset's output.

Everything that changes what is written for an asset goes into ``Settings`` and
its hash: a finished asset is skipped only when its manifest carries the same
hash, so changing the resolution or the decoder re-renders it.
"""
from __future__ import annotations

import argparse
import hashlib
import json
from dataclasses import asdict, dataclass
from pathlib import Path

from richmat_addon.core.texel_vectors import FIT_BUDGET

from .cores import allowed_cores

REPO = Path(__file__).resolve().parents[1]
DEFAULT_PROBE = REPO / "torch_models" / "data" / "studio_small_03_512.hdr"
DEFAULT_DECODER = REPO / "torch_models" / "neural" / "weights"
# 5 M triangles import in about 25 s with 1.2 GB of memory (docs/batch.md); far beyond any one material's needs.
DEFAULT_MAX_TRIANGLES = 5_000_000
# The fit's own step (core.texel_vectors.QUANT); the fit's cost grows with the vectors it leaves, since each
# gets its own samples (torch_models.neural.fit.latents.SAMPLES_PER_VECTOR).
DEFAULT_CLUSTER_STEP = 1 / 256
# How OIDN treats the albedo and normal passes it denoises the beauty with: "accurate" denoises them
# first, which costs about half of a 512 px, 16 spp beauty frame on one thread; "fast" takes them as
# rendered (bench/farm/beauty_denoise.py measures both).
DENOISE_PREFILTERS = ("fast", "accurate")
DEFAULT_DENOISE_PREFILTER = "fast"
# OIDN's network: "high" is Cycles' default; "balanced" and "fast" are smaller networks (bench/farm/beauty_denoise.py
# measures them against a high-sample reference).
DENOISE_QUALITIES = ("high", "balanced", "fast")
DEFAULT_DENOISE_QUALITY = "high"
# Cycles devices (``--device``); OSL shades only on the CPU and OptiX (docs/backends.md).
DEVICES = ("CPU", "CUDA", "OPTIX", "HIP", "METAL", "ONEAPI")
OSL_DEVICES = ("CPU", "OPTIX")
# The beauty pass's material: the native node graph renders on every device and, on the CPU, the farm's
# textured materials in about two thirds of OSL's time (the OSL shader reads its maps through OpenImageIO's
# texture cache); bench/farm/farm_cost.py measures both against an OSL reference.
GRAPHS = ("native", "osl")
DEFAULT_GRAPH = "native"
# Bumped when the per-asset output format or pipeline changes meaning.
PIPELINE_VERSION = 1


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="render_dataset.py",
        description="Render the neural-material dataset: per asset a 16-frame orbit (PNG + MP4), intrinsic "
                    "maps (EXR), fitted latent textures, cameras and a caption. Same arguments under "
                    "`blender -b -P batch/render_dataset.py -- ARGS`.",
        formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    add = parser.add_argument
    add("--input", type=Path, help="a folder of assets (searched recursively) or a text file "
                                   "listing one asset path per line; needed unless --rebuild-index")
    add("--output", type=Path, help="output folder (one subfolder per asset, ledgers in _ledger/, the dataset "
                                    "index _index.jsonl); needed unless --rebuild-index")
    add("--rebuild-index", type=Path, metavar="OUTPUT", help="render nothing: write OUTPUT/_index.jsonl "
                                                             "anew from the manifests of the assets published there")
    add("--frames", type=int, default=16, help="frames of the orbit")
    add("--resolution", type=int, default=512, help="image width and height in pixels")
    add("--samples", type=int, default=12, help="Cycles samples per pixel of the beauty pass (denoised; "
                                                "default chosen by bench/farm/render_speed.py, docs/batch.md)")
    add("--adaptive-threshold", type=float, default=0.01, help="Cycles adaptive sampling noise threshold "
                                                              "(default chosen with --samples)")
    add("--denoise-prefilter", choices=DENOISE_PREFILTERS, default=DEFAULT_DENOISE_PREFILTER,
        help="OIDN's treatment of the albedo and normal it denoises with: 'accurate' denoises them first (about "
             "half of a 512 px beauty frame on one thread), 'fast' takes them as rendered (default chosen by "
             "bench/farm/beauty_denoise.py, docs/batch.md)")
    add("--denoise-quality", choices=DENOISE_QUALITIES, default=DEFAULT_DENOISE_QUALITY,
        help="OIDN's network for the beauty pass: 'high' (Cycles' default), 'balanced' or 'fast' (smaller, "
             "quicker; default chosen by bench/farm/beauty_denoise.py, docs/batch.md)")
    add("--device", choices=DEVICES, default="CPU",
        help="Cycles device of every render pass; a device this machine does not have fails the run at once, "
             "with the reason in the ledger (never a silent CPU fallback)")
    add("--graph", choices=GRAPHS, default=DEFAULT_GRAPH,
        help="the enhanced material the beauty pass renders: the native node graph (any Cycles device, "
             "docs/backends.md) or the exact OSL shader (Cycles on the CPU or OptiX only); intrinsics and latents "
             "are the same")
    add("--aov-samples", type=int, default=8, help="samples of the intrinsics pass (anti-aliasing of the EXR maps)")
    add("--probe", type=Path, default=DEFAULT_PROBE, help="HDR light probe (equirectangular)")
    add("--decoder", type=Path, default=DEFAULT_DECODER, help="trained decoder folder "
                                                             "(weights.safetensors + state.json)")
    add("--fit-steps", type=int, default=300, help="latent optimisation steps per material")
    add("--cluster-step", type=float, default=DEFAULT_CLUSTER_STEP,
        help="texel vectors that agree to this step per normalised parameter are fitted as one, sharing the "
             "fit's samples (bench/farm/farm_cost.py sweeps it, docs/batch.md)")
    add("--fit-budget", type=int, default=FIT_BUDGET,
        help="vectors fitted per material at most: past it, representatives chosen in the encoder's latent "
             "space, so the fit's cost does not grow with the texture (bench/neural/fit_bounded.py); 0: no bound")
    add("--max-texture", type=int, default=512, help="larger textures are downscaled to this size (noted)")
    add("--max-triangles", type=int, default=DEFAULT_MAX_TRIANGLES,
        help="assets whose meshes have more triangles are refused with the count (a glTF before it is imported)")
    add("--shard", default=None, help="I/N: render only the assets of shard I of N (stable hash split); "
                                      "default: SLURM_ARRAY_TASK_ID/SLURM_ARRAY_TASK_COUNT when set, else 0/1")
    add("--workers", type=int, default=1, help="assets rendered at once, each on its own share of the cores")
    add("--timeout", type=float, default=1800.0, help="seconds per asset (all stages of one attempt) before the running process group is killed")
    add("--retries", type=int, default=1, help="extra attempts after a crash or timeout (bad input is not retried)")
    add("--seed", type=int, default=0, help="global seed: enhancement types and parameters, camera start angle")
    add("--blender", default=None, help="Blender executable for the per-asset jobs; default: this Blender "
                                        "when run under `blender -b -P`, else this Python with the bpy module")
    add("--python", default=None, help="Python with torch for the fit step; default: this Python, or "
                                       "the repo's .venv under Blender, or $RICHMAT_PYTHON")
    return parser


@dataclass(frozen=True)
class Settings:
    """What an asset's output depends on (besides the asset file itself)."""

    pipeline: int
    frames: int
    resolution: int
    samples: int
    adaptive_threshold: float
    denoise_prefilter: str
    denoise_quality: str
    aov_samples: int
    device: str
    graph: str
    probe_sha256: str
    decoder_sha256: str
    fit_steps: int
    cluster_step: float
    fit_budget: int
    max_texture: int
    seed: int

    def hash(self) -> str:
        return hashlib.sha256(json.dumps(asdict(self), sort_keys=True).encode()).hexdigest()[:16]


def file_sha256(path: Path) -> str:
    h = hashlib.sha256()
    with path.open("rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def validate(args: argparse.Namespace) -> None:
    if args.input is None or args.output is None:
        raise ValueError("--input and --output are required (unless --rebuild-index)")
    for name in ("frames", "resolution", "samples", "aov_samples", "workers", "fit_steps", "max_texture",
                 "max_triangles"):
        if getattr(args, name) < 1:
            raise ValueError(f"--{name.replace('_', '-')} must be at least 1")
    if args.graph == "osl" and args.device not in OSL_DEVICES:
        raise ValueError(f"--graph osl renders only on {' and '.join(OSL_DEVICES)} (Cycles runs OSL nowhere "
                         f"else): leave --graph out with --device {args.device}, and the native graph is rendered")
    if not 0 < args.cluster_step <= 1:
        raise ValueError("--cluster-step must be in (0, 1]")
    if args.fit_budget < 0:
        raise ValueError("--fit-budget must be 0 (no bound) or more")
    if args.timeout <= 0 or args.retries < 0:
        raise ValueError("--timeout must be positive and --retries non-negative")
    if not args.probe.is_file():
        raise ValueError(f"--probe {args.probe}: no such file")
    if not (args.decoder / "weights.safetensors").is_file():
        raise ValueError(f"--decoder {args.decoder}: no weights.safetensors (train one with "
                         "`python -m torch_models train-decoder` or pass a training run folder)")


def settings_of(args: argparse.Namespace) -> Settings:
    return Settings(PIPELINE_VERSION, args.frames, args.resolution, args.samples, args.adaptive_threshold,
                    args.denoise_prefilter, args.denoise_quality, args.aov_samples, args.device, args.graph,
                    file_sha256(args.probe),
                    file_sha256(args.decoder / "weights.safetensors"), args.fit_steps, args.cluster_step,
                    args.fit_budget, args.max_texture, args.seed)


def cpu_threads(workers: int) -> int:
    """Render threads per job so that K jobs share the cores this process may run on (``cores.allowed_cores``)."""
    return max(1, len(allowed_cores()) // workers)
