"""The hybrid decoder: energy bounded by construction, exact lobe sampling, chosen by its weights folder."""
from __future__ import annotations

import json
import math
from pathlib import Path

import pytest
import torch

from torch_models.brdf import tables
from torch_models.brdf.ggx import ggx_single_scatter
from torch_models.brdf.lobes import sheen_albedo, sheen_eval
from torch_models.cli import main
from torch_models.neural import energy, furnace, kinds, quadrature, trained
from torch_models.neural.data import cosine_hemisphere, view_directions
from torch_models.neural.hybrid.config import HybridConfig
from torch_models.neural.hybrid.kind import KIND, bound_furnace
from torch_models.neural.hybrid.networks import HybridDecoder, LobeSampler
from torch_models.neural.model import NeuralModel
from torch_models.neural.networks import Encoder, direction_features
from tests.chi2 import chi2_test, sidak_threshold
from tests.test_neural_training import TINY


def scrambled(seed: int, scale: float, unit_lobes: bool = False, sheen: bool = False) -> HybridDecoder:
    """A hybrid decoder with random weights ``scale`` times larger than the default init: extreme
    lobes (mirror-sharp and fully rough, F0 near 0 or 1, gates shut or open) a trained one may reach."""
    torch.manual_seed(seed)
    dec = KIND.build_decoder(HybridConfig(unit_lobes=unit_lobes, sheen=sheen))
    with torch.no_grad():
        for p in dec.parameters():
            p.mul_(scale)
    return dec.eval().requires_grad_(False)


class Model:
    """The parts of a ``NeuralModel`` the quadrature reads."""

    def __init__(self, decoder: HybridDecoder) -> None:
        self.decoder = decoder


@pytest.mark.parametrize("seed,scale,unit_lobes,sheen", [(0, 1.0, False, False), (1, 4.0, False, False),
                                                         (2, 12.0, False, False), (3, 4.0, True, False),
                                                         (4, 12.0, True, False), (5, 4.0, True, True),
                                                         (6, 12.0, True, True)])
def test_albedo_plus_transmission_never_exceeds_one(seed: int, scale: float, unit_lobes: bool, sheen: bool) -> None:
    """For random weights and random latents (inside the box and far outside it), the
    quadrature albedo of f_neu plus T stays at or below the decoder's own bound, itself <= 1.
    With unit lobes the GGX lobes are divided by the upper albedo table, whose read is never
    below the albedo, and the sheen is its LTC's density: the same bound holds."""
    dec = scrambled(seed, scale, unit_lobes, sheen)
    z = (torch.rand(96, 6, generator=torch.Generator().manual_seed(seed)) * 2 - 1) * torch.tensor([1.1] * 3 + [3.0] * 3)
    sums = quadrature.half_vector_albedo(Model(dec), z)
    albedo = sums.reflected + sums.diffuse[..., None]  # (K, A, 3)
    bounds = torch.stack([dec.albedo_bound(z, view_directions(torch.full((len(z), 1), mu)))
                          for mu in quadrature.VIEW_COSINES], 1)
    assert (bounds <= 1 + 1e-6).all()  # < 1 in exact arithmetic; a float32 softmax sums to 1 +- rounding
    # the quadrature resolves alpha ~ 1e-3 lobes to a few 1e-4 (quadrature.QUADRATURE_TOLERANCE is 2e-3)
    assert (albedo.amax(-1) <= bounds + 2e-3).all()
    assert albedo.amax() > 0.3  # the test sees real lobes, not a black decoder


def reference_lobes(dec: HybridDecoder, seed: int) -> tuple:
    """At 4096 random (latent, wi, wo): the decoder's (f, T, R), its head and gates, and its GGX and
    diffuse lobes evaluated one by one with ``ggx.ggx_single_scatter`` and Schlick's F."""
    n = 4096
    gen = torch.Generator().manual_seed(seed)
    z, wi, wo = torch.rand(n, 6, generator=gen) * 2 - 1, cosine_hemisphere(n, gen), cosine_hemisphere(n, gen)
    out = dec(z, wi, wo)
    lobes = dec.head_at(z, wi)
    k = dec.lobes
    gates = torch.sigmoid(dec.gates(torch.cat([z, direction_features(wi, wo)], -1))).reshape(n, k + 1 + dec.sheen, 3)
    expected = lobes.weights[:, k:k + 1] * gates[:, k] * lobes.diffuse * wo[:, 2:3] / math.pi
    for j in range(k):
        single, h = ggx_single_scatter(wi, wo, lobes.alpha[:, j:j + 1])
        f0 = lobes.f0[:, j]
        schlick = (1 - (wi * h).sum(-1, keepdim=True)) ** 5
        expected = expected + lobes.weights[:, j:j + 1] * gates[:, j] * (f0 + (1 - f0) * schlick) * single
    return out, lobes, gates, expected, wi, wo


