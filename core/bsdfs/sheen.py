"""The sheen lobe (the Principled BSDF's, and the Sheen BSDF node's
Microfiber): a linearly transformed cosine (LTC).

Cycles' Principled sheen (since 4.0) follows Zeltner, Burley and Chiang 2022,
"Practical Multiple-Scattering Sheen Using Linearly Transformed Cosines": a
thin layer of fibre-like microflakes (SGGX, fibres along the normal, cross
section roughness^2) above the rest of the material. What the layer reflects
is, for a viewing direction wo at cos theta_o,

    f(wo, wi) cos theta_i = R(cos theta_o, r) D(wi)

with R the layer's directional albedo and D a linearly transformed cosine:
in the frame whose x axis is wo's direction along the surface, D is the
cosine distribution pulled through the inverse matrix [[a, 0, b], [0, a, 0],
[0, 0, 1]]. What the layer does not reflect, 1 - R x weight x tint (the
largest channel, one factor for all), reaches the layers below.

R, a and b are our own tabulation (``sheen_ltc.npy``, 32 x 32 over roughness
and cos theta_o, written by ``tools/fit_sheen.py``): random walks through the
fibre layer for R, and a maximum-likelihood fit of (a, b) to the directions
the walks leave by (tests/core/bsdfs/test_sheen.py checks R against fresh walks).

D is a normalised density on the upper hemisphere that can be sampled
exactly (a cosine sample pushed through the matrix), so the lobe's pdf is D
itself and a sample's weight is R x colour: at most the colour, never NaN
(the table is read at cos theta_o clamped to [0, 1]).
"""

import functools
import pathlib

import numpy as np

from ..util.rows import gather, row_max, scale, scatter_add
from ..sampling.warps import INV_PI
from ..util.vectors import luminance

TABLE = pathlib.Path(__file__).with_name("sheen_ltc.npy")


@functools.lru_cache(maxsize=1)
def table():
    """(32, 32, 3) float32: (a, b, R) over roughness (rows) and cos theta_o
    (columns), both at i / 31."""
    return np.load(TABLE, allow_pickle=False).astype(np.float32)


def ltc_terms(rough, cos):
    """(a, b, R) at roughness and cos theta_o arrays (bilinear)."""
    t = table()
    n_r, n_c = t.shape[:2]
    y = np.clip(np.asarray(rough, np.float32), 0, 1) * (n_r - 1)
    x = np.clip(np.asarray(cos, np.float32), 0, 1) * (n_c - 1)
    y0 = np.minimum(y.astype(np.int64), n_r - 2)
    x0 = np.minimum(x.astype(np.int64), n_c - 2)
    fy, fx = (y - y0).astype(np.float32), (x - x0).astype(np.float32)
    i = y0 * n_c + x0
    w00, w01, w10, w11 = (1 - fx) * (1 - fy), fx * (1 - fy), (1 - fx) * fy, fx * fy

    def read(k):
        flat = np.ascontiguousarray(t[..., k]).reshape(-1)
        return (np.take(flat, i) * w00 + np.take(flat, i + 1) * w01
                + np.take(flat, i + n_c) * w10 + np.take(flat, i + n_c + 1) * w11).astype(np.float32)

    return read(0), read(1), read(2)


def _frame(wo):
    """(cos, sin) of wo's azimuth: the LTC frame's x axis along the surface
    (x itself where wo is the normal)."""
    r = np.sqrt(wo[:, 0] * wo[:, 0] + wo[:, 1] * wo[:, 1])
    flat = r < 1e-7
    safe = np.where(flat, 1, r)
    return np.where(flat, 1, wo[:, 0] / safe), np.where(flat, 0, wo[:, 1] / safe)


def ltc_pdf(wo, wi, a, b):
    """(N,) density D(wi) of the lobe seen from wo (solid angle); zero below
    the surface. D = z a^2 / (pi q^2), q = |M^-1 w|^2 in the LTC frame."""
    c, s = _frame(wo)
    x = wi[:, 0] * c + wi[:, 1] * s
    y = wi[:, 1] * c - wi[:, 0] * s
    z = wi[:, 2]
    u = a * x + b * z
    q = u * u + (a * y) ** 2 + z * z
    d = np.maximum(z, 0) * a * a * INV_PI / np.maximum(q * q, 1e-30)
    return np.where((z > 0) & (wo[:, 2] > 0), d, 0).astype(np.float32)


def ltc_sample(wo, a, b, u):
    """(N, 3) directions distributed as D: a cosine sample mapped by M."""
    r = np.sqrt(u[:, 0])
    phi = 2 * np.pi * u[:, 1]
    x0, y0 = r * np.cos(phi), r * np.sin(phi)
    z0 = np.sqrt(np.maximum(1 - u[:, 0], 0))
    a_safe = np.maximum(a, 1e-6)
    x, y, z = (x0 - b * z0) / a_safe, y0 / a_safe, z0
    n = np.sqrt(x * x + y * y + z * z)
    x, y, z = x / n, y / n, z / n
    c, s = _frame(wo)
    return np.stack([x * c - y * s, x * s + y * c, z], axis=1).astype(np.float32)


# --- the lobe in core/bsdfs/bsdf.py's BSDFParams ---------------------------------------

def at_view(params, cos):
    """The sheen layer seen from wo: its albedo R x colour becomes the lobe's
    weight, every lobe below keeps 1 - its largest channel (Cycles' layering
    of Principled v2; a Sheen BSDF node's share, ``sheen_free``, lies over
    nothing), and the sheen gets its share of the lobe choice."""
    a, b, r = ltc_terms(params.sheen_rough, cos)
    albedo = scale(params.sheen, r).astype(np.float32)
    layer = albedo if params.sheen_free is None else scale(albedo, 1.0 - params.sheen_free)
    keep = np.clip(1.0 - row_max(layer), 0.0, 1.0).astype(np.float32)
    rest = luminance(params.diffuse) + luminance(params.f0)
    if params.velvet is not None:
        rest = rest + luminance(params.velvet)
    for name in ("diffuse", "f0", "f90", "layered", "glass_r", "glass_t", "velvet"):
        if getattr(params, name) is not None:
            setattr(params, name, scale(getattr(params, name), keep).astype(np.float32))
    if params.has_glass:
        rest = rest + np.maximum(luminance(params.glass_r), luminance(params.glass_t))
    w = luminance(albedo)
    total = w + keep * rest
    p_sheen = np.where(total > 0, w / np.where(total > 0, total, 1), 0.0).astype(np.float32)
    params.p_spec = (params.p_spec * (1 - p_sheen)).astype(np.float32)
    if params.has_glass:
        params.p_glass = (params.p_glass * (1 - p_sheen)).astype(np.float32)
    params.sheen, params.sheen_a, params.sheen_b, params.p_sheen = albedo, a, b, p_sheen


def add_lobe(params, wo, wi, p_sheen, f, p):
    """Add the sheen lobe's f (R x colour x D / cos theta_i) and p_sheen x D
    into f and p (in place), on the rows that have one."""
    rows = np.nonzero(p_sheen > 0)[0]
    if len(rows) == 0:
        return
    i = gather(wi, rows)
    d = ltc_pdf(gather(wo, rows), i, np.take(params.sheen_a, rows), np.take(params.sheen_b, rows))
    if f is not None:
        scatter_add(f, rows, scale(gather(params.sheen, rows), d / np.maximum(i[:, 2], 1e-7)))
    if p is not None:
        p[rows] = np.take(p, rows) + np.take(p_sheen, rows) * d
