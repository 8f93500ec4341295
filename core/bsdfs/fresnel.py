"""Fresnel terms: the exact dielectric reflectance, Schlick's approximation,
and the two blended as Cycles' Principled BSDF blends them.

Cycles' Principled BSDF reflects with its dielectric specular layer by the
exact Fresnel curve of the layer's IOR, remapped to the layer's normal and
grazing reflectance (a negative exponent in its generalized Schlick
Fresnel): F = f0 + (f90 - f0) s, s = (F_real(cos) - F_real(1)) / (1 -
F_real(1)). Its metals and the Glossy BSDF keep Schlick's s = (1 - cos)^5.
``dielectric_rise`` is that s; a lobe mixing both (a half-metallic
Principled) is linear in the two shares.
"""

import numpy as np

from ..util.rows import scale

# The IOR the Principled BSDF's layer takes at a normal reflectance of one:
# a mirror. Large but finite, so the rise stays defined (it is nearly zero).
ETA_MAX = np.float32(1e4)


def fresnel_and_cos_t(cos_i, eta):
    """Exact unpolarised Fresnel reflectance of a dielectric interface, in
    float64: (F, cos_t) for cos_i (N,) between the incident direction and the
    interface normal (its sign is ignored) and eta (N,), the IOR of the
    transmitted side over the incident side. Total internal reflection
    (sin_t >= 1) gives F = 1 and cos_t = 0."""
    c = np.abs(np.asarray(cos_i, np.float64))
    eta = np.asarray(eta, np.float64)
    sin_t2 = (1.0 - c * c) / (eta * eta)
    tir = sin_t2 >= 1.0
    cos_t = np.sqrt(np.maximum(1.0 - sin_t2, 0.0))
    # Both denominators are positive unless c = cos_t = 0, which is total internal reflection.
    with np.errstate(invalid="ignore", divide="ignore"):
        rs = (c - eta * cos_t) / (c + eta * cos_t)
        rp = (eta * c - cos_t) / (eta * c + cos_t)
        F = 0.5 * (rs * rs + rp * rp)
    return np.where(tir | ~np.isfinite(F), 1.0, F), np.where(tir, 0.0, cos_t)


def fresnel_dielectric(cos_i, eta):
    """fresnel_and_cos_t as float32: (F, cos_t)."""
    F, cos_t = fresnel_and_cos_t(cos_i, eta)
    return F.astype(np.float32), cos_t.astype(np.float32)


def schlick(f0, cos, f90=None):
    """Schlick's Fresnel with normal reflectance f0 (N, 3) and grazing f90
    (N, 3; None: white) at cos (N,)."""
    m = np.clip(1.0 - cos, 0.0, 1.0)
    return f0 + scale((1.0 if f90 is None else f90) - f0, m ** 5)


def dielectric_rise(cos, eta):
    """(N,) float32: how far the exact Fresnel curve of IOR eta (N,) has
    risen from its normal reflectance toward one at cos (N,), in [0, 1]:
    (F(cos) - F(1)) / (1 - F(1)). eta below one reflects totally beyond its
    critical angle, as Cycles' Principled BSDF with an IOR below one.

    In float32, by the form of Cycles' fresnel_dielectric_cos, whose
    denominators stay positive outside total internal reflection."""
    c = np.clip(np.asarray(cos, np.float32), 0.0, 1.0)
    eta = np.clip(np.asarray(eta, np.float32), 1.0 / ETA_MAX, ETA_MAX)
    g2 = eta * eta - 1.0 + c * c
    inside = g2 > 0
    g = np.sqrt(np.where(inside, g2, 1.0))
    a = (g - c) / (g + c)
    b = (c * (g + c) - 1.0) / (c * (g - c) + 1.0)
    f = np.where(inside, 0.5 * a * a * (1.0 + b * b), 1.0)
    r0 = ((eta - 1.0) / (eta + 1.0)) ** 2
    return np.clip((f - r0) / np.maximum(1.0 - r0, 1e-7), 0.0, 1.0).astype(np.float32)


def ior_from_f0(f0, below_one=False):
    """The IOR whose normal reflectance is f0, or its inverse (below_one):
    the same f0 seen from the denser side. As Cycles' ior_from_F0, f0 is
    clamped to 0.99 (an IOR of 199)."""
    r = np.sqrt(np.clip(np.asarray(f0, np.float64), 0.0, 0.99))
    eta = (1.0 + r) / (1.0 - r)
    return np.where(below_one, 1.0 / eta, eta).astype(np.float32)


def ior_axis(n, eta_max=ETA_MAX):
    """n IORs evenly spread over z = sqrt(|eta - 1| / (eta + 1)) in [0, 1],
    the axis of Cycles' tables over the IOR (z^4 is the normal reflectance),
    from 1 to at most eta_max."""
    x = np.linspace(0.0, 1.0, n) ** 2
    return np.minimum((1 + x) / np.maximum(1 - x, 1.0 / eta_max), eta_max)


def ior_axis_coordinate(eta, n):
    """(N,) coordinate in [0, n - 1] of IORs eta (N,) on an ior_axis of n
    points; an IOR and its inverse fall alike."""
    eta = np.clip(np.asarray(eta, np.float32), 1.0 / ETA_MAX, ETA_MAX)
    return np.sqrt(np.abs(eta - 1) / (eta + 1)) * np.float32(n - 1)