def test_vectorised_lobes_match_cycles_ggx_per_lobe() -> None:
    """``lobe_sum`` evaluates all lobes at once; each must be ``ggx.ggx_single_scatter`` with Schlick F."""
    (f, t, r), lobes, _, expected, _, _ = reference_lobes(scrambled(3, 2.0), 0)
    assert torch.allclose(f, expected, rtol=1e-4, atol=1e-6)
    assert torch.equal(t[:, 0], lobes.weights[:, 4]) and ((r >= 0) & (r <= 1)).all()


def test_sheen_slot_is_cycles_sheen_over_its_albedo() -> None:
    """The sheen slot adds w_s g_s c_s times Cycles' sheen divided by its albedo (where Cycles keeps the
    closure: it drops it at roughness near 0, where the slot keeps the LTC, still a distribution), and
    moves T one slot on."""
    dec = scrambled(5, 3.0, sheen=True)
    (f, t, _), lobes, gates, expected, wi, wo = reference_lobes(dec, 1)
    albedo = sheen_albedo(wi[:, 2:3], lobes.sheen_roughness)
    kept = (albedo > 0)[:, 0]
    cycles = sheen_eval(wi, wo, lobes.sheen_roughness) / albedo.clamp(min=1e-9)
    sheen = lobes.weights[:, 4:5] * gates[:, 4] * lobes.sheen * cycles
    assert kept.sum() > 1000 and sheen.amax() > 0.02 and (lobes.sheen_roughness[kept].amin() < 0.3)
    assert torch.allclose(f[kept], (expected + sheen)[kept], rtol=1e-4, atol=1e-6)
    assert torch.equal(t[:, 0], lobes.weights[:, 5]) and dec.t_slot == 5 and scrambled(5, 3.0).t_slot == 4
    # the table the preview shader reads travels in the weights and is the one torch evaluates with
    assert torch.equal(dec.sheen_ltc, tables.table("sheen_ltc", torch.device("cpu"), torch.float32)[:2])


@pytest.mark.parametrize("cos_i,sheen", [(0.95, False), (0.5, False), (0.12, False), (0.5, True), (0.12, True)])
def test_lobe_sampler_matches_its_pdf(cos_i: float, sheen: bool) -> None:
    """Chi-square (Mitsuba-3 style) of the hybrid's exact lobe sampler at three view angles: a
    mixture of three GGX lobes of different widths, the diffuse lobe and, with a sheen, its LTC.
    The floor keeps every lobe wider than the test's cells (32 x 64 over the sphere) can integrate."""
    dec = scrambled(4, 3.0, sheen=sheen)
    dec.alpha_floor.fill_(0.1)
    sampler = LobeSampler(dec)
    z = torch.rand(1, 6, generator=torch.Generator().manual_seed(int(cos_i * 100))) * 2 - 1
    wi = view_directions(torch.tensor([[cos_i]]))
    alphas = dec.head_at(z, wi).alpha
    assert alphas.min() < 0.3  # a peaked lobe is part of what is tested
    gen = torch.Generator().manual_seed(7)

    def sample(n: int) -> torch.Tensor:
        wo = sampler.sample(z.expand(n, -1), wi.expand(n, -1), torch.rand(n, 3, generator=gen))
        return torch.where((wo[:, 2:3] > 0), wo, torch.full_like(wo, float("nan")))

    def pdf(wo: torch.Tensor) -> torch.Tensor:
        return sampler.pdf(z.expand(len(wo), -1), wi.expand(len(wo), -1), wo)

    result = chi2_test(sample, pdf, n_samples=200_000)
    assert result.passed(sidak_threshold(5)), result
    if sheen:  # the sheen is drawn often enough to matter
        p, _ = sampler.components(z, wi)
        assert p[0, -1] > 0.05


def train_tiny_hybrid(folder: Path, **options: object) -> Path:
    """A 40-step hybrid run in ``folder``: its weights folder."""
    cfg = folder / "tiny.json"
    mlp_only = ("sampler_steps",)
    cfg.write_text(json.dumps(dict({k: v for k, v in TINY.items() if k not in mlp_only}, kind="hybrid", steps=40, checkpoint_every=20, lobe_alpha_floor=[0.05, 0.002],
                                   **options)))
    assert main(["train-decoder", "--config", str(cfg), "--out", str(folder / "run")]) == 0
    return folder / "run"


