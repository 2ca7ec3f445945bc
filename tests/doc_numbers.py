"""The numbers the README and the design notes quote from reports, each with the key it comes from.

One row per quoted number: the document, the quoted words with the number in braces
(whitespace is compared collapsed, so a quote may run over a line break), the JSON file it
comes from and the key path inside it, and a scale from the report's units to the quoted
ones. The rounding is the quote's own: the value, scaled, printed with as many decimals as
the quote shows must equal it (thousands may be grouped by a space or a comma).

A key path names keys and list positions (negative from the end) separated by "/", "*" for
every item at that level. Before it, "min:", "max:" or "mean:" reduce what the "*" found,
"len:" counts the items of the list or mapping it names, and "sqrt:" takes a square root
(a texture's side from its texel count).

Numbers measured once by hand have no report: their row has ``report=None``, their quote
must say "by hand", and only its presence in the document is checked.
"""
from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class DocNumber:
    doc: str
    quote: str
    report: str | None
    key: str = ""
    scale: float = 1.0


R = "docs/reports/"
README = "README.md"
GENERATOR = "docs/generator.md"
NEURAL = "docs/neural-material.md"
GEN_STATE = "torch_models/generator/weights/state.json"
GUIDANCE_PER_TYPE = "summary/4"  # generate_guidance.json's summary rows: 1, 1.5, 2, 2.5, per type
GUIDANCE_2 = "summary/2"
MIN = 1 / 60

