"""How much of a real asset's surface the generator's views see (issue 30, item 2).

For every sample asset (../shared/assets/models), read as ``generate`` reads it
(every material with its own UVs and maps), the shares of its latent texels seen
by a view, inpainted from their neighbours and given the diffuse fallback, per
material and for the whole object: with batch's orbit of V views, and with the V
views ``coverage.choose_cameras`` picks. The shares are ``generate``'s own, with
the sampler replaced by a zero residual and the energy guard off: neither changes
which texels a view sees. Also the seconds of each stage but sampling and guard.

    python -m bench.generator.generate_coverage [--views 12] [--assets A.glb ...]

Writes the JSON report and a chart beside it (seen / inpainted / fallback per asset).
"""
from __future__ import annotations

import argparse
from pathlib import Path

import torch

from bench.common import REPO, add_out_argument, pyplot, save_chart, write_report
from torch_models.generator import DEFAULT_TEXTURE_SIZE, DEFAULT_VIEWS
from torch_models.generator import generate as gen
from torch_models.generator.mesh_input import load_mesh
from torch_models.generator.views import orbit_cameras

MODELS = REPO.parent / "shared" / "assets" / "models"


class ZeroResidual:
    """Stands in for the model: which texels the views see does not depend on what it samples."""

    def sample(self, cond, *args, **kwargs) -> torch.Tensor:  # cond: dit.Conditions
        return torch.zeros_like(cond.prior)


def shares(result: gen.Generation) -> dict:
    """The object's shares, each material's, the stages' seconds and the warnings of one generation."""
    return {**result.coverage(), "materials": {m.name: m.stats() for m in result.materials},
            "seconds": {k: round(v, 2) for k, v in result.seconds.items() if k not in ("sampling", "energy_guard")},
            "warnings": result.warnings}


TARGET_SEEN = 0.6  # issue 30: at least 60 % of the texels seen squarely at the defaults


def chart(rows: list[dict], path: Path) -> None:
    """Stacked bars per asset, orbit beside chosen: the shares seen, inpainted and given the fallback."""
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(11, 4.2))
    colours = {"seen": "#3a7d44", "inpainted": "#e0a030", "fallback": "#b03a2e"}
    for k, row in enumerate(rows):
        for offset, label in ((-0.2, "orbit"), (0.2, "chosen")):
            bottom = 0.0
            for share, colour in colours.items():
                value = row[label][share]
                ax.bar(k + offset, value, 0.38, bottom=bottom, color=colour, alpha=0.55 if label == "orbit" else 1.0,
                       label=f"{share} ({label})" if k == 0 else None)
                bottom += value
    ax.axhline(TARGET_SEEN, ls="--", color="gray", lw=0.8, label="target: 60 % seen")
    ax.set_xticks(range(len(rows)), [r["asset"] for r in rows], rotation=25, ha="right")
    ax.set_ylabel("share of latent texels")
    ax.set_title("Texels the generator's views see: batch's orbit (left, pale) against the chosen views (right)")
    ax.legend(fontsize=7, ncol=2, loc="lower left")
    save_chart(fig, path)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--assets", type=Path, nargs="*", default=sorted(MODELS.glob("*.glb")))
    ap.add_argument("--views", type=int, default=DEFAULT_VIEWS)
    add_out_argument(ap, "generate_coverage.json")
    args = ap.parse_args()
    torch.set_num_threads(1)
    _, cfg = gen.load_generator()
    rows = []
    for path in args.assets:
        inp = load_mesh(path)
        row = {"asset": path.stem, "materials": len(inp.materials), "triangles": len(inp.mesh.faces),
               "notes": inp.notes}
        for label, cameras in (("orbit", orbit_cameras(args.views, cfg.model.size)), ("chosen", None)):
            result = gen.generate(inp, "paint with light dust", ZeroResidual(), cfg, views=args.views,
                                  texture_size=DEFAULT_TEXTURE_SIZE, guard_energy=False, cameras=cameras)
            row[label] = shares(result)
        rows.append(row)
        print(f"{path.stem}: seen {row['orbit']['seen']:.0%} (orbit) -> {row['chosen']['seen']:.0%} (chosen)",
              flush=True)
    write_report(args.out, {"views": args.views, "texture_size": DEFAULT_TEXTURE_SIZE, "assets": rows},
                 generator=gen.SHIPPED)
    chart(rows, args.out.with_suffix(".png"))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
