"""An OSL shader that evaluates a frozen neural-material decoder (numpy only).

OSL cannot define new BSDFs, so the preview splits the neural material
``f = s f_neu + T(wi) c / pi`` (torch_models/neural/bsdf.py) in two:

* the diffuse base ``T c`` is a real ``diffuse()`` closure, lit by Cycles
  (every light, shadows, indirect light). The hybrid decoder's T is a slot
  weight of its head, a function of wi alone: the closure's weight is exact.
  The MLP decoder outputs T from the same network as f, so it varies with wo
  although it should not; the torch renderer reads it at every sampled wo, so
  the closure takes its mean over ``t_samples`` cosine-distributed wo and an
  emission adds the covariance of T and the world's radiance over them (read
  at the single point wo = wi, which training never shows, T made the base up
  to 40 % too dark).
* the neural lobe is an ``emission()`` whose radiance is a Monte Carlo estimate
  of ``integral f_neu cos L_world dwo`` inside the shader: ``samples``
  directions from the decoder's sampler (the MLP's sampling decoder, or the
  hybrid's own GGX and diffuse lobes) mixed with a uniform share, with the
  mixture's exact pdf, the decoder at each, and the world probe looked up with ``texture()`` in Blender's
  equirectangular mapping. It sees the world only (no lamps, no shadows).
  Random numbers are hashed from the shading position, which moves with
  Cycles' pixel jitter, so more Cycles samples converge.

The kind is read from the tensor names (``decoder.net.*`` with ``sampler.net.*``,
or ``decoder.head.*``, ``decoder.gates.*`` and ``decoder.alpha_floor``). The
weights are written into the source as constant arrays, so the shader needs
nothing but its latent textures. Both kinds share the shader and its interface;
each supplies ``setup`` (per shading point), ``decode``, ``lobe_pdf`` and
``lobe_sample``, following ``networks.py`` and ``hybrid.py`` exactly.
Directions are local to the Duff et al. tangent frame the torch renderer uses.
"""
from __future__ import annotations

import math

import numpy as np

from .schema import SHEEN_ROUGHNESS_MIN
from .tensor_file import linear_layers

MAX_LOG_F = 12.0  # networks.MAX_LOG_F
# Share of directions drawn uniformly over the hemisphere: at grazing views the MLP's
# sampling decoder's pdf is thin where f is not, and f/pdf becomes heavy-tailed (a dark
# rim with rare fireflies); the uniform share bounds it. The hybrid's lobe sampler leaves
# the gates and the lobes below the horizon out, and agrees better with it too.
UNIFORM_SHARE = 0.2
LOG_SLOPE_FLOOR = 1e-10  # networks.LOG_SLOPE_FLOOR
LOG_ALPHA_MIN = math.log(1e-4)  # hybrid.LOG_ALPHA_MIN
E_MIN = 0.3  # hybrid.E_MIN
SHEEN_DROP = 1e-5  # brdf.lobes._SHEEN_DROP: the smallest LTC A
LUMINANCE = (0.2126, 0.7152, 0.0722)  # brdf.model.LUMINANCE
# A network's input width names its direction encoding (networks.DIRECTION_ENCODINGS):
# 6 latents + 10 ("half") or + 11 ("half_log_slope", which appends ln(tan^2 theta_h) / 8).
_ENCODING_EXTRA = {16: "", 17: ", log_slope"}


def _array(name: str, values: np.ndarray) -> str:
    body = ",".join(f"{float(v):.9g}" for v in values.ravel())
    return f"    float {name}[{values.size}] = {{{body}}};\n"


