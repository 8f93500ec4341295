"""Directional albedo of the rough glass lobe (glass.py), tabulated once, for
Cycles' multiple-scattering compensation of its Glass and Principled
transmission (Multiscatter GGX, the default).

A rough dielectric interface of the single-scattering microfacet model
loses the light that meets a second microfacet: in the transport
convention of glass.py (no 1 / eta^2) a smooth interface passes on all it
receives, F reflected and 1 - F refracted, while a rough one passes E < 1
(at roughness 0.5 about 0.9 entering glass, less leaving it, and a rough
glass sphere's light crosses two interfaces and more). As Cycles, the lobe
is scaled by 1 / E(wo) at the viewing angle, which brings white rough glass
back to one; a tinted one (Principled transmission: its refraction tinted
by sqrt(Base Color)) by 1 + F_ms (1 - E) / E, with Kulla and Conty's
multiple-bounce Fresnel F_ms = T E_avg / (1 - T (1 - E_avg)) of the tint T,
darker, as Cycles does it.

E is tabulated over roughness, cos theta_o and the IOR, on Cycles' axis
sqrt(|eta - 1| / (eta + 1)), in one table for eta > 1 (entering) and one
for eta < 1 (leaving): each entry the mean over visible-normal samples h of
F(wo . h) G2 / G1 for the reflection and (1 - F) G2 / G1 for the
refraction, where each stays on its side. Read trilinearly; built on first
use (a glass lobe in the scene), in under a second.
"""

import functools

import numpy as np

from ..util.rows import gather, row_max, scatter
from .fresnel import fresnel_and_cos_t, ior_axis, ior_axis_coordinate
from .microfacet import ggx_lambda, ggx_sample_visible_normal

N_ROUGH = 16
N_COS = 16
N_ETA = 16
SAMPLES = 16          # per side of the stratified grid of h samples
ETA_FAR = 1e3         # the IOR at the axis' far end


def _etas(entering):
    """The table's IORs (fresnel.ior_axis), inverted leaving."""
    eta = ior_axis(N_ETA, ETA_FAR)
    eta[0] = 1.0 + 1e-4        # index-matched: nothing is lost
    return eta if entering else 1.0 / eta


def _albedo(wo, alpha, eta, u):
    """E of rows (wo, alpha, eta) from one h sample each (u (N, 2))."""
    h = ggx_sample_visible_normal(wo, alpha, u).astype(np.float64)
    o = wo.astype(np.float64)
    cos_o = np.sum(o * h, axis=1)
    F, cos_t = fresnel_and_cos_t(cos_o, eta)
    lam_o = ggx_lambda(o, alpha)
    g1 = 1.0 / (1.0 + lam_o)
    # Reflection 2 (wo.h) h - wo; refraction (wo.h / eta - cos_t) h - wo / eta.
    r = 2.0 * cos_o[:, None] * h - o
    t = (cos_o / eta - cos_t)[:, None] * h - o / eta[:, None]
    t /= np.maximum(np.linalg.norm(t, axis=1), 1e-12)[:, None]
    w_r = np.where(r[:, 2] > 0, 1.0 / (1.0 + lam_o + ggx_lambda(r, alpha)) / g1, 0.0)
    w_t = np.where((t[:, 2] < 0) & (F < 1), 1.0 / (1.0 + lam_o + ggx_lambda(t, alpha)) / g1, 0.0)
    return F * w_r + (1.0 - F) * w_t


@functools.lru_cache(maxsize=1)
def tables():
    """(entering, leaving), each (N_ROUGH, N_COS, N_ETA) float32."""
    cos = (np.arange(N_COS) + 0.5) / N_COS
    rough = np.linspace(0.0, 1.0, N_ROUGH)
    g = (np.arange(SAMPLES) + 0.5) / SAMPLES
    u = np.stack(np.meshgrid(g, g, indexing="ij"), -1).reshape(-1, 2)
    ns = len(u)
    out = []
    for entering in (True, False):
        etas = _etas(entering)
        tab = np.zeros((N_ROUGH, N_COS, N_ETA))
        # Rows: every (cos, eta, sample) of one roughness.
        mu = np.repeat(cos, N_ETA * ns)
        eta = np.tile(np.repeat(etas, ns), N_COS)
        uu = np.tile(u, (N_COS * N_ETA, 1)).astype(np.float32)
        wo = np.stack([np.sqrt(1 - mu * mu), np.zeros_like(mu), mu], axis=1).astype(np.float32)
        for i, rg in enumerate(rough):
            alpha = np.full(len(mu), max(rg * rg, 1e-3), np.float32)
            tab[i] = _albedo(wo, alpha, eta, uu).reshape(N_COS, N_ETA, ns).mean(axis=2)
        out.append(np.clip(tab, 1e-3, 1.0).astype(np.float32))
    return tuple(out)


