"""Rough dielectric (Cycles' Glass BSDF): one GGX interface that reflects and refracts.

The microfacet model of Walter et al. 2007, "Microfacet Models for Refraction
through Rough Surfaces", with the GGX distribution and the height-correlated
Smith shadowing-masking term G2 = 1 / (1 + Lambda(wo) + Lambda(wi)) for both
reflection and refraction (as Cycles' bsdf_microfacet.h and pbrt-v4 do). The
microfacet normal h is drawn from the visible normals of wo (Heitz 2018); the
interface then reflects with probability F(wo . h), the exact unpolarised
dielectric Fresnel term, and refracts otherwise. The Fresnel term is the only
split: ``tint`` (Cycles' Glass colour) multiplies both parts.

Conventions (all arrays per row, directions in the local shading frame):

- ``wo`` (N, 3) points toward the viewer and has wo.z >= 0: the caller flips
  the frame to wo's side. ``wi`` (N, 3) is on wo's side (z > 0: reflection) or
  on the other (z < 0: refraction). Rows with wo.z or |wi.z| below COS_MIN get
  f = 0 and pdf = 0, as do pairs no microfacet connects; never NaN or Inf.
- ``eta`` (N,) = IOR of the side opposite wo / IOR of wo's side: 1.5 entering
  glass from air, 1 / 1.5 leaving it (the caller inverts the IOR on back faces).
- ``alpha`` (N,) = roughness^2, floored at microfacet.ALPHA_MIN here: near-specular
  glass is a very sharp but finite lobe, never a delta, so every sample has a
  density that eval can recompute (ReSTIR and MIS need that).
- Index-matched rows (eta within a factor 1 + ETA_GAP of 1) do not bend light:
  as eta -> 1 the refraction lobe collapses onto -wo whatever the roughness (an
  interface between equal media is invisible; Cycles makes it a delta). There
  the transmitted part is the reflection lobe at ALPHA_MIN turned through the
  surface (wi.z -> -wi.z), centred on -wo and a few 1e-3 rad wide, with the
  same (1 - F) weight; F is about 0 (exactly 0 at eta = 1).
- f excludes the cosine; pdf is the solid-angle density of glass_sample,
  including the choice between reflection (probability F) and refraction.

Transport factor. With ``radiance=True`` (the default) the refracted part is
divided by eta^2: f is the BSDF for radiance, as pbrt-v4's DielectricBxDF in
TransportMode::Radiance. Radiance / n^2 is invariant along a ray, so light
crossing from wi's medium into wo's is scaled by (n_wo / n_wi)^2 = 1 / eta^2:
a smooth interface passes (1 - F) / eta^2 of the radiance behind it. This f is
not symmetric: f(wo, wi) / n_wo^2 = f(wi, wo) / n_wi^2 (Veach 1997, section
5.2). With ``radiance=False`` the factor is left out and the refracted weight
is (1 - F) whatever eta is: the adjoint (importance) BSDF, and exactly what
Cycles evaluates for radiance too (it omits the scaling). The two give the
same images for closed objects with camera and lights outside them, since the
factors cancel on the way in and out; they differ for open refracting
surfaces (a single-sided glass pane) and for cameras or lights inside a medium.

Cycles' multiple-scattering compensation is not in the lobe: at_view
(bsdf.py) scales it by the tables of glass_albedo.py.
"""

import numpy as np

from .fresnel import fresnel_and_cos_t
from .microfacet import ALPHA_MIN, ggx_d, ggx_lambda, ggx_sample_visible_normal
from ..util.rows import scale

ETA_GAP = 1e-3
COS_MIN = 1e-6      # below it ggx_lambda clamps its tangent and f could overflow


def _lobe(alpha, eta):
    """(alpha, eta, matched) as the lobe uses them: alpha floored at ALPHA_MIN
    (at ALPHA_MIN on index-matched rows), eta in float64, and the index-matched rows."""
    eta = np.asarray(eta, np.float64)
    matched = (eta < 1.0 + ETA_GAP) & (eta * (1.0 + ETA_GAP) > 1.0)
    a = np.maximum(np.asarray(alpha, np.float32), ALPHA_MIN)
    return np.where(matched, ALPHA_MIN, a).astype(np.float32), eta, matched


def _columns(w):
    return (np.asarray(w[:, 0], np.float64), np.asarray(w[:, 1], np.float64),
            np.asarray(w[:, 2], np.float64))