def _mlp_function(name: str, layers: list[tuple[np.ndarray, np.ndarray]]) -> str:
    """``void name(float x[n_in], output float y[n_out])``: ReLU between layers, linear output."""
    n_in, n_out = layers[0][0].shape[1], layers[-1][0].shape[0]
    src = f"void {name}(float x[{n_in}], output float y[{n_out}])\n{{\n"
    prev, size = "x", n_in
    for k, (w, b) in enumerate(layers):
        src += _array(f"W{k}", w) + _array(f"B{k}", b)
        out_size = w.shape[0]
        last = k == len(layers) - 1
        target = "y" if last else f"h{k}"
        if not last:
            src += f"    float {target}[{out_size}];\n"
        src += (f"    for (int o = 0; o < {out_size}; o++) {{\n"
                f"        float a = B{k}[o];\n"
                f"        for (int i = 0; i < {size}; i++) a += W{k}[o * {size} + i] * {prev}[i];\n"
                f"        {target}[o] = {'a' if last else 'max(a, 0.0)'};\n    }}\n")
        prev, size = target, out_size
    return src + "}\n\n"


_COMMON = r"""
float sigmoid(float x) { return 1.0 / (1.0 + exp(-x)); }

// [z(6), wi, wo, h, wi.h] and, for the "half_log_slope" encoding, ln(tan^2 theta_h) / 8
void net_input(float z[6], vector wi, vector wo, output float x[NET_INPUTS])
{
    vector h = normalize(wi + wo);
    float hz2 = max(h[2] * h[2], 1e-6);
    float log_slope = log(max(max(1.0 - hz2, 0.0) / hz2, LOG_SLOPE_FLOOR)) / 8.0;
    float v[NET_INPUTS] = {z[0], z[1], z[2], z[3], z[4], z[5], wi[0], wi[1], wi[2], wo[0], wo[1], wo[2],
                           h[0], h[1], h[2], dot(wi, h) NET_EXTRA};
    for (int i = 0; i < NET_INPUTS; i++)
        x[i] = v[i];
}

color world_radiance(string probe, float rotation, color world_color, vector d)
{
    if (probe == "")
        return world_color;
    float c = cos(rotation), s = sin(rotation);
    vector p = vector(c * d[0] - s * d[1], s * d[0] + c * d[1], d[2]);
    float u = 0.5 - atan2(p[1], p[0]) / M_2PI;
    u = u - floor(u);
    float v = 0.5 + atan2(p[2], hypot(p[0], p[1])) / M_PI;
    // Zero derivatives: automatic ones (through P and the hashed samples) would pick a blurred MIP level.
    return (color)texture(probe, u, 1.0 - v, 0, 0, 0, 0, "interp", "bilinear", "swrap", "periodic",
                          "twrap", "clamp");
}
"""

