"""Directional albedo of the GGX reflection lobe, tabulated once.

Two uses, both as Cycles does them with its precomputed tables:

- Layering: the Principled BSDF's diffuse base lies under its dielectric
  specular layer and receives what that layer does not reflect, 1 - E(wo),
  which grows toward grazing views (a constant 1 - f0 would gain energy there).
- Multiple scattering: a single-scattering GGX lobe loses the light that
  bounces between microfacets (up to a fifth at roughness 1); Cycles'
  multiscatter GGX puts it back. Here the lobe is scaled by
  1 + F_avg (1 - E) / E (the Kulla-Conty energy term with a Fresnel average).

With Schlick's Fresnel F = f0 (1 - m^5) + f90 m^5, m = 1 - cos(wo, h), the
albedo is linear in (f0, f90): E = f0 A + f90 B. A and B are tabulated over
(cos theta_o, roughness) by visible-normal sampling (each sample's weight is
G2 / G1) and read bilinearly. The tables are built on first use (about a
tenth of a second) and kept for the process.
"""

import functools

import numpy as np

from .microfacet import ggx_lambda, ggx_sample_visible_normal

N_COS = 32
N_ROUGH = 32
N_SAMPLES = 1024


@functools.lru_cache(maxsize=1)
def tables():
    """(A, B) as (N_ROUGH, N_COS) float32 over roughness and cos theta_o in [0, 1]."""
    cos = (np.arange(N_COS, dtype=np.float64) + 0.5) / N_COS
    rough = np.linspace(0.0, 1.0, N_ROUGH)
    alpha = np.maximum(rough ** 2, 1e-3)
    # Stratified samples on a 32 x 32 grid, the same for every entry.
    k = int(np.sqrt(N_SAMPLES))
    g = (np.arange(k) + 0.5) / k
    u = np.stack(np.meshgrid(g, g, indexing="ij"), -1).reshape(-1, 2).astype(np.float32)
    ns = len(u)
    a_tab = np.zeros((N_ROUGH, N_COS))
    b_tab = np.zeros((N_ROUGH, N_COS))
    for i, al in enumerate(alpha):
        mu = np.repeat(cos, ns)
        wo = np.stack([np.sqrt(1 - mu * mu), np.zeros_like(mu), mu], axis=1).astype(np.float32)
        al_rows = np.full(len(mu), al, np.float32)
        h = ggx_sample_visible_normal(wo, al_rows, np.tile(u, (N_COS, 1)))
        wo_h = np.sum(wo * h, axis=1)
        wi = 2 * wo_h[:, None] * h - wo
        up = wi[:, 2] > 0
        g1 = 1.0 / (1.0 + ggx_lambda(wo, al_rows))
        g2 = 1.0 / (1.0 + ggx_lambda(wo, al_rows) + ggx_lambda(wi, al_rows))
        w = np.where(up, g2 / g1, 0.0)
        m5 = np.clip(1.0 - wo_h, 0.0, 1.0) ** 5
        a_tab[i] = (w * (1 - m5)).reshape(N_COS, ns).mean(axis=1)
        b_tab[i] = (w * m5).reshape(N_COS, ns).mean(axis=1)
    return a_tab.astype(np.float32), b_tab.astype(np.float32)


def albedo_terms(rough, cos):
    """(A, B) at roughness and cos theta_o arrays: E = f0 A + f90 B (bilinear,
    the four taps' indices and weights shared by both tables)."""
    a_tab, b_tab = tables()
    x = np.clip(np.asarray(cos, np.float32) * N_COS - 0.5, 0, N_COS - 1)
    y = np.clip(np.asarray(rough, np.float32) * (N_ROUGH - 1), 0, N_ROUGH - 1)
    x0 = np.minimum(x.astype(np.int64), N_COS - 2)
    y0 = np.minimum(y.astype(np.int64), N_ROUGH - 2)
    fx, fy = x - x0, y - y0     # float64, as are the weights
    gx, gy = 1 - fx, 1 - fy
    i00 = y0 * N_COS
    i00 += x0
    taps = ((i00, gx * gy), (i00 + 1, fx * gy), (i00 + N_COS, gx * fy), (i00 + (N_COS + 1), fx * fy))

    def read(table):
        # ((t00 w00 + t01 w01) + t10 w10) + t11 w11, summed in place.
        flat = table.reshape(-1)
        out = tmp = None
        for index, w in taps:
            if out is None:
                out = np.multiply(np.take(flat, index), w)
                tmp = np.empty_like(out)
            else:
                out += np.multiply(np.take(flat, index), w, out=tmp)
        return out.astype(np.float32)

    return read(a_tab), read(b_tab)


@functools.lru_cache(maxsize=1)
def _dielectric_f90_table():
    """f90 giving Schlick's Fresnel the hemispherical average of the exact
    dielectric Fresnel with that normal reflectance, over f0 in [0, 1]."""
    f0 = np.linspace(0.0, 1.0, 257)
    eta = (1 + np.sqrt(f0)) / np.maximum(1 - np.sqrt(f0), 1e-6)
    mu = (np.arange(2048) + 0.5) / 2048
    c = mu[None, :]
    g2 = eta[:, None] ** 2 - 1 + c * c
    g = np.sqrt(np.maximum(g2, 0))
    a = (g - c) / (g + c)
    b = (c * (g + c) - 1) / (c * (g - c) + 1)
    fresnel = np.where(g2 > 0, 0.5 * a * a * (1 + b * b), 1.0)
    f_avg = 2 * (fresnel * c).mean(axis=1)
    f90 = np.clip(f0 + 21 * (f_avg - f0), 0.0, 1.0)
    f90[0] = 0.0
    f90 = np.maximum.accumulate(f90)        # 1 once it got there (high IORs reach 1 too)
    return f0.astype(np.float32), f90.astype(np.float32)


def dielectric_f90(f0):
    """Schlick's grazing reflectance for a dielectric of normal reflectance f0:
    1 for ordinary IORs, falling to 0 as the IOR approaches 1 (Specular IOR
    Level 0 makes the Principled BSDF's dielectric layer vanish, as in Cycles)."""
    grid, table = _dielectric_f90_table()
    return np.interp(np.asarray(f0, np.float32), grid, table).astype(np.float32)
