"""`make demo`'s command on tiny sizes: every stage runs, and each picture shows what it claims:
panels of the promised size, each under a caption, generated rows that differ, neural balls close to
the analytic ones."""
import json
import subprocess
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from richmat_addon.core import material_folder
from richmat_addon.core.enhancement_types import TYPES
from torch_models import cli_demo
from torch_models.demo_render import to_u8
from torch_models.cli import build_parser, main

RESOLUTION = 32  # ball panels
VIEW = 48  # generated views
CAPTION_GREY = 40  # demo_render.captioned_row's strip

# LDR-FLIP of the neural ball against the analytic one at this test's sizes (8 px texture, 32 px balls,
# 2 spp, one fit step from the encoder's latents), measured: Types 0-5 give 0.123 0.132 0.121 0.158
# 0.180 0.207 (mean 0.154). On Types 0-3, zero latents give ~0.29 each and every type rendered with
# the next type's latents 0.18 on average: a pipeline that loses the fit or mixes up the types fails these.
FLIP_MEAN_BOUND = 0.17
FLIP_TYPE_BOUND = 0.23
GENERATE_SIZE = 16  # latent texels a side of the generated materials


def _fingerprint(folder: Path) -> bytes:
    """Every map of an enhanced material folder, as bytes: equal only for equal materials."""
    mat = material_folder.read(folder).material()
    return b"".join(np.ascontiguousarray(m.value, np.float32).tobytes()
                    for _, m in sorted([("base_color", mat.base_color), *mat.params.items()]))


def _rows(sheet: np.ndarray) -> list[tuple[int, int]]:
    """(first, end) of each run of picture rows: a caption strip is grey at its left edge, a ball or
    object render is black there (its background)."""
    picture = np.r_[False, ~(sheet[:, 0] == CAPTION_GREY).all(-1), False]
    edges = np.flatnonzero(np.diff(picture.astype(int)))
    return list(zip(edges[::2], edges[1::2]))


def _check_captions(sheet: np.ndarray, panel_width: int, panel_height: int, panels: int, rows: int) -> list[np.ndarray]:
    """Assert ``rows`` rows of ``panels`` pictures, each under a caption strip with text in it; the rows' pictures."""
    assert sheet.shape[1] == panels * panel_width
    found = _rows(sheet)
    assert [end - first for first, end in found] == [panel_height] * rows, found
    top = 0
    for first, end in found:
        for k in range(panels):
            strip = sheet[top:first, k * panel_width:(k + 1) * panel_width]
            assert strip.size and (strip.min(-1) > 200).any(), f"no caption text above panel {k} at row {first}"
        top = end
    return [sheet[first:end] for first, end in found]


def test_demo_writes_labelled_pictures_of_types_fits_and_prompts(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    out = tmp_path / "demo"
    assert main(["demo", "--out", str(out), "--size", "8", "--resolution", str(RESOLUTION), "--spp", "2",
                 "--fit-steps", "1", "--refit-steps", "1", "--generate-size", str(GENERATE_SIZE),
                 "--view-size", str(VIEW)]) == 0
    folders = [f"type_{t.index}" for t in TYPES]
    for k in folders:
        assert (out / k / "params.json").is_file() and (out / k / "material.mtlx").is_file()
        record = json.loads((out / k / "neural" / "neural.json").read_text())
        assert record["fitted_vectors"] >= 1 and (out / k / "neural" / "latent_0.exr").is_file()
    assert len({_fingerprint(out / k) for k in folders}) == len(TYPES), "the types must differ"

    side = np.asarray(Image.open(out / "side_by_side.png").convert("RGB"))
    (balls,) = _check_captions(side, RESOLUTION, RESOLUTION, panels=7, rows=1)
    assert balls.max() > 0

    _check_captions(np.asarray(Image.open(out / "neural_vs_analytic.png").convert("RGB")), RESOLUTION, RESOLUTION,
                    panels=3, rows=6)
    flips = json.loads((out / "neural_vs_analytic.json").read_text())["flip"]
    assert set(flips) == set(folders)
    assert max(flips.values()) < FLIP_TYPE_BOUND and np.mean(list(flips.values())) < FLIP_MEAN_BOUND, flips

    generated = json.loads((out / "generated.json").read_text())
    assert len(generated["rows"]) == 3
    assert len({row["type"] for row in generated["rows"]}) == 3  # the prompts name different enhancements
    rows = _check_captions(np.asarray(Image.open(out / "generated.png").convert("RGB")), VIEW, VIEW,
                           panels=2, rows=3)
    references, views = [r[:, :VIEW].astype(float) for r in rows], [r[:, VIEW:].astype(float) for r in rows]
    # The first prompt again with another seed, rendered with the same samples: what the generator's own
    # noise changes. Each row's generated view must differ from every other row's by more than that.
    inp = cli_demo.demo_sphere(GENERATE_SIZE)
    ((_, _, reseeded),) = cli_demo.prompt_views(inp, [generated["rows"][0]["prompt"]], 1, GENERATE_SIZE, VIEW,
                                                cli_demo.PREVIEW_SPP)
    seed_noise = np.abs(to_u8(reseeded).astype(float) - views[0]).mean()
    differences = [np.abs(a - b).mean() for i, a in enumerate(views) for b in views[i + 1:]]
    assert min(differences) > seed_noise, (differences, seed_noise)
    assert min(np.abs(a - b).mean() for i, a in enumerate(references) for b in references[i + 1:]) > seed_noise

    progress = capsys.readouterr().err
    assert "[1/6] enhance" in progress and "[6/6] generate from prompts" in progress and " left" in progress


def test_full_selects_the_larger_sizes_unless_given() -> None:
    args = build_parser().parse_args(["demo", "--full", "--spp", "8"])
    cli_demo.apply_sizes(args)
    assert (args.size, args.fit_steps, args.spp) == (cli_demo.FULL["size"], cli_demo.FULL["fit_steps"], 8)
    args = build_parser().parse_args(["demo"])
    cli_demo.apply_sizes(args)
    assert args.size == cli_demo.QUICK["size"] < cli_demo.FULL["size"]


def test_make_demo_full_passes_the_flag() -> None:
    def demo_command(*variables: str) -> str:
        lines = subprocess.run(["make", "-n", "--no-print-directory", "-C", str(Path(__file__).resolve().parents[1]),
                                "demo", *variables], capture_output=True, text=True, check=True).stdout.splitlines()
        (command,) = [line for line in lines if "torch_models demo" in line]
        return command

    assert "--full" not in demo_command() and demo_command("FULL=1").split()[-1] == "--full"


def test_progress_trusts_the_expected_seconds_until_a_tenth_is_done() -> None:
    progress = cli_demo.Progress({"enhance": 1.0, "fit": 99.0})
    progress.start("enhance")
    progress.advance(1.0)  # 1 % of the weight in a few microseconds: extrapolating would say ~0 s left
    assert progress.seconds_left() == 99.0
    progress.start("fit")
    progress.advance(0.5)  # past a tenth: the measured speed takes over
    progress.bar.start_t = progress.bar._time() - 10.0  # as if 50.5 of the 100 expected seconds took 10 s
    assert abs(progress.seconds_left() - 10.0 * 49.5 / 50.5) < 0.5
    progress.close()