_MLP = r"""
float sinh_approx(float x) { return x * sqrt(1.0 + x * x); }
float tanh_approx(float x) { return x / sqrt(1.0 + x * x); }

// s: the sampling decoder's mixture at wi, which decoding does not read
void decode(float z[6], float s[STATE], vector wi, vector wo, output color f, output float T)
{
    float x[NET_INPUTS];
    net_input(z, wi, wo, x);
    float y[5];
    decoder_mlp(x, y);
    float above = (wi[2] > 0 && wo[2] > 0) ? 1.0 : 0.0;
    f = max(color(exp(min(y[0], MAX_LOG_F)), exp(min(y[1], MAX_LOG_F)), exp(min(y[2], MAX_LOG_F))) - 1.0, color(0.0)) * above;
    T = sigmoid(y[3]);
}

vector tilted_normal(float tx, float ty) { return normalize(vector(-tx, -ty, 1.0)); }

float lobe_pdf(float m[STATE], vector wi, vector wo)
{
    float p_cos = max(dot(wo, tilted_normal(m[2], m[3])), 0.0) / M_PI;
    vector h = normalize(wi + wo);
    float p_ggx = 0.0;
    if (h[2] > 0) {
        float hz = max(h[2], 1e-6);
        float slx = -h[0] / hz - m[7], sly = -h[1] / hz - m[8];
        float ax = m[4], ay = m[5], rho = m[6];
        float sx = slx / ax;
        float sq = sqrt(1.0 - rho * rho);
        float sy = (sly / ay - rho * sx) / sq;
        float d = 1.0 + sx * sx + sy * sy;
        float p22 = 1.0 / (M_PI * d * d) / (ax * ay * sq);
        p_ggx = p22 / (hz * hz * hz) / (4.0 * max(abs(dot(wo, h)), 1e-6));
    }
    return wo[2] > 0 ? m[0] * p_cos + m[1] * p_ggx : 0.0;
}

vector lobe_sample(float m[STATE], vector wi, float u0, float u1, float u2)
{
    if (u0 < m[0]) {
        vector n = tilted_normal(m[2], m[3]);
        float r = sqrt(u1), phi = M_2PI * u2;
        vector helper = abs(n[2]) < 0.9 ? vector(0, 0, 1) : vector(1, 0, 0);
        vector t = normalize(cross(helper, n));
        vector b = cross(n, t);
        return r * cos(phi) * t + r * sin(phi) * b + sqrt(max(1.0 - u1, 0.0)) * n;
    }
    float r = sqrt(u1 / max(1.0 - u1, 1e-7)), phi = M_2PI * u2;
    float sx = r * cos(phi), sy = r * sin(phi);
    float x = m[4] * sx + m[7];
    float y = m[5] * (m[6] * sx + sqrt(1.0 - m[6] * m[6]) * sy) + m[8];
    vector h = normalize(vector(-x, -y, 1.0));
    return 2.0 * dot(wi, h) * h - wi;
}

// the sampling decoder: a tilted cosine lobe and a sheared GGX lobe
void setup(float z[6], vector wi, output float m[STATE])
{
    float x[9] = {z[0], z[1], z[2], z[3], z[4], z[5], wi[0], wi[1], wi[2]};
    float o[9];
    sampler_mlp(x, o);
    float e = exp(o[1] - o[0]);
    m[0] = 1.0 / (1.0 + e);
    m[1] = 1.0 - m[0];
    m[2] = sinh_approx(o[2]);
    m[3] = sinh_approx(o[3]);
    m[4] = 1e-3 + 0.5 * (1.0 + tanh_approx(o[4]));
    m[5] = 1e-3 + 0.5 * (1.0 + tanh_approx(o[5]));
    m[6] = 0.99 * tanh_approx(o[6]);
    m[7] = sinh_approx(o[7]);
    m[8] = sinh_approx(o[8]);
}
"""

