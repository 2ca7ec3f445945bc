"""The preview shader of the hybrid decoder: its lobes as Cycles' own closures.

The hybrid's head (``torch_models/neural/hybrid/networks.py``) turns (latent, wi) into
analytic lobes that Cycles implements itself, so Cycles lights them with its own
light transport (every lamp, shadows, indirect light, its importance sampling):

* each GGX lobe k: ``generalized_schlick_bsdf`` with the lobe's alpha, its
  Schlick F0 and f90 = 1, exponent 5, single-scatter ``"ggx"`` (D, height-
  correlated G2 and Schlick at wi.h as the torch lobes), weighted w_k g_k
  [/ E(alpha, cos θi) for unit lobes];
* the diffuse lobe: ``diffuse()`` weighted w_d g_d c_d;
* the sheen slot: Cycles' ``sheen()`` (f cos = R LTC) weighted w_s g_s c_s / R,
  which leaves the slot's unit-albedo LTC; R is read from the same sheen table
  as the torch lobes (``core/sheen_table.py``);
* the base: ``diffuse()`` weighted T c.

A closure weight cannot depend on the light direction. The gates' input width
says which of the two gate kinds the weights hold (``GATES``); only how the
shader gets its gates differs:

* gates of both directions (16 inputs, the shipped decoder): each gate is
  replaced by its mean over directions drawn from its own lobe
  (``torch_models/neural/hybrid/closure_form.py``, rule ``"mean"``): ``gate_samples``
  draws per lobe and shading sample, hashed from the shading position, so
  Cycles' samples converge to that mean. bench/addon/closure_preview.py measures
  what the constant gates cost against the full decoder;
* view gates (9 inputs: the latent and the view cosine's features, the head's
  own input; ``HybridDecoder(view_gates=True)``): evaluated once per shading
  point at wi, so the closures are the decoder exactly.

The torch renderer renders the same closure form (``ClosureForm``).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from string import Template

import numpy as np

from .neural_osl_parts import COMMON, defines, mlp_function, table_function
from .schema import SHEEN_ROUGHNESS_MIN
from .sheen_table import sheen_table
from .tensor_file import linear_layers

LOG_ALPHA_MIN = math.log(1e-4)  # hybrid.LOG_ALPHA_MIN
E_MIN = 0.3  # hybrid.E_MIN
SHEEN_DROP = 1e-5  # brdf.lobes._SHEEN_DROP: Cycles drops a sheen closure whose A or R is below this

# s: alphas [0, K), Schlick F0s [F0S, F0S + 3K), diffuse colour [DIFFUSE, +3), with a sheen its roughness
# [SHEEN_R] and colour [SHEEN_R + 1, +3), slot weights [WEIGHTS, +K+3+S) (the GGX lobes, diffuse, [sheen,] T,
# absorbed) (S = SHEEN, 0 or 1)
_SETUP = r"""
float pow5(float x) { return x * x * x * x * x; }

// the head at (z, wi): lobes and slot weights
void setup(float z[6], vector wi, output float s[STATE])
{
    float c = clamp(wi[2], 0.0, 1.0);
    float x[9] = {z[0], z[1], z[2], z[3], z[4], z[5], c, sqrt(1.0 - c * c), pow5(1.0 - c)};
    float o[HEAD_OUTPUTS];
    head_mlp(x, o);
    for (int k = 0; k < LOBES; k++) {
        float a = exp(LOG_ALPHA_MIN * (1.0 - sigmoid(o[k])));
        s[k] = sqrt(a * a + ALPHA_FLOOR * ALPHA_FLOOR);
    }
    for (int i = F0S; i < WEIGHTS; i++)
        s[i] = sigmoid(o[i]);
#if SHEEN
    s[SHEEN_R] = SHEEN_ROUGHNESS_MIN + (1.0 - SHEEN_ROUGHNESS_MIN) * s[SHEEN_R];
#endif
    float top = o[WEIGHTS], total = 0.0;
    for (int i = WEIGHTS; i < STATE; i++)
        top = max(top, o[i]);
    for (int i = WEIGHTS; i < STATE; i++) {
        s[i] = exp(o[i] - top);
        total += s[i];
    }
    for (int i = WEIGHTS; i < STATE; i++)
        s[i] /= total;
}

"""

# the gates of a decoder whose gate network reads (latent, wi, wo, h, wi.h): each held at its lobe mean
_PAIR_GATES = r"""#if SHEEN
vector wi_tangent(vector wi)  // frame.tangent_frame: wi's tangential direction, x when wi is the normal
{
    float len = hypot(wi[0], wi[1]);
    return len > 1e-7 ? vector(wi[0] / len, wi[1] / len, 0.0) : vector(1.0, 0.0, 0.0);
}

