"""The Principled BSDF subset: Lambert diffuse plus a GGX microfacet specular lobe.

All directions are in the local shading frame (z = shading normal). ``eval``
returns f (without the cosine), ``pdf`` the solid-angle density of ``sample``,
and ``sample`` draws the specular lobe by visible normals (Heitz 2018) or the
diffuse lobe by cosine-weighted hemisphere sampling.

A Diffuse BSDF node maps to specular = 0 and metallic = 0: pure Lambert, as in
Cycles. A Glossy BSDF node maps to metallic = 1: pure GGX with Schlick Fresnel.
The Principled BSDF's dielectric layer reflects by the exact Fresnel curve of
its IOR, as Cycles' (fresnel.py).
"""

from dataclasses import dataclass, fields

import numpy as np

from ..util.rows import divide, gather, row_max, scale, scatter, scatter_add
from ..sampling.warps import INV_PI, cosine_hemisphere_pdf, square_to_cosine_hemisphere
from ..util.vectors import dot, luminance
from .fresnel import dielectric_rise, ior_from_f0, schlick
from .microfacet import ALPHA_MIN, ggx_d, ggx_g1, ggx_lambda, ggx_sample_visible_normal
from .glass import glass_eval, glass_sample
from .glass_albedo import at_view as glass_at_view
from .microfacet_albedo import albedo_average, albedo_terms, multiple_bounce_fresnel, rise_average
from .sheen import add_lobe, at_view as sheen_at_view, ltc_sample
from .velvet import add_velvet


@dataclass
class BSDFParams:
    diffuse: np.ndarray     # (N, 3) Lambert albedo
    f0: np.ndarray          # (N, 3) specular reflectance at normal incidence
    alpha: np.ndarray       # (N,) GGX roughness (roughness squared)
    p_spec: np.ndarray      # (N,) probability of sampling the specular lobe
    f90: np.ndarray = None  # (N, 3) reflectance at grazing incidence (None: white);
                            # a Glossy BSDF reflects its colour at every angle
    smooth_n: np.ndarray = None  # (N, 3) the unbent smooth normal in the local frame of a
                                 # normal- or bump-mapped shading normal (None: not bent)
    layered: np.ndarray = None   # (N, 3) the part of ``diffuse`` under a dielectric
                                 # specular layer of normal reflectance layer_f0 (N,)
    layer_f0: np.ndarray = None
    # The glass lobe (core/bsdfs/glass.py; None where no row has one): weights of
    # its reflected and refracted parts (N, 3), IOR (N,), GGX alpha (N,), the
    # probability of choosing it (N,), and eta (N,): the IOR across the surface
    # as the ray meets it (inverted on back faces; ShadingFrame sets it).
    glass_r: np.ndarray = None
    glass_t: np.ndarray = None
    ior: np.ndarray = None
    alpha_g: np.ndarray = None
    p_glass: np.ndarray = None
    eta: np.ndarray = None
    # The sheen lobe on top (core/bsdfs/sheen.py; None where no row has one): its
    # colour weight (N, 3), weight x tint, which at_view turns into its albedo
    # toward wo; roughness (N,); and, set by at_view, the LTC's a and b (N,)
    # and the probability of choosing it (N,).
    sheen: np.ndarray = None
    sheen_rough: np.ndarray = None
    sheen_a: np.ndarray = None
    sheen_b: np.ndarray = None
    p_sheen: np.ndarray = None
    # (N,) share of the GGX lobe that scatters once (Cycles' GGX distribution,
    # as opposed to Multiscatter GGX): at_view puts back the energy single
    # scattering loses only on the rest. None: every row is multiscatter.
    spec_ss: np.ndarray = None
    # (N,) share of the sheen lobe that layers over nothing (a Sheen BSDF
    # node's): at_view dims the other lobes by the rest only. None: all of it
    # layers (the Principled BSDF's sheen).
    sheen_free: np.ndarray = None
    # Cycles' Ashikhmin velvet (the Sheen BSDF node's Ashikhmin
    # distribution): colour weight (N, 3) and sigma (N,) (None: no row has
    # one). Sampled with the diffuse lobe's cosine share.
    velvet: np.ndarray = None
    velvet_sigma: np.ndarray = None
    # (N, 3) the share of f90 - f0 that rises along the exact dielectric
    # Fresnel curve of IOR spec_ior (N,) instead of Schlick's (1 - cos)^5
    # (fresnel.py; the Principled BSDF's dielectric layer and coat). None:
    # every row is Schlick's.
    f_exact: np.ndarray = None
    spec_ior: np.ndarray = None

    def subset(self, index):
        index = np.asarray(index)
        if index.dtype == bool:
            index = np.nonzero(index)[0]
        # Row gathers by core/util/rows.py (a[index] is slow on (N, 3) rows).
        return BSDFParams(*(None if v is None else (gather(v, index) if v.ndim == 2 else np.take(v, index))
                            for v in (getattr(self, f.name) for f in fields(BSDFParams))))

    @property
    def has_glass(self):
        return self.p_glass is not None

    @property
    def has_sheen(self):
        return self.p_sheen is not None