# s: alphas [0, K), Schlick F0s [F0S, F0S + 3K), diffuse colour [DIFFUSE, +3), with a sheen its
# roughness [SHEEN_R] and colour [SHEEN_R + 1, +3), slot weights [WEIGHTS, +K+3+S) (the GGX lobes,
# diffuse, [sheen,] T, absorbed), component probabilities [PROBS, +K+1+S) (S = SHEEN, 0 or 1)
_HYBRID = r"""
float pow5(float x) { return x * x * x * x * x; }
float luminance_at(float s[STATE], int i) { return LUM_R * s[i] + LUM_G * s[i + 1] + LUM_B * s[i + 2]; }
float ggx_d(vector h, float a2) { float q = h[0] * h[0] + h[1] * h[1] + a2 * h[2] * h[2]; return a2 / (M_PI * q * q); }
float ggx_lambda(vector w, float a2)
{
    float c = max(w[2], 1e-12);
    return 0.5 * (sqrt(1.0 + a2 * (w[0] * w[0] + w[1] * w[1]) / (c * c)) - 1.0);
}

// the head at (z, wi): lobes, slot weights and the sampler's component probabilities
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
    for (int i = WEIGHTS; i < PROBS; i++)
        top = max(top, o[i]);
    for (int i = WEIGHTS; i < PROBS; i++) {
        s[i] = exp(o[i] - top);
        total += s[i];
    }
    for (int i = WEIGHTS; i < PROBS; i++)
        s[i] /= total;
    float schlick = pow5(1.0 - c), sum = 0.0;
    for (int k = 0; k < COMPONENTS; k++) {
        float albedo = k < LOBES ? luminance_at(s, F0S + 3 * k) : luminance_at(s, k == LOBES ? DIFFUSE : SHEEN_R + 1);
        if (k < LOBES)
            albedo += (1.0 - albedo) * schlick;
        s[PROBS + k] = s[WEIGHTS + k] * albedo + 1e-6;
        sum += s[PROBS + k];
    }
    for (int k = 0; k < COMPONENTS; k++)
        s[PROBS + k] /= sum;
}

#if SHEEN
// lobes.sheen_pdf: Cycles' LTC sheen divided by its albedo, in the frame whose x axis is wi's tangential
// direction; A clamped as for sampling
vector wi_tangent(vector wi)  // frame.tangent_frame: wi's tangential direction, x when wi is the normal
{
    float len = hypot(wi[0], wi[1]);
    return len > 1e-7 ? vector(wi[0] / len, wi[1] / len, 0.0) : vector(1.0, 0.0, 0.0);
}

vector sheen_local(vector wi, vector w)
{
    vector t = wi_tangent(wi);
    return vector(t[0] * w[0] + t[1] * w[1], -t[1] * w[0] + t[0] * w[1], w[2]);
}

void sheen_ab(float s[STATE], vector wi, output float a, output float b)  // the LTC at wi, A as sampled
{
    sheen_ltc(s[SHEEN_R], wi[2], a, b);
    a = max(a, SHEEN_DROP);
}

float sheen_density(float s[STATE], vector wi, vector wo)
{
    float a, b;
    sheen_ab(s, wi, a, b);
    vector l = sheen_local(wi, wo);
    float len_sq = (a * l[0] + b * l[2]) * (a * l[0] + b * l[2]) + (a * l[1]) * (a * l[1]) + l[2] * l[2];
    float q = a / max(len_sq, 1e-30);
    return l[2] > 0 ? l[2] * q * q / M_PI : 0.0;
}

vector sheen_sample(float s[STATE], vector wi, float u1, float u2)
{
    float a, b;
    sheen_ab(s, wi, a, b);
    float r = sqrt(u1), phi = M_2PI * u2;
    float dx = r * cos(phi), dy = r * sin(phi), dz = sqrt(max(1.0 - u1, 0.0));
    vector l = normalize(vector(dx - dz * b, dy, dz * a));
    vector t = wi_tangent(wi);
    return vector(t[0] * l[0] - t[1] * l[1], t[1] * l[0] + t[0] * l[1], l[2]);
}
#endif

void decode(float z[6], float s[STATE], vector wi, vector wo, output color f, output float T)
{
    T = s[WEIGHTS + LOBES + 1 + SHEEN];
    f = 0;
    if (wi[2] > 0 && wo[2] > 0) {
        float x[NET_INPUTS];
        net_input(z, wi, wo, x);
        float g[GATE_OUTPUTS];
        gates_mlp(x, g);
        vector h = normalize(wi + wo);
        float cos_i = max(wi[2], 1e-12), schlick = pow5(1.0 - clamp(dot(wi, h), 0.0, 1.0));
        for (int k = 0; k < LOBES; k++) {
            float a2 = s[k] * s[k];
            float single = ggx_d(h, a2) / ((1.0 + ggx_lambda(wi, a2) + ggx_lambda(wo, a2)) * 4.0 * cos_i);
            color f0 = color(s[F0S + 3 * k], s[F0S + 3 * k + 1], s[F0S + 3 * k + 2]);
            color gate = color(sigmoid(g[3 * k]), sigmoid(g[3 * k + 1]), sigmoid(g[3 * k + 2]));
#ifdef UNIT_LOBES
            single /= max(ggx_e(s[k], cos_i), E_MIN);
#endif
            f += s[WEIGHTS + k] * single * (f0 + (1.0 - f0) * schlick) * gate;
        }
        color gate = color(sigmoid(g[3 * LOBES]), sigmoid(g[3 * LOBES + 1]), sigmoid(g[3 * LOBES + 2]));
        f += s[WEIGHTS + LOBES] / M_PI * wo[2] * color(s[DIFFUSE], s[DIFFUSE + 1], s[DIFFUSE + 2]) * gate;
#if SHEEN
        gate = color(sigmoid(g[3 * LOBES + 3]), sigmoid(g[3 * LOBES + 4]), sigmoid(g[3 * LOBES + 5]));
        f += s[WEIGHTS + LOBES + 1] * sheen_density(s, wi, wo) * color(s[SHEEN_R + 1], s[SHEEN_R + 2], s[SHEEN_R + 3]) * gate;
#endif
    }
}

// ggx.ggx_pdf: D G1(wi) / (4 cos_i), alpha clamped as Cycles does
float lobe_pdf(float s[STATE], vector wi, vector wo)
{
    if (wi[2] <= 0 || wo[2] <= 0)
        return 0.0;
    vector h = normalize(wi + wo);
    float pdf = s[PROBS + LOBES] * wo[2] / M_PI;
    for (int k = 0; k < LOBES; k++) {
        float a = clamp(s[k], 1e-4, 1.0);
        pdf += s[PROBS + k] * ggx_d(h, a * a) / ((1.0 + ggx_lambda(wi, a * a)) * 4.0 * max(wi[2], 1e-12));
    }
#if SHEEN
    pdf += s[PROBS + LOBES + 1] * sheen_density(s, wi, wo);
#endif
    return pdf;
}

// a component by its probability; a GGX lobe by its visible normals (Heitz 2018), the diffuse one by
// cosine, the sheen through its LTC
vector lobe_sample(float s[STATE], vector wi, float u0, float u1, float u2)
{
    int choice = 0;
    float edge = 0.0;
    for (int k = 0; k < COMPONENTS - 1; k++) {
        edge += s[PROBS + k];
        if (u0 >= edge)
            choice = k + 1;
    }
    float r = sqrt(u1), phi = M_2PI * u2;
    if (choice == LOBES)
        return vector(r * cos(phi), r * sin(phi), sqrt(max(1.0 - u1, 0.0)));
#if SHEEN
    if (choice == LOBES + 1)
        return sheen_sample(s, wi, u1, u2);
#endif
    float a = clamp(s[choice], 1e-4, 1.0);
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
"""

