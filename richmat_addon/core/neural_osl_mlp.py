"""The preview shader of the paper's MLP decoder: its lobe integrated from the world probe.

No Cycles closure draws a free-form network, so the preview splits the material
``f = s f_neu + T(wi) c / pi`` (torch_models/neural/bsdf.py) in two:

* the diffuse base ``T c`` is a real ``diffuse()`` closure, lit by Cycles. The
  MLP outputs T from the same network as f, so it varies with wo although it
  should not; the closure takes its mean over ``t_samples`` cosine-distributed
  wo, and an emission adds the covariance of T and the world's radiance over
  them (the torch renderer reads T at every sampled wo);
* the neural lobe is an ``emission()`` whose radiance is a Monte Carlo estimate
  of ``integral f_neu cos L_world dwo``: ``samples`` directions from the
  sampling decoder mixed with a uniform share, with the mixture's exact pdf,
  and the world probe read in Blender's equirectangular mapping. It sees the
  world only (no lamps, no shadows): the hybrid's closures have none of these
  limits (``neural_osl_hybrid``).

Random numbers are hashed from the shading position, which moves with Cycles'
pixel jitter, so more Cycles samples converge.
"""
from __future__ import annotations

import numpy as np

from .neural_osl_parts import COMMON, defines, mlp_function
from .tensor_file import linear_layers

MAX_LOG_F = 12.0  # networks.MAX_LOG_F
# Share of directions drawn uniformly over the hemisphere: at grazing views the sampling decoder's pdf is
# thin where f is not, and f/pdf becomes heavy-tailed (a dark rim with rare fireflies); the share bounds it.
UNIFORM_SHARE = 0.2

_MLP = r"""
float sinh_approx(float x) { return x * sqrt(1.0 + x * x); }
float tanh_approx(float x) { return x / sqrt(1.0 + x * x); }

void decode(float z[6], vector wi, vector wo, output color f, output float T)
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

float lobe_pdf(float m[9], vector wi, vector wo)
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

vector lobe_sample(float m[9], vector wi, float u0, float u1, float u2)
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
void setup(float z[6], vector wi, output float m[9])
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

shader richmat_neural(
    vector latent_0 = 0, vector latent_1 = 0,
    color base_color = 0.8,
    float energy_scale = 1.0,
    string probe = "",
    float probe_rotation = 0.0,
    color world_color = 0.05,
    int samples = 8,
    int t_samples = 4,
    normal Normal = N,
    output closure color BSDF = 0)
{
    vector n, t, bt, wi;
    shading_point(Normal, I, n, t, bt, wi);
    float z[6];
    latent_vector(latent_0, latent_1, z);
    float m[9];
    setup(z, wi, m);
    color f, L, TL = 0, L_sum = 0;
    float T = 0, T_k;
    int n_t = max(t_samples, 2);
    for (int k = 0; k < n_t; k++) {  // negative seeds: the lobe's directions use 0, 1, 2, ...
        float u1 = hashnoise(P, -1 - 2 * k), r = sqrt(u1), phi = M_2PI * hashnoise(P, -2 - 2 * k);
        vector wo = vector(r * cos(phi), r * sin(phi), sqrt(max(1.0 - u1, 0.0)));
        decode(z, wi, wo, f, T_k);
        L = world_radiance(probe, probe_rotation, world_color, wo[0] * t + wo[1] * bt + wo[2] * n);
        T += T_k / n_t;
        TL += T_k * L / n_t;
        L_sum += L / n_t;
    }
    // Cycles lights the base with the mean T; the world light it gets is corrected by the covariance of
    // T and L over cosine-distributed wo (unbiased: the n/(n-1) of a sample covariance), so the world
    // part is c * integral T L cos / pi, as the torch renderer integrates it.
    BSDF = (T * base_color) * diffuse(n) + base_color * (TL - T * L_sum) * (n_t / (n_t - 1.0)) * emission();
    if (wi[2] > 0 && samples > 0) {
        color sum = 0;
        for (int k = 0; k < samples; k++) {
            float u0 = hashnoise(P, 3 * k), u1 = hashnoise(P, 3 * k + 1), u2 = hashnoise(P, 3 * k + 2);
            vector wo;
            if (u0 < UNIFORM_SHARE) {
                float r = sqrt(max(1.0 - u1 * u1, 0.0));
                wo = vector(r * cos(M_2PI * u2), r * sin(M_2PI * u2), u1);
            } else {
                wo = lobe_sample(m, wi, (u0 - UNIFORM_SHARE) / (1.0 - UNIFORM_SHARE), u1, u2);
            }
            float pdf = (1.0 - UNIFORM_SHARE) * lobe_pdf(m, wi, wo) + (wo[2] > 0 ? UNIFORM_SHARE / M_2PI : 0.0);
            if (pdf <= 0.0)
                continue;
            decode(z, wi, wo, f, T_k);
            sum += f * world_radiance(probe, probe_rotation, world_color, wo[0] * t + wo[1] * bt + wo[2] * n) / pdf;
        }
        BSDF += (energy_scale / samples) * sum * emission();
    }
}
"""


def source(tensors: dict[str, np.ndarray]) -> str:
    """The MLP kind's shader: decoder (16 -> 5) and sampling decoder (9 -> 9) in OSL."""
    decoder, sampler = linear_layers(tensors, "decoder.net"), linear_layers(tensors, "sampler.net")
    if decoder[0][0].shape[1] != 16 or decoder[-1][0].shape[0] != 5 or sampler[-1][0].shape[0] != 9:
        raise ValueError("the weights do not match the MLP decoder layout this shader implements "
                         "(decoder 16 -> 5, sampling decoder 9 -> 9)")
    return (defines(NET_INPUTS=16, MAX_LOG_F=MAX_LOG_F, UNIFORM_SHARE=UNIFORM_SHARE)
            + mlp_function("decoder_mlp", decoder) + mlp_function("sampler_mlp", sampler) + COMMON + _MLP)