def without_lobes(p, hidden):
    """params ``p`` (a copy the caller owns, changed in place and returned)
    whose lobes of the hidden kinds give no light: hidden (N, 3) bool per row
    for diffuse (Lambert, sheen), glossy (GGX reflection, glass reflection)
    and transmission (glass refraction)."""
    keep = (~hidden).astype(np.float32)

    def zero(name, col):
        v = getattr(p, name)
        if v is not None:
            setattr(p, name, (v * (keep[:, col:col + 1] if v.ndim == 2 else keep[:, col])).astype(np.float32))

    for name in ("diffuse", "layered", "sheen", "velvet"):
        zero(name, 0)
    for name in ("f0", "glass_r", "f_exact"):
        zero(name, 1)
    if p.f90 is not None or hidden[:, 1].any():
        p.f90 = (np.ones_like(p.f0) if p.f90 is None else p.f90) * keep[:, 1:2]
    zero("glass_t", 2)
    return p


def at_view(params, wo):
    """Adjust parameters to the viewing direction wo (local, (N, 3)), in place,
    as Cycles' precomputed albedo tables do (core/bsdfs/microfacet_albedo.py): the
    layered diffuse keeps 1 - E of the dielectric layer above it, and the GGX
    lobe is scaled up by the energy single scattering loses (Multiscatter
    GGX; not the share ``spec_ss`` of lobes with Cycles' plain GGX), and so
    is a reflecting glass lobe (glass_albedo.py; params.eta must be set)."""
    n = len(params.alpha)
    if n == 0:
        return params
    cos = np.clip(wo[:, 2], 0.0, 1.0)
    f90 = params.f90 if params.f90 is not None else np.ones_like(params.f0)
    f_avg = params.f0 + (f90 - params.f0) * np.float32(1.0 / 21.0)
    if params.f_exact is not None:
        f_avg += scale(params.f_exact, rise_average(params.spec_ior) - np.float32(1.0 / 21.0))
    layered = params.layered is not None and params.layer_f0 is not None
    # The albedo matters only on rows with a dielectric layer or a GGX lobe:
    # elsewhere (diffuse-only materials) a = b = 0 gives the same parameters
    # (the layer takes 0 x E = 0, and a zero F_avg keeps the boost at 1).
    need = (row_max(np.abs(f_avg)) > 0) | (params.layer_f0 != 0 if layered else False)
    rows = None if need.all() else np.nonzero(need)[0]
    pick = (lambda v: v) if rows is None else (lambda v: np.take(v, rows))
    spread = (lambda v: v) if rows is None else (lambda v: scatter(np.zeros(n, v.dtype), rows, v))
    if layered:
        lf0 = params.layer_f0
        layer_eta = ior_from_f0(lf0)
        a, b, r = albedo_terms(np.sqrt(pick(params.alpha)), pick(cos), pick(layer_eta))
        a, b, r = spread(a), spread(b), spread(r)
    else:
        a, b = albedo_terms(np.sqrt(pick(params.alpha)), pick(cos))
        a, b = spread(a), spread(b)
    e1 = np.maximum(a + b, 1e-3)
    lost_ms = (1.0 - e1) / e1
    e_avg = spread(albedo_average(np.sqrt(pick(params.alpha))))
    lost = lost_ms if params.spec_ss is None else lost_ms * (1.0 - params.spec_ss)
    if layered:
        # The layer's albedo with what multiple scattering keeps, whichever
        # distribution the layer scatters by (Cycles estimates it so for
        # layering): its Fresnel rises from lf0 to one along the exact curve
        # (an IOR and its inverse alike, as Cycles' table); at a normal
        # reflectance near one (an IOR near 0) it leaves the base nothing.
        rest = 1.0 - lf0
        f_ms = multiple_bounce_fresnel(lf0 + rest * rise_average(layer_eta), e_avg)
        e_layer = (lf0 * e1 + rest * r) * (1.0 + f_ms * lost_ms)
        e_layer = np.clip(e_layer, 0.0, 1.0).astype(np.float32)
        params.diffuse = np.maximum(params.diffuse - scale(params.layered, e_layer), 0.0).astype(np.float32)
    boost = (1.0 + scale(multiple_bounce_fresnel(f_avg, e_avg), lost)).astype(np.float32)
    params.f0 = (params.f0 * boost).astype(np.float32)
    params.f90 = (f90 * boost).astype(np.float32)
    if params.f_exact is not None:
        params.f_exact = (params.f_exact * boost).astype(np.float32)
    if params.has_glass:
        glass_at_view(params, cos)
    if params.sheen is not None:
        sheen_at_view(params, cos)
    return params