_SHADER = r"""
shader richmat_neural(
    vector latent_0 = 0, vector latent_1 = 0,
    color base_color = 0.8,
    float energy_scale = 1.0,
    string probe = "",
    float probe_rotation = 0.0,
    color world_color = 0.05,
    int samples = 8,
    int t_samples = 4,  // the MLP's T over wo; the hybrid's T depends on wi only
    normal Normal = N,
    output closure color BSDF = 0)
{
    vector n = normalize(Normal);
    float sg = n[2] >= 0 ? 1.0 : -1.0;
    float a = -1.0 / (sg + n[2]);
    float b = n[0] * n[1] * a;
    vector t = vector(1.0 + sg * n[0] * n[0] * a, sg * b, -sg * n[0]);
    vector bt = vector(b, sg + n[1] * n[1] * a, -n[1]);
    vector view = normalize(I);  // Cycles passes its wi here: towards the viewer (checked)
    vector wi = vector(dot(view, t), dot(view, bt), dot(view, n));
    float z[6] = {latent_0[0], latent_0[1], latent_0[2], latent_1[0], latent_1[1], latent_1[2]};
    float s[STATE];
    setup(z, wi, s);
    color f;
    float T;
#ifdef T_SLOT
    BSDF = (s[T_SLOT] * base_color) * diffuse(n);
#else
    color L, TL = 0, L_sum = 0;
    float T_k;
    T = 0;
    int n_t = max(t_samples, 2);
    for (int k = 0; k < n_t; k++) {  // negative seeds: the lobe's directions use 0, 1, 2, ...
        float u1 = hashnoise(P, -1 - 2 * k), r = sqrt(u1), phi = M_2PI * hashnoise(P, -2 - 2 * k);
        vector wo = vector(r * cos(phi), r * sin(phi), sqrt(max(1.0 - u1, 0.0)));
        decode(z, s, wi, wo, f, T_k);
        L = world_radiance(probe, probe_rotation, world_color, wo[0] * t + wo[1] * bt + wo[2] * n);
        T += T_k / n_t;
        TL += T_k * L / n_t;
        L_sum += L / n_t;
    }
    // Cycles lights the base with the mean T; the world light it gets is corrected by the covariance of
    // T and L over cosine-distributed wo (unbiased: the n/(n-1) of a sample covariance), so the world
    // part is c * integral T L cos / pi, as the torch renderer integrates it.
    BSDF = (T * base_color) * diffuse(n) + base_color * (TL - T * L_sum) * (n_t / (n_t - 1.0)) * emission();
#endif
    if (wi[2] > 0 && samples > 0) {
        color sum = 0;
        for (int k = 0; k < samples; k++) {
            float u0 = hashnoise(P, 3 * k), u1 = hashnoise(P, 3 * k + 1), u2 = hashnoise(P, 3 * k + 2);
            vector wo;
            if (u0 < UNIFORM_SHARE) {  // defensive share: bounds f/pdf where the sampler's pdf is thin
                float r = sqrt(max(1.0 - u1 * u1, 0.0));
                wo = vector(r * cos(M_2PI * u2), r * sin(M_2PI * u2), u1);
            } else {
                wo = lobe_sample(s, wi, (u0 - UNIFORM_SHARE) / (1.0 - UNIFORM_SHARE), u1, u2);
            }
            float pdf = (1.0 - UNIFORM_SHARE) * lobe_pdf(s, wi, wo) + (wo[2] > 0 ? UNIFORM_SHARE / M_2PI : 0.0);
            if (pdf <= 0.0)
                continue;
            decode(z, s, wi, wo, f, T);
            sum += f * world_radiance(probe, probe_rotation, world_color, wo[0] * t + wo[1] * bt + wo[2] * n) / pdf;
        }
        BSDF += (energy_scale / samples) * sum * emission();
    }
}
"""