ROWS: tuple[DocNumber, ...] = (
    # README: headline numbers
    DocNumber(README, "worst FLIP {0.013} (target 0.03)", R + "agreement.json", "worst_flip"),
    DocNumber(README, "worst FLIP 0.013 (target {0.03})", R + "agreement.json", "target"),
    DocNumber(README, "mean FLIP {0.0025}, worst 0.0070", R + "native_agreement.json", "summary/all/mean_flip"),
    DocNumber(README, "mean FLIP 0.0025, worst {0.0070}", R + "native_agreement.json", "summary/all/worst_flip"),
    DocNumber(README, "(targets {0.03} / 0.06)", R + "native_agreement.json", "target_mean"),
    DocNumber(README, "(targets 0.03 / {0.06})", R + "native_agreement.json", "target_worst"),
    DocNumber(README, "medians {0.033}-0.047", R + "fit_flip.json", "min:decoders/0/summary/*/median"),
    DocNumber(README, "medians 0.033-{0.047}", R + "fit_flip.json", "max:decoders/0/summary/*/median"),
    DocNumber(README, "the paper's MLP: {0.064}-0.092", R + "fit_flip.json", "min:decoders/0/summary/*/paper/1"),
    DocNumber(README, "the paper's MLP: 0.064-{0.092}", R + "fit_flip.json", "max:decoders/0/summary/*/paper/1"),
    DocNumber(README, "ours, `4f9dd150`: {0.044}-0.075", R + "fit_flip.json", "min:decoders/1/summary/*/median"),
    DocNumber(README, "ours, `4f9dd150`: 0.044-{0.075}", R + "fit_flip.json", "max:decoders/1/summary/*/median"),
    DocNumber(README, "worst {0.058}-0.178, every case", R + "fit_flip.json", "min:decoders/0/summary/*/worst"),
    DocNumber(README, "worst 0.058-{0.178}, every case", R + "fit_flip.json", "max:decoders/0/summary/*/worst"),
    DocNumber(README, "mean FLIP {0.0217} (target 0.05)", R + "preview_agreement.json", "runs/0/mean_flip"),
    DocNumber(README, "mean FLIP 0.0217 (target {0.05})", R + "preview_agreement.json", "target"),
    DocNumber(README, "{19.5} M texels fitted", R + "dedupe.json", "total_texels", 1e-6),
    DocNumber(README, "fitted as {0.89} M vectors", R + "dedupe.json", "total_representatives", 1e-6),
    DocNumber(README, "({22}x fewer evaluations", R + "dedupe.json", "evaluation_ratio"),
    DocNumber(README, "FLIP {0.092} against 0.089 fitting", R + "dedupe.json", "mean:equal_flip_crops/*/deduplicated/flip"),
    DocNumber(README, "FLIP 0.092 against {0.089} fitting", R + "dedupe.json", "mean:equal_flip_crops/*/per_texel/flip"),
    DocNumber(README, "a 1k x 1k material fits in {22} s", R + "fit_full_size.json", "materials/0/total_seconds"),
    DocNumber(README, "`4f9dd150`: {2745} s, nearly all its furnace", R + "fit_full_size.json",
              "materials/1/total_seconds"),
    DocNumber(README, "timed on {512} of the material's", R + "fit_full_size.json", "materials/1/furnace/checked"),
    DocNumber(README, "{26 448} distinct vectors", R + "fit_full_size.json", "materials/1/unique_vectors"),
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
    DocNumber(README, "generations differ {0.90}x as much", R + "generate_prompts_real.json", "ratio"),
    DocNumber(README, "as much as their references (target {0.7})", R + "generate_prompts_real.json", "target"),
    DocNumber(README, "real: {36.3} against 34.9 dB", R + "generate_guidance.json", GUIDANCE_PER_TYPE + "/real/psnr"),
    DocNumber(README, "real: 36.3 against {34.9} dB", R + "generate_guidance.json", GUIDANCE_2 + "/real/psnr"),
    DocNumber(README, "(worst asset {30.7} against 29.2)", R + "generate_guidance.json",
              GUIDANCE_PER_TYPE + "/real/min_psnr"),
    DocNumber(README, "(worst asset 30.7 against {29.2})", R + "generate_guidance.json", GUIDANCE_2 + "/real/min_psnr"),
    DocNumber(README, "in sample: {41.3} against 40.3 dB", R + "generate_guidance.json",
              GUIDANCE_PER_TYPE + "/procedural/psnr"),
    DocNumber(README, "in sample: 41.3 against {40.3} dB", R + "generate_guidance.json",
              GUIDANCE_2 + "/procedural/psnr"),
    DocNumber(README, "| {40.9} dB (rule-based prior 38.0", R + "generate_eval.json", "overall/generated/psnr"),
    DocNumber(README, "(rule-based prior {38.0}, plain PBR 34.5, retrieval 37.1)", R + "generate_eval.json",
              "overall/procedural/psnr"),
    DocNumber(README, "(rule-based prior 38.0, plain PBR {34.5}, retrieval 37.1)", R + "generate_eval.json",
              "overall/pbr/psnr"),
    DocNumber(README, "(rule-based prior 38.0, plain PBR 34.5, retrieval {37.1})", R + "generate_eval.json",
              "overall/retrieval/psnr"),
    DocNumber(README, "| {66}-100 % of latent texels seen", R + "generate_coverage.json", "min:assets/*/chosen/seen",
              100),
    DocNumber(README, "| 66-{100} % of latent texels seen", R + "generate_coverage.json", "max:assets/*/chosen/seen",
              100),
    DocNumber(README, "| {277} CPU s per asset after OIDN's fast prefilter", R + "farm_cost.json",
              "cost_model/after/cpu_seconds_per_asset"),
    DocNumber(README, "({346} before; the beauty pass", R + "farm_cost.json", "cost_model/before/cpu_seconds_per_asset"),
    DocNumber(README, "at FLIP +{0.0002}): 770 CPU-hours", R + "beauty_denoise.json", "flip_added_by_fast"),
    DocNumber(README, "{770} CPU-hours per 10 000 assets", R + "farm_cost.json",
              "cost_model/after/cpu_hours_per_10000_assets"),
    DocNumber(README, "all {10} checks pass", R + "slurm_e2e.json", "len:checks"),
    DocNumber(README, "{415} files compared, identical", R + "batch_restart.json", "comparison/files_compared"),
    DocNumber(README, "(images at {128} texels, 100 fit steps", R + "addon_assets.json", "settings/texture_size"),
    DocNumber(README, "(images at 128 texels, {100} fit steps", R + "addon_assets.json", "settings/fit_steps"),
    DocNumber(README, "Cycles {320} px, 32 samples", R + "addon_assets.json", "settings/render_size"),
    DocNumber(README, "Cycles 320 px, {32} samples", R + "addon_assets.json", "settings/render_samples"),
    DocNumber(README, "`make demo` (1 min 22 s on a fresh clone with 2 cores after `make test`, measured by hand",
              None),

    # docs/generator.md
    DocNumber(GENERATOR, "trained in {54} minutes on the two cores", GEN_STATE, "history/-1/seconds", MIN),
    DocNumber(GENERATOR, "in {54} minutes on two threads", GEN_STATE, "history/-1/seconds", MIN),
    DocNumber(GENERATOR, "sha256 `3b7998e4`: {6000} steps of batch 8", GEN_STATE, "step"),
    DocNumber(GENERATOR, "3.8 minutes on one core beside the procedural corpus, timed by hand", None),
    DocNumber(GENERATOR, "(about 3 steps/s alone on the machine, timed by hand)", None),
    DocNumber(GENERATOR, "took 3.5 minutes by hand", None),
    DocNumber(GENERATOR, "fell from {1.04} at step 100", GEN_STATE, "history/0/loss"),
    DocNumber(GENERATOR, "to {-0.35} at step 3100", GEN_STATE, "history/30/loss"),
    DocNumber(GENERATOR, "and {-0.61} at the last", GEN_STATE, "history/-1/loss"),
    DocNumber(GENERATOR, "| **generated** | **{40.9} / 41.4 dB**", R + "generate_eval.json", "overall/generated/psnr"),
    DocNumber(GENERATOR, "| **generated** | **40.9 / {41.4} dB**", R + "generate_eval_seed1.json",
              "overall/generated/psnr"),
    DocNumber(GENERATOR, "**{0.0346} / 0.0296**", R + "generate_eval.json", "overall/generated/flip"),
    DocNumber(GENERATOR, "**0.0346 / {0.0296}**", R + "generate_eval_seed1.json", "overall/generated/flip"),
    DocNumber(GENERATOR, "| procedural | {38.0} | 0.0412 |", R + "generate_eval.json", "overall/procedural/psnr"),
    DocNumber(GENERATOR, "| retrieval | 37.1 | {0.0489} |", R + "generate_eval.json", "overall/retrieval/flip"),
    DocNumber(GENERATOR, "| **mean** | | | **{36.7} / 36.0 dB** |", R + "generate_eval_real.json",
              "overall/generated/psnr"),
    DocNumber(GENERATOR, "| **mean** | | | **36.7 / {36.0} dB** |", R + "generate_eval_real_seed1.json",
              "overall/generated/psnr"),
    DocNumber(GENERATOR, "| 30.4 | 33.6 | 26.5 | {11.6} (median) |", R + "generate_eval_real.json",
              "median_cpu_seconds_per_object"),
    DocNumber(GENERATOR, "Mean FLIP: generated {0.030} / 0.031", R + "generate_eval_real.json",
              "overall/generated/flip"),
    DocNumber(GENERATOR, "(worst {31.1} and 30.7, WaterBottle)", R + "generate_eval_real.json",
              "min:objects/*/generated/psnr"),
    DocNumber(GENERATOR, "**met** ({85}-99 %)", R + "generate_eval_real.json", "min_seen_share", 100),
    DocNumber(GENERATOR, "11.6 / {12.4} CPU s per object", R + "generate_eval_real_seed1.json",
              "median_cpu_seconds_per_object"),
    DocNumber(GENERATOR, "**{0.90} overall** (target", R + "generate_prompts_real.json", "ratio"),
    DocNumber(GENERATOR, "per pair of types {0.76} (haze against dust", R + "generate_prompts_real.json",
              "per_pair/0-1/ratio"),
    DocNumber(GENERATOR, "and {1.00} (dust, scattering)", R + "generate_prompts_real.json", "per_pair/1-4/ratio"),
    DocNumber(GENERATOR, "a median {38.1} dB against its own reference", R + "generate_prompts_real.json",
              "median_psnr"),
    DocNumber(GENERATOR, "| FlightHelmet | 6 | {58} % | **66 %** |", R + "generate_coverage.json",
              "assets/4/orbit/seen", 100),
    DocNumber(GENERATOR, "Choosing the views costs {0.20}-0.75 s", R + "generate_coverage.json",
              "min:assets/*/chosen/seconds/view_choice"),
    DocNumber(GENERATOR, "Choosing the views costs 0.20-{0.75} s", R + "generate_coverage.json",
              "max:assets/*/chosen/seconds/view_choice"),
    DocNumber(GENERATOR, "the projection ({0.30}-0.72 s)", R + "generate_coverage.json",
              "min:assets/*/chosen/seconds/projection"),
    DocNumber(GENERATOR, "the projection (0.30-{0.72} s)", R + "generate_coverage.json",
              "max:assets/*/chosen/seconds/projection"),
    DocNumber(GENERATOR, "| **18** | **12** | **{37.1}** |", R + "generate_speed.json", "rows/6/psnr"),
    DocNumber(GENERATOR, "| 2 | 8 | {14.5} | 0.8 |", R + "generate_speed.json", "rows/0/psnr"),
    DocNumber(GENERATOR, "| **per type (shipped)** | **{41.3} / 31.0** |", R + "generate_guidance.json",
              GUIDANCE_PER_TYPE + "/procedural/psnr"),
    DocNumber(GENERATOR, "| **{36.3} / 30.7** | **0.90** |", R + "generate_guidance.json",
              GUIDANCE_PER_TYPE + "/real/psnr"),
    DocNumber(GENERATOR, "| 2 (the old default) | 40.3 / 30.3 | 34.9 / 29.2 | {1.01} |", R + "generate_guidance.json",
              GUIDANCE_2 + "/prompt_sensitivity/ratio"),
    DocNumber(GENERATOR, "from guidance 1 to 2 ({42.6} to 37.6 dB)", R + "generate_guidance.json",
              "per_type_psnr/4/0"),
    DocNumber(GENERATOR, "from guidance 1 to 2 (42.6 to {37.6} dB)", R + "generate_guidance.json",
              "per_type_psnr/4/2"),

    # docs/neural-material.md
    DocNumber(NEURAL, "| 0 haze | **{0.035}** / **0.147** |", R + "fit_flip.json", "decoders/0/summary/0/median"),
    DocNumber(NEURAL, "| 0 haze | **0.035** / **{0.147}** |", R + "fit_flip.json", "decoders/0/summary/0/worst"),
    DocNumber(NEURAL, "| 3 dust + coat | **{0.047}** / **0.128** | 0.075", R + "fit_flip.json",
              "decoders/0/summary/3/median"),
    DocNumber(NEURAL, "| 3 dust + coat | **0.047** / **0.128** | {0.075} / 0.189", R + "fit_flip.json",
              "decoders/1/summary/3/median"),
    DocNumber(NEURAL, "| energy check | {300} pass as fitted (bounded)", R + "fit_flip.json",
              "decoders/0/furnace/passed_as_fitted"),
    DocNumber(NEURAL, "| {140} as fitted, 141 after the refit, 19 scaled", R + "fit_flip.json",
              "decoders/1/furnace/passed_as_fitted"),
    DocNumber(NEURAL, "| 140 as fitted, 141 after the refit, {19} scaled", R + "fit_flip.json",
              "decoders/1/furnace/repaired_by_scaling"),
    DocNumber(NEURAL, "the shipped hybrid takes {22.1} s in all", R + "fit_full_size.json",
              "materials/0/total_seconds"),
    DocNumber(NEURAL, "(read 7.4 s, fit {14.7} s, energy check", R + "fit_full_size.json", "materials/0/fit_seconds"),
    DocNumber(NEURAL, "the MLP {2745} s, of which", R + "fit_full_size.json", "materials/1/total_seconds"),
    DocNumber(NEURAL, "its furnace is {2728} s", R + "fit_full_size.json", "materials/1/energy_seconds"),
    DocNumber(NEURAL, "(extrapolated from {512} of the vectors)", R + "fit_full_size.json",
              "materials/1/furnace/checked"),

    # the other design notes
    DocNumber("docs/addon.md", "| **{0.0217}** |", R + "preview_agreement.json", "runs/0/mean_flip"),
    DocNumber("docs/addon.md", "| 0.1 s | 0.1 s | 0.1 s | 10 s | 0.1 s | 0.1 s | {0.156} | 1.1 min |",
              R + "addon_assets.json", "assets/WaterBottle/preview_flip_vs_bake"),
    DocNumber("docs/addon.md", "| 0.1 s | 0.2 s | 0.1 s | {34} s | 0.3 s", R + "addon_assets.json",
              "assets/CesiumMilkTruck/records/3/seconds"),
    DocNumber("docs/addon.md", "| 0.6 s | {0.181} | 2.4 min |", R + "addon_assets.json",
              "assets/FlightHelmet/preview_flip_vs_bake"),
    DocNumber("docs/addon.md", "**0.56 s of CPU** (measured once by hand)", None),
    DocNumber("docs/backends.md", "| Type 5 | 2 | {0.0059} | 0.0070 |", R + "native_agreement.json",
              "summary/type5/mean_flip"),
    DocNumber("docs/backends.md", "| Type 5 | 2 | 0.0059 | {0.0070} |", R + "native_agreement.json",
              "summary/type5/worst_flip"),
    DocNumber("docs/backends.md", "| Type 2 | 2 | 0.0052 | 0.0059 | {8.02} | 7.78 |", R + "native_agreement.json",
              "summary/type2/osl_frame_cpu_s"),
    DocNumber("docs/batch.md", "WaterBottle (one {1024}² material)", R + "farm_cost.json",
              "sqrt:farm/1/materials/BottleMat/texels"),
    DocNumber("docs/batch.md", "two {2048}² textured", R + "farm_cost.json", "sqrt:farm/3/materials/truck/texels"),
    DocNumber("docs/batch.md", "(six {512}² materials)", R + "farm_cost.json",
              "sqrt:farm/5/materials/LensesMat/texels"),
    DocNumber("docs/lobes.md", "falls from {0.071} (fits) to 0.015", R + "sheen_calibration.json",
              "mean_abs_log_error_before"),
    DocNumber("docs/lobes.md", "falls from 0.071 (fits) to {0.015}", R + "sheen_calibration.json",
              "mean_abs_log_error_after"),
    DocNumber("docs/renderer.md", "Type 0 material (two lobes) runs at {6.0} M evaluations/s", R + "brdf_speed.json",
              "evals_per_second_median/type 0/131072", 1e-6),
    DocNumber("docs/renderer.md", "Type 5 (six lobes) at {1.7} M", R + "brdf_speed.json",
              "evals_per_second_median/type 5/131072", 1e-6),
    DocNumber("docs/renderer.md", "{3.4}x the cost of Type 0", R + "brdf_speed.json",
              "cost_relative_to_type0_at_largest_batch/type 5"),
)
