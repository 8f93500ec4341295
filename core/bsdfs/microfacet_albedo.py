"""Directional albedo of the GGX reflection lobe, tabulated once.

Two uses, both as Cycles does them with its precomputed tables:

- Layering: the Principled BSDF's diffuse base lies under its dielectric
  specular layer and receives what that layer does not reflect, 1 - E(wo),
  which grows toward grazing views (a constant 1 - f0 would gain energy there).
- Multiple scattering: a single-scattering GGX lobe loses the light that
  bounces between microfacets (up to a fifth at roughness 1); Cycles'
  multiscatter GGX puts it back. Here, as there, the lobe is scaled by
  1 + F_ms (1 - E) / E, with F_ms = F_avg E_avg / (1 - F_avg (1 - E_avg))
  the Fresnel of light that bounced (Kulla and Conty; F_avg the Fresnel's
  hemispherical average, E_avg the albedo's).

The lobe's Fresnel (fresnel.py) is F = f0 + (f90 - f0 - x) (1 - cos)^5 +
x s_eta(cos): Schlick's, with a share x rising along the exact dielectric
curve s_eta instead. The albedo is linear in those weights: E = f0 A +
(f90 - x) B + x R_eta, with A and B tabulated over (cos theta_o, roughness)
and R over the IOR as well, on Cycles' axis sqrt(|eta - 1| / (eta + 1)),
which takes an IOR and its inverse alike. Each table entry is a mean over
visible-normal samples (each weighted G2 / G1); reads are bilinear, and
trilinear for R. The tables are built on first use (about a fifth of a second)
and kept for the process.
"""

import functools

import numpy as np

from .fresnel import dielectric_rise, ior_axis, ior_axis_coordinate
from .microfacet import ggx_lambda, ggx_sample_visible_normal

N_COS = 32
N_ROUGH = 32
N_SAMPLES = 1024
N_ETA = 24
N_BINS = 4096     # cos(wo, h) bins of the rise table


@functools.lru_cache(maxsize=1)
def tables():
    """(A, B) as (N_ROUGH, N_COS) and R as (N_ROUGH, N_COS, N_ETA) float32
    over roughness, cos theta_o in [0, 1] and the IOR (fresnel.ior_axis)."""
    cos = (np.arange(N_COS, dtype=np.float64) + 0.5) / N_COS
    rough = np.linspace(0.0, 1.0, N_ROUGH)
    alpha = np.maximum(rough ** 2, 1e-3)
    etas = ior_axis(N_ETA)
    grid = (np.arange(N_BINS) + 0.5) / N_BINS
    rise_grid = dielectric_rise(np.broadcast_to(grid[:, None], (N_BINS, N_ETA)), etas[None, :]).astype(np.float64)
    # Stratified samples on a 32 x 32 grid, the same for every entry.
    k = int(np.sqrt(N_SAMPLES))
    g = (np.arange(k) + 0.5) / k
    u = np.stack(np.meshgrid(g, g, indexing="ij"), -1).reshape(-1, 2).astype(np.float32)
    ns = len(u)
    a_tab = np.zeros((N_ROUGH, N_COS))
    b_tab = np.zeros((N_ROUGH, N_COS))
    r_tab = np.zeros((N_ROUGH, N_COS, N_ETA))
    mu = np.repeat(cos, ns)
    wo = np.stack([np.sqrt(1 - mu * mu), np.zeros_like(mu), mu], axis=1).astype(np.float32)
    for i, al in enumerate(alpha):
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
        # The rise at each sample through a fine grid of cos(wo, h): the
        # samples' weights binned per entry, times the curves on the grid.
        bins = np.minimum((wo_h * N_BINS).astype(np.int64), N_BINS - 1) + np.repeat(np.arange(N_COS), ns) * N_BINS
        binned = np.bincount(bins, weights=w, minlength=N_COS * N_BINS).reshape(N_COS, N_BINS)
        r_tab[i] = binned @ rise_grid / ns
    return a_tab.astype(np.float32), b_tab.astype(np.float32), r_tab.astype(np.float32)


