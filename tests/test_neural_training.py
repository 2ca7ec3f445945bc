"""Training data and the training loop on tiny settings."""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
import torch
from safetensors.torch import load_file

from richmat_addon.core.schema import CHANNEL_SLICES, bounds
from torch_models.cli import main
from torch_models.neural.data import make_batch, parameter_vectors

TINY = {"seed": 0, "pool": 120, "buffer_batches": 2, "refresh_every": 2, "batch": 1024, "steps": 100,
        "sampler_steps": 10, "checkpoint_every": 20, "lr": 0.01, "threads": 1}


def test_parameter_vectors_follow_the_rules_and_bounds() -> None:
    v = parameter_vectors(200, np.random.default_rng(0))
    lo, hi = np.array(bounds()[0]), np.array(bounds()[1])
    assert v.shape == (200, 22) and ((v >= lo - 1e-6) & (v <= hi + 1e-6)).all()
    dust = v[:, CHANNEL_SLICES["dust_weight"]].ravel()
    inner = v[:, CHANNEL_SLICES["inner_weight"]].ravel()
    assert 0.2 < (dust > 0).mean() < 0.8 and 0.1 < (inner > 0).mean() < 0.6  # themed, not all uniform
    assert np.array_equal(v, parameter_vectors(200, np.random.default_rng(0)))  # seeded


def test_batches_are_finite_and_see_the_highlights() -> None:
    pool = torch.from_numpy(parameter_vectors(50, np.random.default_rng(1)))
    b = make_batch(pool, 4096, torch.Generator().manual_seed(0))
    assert torch.isfinite(b.f).all() and (b.f >= 0).all()
    assert ((b.t >= 0) & (b.t <= 1)).all() and ((b.r >= 0) & (b.r <= 1.0001)).all()
    assert b.f.max() > 10  # importance-sampled wo reach narrow peaks


def test_training_reduces_the_loss_and_resumes(tmp_path: Path) -> None:
    cfg = tmp_path / "tiny.json"
    cfg.write_text(json.dumps(TINY))
    out = tmp_path / "run"
    assert main(["train-decoder", "--config", str(cfg), "--out", str(out)]) == 0
    history = json.loads((out / "state.json").read_text())["config"]["history"]
    decoder = [h["loss"] for h in history if h["phase"] == "decoder"]
    assert decoder[-1] < 0.8 * decoder[0]
    assert (out / "training_curve.png").stat().st_size > 0
    weights = load_file(str(out / "weights.safetensors"))
    assert any(k.startswith("decoder.") for k in weights) and any(k.startswith("sampler.") for k in weights)
    # A second start refuses to overwrite; --resume continues to a longer schedule.
    assert main(["train-decoder", "--config", str(cfg), "--out", str(out)]) == 2
    cfg.write_text(json.dumps(dict(TINY, steps=120)))
    assert main(["train-decoder", "--config", str(cfg), "--out", str(out), "--resume"]) == 0
    assert json.loads((out / "state.json").read_text())["step"] == 130


def constant_decoder(width: int, depth: int, albedo: float):  # type: ignore[no-untyped-def]
    """A decoder whose f*cos is the constant albedo / (2 pi) (a hemisphere of it integrates
    to ``albedo``) and whose T is ~0, whatever the latent."""
    from torch_models.neural.mlp.networks import Decoder

    dec = Decoder(width, depth)
    with torch.no_grad():
        for p in dec.parameters():
            p.zero_()
        dec.net[-1].bias[:] = torch.tensor([float(np.log1p(albedo / (2 * np.pi)))] * 3 + [-20.0, 0.0])
    return dec


def test_energy_penalty_measures_albedo_above_one() -> None:
    from torch_models.neural.mlp.training import energy_penalty

    gen = torch.Generator().manual_seed(0)
    z = torch.zeros(8, 6)
    for albedo, expected in ((0.5, 0.0), (1.5, 3 * 0.5)):
        got = float(energy_penalty(constant_decoder(8, 1, albedo), z, 50_000, gen))
        assert abs(got - expected) < 0.05, (albedo, got)


def test_energy_phase_removes_energy_gain(tmp_path: Path) -> None:
    from torch_models.neural.mlp.config import MlpConfig
    from torch_models.neural.train import Trainer
    from torch_models.neural.mlp.training import energy_penalty

    cfg = MlpConfig(**dict(TINY, width=16, depth=2, steps=0, energy_steps=80, energy_latents=64,
                             energy_samples=64, sampler_steps=0, checkpoint_every=100, lr_final=2e-3))
    trainer = Trainer(cfg, tmp_path / "run")
    trainer.decoder.load_state_dict(constant_decoder(16, 2, 1.6).state_dict())
    z = torch.rand(256, 6, generator=torch.Generator().manual_seed(0)) * 2 - 1
    gen = torch.Generator().manual_seed(1)
    before = float(energy_penalty(trainer.decoder, z, 256, gen))
    trainer.run()
    after = float(energy_penalty(trainer.decoder, z, 256, gen))
    assert before > 1.0 and after < 0.2 * before