vector sheen_sample(float roughness, vector wi, float u1, float u2)  // lobes.sheen_sample: through the LTC
{
    float a, b;
    sheen_ltc(roughness, wi[2], a, b);
    a = max(a, SHEEN_DROP);
    float r = sqrt(u1), phi = M_2PI * u2;
    float dx = r * cos(phi), dy = r * sin(phi), dz = sqrt(max(1.0 - u1, 0.0));
    vector l = normalize(vector(dx - dz * b, dy, dz * a));
    vector t = wi_tangent(wi);
    return vector(t[0] * l[0] - t[1] * l[1], t[1] * l[0] + t[0] * l[1], l[2]);
}
#endif

// ggx.ggx_sample: wi mirrored about a visible normal (Heitz 2018), alpha clamped as Cycles does
vector ggx_sample(float alpha, vector wi, float u1, float u2)
{
    float a = clamp(alpha, 1e-4, 1.0);
    float r = sqrt(u1), phi = M_2PI * u2;
    vector wi_s = normalize(vector(a * wi[0], a * wi[1], wi[2]));
    float lensq = wi_s[0] * wi_s[0] + wi_s[1] * wi_s[1];
    vector t1 = lensq > 1e-7 ? vector(-wi_s[1], wi_s[0], 0.0) / sqrt(lensq) : vector(1.0, 0.0, 0.0);
    vector t2 = cross(wi_s, t1);
    float tx = r * cos(phi), ty = r * sin(phi), w = 0.5 * (1.0 + wi_s[2]);
    ty = (1.0 - w) * sqrt(max(1.0 - tx * tx, 0.0)) + w * ty;
    vector hs = tx * t1 + ty * t2 + sqrt(max(1.0 - tx * tx - ty * ty, 0.0)) * wi_s;
    vector h = normalize(vector(a * hs[0], a * hs[1], max(hs[2], 0.0)));
    return 2.0 * dot(wi, h) * h - wi;
}

// a direction from lobe slot k: GGX lobe k, the cosine lobe (k = LOBES), the sheen (k = LOBES + 1)
vector slot_sample(float s[STATE], int k, vector wi, float u1, float u2)
{
    if (k < LOBES)
        return ggx_sample(s[k], wi, u1, u2);
#if SHEEN
    if (k == LOBES + 1)
        return sheen_sample(s[SHEEN_R], wi, u1, u2);
#endif
    float r = sqrt(u1), phi = M_2PI * u2;
    return vector(r * cos(phi), r * sin(phi), sqrt(max(1.0 - u1, 0.0)));
}

// each slot's gate averaged over directions drawn from its own lobe (closure_form.ClosureForm, "mean")
void mean_gates(float z[6], float s[STATE], vector wi, point p, int samples, output color g[SLOTS])
{
    for (int k = 0; k < SLOTS; k++) {
        color sum = 0;
        for (int j = 0; j < samples; j++) {
            float u1 = hashnoise(p, 2 * (k * samples + j)), u2 = hashnoise(p, 2 * (k * samples + j) + 1);
            vector wo = slot_sample(s, k, wi, u1, u2);
            wo[2] = abs(wo[2]);  // below the horizon: its mirror image above, so every draw counts
            float x[NET_INPUTS], o[GATE_OUTPUTS];
            net_input(z, wi, wo, x);
            gates_mlp(x, o);
            sum += color(sigmoid(o[3 * k]), sigmoid(o[3 * k + 1]), sigmoid(o[3 * k + 2]));
        }
        g[k] = sum / samples;
    }
}

"""

# the gates of a view-gated decoder: its gate network reads the head's input (setup), so they are exact
_VIEW_GATES = r"""// the gates at (z, wi), once per shading point
void view_gates(float z[6], vector wi, output color g[SLOTS])
{
    float c = clamp(wi[2], 0.0, 1.0);
    float x[9] = {z[0], z[1], z[2], z[3], z[4], z[5], c, sqrt(1.0 - c * c), pow5(1.0 - c)};
    float o[GATE_OUTPUTS];
    gates_mlp(x, o);
    for (int k = 0; k < SLOTS; k++)
        g[k] = color(sigmoid(o[3 * k]), sigmoid(o[3 * k + 1]), sigmoid(o[3 * k + 2]));
}

"""


@dataclass(frozen=True)
class _Gates:
    """How a shader gets its gates: its OSL functions, the shader's inputs they need, and the call that
    fills ``g[SLOTS]``. The gate network's input width names the kind."""

    functions: str
    parameters: str
    call: str


GATES = {
    16: _Gates(_PAIR_GATES, "    int gate_samples = 2,  // directions per lobe and shading sample for the gates' means\n",
               "mean_gates(z, s, wi, P, max(gate_samples, 1), g);"),
    9: _Gates(_VIEW_GATES, "", "view_gates(z, wi, g);"),
}

