"""The hybrid decoder: analytic GGX lobes from the latent, a small network that gates them.

The direct MLP (``mlp.networks.Decoder``) must draw every lobe, peaks included, from
(latent, directions); shared across materials it draws near-mirror metals and half
metals badly and half its latents gain energy. Here the peaks are closed-form:

* **head** (latent and the view cosine, once per shading point and view): K isotropic
  GGX lobes, each with its alpha and an RGB Schlick F0, a diffuse lobe with an RGB
  colour, optionally a sheen lobe (Cycles' LTC sheen, normalised to unit albedo, with
  its roughness and an RGB colour: dust and fuzz scatter towards grazing angles, which
  a gated Lambertian cannot), softmax weights over the lobes' slots, the transmittance
  T to the diffuse base and an absorbed slot (a weight that follows the view angle is
  how a coat's Fresnel moves energy between its peak and the base) and R(wi) for the
  renderer's sampling split;
* **gates** (latent and both directions): per-lobe RGB factors in [0, 1] that shape
  each lobe (layering, haze, coat tint, dust, Fresnel beyond Schlick). A view-gated
  hybrid (``view_gates``) reads the latent and the view cosine only: its lobes are
  then exactly closures a renderer can light (``closure_form.py``), for less shaping.

    f_neu cos = sum_k w_k(wi) g_k(wi, wo) F_k(wi.h) D_k G2_k / (4 cos_i)
                + w_d(wi) g_d(wi, wo) c_d cos_o / pi
                + w_s(wi) g_s(wi, wo) c_s LTC(wo; wi, r_s),     T(wi) = w_T(wi)

Single-scatter Smith GGX with F <= 1 has albedo <= 1, so do the Lambertian with
c_d <= 1 and the sheen's LTC (a distribution over the sphere, cut at the horizon),
and gates only remove energy: albedo(f_neu) + T <= 1 - w_absorbed < 1 for
every latent and view direction, with no furnace to repair anything (unit lobes: see
``HybridDecoder.bounded``). A half metal is
a metal lobe and a dielectric lobe in proportion, linear in the weights.

The lobes' alphas are sqrt(a^2 + floor^2): training anneals ``alpha_floor`` down
(gradients through a 1e-3 peak are spiky while the lobes are still far off) and the
weights file keeps the final floor.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import torch
from torch import Tensor, nn

from richmat_addon.core.schema import SHEEN_ROUGHNESS_MIN

from ...brdf.frame import cos_theta, safe_normalize, sin2_theta
from ...brdf import tables
from ...brdf.ggx import ggx_pdf, ggx_sample
from ...brdf.lobes import sheen_pdf_at, sheen_pdf_setup, sheen_sample
from ...brdf.model import luminance
from ..networks import LATENT, direction_features, mlp

LOG_ALPHA_MIN = math.log(1e-4)  # the lobe head's alphas span (1e-4, 1) before the floor
INITIAL_ALPHAS = (0.02, 0.12, 0.45)  # lobe k starts near the k-th: a mirror-like, a glossy and a rough lobe
E_MIN = 0.3  # Cycles' single-scatter GGX albedo table stays above this everywhere


def upper_table() -> Tensor:
    """The GGX albedo table a unit lobe divides by: raised above Cycles' so its bilinear read
    never falls short of the albedo (``tables.generate_ggx_e_upper``)."""
    return tables.table("ggx_E_upper", torch.device("cpu"), torch.float32).clone()


def view_features(cos_i: Tensor) -> Tensor:
    """(N, 3) features of the view cosine: cos, sin and the Schlick term (1 - cos)^5."""
    c = cos_i.clamp(0.0, 1.0)
    return torch.cat([c, (1.0 - c * c).sqrt(), (1.0 - c) ** 5], -1)


@dataclass
class Lobes:
    """What the head predicts at N (latent, view) points: GGX alphas (N, K), Schlick F0s
    (N, K, 3), the diffuse lobe's colour (N, 3), the sheen's roughness (N, 1) and colour
    (N, 3) (zero-width without a sheen), slot weights (N, K + 3 + S: the GGX lobes,
    diffuse, the sheen when S = 1, T, absorbed; they sum to 1) and R (N, 1).

    Then what the lobes' evaluation needs of wi alone, so that a shading point computes it
    once for all its wo: each GGX lobe's weight over 4 cos θi (and its albedo, for unit
    lobes) (N, K), its Smith Λ(wi) (N, K), and the sheen's ``sheen_pdf_setup`` (N, 8; zero-width
    without a sheen)."""

    alpha: Tensor
    f0: Tensor
    diffuse: Tensor
    sheen_roughness: Tensor
    sheen: Tensor
    weights: Tensor
    r: Tensor
    ggx_scale: Tensor
    lambda_i: Tensor
    sheen_setup: Tensor

    def repeat(self, m: int) -> "Lobes":
        """Each point's lobes for m directions in a row (a shading point's many wo)."""
        return Lobes(*(getattr(self, k).repeat_interleave(m, 0) for k in self.__dataclass_fields__))


def softmax(x: Tensor) -> Tensor:
    """Softmax over the last axis; torch's CPU kernel is far slower on a few columns of a wide slice."""
    e = (x - x.amax(-1, keepdim=True)).exp()
    return e / e.sum(-1, keepdim=True)


