"""The numbers a reader acts on, as the README and the design notes quote them, each with its report's key.

What is pinned (tests/test_docs_reports.py enforces it): every number the README quotes; in the
design notes, the numbers of their Markdown tables (a row's quote lies inside a line that starts
with "|"), where each note keeps its current numbers; and a few headline figures in prose, listed
in HEADLINE_PROSE with why a reader acts on them (defaults, accuracy and speed of what ships).
Other numbers in a note's prose are not pinned, so rewording prose does not break a test; a note
that cites a JSON report keeps at least one row.

One row per quoted number: the document, the quoted words with the number in braces
(whitespace is compared collapsed, so a quote may run over a line break), the JSON file it
comes from and the key path inside it, and a scale from the report's units to the quoted
ones. The rounding is the quote's own: the value, scaled, printed with as many decimals as
the quote shows must equal it (thousands may be grouped by a space or a comma).

A key path names keys and list positions (negative from the end) separated by "/", "*" for
every item at that level. Before it, "min:", "max:" or "mean:" reduce what the "*" found,
"len:" counts the items of the list or mapping it names, and "sqrt:" takes a square root
(a texture's side from its texel count).
"""
from __future__ import annotations

import re
from dataclasses import dataclass


@dataclass(frozen=True)
class DocNumber:
    doc: str
    quote: str
    report: str
    key: str = ""
    scale: float = 1.0


R = "docs/reports/"
README = "README.md"
GENERATOR = "docs/generator.md"
NEURAL = "docs/neural-material.md"
TABLE_1K = "materials/wooden_table_02_1k/"  # fit_bounded.json: the wooden table at 1k
GUIDANCE_PER_TYPE = "summary/4"  # generate_guidance.json's summary rows: 1, 1.5, 2, 2.5, per type
GUIDANCE_2 = "summary/2"
WIDE = R + "decoder_candidates_wide.json"
FOLLOW = R + "generate_follow.json"
FOLLOWED, TODAY_FOLLOWED = "strength/words, generated", "strength/today, generated"
BACKENDS = "docs/backends.md"
EEVEE_REPORT = R + "native_eevee.json"
SWEPT = "type0_diel_0"  # native_eevee.json's Type 0 draw of the settings sweep
NUMBER = re.compile(r"\{([^{}]*)\}")  # a quoted number in braces

# The prose quotes that stay pinned (at most a dozen), each with why a reader acts on it.
HEADLINE_PROSE: dict[str, str] = {
    "the shipped hybrid takes {50.8} s in all": "the shipped decoder fitting every vector of a 1k material",
    "mean FLIP {0.055} under the probe and 0.057": "the accuracy of the preview that ships",
    "after merging) takes {19.1} s, its error readout": "what the add-on's Fit costs on a 1k scan",
    "(mean {0.0025} against <= 0.03, worst 0.0070": "the accuracy of the farm's native graph",
    "worst {0.0070} against <= 0.06)": "the accuracy of the farm's native graph",
    "**{12} spp, threshold 0.01**": "the farm's default beauty samples",
    "**{1544} assets/hour**": "the farm's throughput at its defaults",
    "rule, the fewest samples whose every layer's mean error and share are at most the default's plus the "
    "floor, keeps **{8}**": "the farm's default intrinsics samples",
    "falls from 0.071 (fits) to {0.015}": "the accuracy of the shipped sheen table",
    "Type 0 material (two lobes) runs at {6.0} M evaluations/s": "the speed of the torch renderer",
    "Type 5 (six lobes) at {1.7} M": "the speed of the torch renderer",
}


def table_row(doc: str, row: str, report: str, keys: list[str]) -> tuple[DocNumber, ...]:
    """One row per braced number of a quoted table row, each quoting the whole row with only its
    own number in braces; ``keys`` in the order of the numbers."""
    parts = NUMBER.split(row)
    texts, numbers = parts[::2], parts[1::2]
    if len(numbers) != len(keys):
        raise ValueError(f"{len(numbers)} numbers and {len(keys)} keys in {row!r}")

    def quote(braced: int) -> str:
        cells = ((f"{{{n}}}" if i == braced else n) + t for i, (n, t) in enumerate(zip(numbers, texts[1:])))
        return texts[0] + "".join(cells)

    return tuple(DocNumber(doc, quote(i), report, k) for i, k in enumerate(keys))


def candidate_keys(decoder: str, worst: tuple[str, ...] = ()) -> list[str]:
    """decoder_candidates_wide.json's keys of one table row under the probe: the means of Table 1's
    metals, the real metals and the real dielectrics, each metal mean of a set in ``worst`` followed
    by its worst."""
    out = []
    for case_set, group in (("table1", "metals"), ("real", "metals"), ("real", "dielectrics")):
        key = f"sets/{case_set}/summary/probe_{group}/{decoder}"
        out += [f"{key}/mean", f"{key}/worst"] if group == "metals" and case_set in worst else [f"{key}/mean"]
    return out


def sweep_keys(setting: int) -> list[str]:
    """native_eevee.json's keys of one row of backends.md's EEVEE settings table: FLIP and brightness
    ratio on the Principled ball, then on the swept Type 0 draw."""
    key = f"settings_sweep/{setting}/"
    return [key + f"{k}/{ball}" for ball in ("control", SWEPT) for k in ("flip", "brightness_ratio")]


def eevee_keys(group: str, ranged: bool) -> list[str]:
    """native_eevee.json's keys of one row of backends.md's EEVEE table: cases, mean and worst FLIP,
    noise floor, and the brightness ratio's least (and, ``ranged``, greatest) value."""
    key = f"summary/{group}/"
    return [key + k for k in ("cases", "mean_flip", "worst_flip", "mean_cycles_floor", "brightness_ratio/0")] + \
        ([key + "brightness_ratio/1"] if ranged else [])