def glass_eval(wo, wi, alpha, eta, tint, radiance=True):
    """f(wo, wi) (N, 3) without the cosine and the pdf (N,) of glass_sample.

    Reflection (wi.z > 0): h = normalize(wo + wi) and
        f = F D G2 / (4 wo.z wi.z),
        pdf = F D_wo(h) / (4 wo.h).
    Refraction (wi.z < 0): h = -(eta wi + wo), normalised and turned to h.z > 0,
    valid only with wo.h > 0 > wi.h (the two on opposite sides of the
    microfacet); with the Jacobian J = eta^2 |wi.h| / (wo.h + eta wi.h)^2
        f = (1 - F) D G2 |wo.h| J / (wo.z |wi.z|)   [/ eta^2 if radiance],
        pdf = (1 - F) D_wo(h) J.
    Index-matched rows refract as they reflect, with wi.z turned over and (1 - F).
    D_wo(h) = G1(wo) (wo.h) D(h) / wo.z is the visible-normal density and F =
    F(wo.h, eta). So f |wi.z| / pdf = tint G2 / G1(wo) [/ eta^2]: at most tint.
    """
    a, e, matched = _lobe(alpha, eta)
    ox, oy, oz = _columns(wo)
    ix, iy, iz = _columns(wi)
    refl = iz > 0
    refr = iz < 0
    bend = refr & ~matched
    # h along wo + k wi, k = 1 (reflection) or eta (refraction), turned to z > 0;
    # index-matched refraction as reflection of wi turned back over the surface.
    k = np.where(bend, e, 1.0)
    jz = np.where(refr & matched, -iz, iz)
    hx, hy, hz = ox + k * ix, oy + k * iy, oz + k * jz
    length = np.sqrt(hx * hx + hy * hy + hz * hz)
    s = np.where(hz < 0, -1.0, 1.0) / np.where(length > 0, length, 1.0)
    hx, hy, hz = hx * s, hy * s, hz * s
    cos_o = ox * hx + oy * hy + oz * hz
    cos_ih = ix * hx + iy * hy + jz * hz
    ok = ((oz > COS_MIN) & (np.abs(iz) > COS_MIN) & (length > 0) & (hz > 0) & (cos_o > 0)
          & np.where(bend, cos_ih < 0, cos_ih > 0))
    F = fresnel_and_cos_t(cos_o, e)[0]
    den = cos_o + e * cos_ih
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        jac = np.where(bend, e * e * np.abs(cos_ih) / (den * den), 0.25 / cos_o)
        d = ggx_d(np.stack([hx, hy, hz], axis=1), a)
        lam_o, lam_i = ggx_lambda(wo, a), ggx_lambda(wi, a)
        common = d * cos_o * jac / oz                   # D_wo(h) J / G1(wo)
        share = np.where(refr, 1.0 - F, F)
        pdf = share * common / (1.0 + lam_o)
        g2 = 1.0 / (1.0 + lam_o + lam_i)
        fs = share * g2 * common / np.abs(iz)
        if radiance:
            fs = np.where(refr, fs / (e * e), fs)
    ok &= (refl | refr) & np.isfinite(pdf) & np.isfinite(fs) & (pdf > 0)
    pdf = np.where(ok, pdf, 0.0).astype(np.float32)
    fs = np.where(ok, fs, 0.0).astype(np.float32)
    return scale(np.asarray(tint, np.float32), fs), pdf


def glass_sample(wo, alpha, eta, tint, u_lobe, u, radiance=True):
    """Draw wi; returns (wi (N, 3), f (N, 3), pdf (N,)), f and pdf as glass_eval's.

    h from the visible normals of wo; reflect about h if u_lobe < F(wo . h),
    else refract through it (Snell's law, wi = (wo.h / eta - cos_t) h - wo / eta;
    index-matched rows reflect and turn wi.z over). A reflection that ends
    below the surface or a refraction that ends above it is lost: pdf = 0 and
    f = 0 (its wi is finite but meaningless). So the density of the kept
    samples is glass_eval's pdf, whose integral over the sphere is one minus
    the lost fraction.
    """
    a, e, matched = _lobe(alpha, eta)
    up = wo[:, 2] > COS_MIN
    wo_s = wo if up.all() else np.where(up[:, None], wo, np.float32([0, 0, 1]))
    h = ggx_sample_visible_normal(wo_s, a, u)
    ox, oy, oz = _columns(wo_s)
    hx, hy, hz = _columns(h)
    cos_o = ox * hx + oy * hy + oz * hz
    F, cos_t = fresnel_and_cos_t(cos_o, e)
    refl = np.asarray(u_lobe) < F
    mirror = refl | matched
    # Reflection: 2 (wo.h) h - wo. Refraction: (wo.h / eta - cos_t) h - wo / eta.
    c = np.where(mirror, 2.0 * cos_o, cos_o / e - cos_t)
    g = np.where(mirror, 1.0, 1.0 / e)
    wx, wy, wz = c * hx - g * ox, c * hy - g * oy, c * hz - g * oz
    wz = np.where(refl | ~matched, wz, -wz)
    length = np.sqrt(wx * wx + wy * wy + wz * wz)
    length = np.where(length > 0, length, 1.0)
    wi = np.stack([wx / length, wy / length, wz / length], axis=1).astype(np.float32)
    ok = up & (cos_o > 0) & np.where(refl, wi[:, 2] > 0, wi[:, 2] < 0)
    f, pdf = glass_eval(wo_s, wi, a, eta, tint, radiance)
    if not ok.all():
        pdf = pdf * ok
        f = scale(f, ok.astype(np.float32))     # a product: masks on (N, 3) rows are slow
    return wi, f, pdf
