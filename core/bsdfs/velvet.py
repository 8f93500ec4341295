"""Cycles' Ashikhmin velvet: the Sheen BSDF node's Ashikhmin distribution
(Cycles' Velvet BSDF before 4.0). Sampled by the diffuse lobe's cosine
samples (bsdf.py), so only its f is here."""

import numpy as np

from ..sampling.warps import INV_PI
from ..util.rows import divide, gather, row_max, scale, scatter_add
from ..util.vectors import dot


def velvet_f(wo, wi, sigma):
    """(N,) Cycles' Ashikhmin velvet (bsdf_ashikhmin_velvet.h; Ashikhmin,
    Premoze and Shirley 2000): f = D G / (4 cos_o cos_i) without the cosine,
    D = exp(-cot^2(h) / sigma^2) / (pi sigma^2 sin^4(h)) an inverted
    Gaussian of the half vector h's angle to the normal, G = min(1,
    2 cos(h) cos_o / (h . wo), 2 cos(h) cos_i / (h . wo)); sigma at least
    0.01. Zero unless both directions lie above the surface."""
    cos_o, cos_i = wo[:, 2], wi[:, 2]
    h = wo + wi
    h = divide(h, np.maximum(np.sqrt(dot(h, h)), 1e-12).astype(h.dtype, copy=False))
    cos_nh = h[:, 2]
    cos_hi = np.abs(dot(wo, h))
    ok = (cos_o > 0) & (cos_i > 0) & (np.abs(cos_nh) < 1.0 - 1e-5) & (cos_hi > 1e-5)
    ratio = np.maximum(cos_nh / np.where(ok, cos_hi, 1.0), 1e-5)
    g = np.minimum(1.0, np.minimum(2.0 * ratio * cos_o, 2.0 * ratio * cos_i))
    sin2 = np.where(ok, 1.0 - cos_nh * cos_nh, 1.0)
    inv_s2 = 1.0 / np.maximum(np.asarray(sigma, np.float64), 0.01) ** 2
    d = np.exp(-(cos_nh * cos_nh / sin2) * inv_s2) * inv_s2 * INV_PI / (sin2 * sin2)
    f = 0.25 * d * g / np.maximum(cos_o * cos_i, 1e-12)
    return np.where(ok, f, 0.0).astype(np.float32)


def add_velvet(params, wo, wi, f):
    """Add the velvet lobe's f into f (in place), on the rows that have one."""
    rows = np.nonzero(row_max(params.velvet) > 0)[0]
    if len(rows):
        v = velvet_f(gather(wo, rows), gather(wi, rows), np.take(params.velvet_sigma, rows))
        scatter_add(f, rows, scale(gather(params.velvet, rows), v))