def _defines(**values: object) -> str:
    return "".join(f"#define {k} {v}\n" for k, v in values.items())


def _mlp_parts(tensors: dict[str, np.ndarray]) -> str:
    decoder, sampler = linear_layers(tensors, "decoder.net"), linear_layers(tensors, "sampler.net")
    inputs = decoder[0][0].shape[1]
    if inputs not in _ENCODING_EXTRA or decoder[-1][0].shape[0] != 5 or sampler[-1][0].shape[0] != 9:
        raise ValueError("the weights do not match the MLP decoder layout this shader implements "
                         "(decoder 16 or 17 -> 5, sampling decoder 9 -> 9)")
    return (_defines(NET_INPUTS=inputs, NET_EXTRA=_ENCODING_EXTRA[inputs], STATE=9)
            + _mlp_function("decoder_mlp", decoder) + _mlp_function("sampler_mlp", sampler) + _COMMON + _MLP)


def _hybrid_parts(tensors: dict[str, np.ndarray]) -> str:
    head, gates = linear_layers(tensors, "decoder.head"), linear_layers(tensors, "decoder.gates")
    sheen = int("decoder.sheen_ltc" in tensors)
    k = (head[-1][0].shape[0] - 7 - 5 * sheen) // 5
    if (head[0][0].shape[1] != 9 or head[-1][0].shape[0] != 5 * k + 7 + 5 * sheen or k < 1
            or gates[0][0].shape[1] != 16 or gates[-1][0].shape[0] != 3 * (k + 1 + sheen)
            or "decoder.alpha_floor" not in tensors):
        raise ValueError("the weights do not match the hybrid decoder layout this shader implements "
                         "(head 9 -> 5K + 7 [+ 5 with a sheen], gates 16 -> 3K + 3 [+ 3], alpha_floor)")
    weights = 4 * k + 3 + 4 * sheen
    probs = weights + k + 3 + sheen
    r, g, b = LUMINANCE
    return (_defines(NET_INPUTS=16, NET_EXTRA="", LOBES=k, SHEEN=sheen, COMPONENTS=k + 1 + sheen,
                     HEAD_OUTPUTS=probs + 1, GATE_OUTPUTS=3 * (k + 1 + sheen), F0S=k, DIFFUSE=4 * k,
                     SHEEN_R=4 * k + 3, WEIGHTS=weights, PROBS=probs, STATE=probs + k + 1 + sheen,
                     T_SLOT=weights + k + 1 + sheen, ALPHA_FLOOR=f"{float(tensors['decoder.alpha_floor']):.9g}",
                     LOG_ALPHA_MIN=f"{LOG_ALPHA_MIN:.9g}", LUM_R=r, LUM_G=g, LUM_B=b)
            + _unit_lobes(tensors) + _sheen(tensors) + _mlp_function("head_mlp", head)
            + _mlp_function("gates_mlp", gates) + _COMMON + _HYBRID)