def lobe_params(diffuse, f0, roughness, f90=None, glass=None, velvet=None, exact=None):
    """BSDFParams from lobe weights: Lambert albedo (N, 3), GGX f0 (N, 3),
    roughness (N,), and the reflectance at grazing incidence f90 (N, 3; None:
    white); glass: (reflection weight (N, 3), refraction weight (N, 3), IOR
    (N,), roughness (N,)) of a glass lobe, or None; velvet: (colour (N, 3),
    sigma (N,)) of an Ashikhmin velvet lobe, or None; exact: (the share of
    f90 - f0 that rises along the exact dielectric curve (N, 3), its IOR
    (N,)), or None (BSDFParams.f_exact).

    Lobes are picked in proportion to their share of the luminance (the
    velvet's counts with the diffuse lobe's, whose cosine samples serve
    both); between diffuse and specular alone the specular share is kept
    within [0.1, 0.9]."""
    ws = luminance(f0)
    wd = luminance(diffuse)
    if velvet is not None:
        wd = wd + luminance(velvet[0])
    wg = 0.0
    if glass is not None:
        wg = np.maximum(luminance(glass[0]), luminance(glass[1]))
        if not (wg > 0).any():
            glass, wg = None, 0.0
    total = ws + wd + wg
    safe = np.where(total > 0, total, 1)
    p_spec = np.where(total > 0, ws / safe, 0.0)
    p_spec = np.where((ws > 0) & (wd > 0) & ~np.greater(wg, 0), np.clip(p_spec, 0.1, 0.9), p_spec)
    alpha = np.maximum(np.asarray(roughness) ** 2, ALPHA_MIN)
    p = BSDFParams(np.ascontiguousarray(diffuse, np.float32), np.ascontiguousarray(f0, np.float32),
                   np.ascontiguousarray(alpha, np.float32), np.ascontiguousarray(p_spec, np.float32),
                   None if f90 is None else np.ascontiguousarray(f90, np.float32))
    if glass is not None:
        n = len(p.alpha)
        p.glass_r = np.array(np.broadcast_to(glass[0], (n, 3)), np.float32)
        p.glass_t = np.array(np.broadcast_to(glass[1], (n, 3)), np.float32)
        p.ior = np.array(np.broadcast_to(np.maximum(glass[2], 1.0), (n,)), np.float32)
        p.alpha_g = np.array(np.maximum(np.broadcast_to(glass[3], (n,)) ** 2, ALPHA_MIN), np.float32)
        p.p_glass = np.where(total > 0, wg / safe, 0.0).astype(np.float32)
        p.eta = p.ior.copy()
    if velvet is not None:
        n = len(p.alpha)
        p.velvet = np.array(np.broadcast_to(velvet[0], (n, 3)), np.float32)
        p.velvet_sigma = np.array(np.broadcast_to(velvet[1], (n,)), np.float32)
    if exact is not None:
        n = len(p.alpha)
        p.f_exact = np.array(np.broadcast_to(exact[0], (n, 3)), np.float32)
        p.spec_ior = np.array(np.broadcast_to(exact[1], (n,)), np.float32)
    return p


def _half(wo, wi):
    h = wo + wi
    n = np.sqrt(dot(h, h))
    return divide(h, np.where(n > 0, n, 1).astype(n.dtype, copy=False))


def _spec_pdf(wo, h, alpha):
    return ggx_g1(wo, alpha) * ggx_d(h, alpha) / (4.0 * np.maximum(wo[:, 2], 1e-7))


# --- BSDF interface ---------------------------------------------------------