class HybridDecoder(nn.Module):
    """f_neu * cos (N, 3), T (N, 1), R (N, 1) from latents (N, 6) and directions (N, 3),
    energy-bounded by construction."""

    kind = "hybrid"

    def __init__(self, lobes: int, width: int, gate_width: int, gate_depth: int, alpha_floor: float,
                 unit_lobes: bool, sheen: bool, view_gates: bool = False) -> None:
        """Sizes and options from the run's config (``hybrid.config.HybridConfig``)."""
        super().__init__()
        self.lobes, self.width, self.gate_width, self.gate_depth = lobes, width, gate_width, gate_depth
        self.unit_lobes, self.sheen, self.view_gates = unit_lobes, sheen, view_gates
        self.t_slot = lobes + 1 + sheen  # slots: K GGX lobes, diffuse, [sheen], T, absorbed
        if unit_lobes:  # each GGX lobe divided by its albedo, so slot weights are energies; the table
            # travels in the weights file, so the preview shader reads the same one
            self.register_buffer("ggx_e", upper_table())
        # per lobe an alpha logit and F0 rgb; diffuse rgb; [sheen roughness and rgb]; slot logits; R
        self.head = mlp(LATENT + 3, width, 2, 4 * lobes + 3 + 4 * sheen + self.t_slot + 2 + 1)
        self.gates = mlp(LATENT + (3 if view_gates else 10), gate_width, gate_depth, 3 * (lobes + 1 + sheen))
        if sheen:  # Cycles' LTC table (A, B), so the preview shader needs nothing but the weights file
            self.register_buffer("sheen_ltc", tables.table("sheen_ltc", torch.device("cpu"), torch.float32)[:2].clone())
        self.register_buffer("alpha_floor", torch.tensor(float(alpha_floor)))
        with torch.no_grad():  # spread the lobes over the roughness range from the start
            bias = self.head[-1].bias
            for k in range(lobes):
                s = math.log(INITIAL_ALPHAS[k % len(INITIAL_ALPHAS)]) / LOG_ALPHA_MIN
                bias[k] = math.log((1.0 - s) / s)
            self.gates[-1].bias.fill_(2.0)  # gates start open (sigmoid(2) = 0.88)

    @property
    def bounded(self) -> bool:
        """albedo(f_neu) + T <= 1 for every latent, so fitting needs no furnace. A unit lobe's albedo
        is E / table: <= 1 where the table (its bilinear read) is at least E everywhere, as the upper
        table is; decoders saved with Cycles' own table (which reads short between nodes) are not,
        and their fits are refused (``kind``)."""
        return not self.unit_lobes or bool((self.ggx_e >= tables.table("ggx_E_upper", self.ggx_e.device,
                                                                        self.ggx_e.dtype)).all())

    def head_at(self, latent: Tensor, wi: Tensor) -> Lobes:
        """The lobes at (latent, wi): once per shading point and view direction."""
        k, s = self.lobes, 4 * self.sheen
        o = self.head(torch.cat([latent, view_features(cos_theta(wi))], -1))
        alpha = torch.exp(LOG_ALPHA_MIN * (1.0 - torch.sigmoid(o[:, :k])))
        alpha = (alpha.square() + self.alpha_floor.square()).sqrt()
        sheen = torch.sigmoid(o[:, 4 * k + 3:4 * k + 3 + s])
        roughness = SHEEN_ROUGHNESS_MIN + (1.0 - SHEEN_ROUGHNESS_MIN) * sheen[:, :1]
        weights = softmax(o[:, 4 * k + 3 + s:-1])
        a2, cos_i = alpha.square(), cos_theta(wi).clamp(min=1e-12)
        lambda_i = 0.5 * ((1.0 + a2 * sin2_theta(wi) / cos_i.square()).sqrt() - 1.0)
        scale = weights[:, :k] / (4.0 * cos_i)
        if self.unit_lobes:
            scale = scale / tables.lookup(self.ggx_e, alpha.sqrt(), cos_theta(wi).clamp(0.0, 1.0)).clamp(min=E_MIN)
        setup = sheen_pdf_setup(wi, roughness) if self.sheen else wi[:, :0]
        return Lobes(alpha, torch.sigmoid(o[:, k:4 * k]).reshape(-1, k, 3), torch.sigmoid(o[:, 4 * k:4 * k + 3]),
                     roughness, sheen[:, 1:], weights, torch.sigmoid(o[:, -1:]), scale, lambda_i, setup)

    def forward(self, latent: Tensor, wi: Tensor, wo: Tensor) -> tuple[Tensor, Tensor, Tensor]:
        lobes = self.head_at(latent, wi)
        return self.lobe_sum(lobes, latent, wi, wo), lobes.weights[:, self.t_slot:self.t_slot + 1], lobes.r

    def gates_at(self, latent: Tensor, wi: Tensor, wo: Tensor) -> Tensor:
        """(N, slots, 3) the gates of the GGX lobes, the diffuse lobe [and the sheen] at (wi, wo)
        (at wi alone for view gates)."""
        directions = view_features(cos_theta(wi)) if self.view_gates else direction_features(wi, wo)
        gates = torch.sigmoid(self.gates(torch.cat([latent, directions], -1)))
        return gates.reshape(-1, self.lobes + 1 + self.sheen, 3)

    def lobe_sum(self, lobes: Lobes, latent: Tensor, wi: Tensor, wo: Tensor, gates: Tensor | None = None) -> Tensor:
        """f_neu cos (N, 3) of the predicted lobes, gated: all K GGX lobes at once, sharing the
        half vector and the Schlick term (the same D, G2 as ``ggx.ggx_single_scatter``); what
        depends on wi alone comes precomputed in ``lobes``. ``gates`` (N, slots, 3) replaces the
        gate network's (the closure form's gates, constant over wo)."""
        k = self.lobes
        if gates is None:
            gates = self.gates_at(latent, wi, wo)
        h = safe_normalize(wi + wo)
        a2 = lobes.alpha.square()  # (N, K)
        cos_o = cos_theta(wo).clamp(min=1e-12)
        d = a2 / (math.pi * (sin2_theta(h) + a2 * cos_theta(h).square()).square())
        lambda_o = 0.5 * ((1.0 + a2 * sin2_theta(wo) / cos_o.square()).sqrt() - 1.0)
        single = d / (1.0 + lobes.lambda_i + lambda_o) * lobes.ggx_scale  # (N, K)
        schlick = (1.0 - (wi * h).sum(-1, keepdim=True).clamp(0.0, 1.0)) ** 5  # (N, 1)
        fresnel = lobes.f0 + (1.0 - lobes.f0) * schlick[:, :, None]  # (N, K, 3)
        glossy = (single[:, :, None] * fresnel * gates[:, :k]).sum(1)
        diffuse = (lobes.weights[:, k:k + 1] / math.pi) * cos_o * lobes.diffuse * gates[:, k]
        if self.sheen:  # the LTC's density: the sheen divided by its albedo
            unit = sheen_pdf_at(wo, lobes.sheen_setup)
            diffuse = diffuse + lobes.weights[:, k + 1:k + 2] * unit * lobes.sheen * gates[:, k + 1]
        above = (cos_theta(wi) > 0) & (cos_theta(wo) > 0)
        return torch.where(above, glossy + diffuse, torch.zeros_like(glossy))

    def log_forward(self, latent: Tensor, wi: Tensor, wo: Tensor) -> tuple[Tensor, Tensor, Tensor]:
        """(log(1 + f * cos), T, R): the quantity the training loss compares."""
        f, t, r = self(latent, wi, wo)
        return torch.log1p(f), t, r

    def albedo_bound(self, latent: Tensor, wi: Tensor) -> Tensor:
        """(N,) an upper bound of albedo(f_neu) + T at wi: the weight of every slot but the absorbed one."""
        return self.head_at(latent, wi).weights[:, :-1].sum(-1)