def test_albedo_loss_vanishes_for_the_analytic_model_and_sees_a_wrong_albedo() -> None:
    """The importance-sampled albedo of the analytic lobes themselves matches R(wi): the pdf,
    the samples and the target agree; a decoder with the wrong energy scores far worse."""
    from torch_models.brdf.model import LayeredBsdf, params_from_vectors
    from torch_models.neural.loss import albedo_loss

    vectors = torch.from_numpy(parameter_vectors(24, np.random.default_rng(4)))
    n = 2048

    def analytic(z: torch.Tensor, wi: torch.Tensor, wo: torch.Tensor):  # type: ignore[no-untyped-def]
        bsdf = LayeredBsdf(params_from_vectors(vectors.repeat_interleave(n, 0)), torch.ones(1, 3))
        return bsdf.eval_neural_part(wi, wo), None, None

    z = torch.zeros(len(vectors), 6)
    exact = float(albedo_loss(analytic, z, vectors, n, torch.Generator().manual_seed(0)))
    wrong = float(albedo_loss(constant_decoder(8, 1, 1.5), z, vectors, n, torch.Generator().manual_seed(0)))
    assert exact < 0.01 and wrong > 20 * exact, (exact, wrong)


def test_fine_tune_from_a_run_keeps_its_encoder(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    base = tmp_path / "base.json"
    base.write_text(json.dumps(dict(TINY, steps=20, sampler_steps=0)))
    tune = tmp_path / "tune.json"
    tune.write_text(json.dumps(dict(TINY, steps=10, sampler_steps=0, init="base", freeze_encoder=True,
                                    albedo_weight=0.1, albedo_materials=8, albedo_samples=16)))
    # before its init run exists, the fine-tune stops at once with a line naming that run
    assert main(["train-decoder", "--config", str(tune), "--out", str(tmp_path / "tune")]) == 2
    assert f"init run {(tmp_path / 'base').resolve()} holds no weights.safetensors" in capsys.readouterr().err
    assert main(["train-decoder", "--config", str(base), "--out", str(tmp_path / "base")]) == 0
    assert main(["train-decoder", "--config", str(tune), "--out", str(tmp_path / "tune")]) == 0
    before, after = (load_file(str(tmp_path / run / "weights.safetensors")) for run in ("base", "tune"))
    assert all(torch.equal(before[k], after[k]) for k in before if k.startswith("encoder."))
    assert any(not torch.equal(before[k], after[k]) for k in before if k.startswith("decoder."))


def test_new_decoder_against_a_runs_frozen_encoder(tmp_path: Path) -> None:
    """init_networks ["encoder"]: the latent space comes from the run, the decoder (here of
    another width) starts fresh and loads back as trained."""
    from torch_models.neural.trained import load

    base = tmp_path / "base.json"
    base.write_text(json.dumps(dict(TINY, steps=20, sampler_steps=0)))
    assert main(["train-decoder", "--config", str(base), "--out", str(tmp_path / "base")]) == 0
    new = tmp_path / "new.json"
    new.write_text(json.dumps(dict(TINY, steps=10, sampler_steps=0, init="base", init_networks=["encoder"],
                                   freeze_encoder=True, width=32)))
    assert main(["train-decoder", "--config", str(new), "--out", str(tmp_path / "new")]) == 0
    before, after = (load_file(str(tmp_path / run / "weights.safetensors")) for run in ("base", "new"))
    assert all(torch.equal(before[k], after[k]) for k in before if k.startswith("encoder."))
    assert before["decoder.net.0.weight"].shape[0] == 64 and after["decoder.net.0.weight"].shape[0] == 32
    assert load(tmp_path / "new").decoder.width == 32 and load(tmp_path / "base").decoder.width == 64


def test_every_committed_config_loads_and_starts_inside_the_repository() -> None:
    """A misspelt key in a committed config fails here, not an hour into a run;
    a fine-tune's ``init`` names a run folder inside the checkout, never outside it.
    The shipped decoder's recipe and the MLP baseline's (its base run, then the fine-tune) are committed."""
    from torch_models.cli_train_decoder import CONFIGS
    from torch_models.neural.kinds import load_config

    repo = CONFIGS.parents[2]
    paths = sorted(CONFIGS.glob("*.json"))
    assert {"decoder_hybrid_sheen.json", "decoder_cpu.json", "decoder_relative.json"} <= {p.name for p in paths}
    for path in paths:
        cfg = load_config(path)
        assert cfg.steps > 0, path.name
        if cfg.init:
            assert Path(cfg.init).is_relative_to(repo), (path.name, cfg.init)


def test_angular_floor_raises_the_ggx_alphas_alone_and_the_trainer_draws_floored() -> None:
    """Only the four GGX alphas move, and only those below the floor; a trainer with a floor
    trains on floored vectors (targets and encoder inputs alike) of the pool its seed draws."""
    from torch_models.neural.data import GGX_ALPHAS, angular_floor
    from torch_models.neural.mlp.config import MlpConfig
    from torch_models.neural.train import Trainer

    v = parameter_vectors(TINY["pool"], np.random.default_rng(TINY["seed"]))
    floored = angular_floor(v, 0.01).numpy()
    alphas = np.concatenate([np.arange(22)[CHANNEL_SLICES[n]] for n in GGX_ALPHAS])
    others = np.setdiff1d(np.arange(22), alphas)
    assert np.array_equal(floored[:, others], v[:, others])
    assert (floored[:, alphas] >= 0.01).all() and (v[:, alphas] < 0.01).any()
    above = v[:, alphas] >= 0.01
    assert np.array_equal(floored[:, alphas][above], v[:, alphas][above])
    assert np.array_equal(angular_floor(v, 0.0).numpy(), v)
    trainer = Trainer(MlpConfig(**dict(TINY, alpha_floor=0.01)), Path("unused"))
    assert torch.equal(trainer.pool, torch.from_numpy(floored))
    assert all((b.vectors[:, alphas] >= 0.01).all() for b in trainer.buffer)


def test_relative_term_sees_a_broad_lobe_half_wrong() -> None:
    """A decoder at half a broad lobe's value (f cos 0.05 against 0.1): log(1 + f cos) calls that
    an error of 0.046, the relative term ln 2 minus what RELATIVE_EPS takes off; without its
    weight the loss is the plain one, and an exact decoder scores zero in the term."""
    from torch_models.neural.data import Batch
    from torch_models.neural.loss import RELATIVE_EPS, decoder_loss

    n = 256
    wi = torch.tensor([[0.0, 0.0, 1.0]]).expand(n, 3)
    batch = Batch(torch.zeros(n, dtype=torch.long), torch.zeros(n, 22), wi, wi,
                  torch.full((n, 3), 0.1), torch.zeros(n, 1), torch.full((n, 1), 0.5))
    half = constant_decoder(8, 1, 0.05 * 2 * np.pi)
    exact = constant_decoder(8, 1, 0.1 * 2 * np.pi)
    z = torch.zeros(n, 6)
    plain = float(decoder_loss(half, z, batch))
    with_term = float(decoder_loss(half, z, batch, relative_weight=1.0))
    expected = 0.95 * np.log((RELATIVE_EPS + 0.1) / (RELATIVE_EPS + 0.05))
    assert abs(plain - 0.95 * np.log(1.1 / 1.05)) < 1e-4, plain  # T and R exact (0 and 0.5)
    assert abs(with_term - plain - expected) < 1e-3, (with_term, plain)
    assert abs(float(decoder_loss(exact, z, batch, relative_weight=1.0)) - float(decoder_loss(exact, z, batch))) < 1e-5


def test_a_batch_with_a_non_finite_gradient_is_skipped_not_applied(tmp_path: Path) -> None:
    """One NaN gradient would turn every weight NaN (a hybrid from scratch hit one at step 4595):
    the step is skipped, counted, and the weights stay as they were."""
    from torch_models.neural.mlp.config import MlpConfig
    from torch_models.neural.train import Trainer

    cfg = MlpConfig(**dict(TINY, width=16, depth=2, steps=3, sampler_steps=0))
    trainer = Trainer(cfg, tmp_path / "run")
    before = [p.detach().clone() for p in trainer.decoder.parameters()]
    objective = trainer.objective.forward
    trainer.objective.forward = lambda *a, **k: objective(*a, **k) * torch.tensor(float("nan"))
    assert math.isnan(trainer.decoder_step()) and trainer.skipped == 1
    assert all(torch.equal(b, p) for b, p in zip(before, trainer.decoder.parameters()))
    trainer.objective.forward = objective
    assert math.isfinite(trainer.decoder_step())
    assert not all(torch.equal(b, p) for b, p in zip(before, trainer.decoder.parameters()))


@pytest.mark.skipif(not torch.cuda.is_available(), reason="no CUDA device")
def test_a_training_step_on_cuda_matches_the_cpu(tmp_path: Path) -> None:
    """A GPU run draws its data from the same CPU generator and computes the albedo term on the
    GPU: the first step's loss (same weights, same samples) agrees with the CPU's."""
    from torch_models.neural.kinds import load_config
    from torch_models.neural.train import Trainer

    hybrid = {k: v for k, v in TINY.items() if k != "sampler_steps"}  # the MLP's phase
    hybrid.update(kind="hybrid", sheen=True, unit_lobes=True, view_gates=True, albedo_weight=0.1,
                  albedo_materials=16, albedo_samples=32)
    losses = []
    for device in ("cpu", "cuda"):
        path = tmp_path / f"{device}.json"
        path.write_text(json.dumps(dict(hybrid, device=device)))
        losses.append(Trainer(load_config(path), tmp_path / device).decoder_step())
    assert math.isfinite(losses[0]) and losses[1] == pytest.approx(losses[0], rel=1e-3)