def _read(table, rough, cos, z):
    """Trilinear read of a (N_ROUGH, N_COS, N_ETA) table at coordinates in [0, 1]."""
    coords = []
    for v, n, centred in ((rough, N_ROUGH, False), (cos, N_COS, True), (z, N_ETA, False)):
        x = np.asarray(v, np.float64) * (n if centred else n - 1) - (0.5 if centred else 0.0)
        x = np.clip(x, 0, n - 1)
        i0 = np.minimum(x.astype(np.int64), n - 2)
        coords.append((i0, x - i0))
    (y0, fy), (x0, fx), (z0, fz) = coords
    flat = table.reshape(-1)
    out = np.zeros(len(y0))
    for dy, wy in ((0, 1 - fy), (1, fy)):
        for dx, wx in ((0, 1 - fx), (1, fx)):
            for dz, wz in ((0, 1 - fz), (1, fz)):
                index = ((y0 + dy) * N_COS + (x0 + dx)) * N_ETA + (z0 + dz)
                out += np.take(flat, index) * (wy * wx * wz)
    return out.astype(np.float32)


def glass_albedo(rough, cos, eta, average=False):
    """(N,) E of glass lobes of roughness (N,) seen at cos theta_o (N,)
    across IOR ratios eta (N,) (the side opposite wo over wo's side); with
    ``average``, also (N,) its cosine-weighted hemispherical average E_avg."""
    eta = np.asarray(eta, np.float32)
    z = ior_axis_coordinate(eta, N_ETA) / np.float32(N_ETA - 1)
    entering, leaving = tables()
    e = np.where(eta >= 1, _read(entering, rough, cos, z), _read(leaving, rough, cos, z)).astype(np.float32)
    if not average:
        return e
    # 2 int E mu dmu by the midpoint rule over the table's cos axis: a table
    # of the averages read at cos theta_o = 0.5 (constant along that axis).
    avg_in, avg_out = _averages()
    half = np.full(len(e), 0.5, np.float32)
    e_avg = np.where(eta >= 1, _read(avg_in, rough, half, z), _read(avg_out, rough, half, z))
    return e, e_avg.astype(np.float32)


@functools.lru_cache(maxsize=1)
def _averages():
    """The tables' cosine-weighted averages over cos theta_o, spread along that axis."""
    mu = (np.arange(N_COS) + 0.5) / N_COS
    return tuple(np.repeat(2.0 * np.mean(t * mu[None, :, None], axis=1, keepdims=True), N_COS, axis=1)
                 .astype(np.float32) for t in tables())


def at_view(params, cos):
    """Scale the glass lobes of BSDFParams by 1 / E at cos theta_o (N,), in
    place: Cycles' multiple-scattering compensation. Only lobes that reflect
    (Glass, Principled transmission) take it; a Refraction BSDF alone is
    single-scattering in Cycles too. Needs params.eta as the ray meets the
    surface."""
    rows = np.nonzero((params.p_glass > 0) & (row_max(params.glass_r) > 0))[0]
    if len(rows) == 0:
        return
    e, e_avg = glass_albedo(np.sqrt(np.take(params.alpha_g, rows)), np.take(cos, rows),
                            np.take(params.eta, rows), average=True)
    glass_r, glass_t = gather(params.glass_r, rows), gather(params.glass_t, rows)
    # The refraction's tint: its weight over the reflection's (one for a
    # Glass BSDF, sqrt(Base Color) for the Principled's transmission).
    tint = np.clip(glass_t / np.maximum(glass_r, 1e-6), 0.0, 1.0)
    e_avg = e_avg[:, None]
    f_ms = tint * e_avg / np.maximum(1.0 - tint * (1.0 - e_avg), 1e-6)
    k = (1.0 + f_ms * ((1.0 - e) / e)[:, None]).astype(np.float32)
    scatter(params.glass_r, rows, glass_r * k)
    scatter(params.glass_t, rows, glass_t * k)
