"""Fit step of one asset (a torch process): every enhanced material of the work folder.

Runs the fit (``torch_models.neural.fit.material``, what ``python -m torch_models fit``
runs) once per material folder (``materials/<name>/`` -> ``materials/<name>/neural/``),
in one process, so torch is imported once per asset, and writes ``fit.json`` with each material's white-furnace
result. The fit refits a latent that gains energy under the energy bound and
scales the f_neu of one that still does (``energy_scale``, see
docs/neural-material.md) instead of dropping the material; how many passed as
fitted, after the refit and by scaling is recorded per material and in the manifest,
with the wall and CPU seconds of each fit and of its energy check.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--work", type=Path, required=True)
    parser.add_argument("--decoder", type=Path, required=True)
    parser.add_argument("--steps", type=int, required=True)
    parser.add_argument("--cluster-step", type=float, required=True)
    parser.add_argument("--budget", type=int, required=True)
    parser.add_argument("--threads", type=int, default=1)
    args = parser.parse_args(argv)
    sys.path.insert(0, str(REPO))
    import torch

    from richmat_addon.core import material_folder
    from torch_models.stage_clock import StageClock
    from torch_models.neural import trained
    from torch_models.neural.fit.material import FitSettings, fit_material

    clock = StageClock()
    torch.set_num_threads(args.threads)
    model = trained.load(args.decoder)
    settings = FitSettings(steps=args.steps, cluster_step=args.cluster_step, budget=args.budget)
    record: dict = {"torch_version": torch.__version__, "decoder": str(args.decoder), "materials": {}}
    for folder in sorted(p.parent for p in (args.work / "materials").glob(f"*/{material_folder.RECORD}")):
        with clock.stage("fit"):
            neural = fit_material(model, folder, folder / "neural", settings)
        record["materials"][folder.name] = {"furnace": neural["furnace"], "final_loss": neural["final_loss"],
                                            "fitted_vectors": neural["fitted_vectors"],
                                            "decoder_sha256": neural["decoder_sha256"],
                                            "timings_s": neural["timings_s"], "cpu_s": neural["cpu_s"]}
    timed = clock.record()
    for kind in timed:  # the energy check's share of "fit", over all materials
        timed[kind]["energy"] = round(sum(m[kind]["energy"] for m in record["materials"].values()), 3)
    (args.work / "fit.json").write_text(json.dumps({**record, **timed}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
