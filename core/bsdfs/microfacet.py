"""The GGX microfacet distribution (Trowbridge-Reitz): what the BSDF lobes
built on microfacets share (bsdf.py, glass.py, the albedo tables of
microfacet_albedo.py). Their Fresnel terms are in fresnel.py."""

import numpy as np


ALPHA_MIN = np.float32(1e-3)


# --- GGX ------------------------------------------------------------------
#
# Per-row (N, 3) work is written column by column (core/util/rows.py explains why):
# no np.cross, np.linalg.norm(axis=1), ``a * s[:, None]`` or np.where on rows.

def ggx_d(h, alpha):
    # cos^2 (a2 - 1) + 1 written as sin^2 + a2 cos^2, with sin^2 from the tangential
    # components: in float32 the other form cancels catastrophically for sharp lobes.
    a2 = np.asarray(alpha, np.float64) ** 2
    c2 = np.asarray(h[:, 2], np.float64) ** 2
    den = (np.asarray(h[:, 0], np.float64) ** 2 + np.asarray(h[:, 1], np.float64) ** 2) + a2 * c2
    return np.where(h[:, 2] > 0, a2 / (np.pi * den * den), 0.0)


def ggx_lambda(w, alpha):
    z2 = np.maximum(w[:, 2] * w[:, 2], 1e-12)
    t2 = np.maximum(1.0 - z2, 0.0) / z2
    return 0.5 * (np.sqrt(1.0 + alpha * alpha * t2) - 1.0)


def ggx_g1(w, alpha):
    return 1.0 / (1.0 + ggx_lambda(w, alpha))


def _length(x, y, z):
    """sqrt(x^2 + y^2 + z^2) of columns, summed in np.linalg.norm's order."""
    return np.sqrt(x * x + y * y + z * z)


def ggx_sample_visible_normal(wo, alpha, u):
    """Heitz 2018: a microfacet normal distributed as D_wo (visible normals)."""
    vx, vy, vz = alpha * wo[:, 0], alpha * wo[:, 1], wo[:, 2]
    n = _length(vx, vy, vz)
    vx, vy, vz = vx / n, vy / n, vz / n
    lensq = vx ** 2 + vy ** 2
    flat = ~(lensq > 0)                 # view along the normal: t1 = (1, 0, 0)
    inv = 1.0 / np.sqrt(np.where(flat, 1, lensq))
    t1x, t1y = -vy * inv, vx * inv      # t1 = (t1x, t1y, 0)
    if flat.any():
        t1x[flat], t1y[flat] = 1, 0
    # t2 = vh x t1 with t1's zero z.
    t2x, t2y, t2z = -(vz * t1y), vz * t1x, vx * t1y - vy * t1x
    r = np.sqrt(u[:, 0])
    phi = 2.0 * np.pi * u[:, 1]
    p1 = r * np.cos(phi)
    p2 = r * np.sin(phi)
    s = 0.5 * (1.0 + vz)
    p2 = (1.0 - s) * np.sqrt(np.maximum(0.0, 1.0 - p1 * p1)) + s * p2
    pz = np.sqrt(np.maximum(0.0, 1.0 - p1 * p1 - p2 * p2))
    # nh = p1 t1 + p2 t2 + pz vh, then stretched back: ne = (alpha nh_x, alpha nh_y, nh_z).
    ex = alpha * ((p1 * t1x + p2 * t2x) + pz * vx)
    ey = alpha * ((p1 * t1y + p2 * t2y) + pz * vy)
    ez = np.maximum(p2 * t2z + pz * vz, 1e-6)
    n = _length(ex, ey, ez)
    return np.stack([ex / n, ey / n, ez / n], axis=1).astype(np.float32)
