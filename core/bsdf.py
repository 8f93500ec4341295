"""The Principled BSDF subset: Lambert diffuse plus a GGX microfacet specular lobe.

All directions are in the local shading frame (z = shading normal). ``eval``
returns f (without the cosine), ``pdf`` the solid-angle density of ``sample``,
and ``sample`` draws the specular lobe by visible normals (Heitz 2018) or the
diffuse lobe by cosine-weighted hemisphere sampling.

A Diffuse BSDF node maps to specular = 0 and metallic = 0: pure Lambert, as in
Cycles. A Glossy BSDF node maps to metallic = 1: pure GGX with Schlick Fresnel.
"""

from dataclasses import dataclass

import numpy as np

from .sampling import (INV_PI, cosine_hemisphere_pdf, luminance,
                       square_to_cosine_hemisphere)

ALPHA_MIN = np.float32(1e-3)


@dataclass
class BSDFParams:
    diffuse: np.ndarray     # (N, 3) Lambert albedo
    f0: np.ndarray          # (N, 3) specular reflectance at normal incidence
    alpha: np.ndarray       # (N,) GGX roughness (roughness squared)
    p_spec: np.ndarray      # (N,) probability of sampling the specular lobe

    def subset(self, index):
        return BSDFParams(self.diffuse[index], self.f0[index], self.alpha[index], self.p_spec[index])


def bsdf_params(materials, material_ids):
    """Per-hit BSDF parameters from the material table."""
    base = materials.base_color[material_ids]
    metallic = np.clip(materials.metallic[material_ids], 0, 1)[:, None]
    rough = np.clip(materials.roughness[material_ids], 0, 1)
    ior = materials.ior[material_ids]
    level = np.maximum(materials.specular[material_ids], 0)
    f0_dielectric = np.minimum(((ior - 1) / (ior + 1)) ** 2 * 2.0 * level, 1.0)[:, None]
    f0 = (1 - metallic) * f0_dielectric + metallic * base
    diffuse = (1 - metallic) * (1 - f0_dielectric) * base
    ws = luminance(f0)
    wd = luminance(diffuse)
    total = ws + wd
    p_spec = np.where(total > 0, ws / np.where(total > 0, total, 1), 0.0)
    p_spec = np.where((ws > 0) & (wd > 0), np.clip(p_spec, 0.1, 0.9), p_spec)
    alpha = np.maximum(rough * rough, ALPHA_MIN)
    return BSDFParams(diffuse.astype(np.float32), f0.astype(np.float32),
                      alpha.astype(np.float32), p_spec.astype(np.float32))


# --- GGX ------------------------------------------------------------------

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


def ggx_sample_visible_normal(wo, alpha, u):
    """Heitz 2018: a microfacet normal distributed as D_wo (visible normals)."""
    vh = np.stack([alpha * wo[:, 0], alpha * wo[:, 1], wo[:, 2]], axis=1)
    vh /= np.linalg.norm(vh, axis=1, keepdims=True)
    lensq = vh[:, 0] ** 2 + vh[:, 1] ** 2
    inv = np.where(lensq > 0, 1.0 / np.sqrt(np.where(lensq > 0, lensq, 1)), 0.0)
    t1 = np.where((lensq > 0)[:, None],
                  np.stack([-vh[:, 1] * inv, vh[:, 0] * inv, np.zeros_like(inv)], axis=1),
                  np.float32([1, 0, 0]))
    t2 = np.cross(vh, t1)
    r = np.sqrt(u[:, 0])
    phi = 2.0 * np.pi * u[:, 1]
    p1 = r * np.cos(phi)
    p2 = r * np.sin(phi)
    s = 0.5 * (1.0 + vh[:, 2])
    p2 = (1.0 - s) * np.sqrt(np.maximum(0.0, 1.0 - p1 * p1)) + s * p2
    pz = np.sqrt(np.maximum(0.0, 1.0 - p1 * p1 - p2 * p2))
    nh = p1[:, None] * t1 + p2[:, None] * t2 + pz[:, None] * vh
    ne = np.stack([alpha * nh[:, 0], alpha * nh[:, 1], np.maximum(nh[:, 2], 1e-6)], axis=1)
    return (ne / np.linalg.norm(ne, axis=1, keepdims=True)).astype(np.float32)


def schlick(f0, cos):
    m = np.clip(1.0 - cos, 0.0, 1.0)[:, None]
    return f0 + (1.0 - f0) * (m ** 5)


def _half(wo, wi):
    h = wo + wi
    n = np.linalg.norm(h, axis=1, keepdims=True)
    return h / np.where(n > 0, n, 1)


def _spec_pdf(wo, h, alpha):
    return ggx_g1(wo, alpha) * ggx_d(h, alpha) / (4.0 * np.maximum(wo[:, 2], 1e-7))


# --- BSDF interface ---------------------------------------------------------

def evaluate(params, wo, wi):
    """f(wo, wi) as (N, 3). The diffuse lobe needs only wi above the shading
    normal (as Cycles: bent smooth-shaded normals must not blacken surfaces);
    the specular lobe needs both directions above it."""
    f = np.where((wi[:, 2] > 0)[:, None], params.diffuse * INV_PI, 0.0).astype(np.float32)
    rows = np.nonzero((params.p_spec > 0) & (wo[:, 2] > 0) & (wi[:, 2] > 0))[0]
    if len(rows):   # the GGX lobe, only where there is one
        a, o, i = params.alpha[rows], wo[rows], wi[rows]
        h = _half(o, i)
        d = ggx_d(h, a)
        g2 = 1.0 / (1.0 + ggx_lambda(o, a) + ggx_lambda(i, a))
        fr = schlick(params.f0[rows], np.einsum("ij,ij->i", o, h))
        den = 4.0 * np.maximum(o[:, 2] * i[:, 2], 1e-12)
        f[rows] += fr * (d * g2 / den)[:, None]
    return f


def _p_spec(params, wo):
    """Specular lobe selection probability; zero where wo is below the shading normal."""
    return np.where(wo[:, 2] > 0, params.p_spec, 0.0)


def pdf(params, wo, wi):
    p_spec = _p_spec(params, wo)
    p = (1.0 - p_spec) * cosine_hemisphere_pdf(wi[:, 2])
    p = p.astype(np.float32)
    rows = np.nonzero((p_spec > 0) & (wi[:, 2] > 0))[0]
    if len(rows):
        o = wo[rows]
        p[rows] += p_spec[rows] * _spec_pdf(o, _half(o, wi[rows]), params.alpha[rows])
    return np.where(wi[:, 2] > 0, p, 0.0).astype(np.float32)


def sample(params, wo, u_lobe, u):
    """Draw wi; returns (wi, f, pdf). pdf is 0 where no valid direction was found."""
    wi = square_to_cosine_hemisphere(u)
    spec = u_lobe < _p_spec(params, wo)
    if spec.any():
        h = ggx_sample_visible_normal(wo[spec], params.alpha[spec], u[spec])
        wos = wo[spec]
        wi[spec] = 2.0 * np.einsum("ij,ij->i", wos, h)[:, None] * h - wos
    return wi.astype(np.float32), evaluate(params, wo, wi), pdf(params, wo, wi)