def _p_spec(params, wo):
    """Specular lobe selection probability; zero where wo is below the shading normal."""
    return params.p_spec * (wo[:, 2] > 0)      # a product: np.where on rows is slow


def _lobes(params, wo, wi, want_f, want_pdf):
    """f(wo, wi) and/or pdf(wo, wi), sharing the specular lobe's terms.

    The GGX lobe is evaluated only on the rows that have one (p_spec > 0, both
    directions above the shading normal); rows move by core/util/rows.py gathers and
    scatters, and not at all when every row has the lobe."""
    wi_up = wi[:, 2] > 0
    p_spec = _p_spec(params, wo)
    p_glass = _p_glass(params, wo)
    p_sheen = _p_sheen(params, wo)
    f = p = None
    if want_f:
        f = scale(params.diffuse, wi_up * INV_PI)      # 1 / pi or 0 per row
        if params.smooth_n is not None:
            f = scale(f, bump_shadowing(params.smooth_n, wi))
    if want_pdf:
        p = ((1.0 - p_spec - p_glass - p_sheen) * cosine_hemisphere_pdf(wi[:, 2])).astype(np.float32)
    if params.has_glass:
        _glass_lobe(params, wo, wi, p_glass, f, p)
    if params.has_sheen:
        add_lobe(params, wo, wi, p_sheen, f, p)
    if want_f and params.velvet is not None:
        add_velvet(params, wo, wi, f)
    spec = (p_spec > 0) & wi_up
    if not spec.any():
        return f, p
    every = spec.all()
    rows = None if every else np.nonzero(spec)[0]

    def take(a):
        return a if every else (gather(a, rows) if a.ndim == 2 else np.take(a, rows))

    a, o, i = take(params.alpha), take(wo), take(wi)
    h = _half(o, i)
    d = ggx_d(h, a)
    lam_o = ggx_lambda(o, a)
    if want_f:
        g2 = 1.0 / (1.0 + lam_o + ggx_lambda(i, a))
        cos_oh = dot(o, h)
        fr = schlick(take(params.f0), cos_oh, None if params.f90 is None else take(params.f90))
        if params.f_exact is not None:
            # The exact share rises by its own curve, not Schlick's.
            m5 = np.clip(1.0 - cos_oh, 0.0, 1.0) ** 5
            fr += scale(take(params.f_exact), dielectric_rise(cos_oh, take(params.spec_ior)) - m5)
        den = 4.0 * np.maximum(o[:, 2] * i[:, 2], 1e-12)
        spec_f = scale(fr, (d * g2 / den).astype(np.float32))
        if every:
            f += spec_f
        else:
            scatter_add(f, rows, spec_f)
    if want_pdf:
        # _spec_pdf, with G1 from the Lambda already at hand.
        spec_p = (1.0 / (1.0 + lam_o)) * d / (4.0 * np.maximum(o[:, 2], 1e-7))
        if every:
            p = (p + p_spec * spec_p).astype(np.float32)
        else:
            p[rows] = np.take(p, rows) + np.take(p_spec, rows) * spec_p
    return f, p


def bump_shadowing(smooth_n, wi):
    """Cycles' softening of diffuse light on normal- and bump-mapped surfaces
    (``bump_shadowing_term``): zero where the light and the bent normal lie
    on opposite sides of the smooth normal, else the GGX masking term of a
    roughness that grows with how far the normal was bent, so shading fades
    out toward the smooth surface's horizon instead of cutting off."""
    cos_i = dot(smooth_n, wi)
    cos_d = smooth_n[:, 2]             # the bent normal is the frame's z
    keep = ~(cos_i * cos_d * wi[:, 2] < 0)
    ci, cd = np.abs(cos_i), np.abs(cos_d)
    tan2_d = 1.0 / np.maximum(cd * cd, 1e-12) - 1.0
    a2 = np.clip(0.125 * tan2_d, 0.0, 1.0)
    ci2 = np.maximum(ci * ci, 1e-12)
    g = 2.0 / (1.0 + np.sqrt(1.0 + a2 * (1.0 - ci2) / ci2))
    g = np.where((cd >= 1.0) | (ci >= 1.0), 1.0, np.where(ci < 1e-6, 0.0, g))
    return (g * keep).astype(np.float32)


def _p_glass(params, wo):
    if not params.has_glass:
        return np.float32(0)
    return params.p_glass * (wo[:, 2] > 0)