_SHADER = Template(r"""shader richmat_neural(
    vector latent_0 = 0, vector latent_1 = 0,
    color base_color = 0.8,
    float energy_scale = 1.0,
${gate_parameters}    normal Normal = N,
    output closure color BSDF = 0)
{
    vector n, t, bt, wi;
    shading_point(Normal, I, n, t, bt, wi);
    float z[6];
    latent_vector(latent_0, latent_1, z);
    float s[STATE];
    setup(z, wi, s);
    BSDF = (s[T_SLOT] * base_color) * diffuse(n);
    if (wi[2] <= 0)
        return;
    color g[SLOTS];
    ${gate_call}
    float cos_i = wi[2];
    for (int k = 0; k < LOBES; k++) {
        float w = energy_scale * s[WEIGHTS + k];
#ifdef UNIT_LOBES
        w /= max(ggx_e(s[k], cos_i), E_MIN);
#endif
        color f0 = color(s[F0S + 3 * k], s[F0S + 3 * k + 1], s[F0S + 3 * k + 2]);
        BSDF += (w * g[k]) * generalized_schlick_bsdf(n, t, color(1), color(0), s[k], s[k], f0, color(1), 5.0, "ggx");
    }
    color c_d = color(s[DIFFUSE], s[DIFFUSE + 1], s[DIFFUSE + 2]);
    BSDF += (energy_scale * s[WEIGHTS + LOBES] * c_d * g[LOBES]) * diffuse(n);
#if SHEEN
    float albedo = sheen_albedo(s[SHEEN_R], cos_i);
    if (albedo > SHEEN_DROP) {
        color c_s = color(s[SHEEN_R + 1], s[SHEEN_R + 2], s[SHEEN_R + 3]);
        BSDF += (energy_scale * s[WEIGHTS + LOBES + 1] / albedo * c_s * g[LOBES + 1]) * sheen(n, s[SHEEN_R]);
    }
#endif
}
""")


def _unit_lobes(tensors: dict[str, np.ndarray]) -> str:
    """The E table of a hybrid whose GGX lobes are divided by their albedo (``decoder.ggx_e``), or nothing."""
    table = tensors.get("decoder.ggx_e")
    if table is None:
        return ""
    return defines(UNIT_LOBES=1, E_MIN=E_MIN) + table_function(
        "ggx_e", {"GGX_E": table}, "clamp(sqrt(alpha), 0.0, 1.0)", "mu", "float alpha, float mu", "float")


def _sheen(tensors: dict[str, np.ndarray]) -> str:
    """The sheen slot's LTC (A, B, from the weights) and Cycles' albedo R (the sheen table), or nothing."""
    table = tensors.get("decoder.sheen_ltc")
    if table is None:
        return ""
    return (defines(SHEEN_ROUGHNESS_MIN=SHEEN_ROUGHNESS_MIN, SHEEN_DROP=SHEEN_DROP)
            + table_function("sheen_ltc", {"SHEEN_A": table[0], "SHEEN_B": table[1]}, "mu", "roughness",
                             "float roughness, float mu, output float a, output float b", "void")
            + table_function("sheen_albedo", {"SHEEN_ALBEDO": sheen_table()[2]}, "mu", "roughness",
                             "float roughness, float mu", "float"))


def source(tensors: dict[str, np.ndarray]) -> str:
    """The hybrid kind's shader: head (9 -> 5K + 7 [+ 5]) and gates (16 or 9 -> 3 per slot) in OSL."""
    head, gates = linear_layers(tensors, "decoder.head"), linear_layers(tensors, "decoder.gates")
    sheen = int("decoder.sheen_ltc" in tensors)
    k = (head[-1][0].shape[0] - 7 - 5 * sheen) // 5
    if (head[0][0].shape[1] != 9 or head[-1][0].shape[0] != 5 * k + 7 + 5 * sheen or k < 1
            or gates[0][0].shape[1] not in GATES or gates[-1][0].shape[0] != 3 * (k + 1 + sheen)
            or "decoder.alpha_floor" not in tensors):
        raise ValueError("the weights do not match the hybrid decoder layout this shader implements "
                         "(head 9 -> 5K + 7 [+ 5 with a sheen], gates 16 or 9 -> 3K + 3 [+ 3], alpha_floor)")
    gate = GATES[gates[0][0].shape[1]]
    weights = 4 * k + 3 + 4 * sheen
    state = weights + k + 3 + sheen  # the slot weights end the state; the head's last output (R) is unused
    # NET_INPUTS: COMMON's direction-pair input, which only the 16-input gates read
    return (defines(NET_INPUTS=16, LOBES=k, SHEEN=sheen, SLOTS=k + 1 + sheen, HEAD_OUTPUTS=state + 1,
                    GATE_OUTPUTS=3 * (k + 1 + sheen), F0S=k, DIFFUSE=4 * k, SHEEN_R=4 * k + 3, WEIGHTS=weights,
                    STATE=state, T_SLOT=weights + k + 1 + sheen,
                    ALPHA_FLOOR=f"{float(tensors['decoder.alpha_floor']):.9g}", LOG_ALPHA_MIN=f"{LOG_ALPHA_MIN:.9g}")
            + _unit_lobes(tensors) + _sheen(tensors) + mlp_function("head_mlp", head)
            + mlp_function("gates_mlp", gates) + COMMON + _SETUP + gate.functions
            + _SHADER.substitute(gate_parameters=gate.parameters, gate_call=gate.call))