@functools.lru_cache(maxsize=1)
def _rise_average_table():
    """2 int s_eta(mu) mu dmu over the rise table's IOR axis: the exact
    curve's hemispherical (cosine-weighted) average share."""
    mu = (np.arange(4096) + 0.5) / 4096
    etas = ior_axis(N_ETA)
    rise = dielectric_rise(np.broadcast_to(mu, (N_ETA, len(mu))), etas[:, None])
    return (2.0 * (rise * mu).mean(axis=1)).astype(np.float32)


@functools.lru_cache(maxsize=1)
def _albedo_average_table():
    """2 int E(mu) mu dmu of the lobe with F = 1 over the roughness axis."""
    a_tab, b_tab, _ = tables()
    mu = (np.arange(N_COS) + 0.5) / N_COS
    return (2.0 * np.mean((a_tab + b_tab) * mu[None, :], axis=1)).astype(np.float32)


def albedo_average(rough):
    """(N,) E_avg: the cosine-weighted hemispherical average of the GGX
    lobe's albedo with F = 1 at roughness (N,)."""
    y = np.asarray(rough, np.float32) * np.float32(N_ROUGH - 1)
    return np.interp(y, np.arange(N_ROUGH), _albedo_average_table()).astype(np.float32)


def multiple_bounce_fresnel(f_avg, e_avg):
    """Kulla and Conty's Fresnel of light that bounced between microfacets,
    F_avg E_avg / (1 - F_avg (1 - E_avg)), with one F_avg cancelled, as
    Cycles scales its lost energy: f_avg (N, 3) or (N,), e_avg (N,)."""
    e = e_avg[:, None] if np.ndim(f_avg) == 2 else e_avg
    return f_avg * e / np.maximum(1.0 - f_avg * (1.0 - e), 1e-6)


def rise_average(eta):
    """(N,) cosine-weighted hemispherical average of dielectric_rise at IORs eta (N,)."""
    return np.interp(ior_axis_coordinate(eta, N_ETA), np.arange(N_ETA), _rise_average_table()).astype(np.float32)


def albedo_terms(rough, cos, eta=None):
    """(A, B) at roughness and cos theta_o arrays: E = f0 A + f90 B for
    Schlick's Fresnel (bilinear, the four taps' indices and weights shared by
    both tables); with IORs eta, (A, B, R), R the albedo of the exact curve's
    rise (trilinear)."""
    a_tab, b_tab, r_tab = tables()
    x = np.clip(np.asarray(cos, np.float32) * N_COS - 0.5, 0, N_COS - 1)
    y = np.clip(np.asarray(rough, np.float32) * (N_ROUGH - 1), 0, N_ROUGH - 1)
    x0 = np.minimum(x.astype(np.int64), N_COS - 2)
    y0 = np.minimum(y.astype(np.int64), N_ROUGH - 2)
    fx, fy = x - x0, y - y0     # float64, as are the weights
    gx, gy = 1 - fx, 1 - fy
    i00 = y0 * N_COS
    i00 += x0
    taps = ((i00, gx * gy), (i00 + 1, fx * gy), (i00 + N_COS, gx * fy), (i00 + (N_COS + 1), fx * fy))

    def read(table, taps):
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

    if eta is None:
        return read(a_tab, taps), read(b_tab, taps)
    z = ior_axis_coordinate(eta, N_ETA)
    z0 = np.minimum(z.astype(np.int64), N_ETA - 2)
    fz = z - z0
    gz = 1 - fz
    deep = tuple((index * N_ETA + z0 + k, w * wz) for index, w in taps for k, wz in ((0, gz), (1, fz)))
    return read(a_tab, taps), read(b_tab, taps), read(r_tab, deep)