def _glass_lobe(params, wo, wi, p_glass, f, p):
    """Add the glass lobe's f and p_glass x pdf into f and p (in place), on
    the rows that have one. Cycles' transport convention (no 1 / eta^2 on
    refraction), so closed glass objects and panes render as in Cycles."""
    rows = np.nonzero(p_glass > 0)[0]
    if len(rows) == 0:
        return
    o, i = gather(wo, rows), gather(wi, rows)
    ones = np.ones((len(rows), 3), np.float32)
    gf, gp = glass_eval(o, i, np.take(params.alpha_g, rows), np.take(params.eta, rows), ones,
                        radiance=False)
    if f is not None:
        up = (i[:, 2] > 0)[:, None]
        tint = np.where(up, gather(params.glass_r, rows), gather(params.glass_t, rows))
        scatter_add(f, rows, (gf * tint).astype(np.float32))
    if p is not None:
        p[rows] = np.take(p, rows) + np.take(p_glass, rows) * gp


def _p_sheen(params, wo):
    if not params.has_sheen:
        return np.float32(0)
    return params.p_sheen * (wo[:, 2] > 0)


def evaluate(params, wo, wi):
    """f(wo, wi) as (N, 3). The diffuse lobe needs only wi above the shading
    normal (as Cycles: bent smooth-shaded normals must not blacken surfaces);
    the specular lobe needs both directions above it."""
    return _lobes(params, wo, wi, True, False)[0]


def pdf(params, wo, wi):
    return _lobes(params, wo, wi, False, True)[1]


def evaluate_pdf(params, wo, wi):
    """(evaluate, pdf) in one pass over the shared specular terms."""
    return _lobes(params, wo, wi, True, True)


def sample(params, wo, u_lobe, u):
    """Draw wi; returns (wi, f, pdf). pdf is 0 where no valid direction was found."""
    wi = square_to_cosine_hemisphere(u)
    p_spec = _p_spec(params, wo)
    spec = u_lobe < p_spec
    if params.has_sheen:
        below = p_spec + _p_glass(params, wo)
        rows = np.nonzero((u_lobe >= below) & (u_lobe < below + _p_sheen(params, wo)))[0]
        if len(rows):
            scatter(wi, rows, ltc_sample(gather(wo, rows), np.take(params.sheen_a, rows),
                                         np.take(params.sheen_b, rows), gather(u, rows)))
    if params.has_glass:
        p_glass = _p_glass(params, wo)
        glass = ~spec & (u_lobe < p_spec + p_glass)
        if glass.any():
            rows = np.nonzero(glass)[0]
            u_g = (np.take(u_lobe, rows) - np.take(p_spec, rows)) / np.maximum(np.take(p_glass, rows), 1e-12)
            wg, _, gp = glass_sample(gather(wo, rows), np.take(params.alpha_g, rows), np.take(params.eta, rows),
                                     np.ones((len(rows), 3), np.float32), np.clip(u_g, 0, 1 - 1e-7),
                                     gather(u, rows), radiance=False)
            # A sample the glass lobe discarded (a reflection below the surface,
            # a refraction above it) ends the path: a zero direction has pdf 0.
            scatter(wi, rows, scale(wg, (gp > 0).astype(np.float32)))
    if spec.any():
        rows = np.nonzero(spec)[0]
        wos = gather(wo, rows)
        h = ggx_sample_visible_normal(wos, np.take(params.alpha, rows), gather(u, rows))
        # Mirror wo about h: 2 (wo . h) h - wo.
        scatter(wi, rows, scale(h, 2.0 * dot(wos, h)) - wos)
    wi = wi.astype(np.float32, copy=False)
    f, p = _lobes(params, wo, wi, True, True)
    return wi, f, p


KIND_DIFFUSE, KIND_GLOSSY, KIND_TRANSMISSION = 0, 1, 2


def sampled_kinds(params, wo, wi, u_lobe):
    """Kind of bounce of each direction ``sample`` drew with the lobe choice
    u_lobe (integrators/bounces.py): below the surface transmission; above
    it glossy from the specular and glass lobes, diffuse from the others
    (diffuse, sheen), in the order ``sample`` picks lobes."""
    kinds = np.full(len(wi), KIND_DIFFUSE, np.int8)
    above = wi[:, 2] > 0
    glossy = u_lobe < _p_spec(params, wo)
    if params.has_glass:
        glossy |= u_lobe < _p_spec(params, wo) + _p_glass(params, wo)
    kinds[glossy & above] = KIND_GLOSSY
    kinds[~above] = KIND_TRANSMISSION
    return kinds