@pytest.fixture(scope="module")
def tiny_hybrid(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return train_tiny_hybrid(tmp_path_factory.mktemp("tiny_hybrid"))


@pytest.fixture(scope="module")
def tiny_unit_hybrid(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A hybrid whose GGX lobes are divided by their albedo; the E table travels in its weights."""
    return train_tiny_hybrid(tmp_path_factory.mktemp("tiny_unit_hybrid"), unit_lobes=True)


def test_the_weights_folder_names_its_kind(tiny_hybrid: Path, tmp_path: Path) -> None:
    model = trained.load(tiny_hybrid)
    assert isinstance(model.decoder, HybridDecoder) and isinstance(model.sampler, LobeSampler)
    assert float(model.decoder.alpha_floor) == pytest.approx(0.002)  # the annealed floor's last value is kept
    assert trained.load().decoder.kind == "hybrid" and trained.load(trained.BASELINE).decoder.kind == "mlp"
    state = json.loads((tiny_hybrid / "state.json").read_text())
    assert state["config"]["kind"] == "hybrid" and state["step"] == 40  # no sampler phase to train
    bad = tmp_path / "bad"
    bad.mkdir()
    (bad / "weights.safetensors").write_bytes((tiny_hybrid / "weights.safetensors").read_bytes())
    (bad / "state.json").write_text(json.dumps({"step": 1, "config": dict(state["config"], kind="transformer")}))
    with pytest.raises(ValueError, match="unknown decoder kind 'transformer'"):
        trained.load(bad)
    assert tuple(kinds.KINDS) == ("mlp", "hybrid")


def test_each_kind_names_the_preview_shader_the_addon_picks_for_its_weights() -> None:
    """The add-on, without torch, picks a preview shader by the weights' tensor names; each kind's entry
    names its shader too, and for the shipped hybrid and the MLP baseline the two agree."""
    from richmat_addon.core.neural_osl import neural_osl_source
    from richmat_addon.core.neural_osl_parts import HEADER
    from richmat_addon.core.tensor_file import read_safetensors

    for folder, name in ((trained.SHIPPED, "hybrid"), (trained.BASELINE, "mlp")):
        tensors = read_safetensors(folder / "weights.safetensors")
        kind = kinds.of(trained.load(folder))
        assert kind.name == name and neural_osl_source(tensors) == HEADER + kind.osl.source(tensors)
    assert kinds.KINDS["hybrid"].osl is not kinds.KINDS["mlp"].osl


def test_a_bounded_decoder_skips_the_furnace_repair(tiny_hybrid: Path) -> None:
    """Fits and generated latents of the hybrid pass as they are: no refit, no energy scale."""
    model = trained.load(tiny_hybrid)
    z = torch.rand(64, 6, generator=torch.Generator().manual_seed(0)) * 2.2 - 1.1
    assert (energy.guard(model, z) == 1).all()
    fitted = energy.fit_bounded(model, torch.zeros(64, 22).numpy(), z)
    assert fitted.counts() == {"checked": 64, "passed_as_fitted": 64, "passed_after_refit": 0, "repaired_by_scaling": 0}
    measured = furnace.furnace(model, z)  # the real furnace agrees with the bound
    assert not measured.failing.any() and (measured.albedo <= fitted.check.albedo + 2e-3).all()


def test_unit_lobes_load_from_their_own_config_and_table(tiny_unit_hybrid: Path) -> None:
    model = trained.load(tiny_unit_hybrid)
    assert model.decoder.unit_lobes and model.decoder.ggx_e.shape == (32, 32) and model.decoder.bounded
    z = torch.rand(32, 6, generator=torch.Generator().manual_seed(1)) * 2 - 1
    sums = quadrature.half_vector_albedo(model, z)
    assert (sums.reflected.amax(-1) + sums.diffuse <= 1.0 + 2e-3).all()


def test_unit_lobes_divided_by_cycles_own_table_are_not_trusted_as_bounded() -> None:
    """Cycles' table reads up to 0.86 % short between nodes: such a decoder is refused, not checked
    off its lobe weights as if it were bounded."""
    dec = KIND.build_decoder(HybridConfig(unit_lobes=True)).eval()
    assert dec.bounded
    dec.ggx_e.copy_(tables.table("ggx_E", torch.device("cpu"), torch.float32))
    assert not dec.bounded
    model = NeuralModel(Encoder(), dec, LobeSampler(dec), "cycles table", 1e-3, 1.0, 0.5)
    z = torch.zeros(2, 6)
    for call in (lambda: energy.guard(model, z), lambda: energy.fit_bounded(model, torch.zeros(2, 22).numpy(), z),
                 lambda: bound_furnace(model, z)):
        with pytest.raises(ValueError, match="not energy-bounded"):
            call()


def test_the_shipped_hybrid_passes_the_furnace_at_the_corners_of_the_latent_box() -> None:
    """Corner latents, where a diffusion sampler clamps: 32 azimuths cut the horizon at cos 0.05 so
    coarsely that they read up to 0.6 % high; the bounded decoder's quadrature reads them <= 1."""
    model = trained.load()
    z = torch.tensor([[0.843, -1, -1, 1, -1, 1], [1, -1, -1, 1, -1, 0.695], [1, -1, -1, 1, -1, 1]])
    coarse = quadrature.half_vector_albedo(model, z, furnace.BOUNDED_QUADRATURE_THETA).albedo()
    assert (coarse[:, -1] > 1.002).all()  # the quadrature's error, not the decoder's
    assert not furnace.furnace(model, z).failing.any()