class LobeSampler:
    """Exact importance sampling of a hybrid decoder's own lobes (gates left out): the
    component is chosen by weight times an albedo estimate, a GGX lobe by its visible
    normals, the diffuse lobe by cosine, the sheen by its LTC. Same interface as
    the MLP's ``SamplingDecoder``."""

    def __init__(self, decoder: HybridDecoder) -> None:
        self.decoder = decoder

    def components(self, latent: Tensor, wi: Tensor) -> tuple[Tensor, Lobes]:
        """Probabilities (N, K + 1 [+ 1]) of the GGX lobes, the diffuse lobe [and the sheen], and the lobes."""
        k = self.decoder.lobes
        lobes = self.decoder.head_at(latent, wi)
        schlick = (1.0 - cos_theta(wi).clamp(0.0, 1.0)) ** 5
        f0 = luminance(lobes.f0)[..., 0]
        glossy = lobes.weights[:, :k] * (f0 + (1.0 - f0) * schlick)
        diffuse = lobes.weights[:, k:k + 1] * luminance(lobes.diffuse)
        parts = [glossy, diffuse]
        if self.decoder.sheen:
            parts.append(lobes.weights[:, k + 1:k + 2] * luminance(lobes.sheen))
        p = torch.cat(parts, -1) + 1e-6
        return p / p.sum(-1, keepdim=True), lobes

    def pdf(self, latent: Tensor, wi: Tensor, wo: Tensor) -> Tensor:
        p, lobes = self.components(latent, wi)
        k = self.decoder.lobes
        out = p[:, k] * wo[:, 2].clamp(min=0.0) / math.pi
        for j in range(k):
            out = out + p[:, j] * ggx_pdf(wi, wo, lobes.alpha[:, j:j + 1])[:, 0]
        if self.decoder.sheen:
            out = out + p[:, k + 1] * sheen_pdf_at(wo, lobes.sheen_setup)[:, 0]
        return out * (wo[:, 2] > 0)

    def sample(self, latent: Tensor, wi: Tensor, u: Tensor) -> Tensor:
        """u (N, 3): u[:, 0] picks the component, u[:, 1:] samples it."""
        p, lobes = self.components(latent, wi)
        k, last = self.decoder.lobes, p.shape[1] - 1
        choice = (u[:, :1] >= p.cumsum(-1)).sum(-1, keepdim=True).clamp(max=last)  # (N, 1); k: diffuse, k + 1: sheen
        glossy = ggx_sample(wi, lobes.alpha.gather(1, choice.clamp(max=k - 1)), u[:, 1:3])
        r, phi = u[:, 1:2].sqrt(), 2.0 * math.pi * u[:, 2:3]
        cosine = torch.cat([r * phi.cos(), r * phi.sin(), (1.0 - u[:, 1:2]).clamp(min=0.0).sqrt()], -1)
        out = torch.where(choice < k, glossy, cosine)
        if self.decoder.sheen:
            out = torch.where(choice == k + 1, sheen_sample(wi, lobes.sheen_roughness, u[:, 1:3]), out)
        return out