ROWS: tuple[DocNumber, ...] = (
    # README: headline numbers
    DocNumber(README, "worst FLIP {0.013} (target 0.03)", R + "agreement.json", "worst_flip"),
    DocNumber(README, "worst FLIP 0.013 (target {0.03})", R + "agreement.json", "target"),
    DocNumber(README, "medians {0.033}-0.047", R + "fit_flip.json", "min:decoders/0/summary/*/median"),
    DocNumber(README, "medians 0.033-{0.047}", R + "fit_flip.json", "max:decoders/0/summary/*/median"),
    DocNumber(README, "worst {0.058}-0.178, every case", R + "fit_flip.json", "min:decoders/0/summary/*/worst"),
    DocNumber(README, "worst 0.058-{0.178}, every case", R + "fit_flip.json", "max:decoders/0/summary/*/worst"),
    *table_row(README, "(the paper: {0.064}-{0.092})", R + "fit_flip.json",
               [f"{op}:decoders/0/summary/*/paper/1" for op in ("min", "max")]),
    # the bounded fit (budget 1024, designs/5) against the fit of every vector (designs/0)
    *table_row(README, "{18.7} s in all on one thread, against {1120} CPU s (extrapolated); texel fit error {0.064} "
               "against {0.071}", R + "fit_bounded.json", [TABLE_1K + k for k in (
                   "shipped_fit/wall_s", "designs/0/fit_cpu", "designs/5/texel_error", "designs/0/texel_error")]),
    DocNumber(README, "| {36.7} / 36.0 dB, every asset", R + "generate_eval_real.json", "overall/generated/psnr"),
    DocNumber(README, "| 36.7 / {36.0} dB, every asset", R + "generate_eval_real_seed1.json", "overall/generated/psnr"),
    DocNumber(README, "every asset at least {30.7} (rule-based", R + "generate_eval_real_seed1.json",
              "min:objects/*/generated/psnr"),
    DocNumber(README, "(rule-based prior {33.6}, plain PBR 30.4, retrieval 26.5)", R + "generate_eval_real.json",
              "overall/procedural/psnr"),
    DocNumber(README, "(rule-based prior 33.6, plain PBR {30.4}, retrieval 26.5)", R + "generate_eval_real.json",
              "overall/pbr/psnr"),
    DocNumber(README, "(rule-based prior 33.6, plain PBR 30.4, retrieval {26.5})", R + "generate_eval_real.json",
              "overall/retrieval/psnr"),
    DocNumber(README, "{12} CPU s per object", R + "generate_eval_real.json", "median_cpu_seconds_per_object"),
    DocNumber(README, "{416} files compared, identical", R + "batch_restart.json", "comparison/files_compared"),

    # docs/neural-material.md: the targets' table (the preview's error budget)
    DocNumber(NEURAL, 'WaterBottle {0.140} / 0.140, SheenCloth', R + "neural_error_budget.json", "assets/WaterBottle/probe/all/flip/closure"),
    DocNumber(NEURAL, 'WaterBottle 0.140 / {0.140}, SheenCloth', R + "neural_error_budget.json", "assets/WaterBottle/probe_and_sun/all/flip/closure"),
    DocNumber(NEURAL, 'SheenCloth {0.056} / 0.056, CesiumMilkTruck', R + "neural_error_budget.json", "assets/SheenCloth/probe/all/flip/closure"),
    DocNumber(NEURAL, 'SheenCloth 0.056 / {0.056}, CesiumMilkTruck', R + "neural_error_budget.json", "assets/SheenCloth/probe_and_sun/all/flip/closure"),
    DocNumber(NEURAL, 'CesiumMilkTruck {0.016} / 0.015; the add-on', R + "neural_error_budget.json", "assets/CesiumMilkTruck/probe/all/flip/closure"),
    DocNumber(NEURAL, 'CesiumMilkTruck 0.016 / {0.015}; the add-on', R + "neural_error_budget.json", "assets/CesiumMilkTruck/probe_and_sun/all/flip/closure"),
    DocNumber(NEURAL, '| {0.029} / 0.027, 0.025 / 0.023, 0.018 / 0.017 (256 px', R + "neural_error_budget.json", "assets/WaterBottle/probe/all/flip/noise_floor"),
    DocNumber(NEURAL, '| 0.029 / {0.027}, 0.025 / 0.023, 0.018 / 0.017 (256 px', R + "neural_error_budget.json", "assets/WaterBottle/probe_and_sun/all/flip/noise_floor"),
    DocNumber(NEURAL, '| 0.029 / 0.027, {0.025} / 0.023, 0.018 / 0.017 (256 px', R + "neural_error_budget.json", "assets/SheenCloth/probe/all/flip/noise_floor"),
    DocNumber(NEURAL, '| 0.029 / 0.027, 0.025 / {0.023}, 0.018 / 0.017 (256 px', R + "neural_error_budget.json", "assets/SheenCloth/probe_and_sun/all/flip/noise_floor"),
    DocNumber(NEURAL, '| 0.029 / 0.027, 0.025 / 0.023, {0.018} / 0.017 (256 px', R + "neural_error_budget.json", "assets/CesiumMilkTruck/probe/all/flip/noise_floor"),
    DocNumber(NEURAL, '| 0.029 / 0.027, 0.025 / 0.023, 0.018 / {0.017} (256 px', R + "neural_error_budget.json", "assets/CesiumMilkTruck/probe_and_sun/all/flip/noise_floor"),

    # docs/generator.md
    DocNumber(GENERATOR, "| **generated** | **{40.9} / 41.4 dB**", R + "generate_eval.json", "overall/generated/psnr"),
    DocNumber(GENERATOR, "| **generated** | **40.9 / {41.4} dB**", R + "generate_eval_seed1.json",
              "overall/generated/psnr"),
    DocNumber(GENERATOR, "**{0.0346} / 0.0296**", R + "generate_eval.json", "overall/generated/flip"),
    DocNumber(GENERATOR, "**0.0346 / {0.0296}**", R + "generate_eval_seed1.json", "overall/generated/flip"),
    DocNumber(GENERATOR, "| procedural | {38.0} | 0.0412 |", R + "generate_eval.json", "overall/procedural/psnr"),
    DocNumber(GENERATOR, "| retrieval | 37.1 | {0.0489} |", R + "generate_eval.json", "overall/retrieval/flip"),
    DocNumber(GENERATOR, "| pbr | {34.5} | 0.0602 |", R + "generate_eval.json", "overall/pbr/psnr"),
    DocNumber(GENERATOR, "| retrieval | {37.1} | 0.0489 |", R + "generate_eval.json", "overall/retrieval/psnr"),
    DocNumber(GENERATOR, "| **mean** | | | **{36.7} / 36.0 dB** |", R + "generate_eval_real.json",
              "overall/generated/psnr"),
    DocNumber(GENERATOR, "| **mean** | | | **36.7 / {36.0} dB** |", R + "generate_eval_real_seed1.json",
              "overall/generated/psnr"),
    DocNumber(GENERATOR, "| 30.4 | 33.6 | 26.5 | {11.6} (median) |", R + "generate_eval_real.json",
              "median_cpu_seconds_per_object"),
    DocNumber(GENERATOR, "| FlightHelmet | 6 | {58} % | **66 %** |", R + "generate_coverage.json",
              "assets/4/orbit/seen", 100),
    DocNumber(GENERATOR, "| FlightHelmet | 6 | 58 % | **{66} %** |", R + "generate_coverage.json",
              "assets/4/chosen/seen", 100),
    DocNumber(GENERATOR, "| NormalTangentTest | 1 | 100 % | **{100} %** |", R + "generate_coverage.json",
              "assets/5/chosen/seen", 100),
    DocNumber(GENERATOR, "| **18** | **12** | **{37.1}** |", R + "generate_speed.json", "rows/6/psnr"),
    DocNumber(GENERATOR, "| 2 | 8 | {14.5} | 0.8 |", R + "generate_speed.json", "rows/0/psnr"),
    DocNumber(GENERATOR, "| **per type (shipped)** | **{41.3} / 31.0** |", R + "generate_guidance.json",
              GUIDANCE_PER_TYPE + "/procedural/psnr"),
    *table_row(GENERATOR, "| **{36.3} / {30.7}** | **0.90** |", R + "generate_guidance.json",
               [GUIDANCE_PER_TYPE + "/real/psnr", GUIDANCE_PER_TYPE + "/real/min_psnr"]),
    *table_row(GENERATOR, "| 2 (the old default) | {40.3} / 30.3 | {34.9} / {29.2} | {1.01} |", R + "generate_guidance.json",
               [GUIDANCE_2 + k for k in ("/procedural/psnr", "/real/psnr", "/real/min_psnr", "/prompt_sensitivity/ratio")]),

    # issue 50: following the words (bench/generator/generate_follow.py)
    *table_row(GENERATOR, "| named colour, CIEDE2000 of the mean base colour (21 prompts x 4 meshes), median / worst "
               "| {33.9} / {88.0} | **{0.0} / {0.0}** | 10 |", FOLLOW,
               ["base/today/median_de", "base/today/worst_de", "base/words/median_de", "base/words/worst_de"]),
    DocNumber(GENERATOR, "(gold, copper, brass, silver, aluminium, iron, chrome) | {25} % | **100 %**", FOLLOW,
              "base/today/metals_read", 100),
    DocNumber(GENERATOR, "(gold, copper, brass, silver, aluminium, iron, chrome) | 25 % | **{100} %**", FOLLOW,
              "base/words/metals_read", 100),
    DocNumber(GENERATOR, "| type read | {100} % | 100 % |", FOLLOW, "base/today/types_read", 100),
    DocNumber(GENERATOR, "| type read | 100 % | {100} % |", FOLLOW, "base/words/types_read", 100),
    *table_row(GENERATOR, "| strength triples ordered light < moderate < heavy, generated | {5} of {10} | "
               "**{10} of {10}** | 90 % |", FOLLOW, [TODAY_FOLLOWED + "/ordered", TODAY_FOLLOWED + "/triples",
                                                 FOLLOWED + "/ordered", FOLLOWED + "/triples"]),
    *table_row(GENERATOR, "| effect (heavy - light) over the seed spread, per family | at most {0.26} | "
               "**{1.2}-{2.8}** | > 1 |", FOLLOW, ["max:" + TODAY_FOLLOWED + "/effect_over_spread/*",
                                                   "min:" + FOLLOWED + "/effect_over_spread/*",
                                                   "max:" + FOLLOWED + "/effect_over_spread/*"]),

    # docs/neural-material.md
    # fit_flip.json's Table 1: per type, the shipped hybrid's and the MLP's median / worst, then the paper's
    *(number for t, cells in enumerate((
        "0 haze | **{0.035}** / **{0.147}** | {0.058} / {0.167} | {0.092} / {0.187}",
        "1 dust | **{0.033}** / **{0.178}** | {0.067} / {0.251} | {0.073} / {0.167}",
        "2 clearcoat | **{0.036}** / **{0.130}** | {0.063} / {0.159} | {0.086} / {0.119}",
        "3 dust + coat | **{0.047}** / **{0.127}** | {0.075} / {0.189} | {0.088} / {0.166}",
        "4 inner scattering | **{0.034}** / **{0.069}** | {0.044} / {0.099} | {0.064} / {0.171}",
        "5 subcutaneous | **{0.035}** / **{0.058}** | {0.050} / {0.128} | {0.081} / {0.175}"))
      for number in table_row(NEURAL, f"| {cells} |", R + "fit_flip.json",
                              [f"decoders/{d}/summary/{t}/{s}" for d in (0, 1) for s in ("median", "worst")]
                              + [f"decoders/0/summary/{t}/paper/{i}" for i in (1, 2)])),
    DocNumber(NEURAL, "| energy check | {300} pass as fitted (bounded)", R + "fit_flip.json",
              "decoders/0/furnace/passed_as_fitted"),
    DocNumber(NEURAL, "| {140} as fitted, 141 after the refit, 19 scaled", R + "fit_flip.json",
              "decoders/1/furnace/passed_as_fitted"),
    DocNumber(NEURAL, "| 140 as fitted, 141 after the refit, {19} scaled", R + "fit_flip.json",
              "decoders/1/furnace/repaired_by_scaling"),
    DocNumber(NEURAL, "| WaterBottle | 1k | {26 448} | 0.117 / 0.057 / 104 | 0.117 / 0.060 / 11.7 | 17.5 (3.1) | 0.016 |", R + "fit_bounded.json",
              "materials/WaterBottle/merged_vectors"),
    DocNumber(NEURAL, "| WaterBottle | 1k | 26 448 | {0.117} / 0.057 / 104 | 0.117 / 0.060 / 11.7 | 17.5 (3.1) | 0.016 |", R + "fit_bounded.json",
              "materials/WaterBottle/designs/0/texel_error"),
    DocNumber(NEURAL, "| WaterBottle | 1k | 26 448 | 0.117 / {0.057} / 104 | 0.117 / 0.060 / 11.7 | 17.5 (3.1) | 0.016 |", R + "fit_bounded.json",
              "materials/WaterBottle/designs/0/crop_flip"),
    DocNumber(NEURAL, "| WaterBottle | 1k | 26 448 | 0.117 / 0.057 / {104} | 0.117 / 0.060 / 11.7 | 17.5 (3.1) | 0.016 |", R + "fit_bounded.json",
              "materials/WaterBottle/designs/0/fit_cpu"),
    DocNumber(NEURAL, "| WaterBottle | 1k | 26 448 | 0.117 / 0.057 / 104 | {0.117} / 0.060 / 11.7 | 17.5 (3.1) | 0.016 |", R + "fit_bounded.json",
              "materials/WaterBottle/designs/5/texel_error"),
    DocNumber(NEURAL, "| WaterBottle | 1k | 26 448 | 0.117 / 0.057 / 104 | 0.117 / {0.060} / 11.7 | 17.5 (3.1) | 0.016 |", R + "fit_bounded.json",
              "materials/WaterBottle/designs/5/crop_flip"),
    DocNumber(NEURAL, "| WaterBottle | 1k | 26 448 | 0.117 / 0.057 / 104 | 0.117 / 0.060 / {11.7} | 17.5 (3.1) | 0.016 |", R + "fit_bounded.json",
              "materials/WaterBottle/designs/5/fit_cpu"),
    DocNumber(NEURAL, "| WaterBottle | 1k | 26 448 | 0.117 / 0.057 / 104 | 0.117 / 0.060 / 11.7 | {17.5} (3.1) | 0.016 |", R + "fit_bounded.json",
              "materials/WaterBottle/shipped_fit/wall_s"),
    DocNumber(NEURAL, "| WaterBottle | 1k | 26 448 | 0.117 / 0.057 / 104 | 0.117 / 0.060 / 11.7 | 17.5 ({3.1}) | 0.016 |", R + "fit_bounded.json",
              "materials/WaterBottle/shipped_fit/stages_wall_s/read"),
    DocNumber(NEURAL, "| WaterBottle | 1k | 26 448 | 0.117 / 0.057 / 104 | 0.117 / 0.060 / 11.7 | 17.5 (3.1) | {0.016} |", R + "fit_bounded.json",
              "materials/WaterBottle/crop_noise_floor"),
    DocNumber(NEURAL, "| wooden table | 1k | {409 590} | 0.071 / 0.053 / 1120 | 0.064 / 0.050 / 12.1 | 18.7 (5.1) | 0.024 |", R + "fit_bounded.json",
              "materials/wooden_table_02_1k/merged_vectors"),
    DocNumber(NEURAL, "| wooden table | 1k | 409 590 | {0.071} / 0.053 / 1120 | 0.064 / 0.050 / 12.1 | 18.7 (5.1) | 0.024 |", R + "fit_bounded.json",
              "materials/wooden_table_02_1k/designs/0/texel_error"),
    DocNumber(NEURAL, "| wooden table | 1k | 409 590 | 0.071 / {0.053} / 1120 | 0.064 / 0.050 / 12.1 | 18.7 (5.1) | 0.024 |", R + "fit_bounded.json",
              "materials/wooden_table_02_1k/designs/0/crop_flip"),
    DocNumber(NEURAL, "| wooden table | 1k | 409 590 | 0.071 / 0.053 / {1120} | 0.064 / 0.050 / 12.1 | 18.7 (5.1) | 0.024 |", R + "fit_bounded.json",
              "materials/wooden_table_02_1k/designs/0/fit_cpu"),
    DocNumber(NEURAL, "| wooden table | 1k | 409 590 | 0.071 / 0.053 / 1120 | {0.064} / 0.050 / 12.1 | 18.7 (5.1) | 0.024 |", R + "fit_bounded.json",
              "materials/wooden_table_02_1k/designs/5/texel_error"),
    DocNumber(NEURAL, "| wooden table | 1k | 409 590 | 0.071 / 0.053 / 1120 | 0.064 / {0.050} / 12.1 | 18.7 (5.1) | 0.024 |", R + "fit_bounded.json",
              "materials/wooden_table_02_1k/designs/5/crop_flip"),
    DocNumber(NEURAL, "| wooden table | 1k | 409 590 | 0.071 / 0.053 / 1120 | 0.064 / 0.050 / {12.1} | 18.7 (5.1) | 0.024 |", R + "fit_bounded.json",
              "materials/wooden_table_02_1k/designs/5/fit_cpu"),
    DocNumber(NEURAL, "| wooden table | 1k | 409 590 | 0.071 / 0.053 / 1120 | 0.064 / 0.050 / 12.1 | {18.7} (5.1) | 0.024 |", R + "fit_bounded.json",
              "materials/wooden_table_02_1k/shipped_fit/wall_s"),
    DocNumber(NEURAL, "| wooden table | 1k | 409 590 | 0.071 / 0.053 / 1120 | 0.064 / 0.050 / 12.1 | 18.7 ({5.1}) | 0.024 |", R + "fit_bounded.json",
              "materials/wooden_table_02_1k/shipped_fit/stages_wall_s/read"),
    DocNumber(NEURAL, "| wooden table | 1k | 409 590 | 0.071 / 0.053 / 1120 | 0.064 / 0.050 / 12.1 | 18.7 (5.1) | {0.024} |", R + "fit_bounded.json",
              "materials/wooden_table_02_1k/crop_noise_floor"),
    DocNumber(NEURAL, "| wooden table | 2k | {1 385 321} | 0.070 / 0.059 / 3389 | 0.063 / 0.049 / 10.3 | 59.0 (44.3) | 0.023 |", R + "fit_bounded.json",
              "materials/wooden_table_02_1k@2k/merged_vectors"),
    DocNumber(NEURAL, "| wooden table | 2k | 1 385 321 | {0.070} / 0.059 / 3389 | 0.063 / 0.049 / 10.3 | 59.0 (44.3) | 0.023 |", R + "fit_bounded.json",
              "materials/wooden_table_02_1k@2k/designs/0/texel_error"),
    DocNumber(NEURAL, "| wooden table | 2k | 1 385 321 | 0.070 / {0.059} / 3389 | 0.063 / 0.049 / 10.3 | 59.0 (44.3) | 0.023 |", R + "fit_bounded.json",
              "materials/wooden_table_02_1k@2k/designs/0/crop_flip"),
    DocNumber(NEURAL, "| wooden table | 2k | 1 385 321 | 0.070 / 0.059 / {3389} | 0.063 / 0.049 / 10.3 | 59.0 (44.3) | 0.023 |", R + "fit_bounded.json",
              "materials/wooden_table_02_1k@2k/designs/0/fit_cpu"),
    DocNumber(NEURAL, "| wooden table | 2k | 1 385 321 | 0.070 / 0.059 / 3389 | {0.063} / 0.049 / 10.3 | 59.0 (44.3) | 0.023 |", R + "fit_bounded.json",
              "materials/wooden_table_02_1k@2k/designs/5/texel_error"),
    DocNumber(NEURAL, "| wooden table | 2k | 1 385 321 | 0.070 / 0.059 / 3389 | 0.063 / {0.049} / 10.3 | 59.0 (44.3) | 0.023 |", R + "fit_bounded.json",
              "materials/wooden_table_02_1k@2k/designs/5/crop_flip"),
    DocNumber(NEURAL, "| wooden table | 2k | 1 385 321 | 0.070 / 0.059 / 3389 | 0.063 / 0.049 / {10.3} | 59.0 (44.3) | 0.023 |", R + "fit_bounded.json",
              "materials/wooden_table_02_1k@2k/designs/5/fit_cpu"),
    DocNumber(NEURAL, "| wooden table | 2k | 1 385 321 | 0.070 / 0.059 / 3389 | 0.063 / 0.049 / 10.3 | {59.0} (44.3) | 0.023 |", R + "fit_bounded.json",
              "materials/wooden_table_02_1k@2k/shipped_fit/wall_s"),
    DocNumber(NEURAL, "| wooden table | 2k | 1 385 321 | 0.070 / 0.059 / 3389 | 0.063 / 0.049 / 10.3 | 59.0 ({44.3}) | 0.023 |", R + "fit_bounded.json",
              "materials/wooden_table_02_1k@2k/shipped_fit/stages_wall_s/read"),
    DocNumber(NEURAL, "| wooden table | 2k | 1 385 321 | 0.070 / 0.059 / 3389 | 0.063 / 0.049 / 10.3 | 59.0 (44.3) | {0.023} |", R + "fit_bounded.json",
              "materials/wooden_table_02_1k@2k/crop_noise_floor"),
    DocNumber(NEURAL, "| wooden table | 4k | {2 925 579} | 0.070 / 0.045 / 7555 | 0.061 / 0.038 / 10.8 | 141.7 (125.0) | 0.024 |", R + "fit_bounded.json",
              "materials/wooden_table_02_1k@4k/merged_vectors"),
    DocNumber(NEURAL, "| wooden table | 4k | 2 925 579 | {0.070} / 0.045 / 7555 | 0.061 / 0.038 / 10.8 | 141.7 (125.0) | 0.024 |", R + "fit_bounded.json",
              "materials/wooden_table_02_1k@4k/designs/0/texel_error"),
    DocNumber(NEURAL, "| wooden table | 4k | 2 925 579 | 0.070 / {0.045} / 7555 | 0.061 / 0.038 / 10.8 | 141.7 (125.0) | 0.024 |", R + "fit_bounded.json",
              "materials/wooden_table_02_1k@4k/designs/0/crop_flip"),
    DocNumber(NEURAL, "| wooden table | 4k | 2 925 579 | 0.070 / 0.045 / {7555} | 0.061 / 0.038 / 10.8 | 141.7 (125.0) | 0.024 |", R + "fit_bounded.json",
              "materials/wooden_table_02_1k@4k/designs/0/fit_cpu"),
    DocNumber(NEURAL, "| wooden table | 4k | 2 925 579 | 0.070 / 0.045 / 7555 | {0.061} / 0.038 / 10.8 | 141.7 (125.0) | 0.024 |", R + "fit_bounded.json",
              "materials/wooden_table_02_1k@4k/designs/5/texel_error"),
    DocNumber(NEURAL, "| wooden table | 4k | 2 925 579 | 0.070 / 0.045 / 7555 | 0.061 / {0.038} / 10.8 | 141.7 (125.0) | 0.024 |", R + "fit_bounded.json",
              "materials/wooden_table_02_1k@4k/designs/5/crop_flip"),
    DocNumber(NEURAL, "| wooden table | 4k | 2 925 579 | 0.070 / 0.045 / 7555 | 0.061 / 0.038 / {10.8} | 141.7 (125.0) | 0.024 |", R + "fit_bounded.json",
              "materials/wooden_table_02_1k@4k/designs/5/fit_cpu"),
    DocNumber(NEURAL, "| wooden table | 4k | 2 925 579 | 0.070 / 0.045 / 7555 | 0.061 / 0.038 / 10.8 | {141.7} (125.0) | 0.024 |", R + "fit_bounded.json",
              "materials/wooden_table_02_1k@4k/shipped_fit/wall_s"),
    DocNumber(NEURAL, "| wooden table | 4k | 2 925 579 | 0.070 / 0.045 / 7555 | 0.061 / 0.038 / 10.8 | 141.7 ({125.0}) | 0.024 |", R + "fit_bounded.json",
              "materials/wooden_table_02_1k@4k/shipped_fit/stages_wall_s/read"),
    DocNumber(NEURAL, "| wooden table | 4k | 2 925 579 | 0.070 / 0.045 / 7555 | 0.061 / 0.038 / 10.8 | 141.7 (125.0) | {0.024} |", R + "fit_bounded.json",
              "materials/wooden_table_02_1k@4k/crop_noise_floor"),
    DocNumber(NEURAL, "the shipped hybrid takes {50.8} s in all", R + "fit_full_size.json",
              "materials/0/total_seconds"),

    # the other design notes
    DocNumber("docs/addon.md", "| probe | **{0.055}** (worst 0.109)", R + "closure_preview.json", "scenes/probe/summary/closures/mean_flip"),
    DocNumber("docs/addon.md", "| probe | **0.055** (worst {0.109})", R + "closure_preview.json", "scenes/probe/summary/closures/worst_flip"),
    DocNumber("docs/addon.md", "(worst 0.109) | {0.064} (worst 0.101)", R + "closure_preview.json", "scenes/probe/summary/emission/mean_flip"),
    DocNumber("docs/addon.md", "| {0.038} / 0.056 | 0.036 |", R + "closure_preview.json", "scenes/probe/summary/closures/median_cycles_noise"),
    DocNumber("docs/addon.md", "| 0.038 / {0.056} | 0.036 |", R + "closure_preview.json", "scenes/probe/summary/emission/median_cycles_noise"),
    DocNumber("docs/addon.md", "| {10.5} / 13.3 |", R + "closure_preview.json", "scenes/probe/summary/closures/median_seconds"),
    DocNumber("docs/addon.md", "| 10.5 / {13.3} |", R + "closure_preview.json", "scenes/probe/summary/emission/median_seconds"),
    DocNumber("docs/addon.md", "| probe + sun | **{0.057}** (worst 0.113)", R + "closure_preview.json",
              "scenes/probe_and_sun/summary/closures/mean_flip"),
    DocNumber("docs/addon.md", "| probe + sun | **0.057** (worst {0.113})", R + "closure_preview.json",
              "scenes/probe_and_sun/summary/closures/worst_flip"),
    DocNumber("docs/addon.md", "(worst 0.113) | {0.108} (worst 0.202)", R + "closure_preview.json",
              "scenes/probe_and_sun/summary/emission/mean_flip"),
    DocNumber("docs/addon.md", "| {12.9} / 12.6 |", R + "closure_preview.json", "scenes/probe_and_sun/summary/closures/median_seconds"),
    DocNumber("docs/addon.md", "| 12.9 / {12.6} |", R + "closure_preview.json", "scenes/probe_and_sun/summary/emission/median_seconds"),
    DocNumber(NEURAL, "mean FLIP {0.055} under the probe and 0.057", R + "closure_preview.json", "scenes/probe/summary/closures/mean_flip"),

    # decoder_candidates_wide.json's table (neural-material.md, "How far the lobe form reaches")
    *table_row(NEURAL, "| noise floor | {0.034} | {0.030} | {0.033} |", WIDE, candidate_keys("noise_floor")),
    *table_row(NEURAL, "| shipped, closure form (the preview) | {0.106} ({0.128}) | {0.105} ({0.125}) | {0.039} |",
               WIDE, candidate_keys("shipped", worst=("table1", "real"))),
    *table_row(NEURAL, "| shipped in full (torch) | {0.072} | {0.081} | {0.037} |", WIDE, candidate_keys("shipped_full")),
    *table_row(NEURAL, "| view-gated, head 32 wide (`a208ac7c`) | {0.068} | {0.094} | {0.042} |", WIDE,
               candidate_keys("view_gates")),
    *table_row(NEURAL, "| **lobe form, free per case** | **{0.023}** ({0.031}) | **{0.036}** ({0.044}) | **{0.033}** |",
               WIDE, candidate_keys("lobe_form", worst=("table1", "real"))),
    DocNumber("docs/addon.md", "| 0.1 s | 0.1 s | 0.1 s | 10 s | 0.1 s | 0.1 s | {0.156} | 1.1 min |",
              R + "addon_assets.json", "assets/WaterBottle/preview_flip_vs_bake"),
    DocNumber("docs/addon.md", "| 0.1 s | 0.2 s | 0.1 s | {34} s | 0.3 s", R + "addon_assets.json",
              "assets/CesiumMilkTruck/records/3/seconds"),
    DocNumber("docs/addon.md", "| 0.6 s | {0.181} | 2.4 min |", R + "addon_assets.json",
              "assets/FlightHelmet/preview_flip_vs_bake"),
    DocNumber("docs/backends.md", "| Type 5 | 2 | {0.0059} | 0.0070 |", R + "native_agreement.json",
              "summary/type5/mean_flip"),
    DocNumber("docs/backends.md", "| Type 5 | 2 | 0.0059 | {0.0070} |", R + "native_agreement.json",
              "summary/type5/worst_flip"),
    DocNumber("docs/backends.md", "| Type 2 | 2 | 0.0052 | 0.0059 | {8.02} | 7.78 |", R + "native_agreement.json",
              "summary/type2/osl_frame_cpu_s"),
    DocNumber(BACKENDS, "(mean {0.0025} against <= 0.03, worst 0.0070", R + "native_agreement.json", "summary/all/mean_flip"),
    DocNumber(BACKENDS, "worst {0.0070} against <= 0.06)", R + "native_agreement.json", "summary/all/worst_flip"),
    # docs/backends.md 3.7: the native graph in EEVEE against Cycles, one table row per group
    *table_row(BACKENDS, '| Type 0 | {2} | {0.253} | {0.289} | {0.011} | {0.72}-{0.96} |',
               EEVEE_REPORT, eevee_keys('type0', True)),
    *table_row(BACKENDS, '| Type 1 | {2} | {0.245} | {0.272} | {0.012} | {0.81}-{0.96} |',
               EEVEE_REPORT, eevee_keys('type1', True)),
    *table_row(BACKENDS, '| Type 2 | {2} | {0.210} | {0.220} | {0.010} | {0.90}-{0.96} |',
               EEVEE_REPORT, eevee_keys('type2', True)),
    *table_row(BACKENDS, '| Type 3 | {2} | {0.187} | {0.192} | {0.010} | {0.92}-{0.96} |',
               EEVEE_REPORT, eevee_keys('type3', True)),
    *table_row(BACKENDS, '| Type 4 | {2} | {0.191} | {0.198} | {0.011} | {0.95}-{0.96} |',
               EEVEE_REPORT, eevee_keys('type4', True)),
    *table_row(BACKENDS, '| Type 5 | {2} | {0.199} | {0.205} | {0.011} | {0.95}-{0.96} |',
               EEVEE_REPORT, eevee_keys('type5', True)),
    *table_row(BACKENDS, '| dust (sheen) alone | {1} | {0.218} | {0.218} | {0.012} | {1.00} |',
               EEVEE_REPORT, eevee_keys('lobe dust', False)),
    *table_row(BACKENDS, '| coat alone | {1} | {0.046} | {0.046} | {0.004} | {0.85} |',
               EEVEE_REPORT, eevee_keys('lobe coat', False)),
    *table_row(BACKENDS, '| conductor core alone | {1} | {0.083} | {0.083} | {0.005} | {0.89} |',
               EEVEE_REPORT, eevee_keys('lobe cond_core', False)),
    *table_row(BACKENDS, '| conductor haze alone | {1} | {0.265} | {0.265} | {0.012} | {0.93} |',
               EEVEE_REPORT, eevee_keys('lobe cond_haze', False)),
    *table_row(BACKENDS, '| dielectric core alone | {1} | {0.079} | {0.079} | {0.005} | {0.76} |',
               EEVEE_REPORT, eevee_keys('lobe diel_core', False)),
    *table_row(BACKENDS, '| dielectric haze alone | {1} | {0.156} | {0.156} | {0.006} | {0.89} |',
               EEVEE_REPORT, eevee_keys('lobe diel_haze', False)),
    *table_row(BACKENDS, '| inner sheen alone | {1} | {0.216} | {0.216} | {0.011} | {1.01} |',
               EEVEE_REPORT, eevee_keys('lobe inner', False)),
    *table_row(BACKENDS, '| tinted dielectric (subcutaneous) alone | {1} | {0.155} | {0.155} | {0.006} | {0.56} |',
               EEVEE_REPORT, eevee_keys('lobe subsurf', False)),
    *table_row(BACKENDS, '| WaterBottle, uplifted | {2} | {0.205} | {0.269} | {0.009} | {0.77} |',
               EEVEE_REPORT, eevee_keys('WaterBottle', False)),
    *table_row(BACKENDS, "| Blender's Principled BSDF (reference) | {1} | {0.184} | {0.184} | {0.010} | {0.97} |",
               EEVEE_REPORT, eevee_keys('Principled BSDF', False)),
    *table_row(BACKENDS, '| **all** (not the reference) | {22} | **{0.191}** | **{0.289}** | {0.010} | {0.56}-{1.01} |',
               EEVEE_REPORT, eevee_keys('all', True)),
    # docs/backends.md 3.7: EEVEE's settings one at a time
    *(number for i, row in enumerate((
        "| the preview scene's (`sun_threshold` 0, Blender's defaults otherwise) | {0.184}, {0.97} | {0.216}, {0.96} |",
        "| `clamp_surface_indirect` 0 (no clamp; default 10) | {0.184}, {0.98} | {0.213}, {0.96} |",
        "| `sun_threshold` 10 (Blender's default) | {0.244}, {0.85} | {0.299}, {0.75} |",
        "| screen-space ray tracing | {0.185}, {0.97} | {0.216}, {0.96} |",
        "| ray tracing, `trace_max_roughness` 1 | {0.268}, {0.82} | {0.310}, {0.74} |",
        "| world `probe_resolution` 4096 (default 1024) | {0.186}, {0.97} | {0.217}, {0.95} |"))
      for number in table_row(BACKENDS, row, EEVEE_REPORT, sweep_keys(i))),
    # docs/backends.md 4.1: the MaterialX export through MaterialX's own OSL generator, in Cycles
    DocNumber("docs/backends.md", "| genosl as generated | {0.0332} | 0.1290", R + "mtlx_osl_agreement.json", "summary/all/mean_flip"),
    DocNumber("docs/backends.md", "| genosl as generated | 0.0332 | {0.1290} (type2_metal_1)", R + "mtlx_osl_agreement.json",
              "summary/all/worst_flip"),
    DocNumber("docs/backends.md", '`"multi_ggx"` | {0.0098} | 0.0114 |', R + "mtlx_osl_agreement.json", "summary/all/mean_flip_multi_ggx"),
    DocNumber("docs/backends.md", '`"multi_ggx"` | 0.0098 | {0.0114} |', R + "mtlx_osl_agreement.json", "summary/all/worst_flip_multi_ggx"),
    DocNumber("docs/backends.md", "two seeds) | {0.0098} | 0.0114 |", R + "mtlx_osl_agreement.json", "summary/all/mean_noise_floor"),
    DocNumber("docs/backends.md", "two seeds) | 0.0098 | {0.0114} |", R + "mtlx_osl_agreement.json", "max:cases/*/noise_floor"),
    DocNumber(README, "| {71} CPU s per asset (849 before)", R + "farm_cost.json",
              "cost_model/after/cpu_seconds_per_asset"),
    DocNumber(README, "CPU s per asset ({849} before), the fit", R + "farm_cost.json",
              "cost_model/before/cpu_seconds_per_asset"),
    DocNumber(README, "unchanged: {197} CPU-hours per 10 000", R + "farm_cost.json",
              "cost_model/after/cpu_hours_per_10000_assets"),
    DocNumber(README, "10 000 assets ({2360} before)", R + "farm_cost.json",
              "cost_model/before/cpu_hours_per_10000_assets"),
    DocNumber("docs/batch.md", "| WaterBottle | after | 1 | 1 | 0 | {23} | 34 |", R + "farm_cost.json",
              "before_after/0/after/fit"),
    DocNumber("docs/batch.md", "| wooden table (scan) | before | 1 | 0 | 0 | {1499} | 33 |", R + "farm_cost.json",
              "before_after/1/before/fit"),
    DocNumber("docs/batch.md", "| wooden table (scan) | after | 1 | 0 | 0 | {26} | 37 |", R + "farm_cost.json",
              "before_after/1/after/fit"),
    DocNumber("docs/addon.md", "after merging) takes {19.1} s, its error readout", R + "addon_fit_1k.json",
              "assets/wooden_table_02_1k/records/3/seconds"),
    DocNumber("docs/batch.md", "**{12} spp, threshold 0.01**", R + "render_speed.json", "default/samples"),
    DocNumber("docs/batch.md", "**{1544} assets/hour**", R + "render_speed.json", "throughput/ours_assets_per_hour"),
    DocNumber("docs/lobes.md", "falls from 0.071 (fits) to {0.015}", R + "sheen_calibration.json",
              "mean_abs_log_error_after"),
    DocNumber("docs/renderer.md", "Type 0 material (two lobes) runs at {6.0} M evaluations/s", R + "brdf_speed.json",
              "evals_per_second_median/type 0/131072", 1e-6),
    DocNumber("docs/renderer.md", "Type 5 (six lobes) at {1.7} M", R + "brdf_speed.json",
              "evals_per_second_median/type 5/131072", 1e-6),
    DocNumber("docs/batch.md", "| CPU s (4 frames) | {0.91} |", R + "intrinsics_samples.json", "samples/1/cpu_s"),
    DocNumber("docs/batch.md", "| 0.91 | 1.20 | {1.49} | 1.85", R + "intrinsics_samples.json", "samples/4/cpu_s"),
    DocNumber("docs/batch.md", "| 1.49 | 1.85 | {2.31} | | |", R + "intrinsics_samples.json", "samples/8/cpu_s"),
    DocNumber("docs/batch.md", "| Normal | 10.4 (16 %) | 12.2 (55 %) | {7.5} (33 %)", R + "intrinsics_samples.json",
              "samples/4/layers/Normal/mae", 1000),
    DocNumber("docs/batch.md", "5.8 (26 %) | {4.2} (18 %) | 1.1 (9 %)", R + "intrinsics_samples.json",
              "samples/8/layers/Normal/mae", 1000),
    DocNumber("docs/batch.md", "4.2 (18 %) | {1.1} (9 %) | 4.5", R + "intrinsics_samples.json",
              "floor/Normal/mae", 1000),
    DocNumber("docs/batch.md", "| basecolor | 4.7 (11 %) | 4.4 (11 %) | {2.7} (9 %)", R + "intrinsics_samples.json",
              "samples/4/layers/basecolor/mae", 1000),
    DocNumber("docs/batch.md", "2.1 (9 %) | {1.6} (8 %) | 0.4", R + "intrinsics_samples.json",
              "samples/8/layers/basecolor/mae", 1000),
    DocNumber("docs/batch.md", "| latent_a | 13.7 (88 %) | 11.8 (83 %) | 7.4 ({68} %)", R + "intrinsics_samples.json",
              "samples/4/layers/latent_a/differ", 100),
    DocNumber("docs/batch.md", "5.8 (58 %) | 4.4 ({45} %) | 1.1", R + "intrinsics_samples.json",
              "samples/8/layers/latent_a/differ", 100),
    DocNumber("docs/batch.md", "rule, the fewest samples whose every layer's mean error and share are at most the "
              "default's plus the floor, keeps **{8}**", R + "intrinsics_samples.json", "chosen"),
)