def _unit_lobes(tensors: dict[str, np.ndarray]) -> str:
    """The E table of a hybrid whose GGX lobes are divided by their albedo (``decoder.ggx_e``), or nothing."""
    table = tensors.get("decoder.ggx_e")
    if table is None:
        return ""
    return _defines(UNIT_LOBES=1, E_MIN=E_MIN) + _table_function(
        "ggx_e", {"GGX_E": table}, "clamp(sqrt(alpha), 0.0, 1.0)", "mu", "float alpha, float mu", "float")


def _sheen(tensors: dict[str, np.ndarray]) -> str:
    """Cycles' sheen LTC table (A, B) that a hybrid with a sheen slot carries (``decoder.sheen_ltc``), or nothing."""
    table = tensors.get("decoder.sheen_ltc")
    if table is None:
        return ""
    return _defines(SHEEN_ROUGHNESS_MIN=SHEEN_ROUGHNESS_MIN, SHEEN_DROP=SHEEN_DROP) + _table_function(
        "sheen_ltc", {"SHEEN_A": table[0], "SHEEN_B": table[1]}, "mu", "roughness",
        "float roughness, float mu, output float a, output float b", "void")


def _table_function(name: str, tables: dict[str, np.ndarray], x: str, y: str, params: str, returns: str) -> str:
    """An OSL function reading square tables as ``tables.lookup`` does at (x, y): bilinear, node-centred,
    clamped; x indexes a table's last axis. One table returns its value; several write their outputs,
    named by the lower-case table names after the function's (``SHEEN_A`` -> ``a``)."""
    size = next(iter(tables.values())).shape[-1]
    src = f"{returns} {name}({params})\n{{\n"
    for array, values in tables.items():
        src += _array(array, np.asarray(values, np.float32).reshape(-1))
    src += (f"    float x = clamp({x}, 0.0, 1.0) * {size - 1}, y = clamp({y}, 0.0, 1.0) * {size - 1};\n"
            f"    int x0 = min(int(floor(x)), {size - 1}), y0 = min(int(floor(y)), {size - 1});\n"
            f"    int x1 = min(x0 + 1, {size - 1}), y1 = min(y0 + 1, {size - 1});\n"
            "    float fx = x - x0, fy = y - y0;\n")
    for array in tables:
        read = (f"(1.0 - fy) * ((1.0 - fx) * {array}[y0 * {size} + x0] + fx * {array}[y0 * {size} + x1])\n"
                f"        + fy * ((1.0 - fx) * {array}[y1 * {size} + x0] + fx * {array}[y1 * {size} + x1])")
        src += f"    return {read};\n" if len(tables) == 1 else f"    {array.split('_')[-1].lower()} = {read};\n"
    return src + "}\n\n"


def neural_osl_source(tensors: dict[str, np.ndarray]) -> str:
    """The preview shader for a trained model's tensors, of the decoder kind their names say."""
    parts = _hybrid_parts(tensors) if "decoder.alpha_floor" in tensors or any(
        k.startswith("decoder.head.") for k in tensors) else _mlp_parts(tensors)
    return ("// Generated by richmat_addon.core.neural_osl from trained weights: do not edit.\n"
            "#include \"stdosl.h\"\n\n"
            + _defines(MAX_LOG_F=MAX_LOG_F, LOG_SLOPE_FLOOR=LOG_SLOPE_FLOOR, UNIFORM_SHARE=UNIFORM_SHARE) + parts + _SHADER)
