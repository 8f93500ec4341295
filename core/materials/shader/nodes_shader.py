"""Shader nodes: BSDFs, emission and the nodes that combine them into a Closure.

The Principled BSDF follows the layering of Cycles' Principled v2
(``svm/closure.h``), folded into this engine's lobes (core/materials/shader/closure.py):

- Alpha scales every lobe by alpha and adds a transparent lobe of 1 - alpha.
- Coat: a GGX reflection of f0 from the Coat IOR on top; what lies below is
  tinted by mix(1, Coat Tint, Coat Weight) and loses the coat's reflectance.
- Metallic: base colour as f0 (Schlick; Cycles' F82 edge tint from Specular
  Tint is not modelled, its effect is at grazing angles only).
- Transmission: the dielectric share that is not diffuse refracts (tinted by
  the base colour) with the IOR's Fresnel reflection on top.
- Dielectric specular: f0 = ((IOR - 1) / (IOR + 1))^2 x 2 x Specular IOR
  Level x Specular Tint, over a Lambert base of weight (1 - f0).
- Sheen: Weight x Tint and Roughness become the sheen lobe on top of all
  the others (core/bsdfs/sheen.py: Cycles' microfibre layer as a linearly
  transformed cosine, our own tables); at the viewing angle every other lobe
  of the closure keeps 1 - the sheen's albedo (largest channel). Emission is
  not dimmed by it (nor by the coat). Within 0.5 % of Cycles' mean on the
  sheen family of tests/support/node_families.py, block chi 2.1 at 128x128.
- Distribution GGX (older files, glTF imports) scatters once: the metallic
  and specular lobes lose the energy Multiscatter GGX (the default) puts
  back, as in Cycles. The Glossy BSDF's GGX, Beckmann and Ashikhmin-Shirley
  do the same (the latter two drawn as GGX of the same roughness).
- Anisotropy is approximated: Anisotropic stretches GGX's alpha to
  r^2 / a along the tangent and r^2 x a across it, a = sqrt(1 - 0.9 x
  Anisotropic) (Burley 2012's mapping, which Cycles follows); the lobe here
  is the isotropic GGX of their geometric mean, r^2 itself. Mean brightness
  agrees with Cycles (within 0.5 % on the anisotropic family of
  tests/support/node_families.py), highlights are round where Cycles stretches them
  (block chi 3.8 at 64x64, 18 at 128x128 with 256 samples:
  ``bench/contact_sheet.py --only sheen anisotropic``).
- A sheen inside a Mix Shader dims every lobe of the mixture at the viewing
  angle, not only the layers under it (the lobes are summed before the view
  is known).
- Subsurface scattering renders as diffuse reflection of the base colour.

The Sheen BSDF node (Microfiber) is the same sheen lobe on its own: it dims
nothing below it, as in Cycles, where only the Principled BSDF layers its
sheen over the other lobes.
"""

import numpy as np

from ...bsdfs.principled import layer_ior
from .closure import BSDF_LOBES, Closure
from .evaluate import f32, node


def _normal(inp, geom, name="Normal"):
    """A BSDF's own normal when its Normal socket is linked, else None."""
    if not inp.linked(name):
        return None
    n = np.broadcast_to(inp.vector(name), (geom.n, 3)).astype(np.float32)
    length = np.sqrt((n * n).sum(axis=1))
    ok = length > 1e-8
    return np.where(ok[:, None], n / np.where(ok, length, 1)[:, None], geom.normal)


def _c(x):
    """A scalar or (N,) array ready to multiply an (N, 3) or (3,) colour."""
    x = f32(x)
    return x[..., None] if x.ndim else x


def _f0_from_ior(ior):
    ior = np.maximum(f32(ior), 0.0)
    return ((ior - 1) / (ior + 1)) ** 2


@node("BSDF_PRINCIPLED")
def principled(inp, geom, n, sh):
    base = np.clip(inp.color("Base Color", (0.8, 0.8, 0.8)), 0, None)
    metallic = np.clip(inp.float("Metallic", 0.0), 0, 1)
    rough = np.clip(inp.float("Roughness", 0.5), 0, 1)
    # The specular layer's Fresnel takes an IOR below one as Cycles does: the
    # normal reflectance of 1 / IOR, total reflection beyond the critical
    # angle, and a mirror at 0 (older glTF imports wrote 0). The glass part
    # refracts with an IOR of at least one.
    ior_in = np.maximum(inp.float("IOR", 1.5), 0.0)
    ior = np.maximum(ior_in, 1.0)
    alpha = np.clip(inp.float("Alpha", 1.0), 0, 1)
    level = np.maximum(inp.float("Specular IOR Level", 0.5), 0)
    spec_tint = np.clip(inp.color("Specular Tint", (1, 1, 1)), 0, None)
    trans = np.clip(inp.float("Transmission Weight", 0.0), 0, 1)
    coat = np.clip(inp.float("Coat Weight", 0.0), 0, 1)
    strength = inp.float("Emission Strength", 0.0)
    emission = inp.color("Emission Color", (1, 1, 1)) * _c(strength)
    normal = _normal(inp, geom)

    dielectric = 1 - metallic
    f0_untinted = np.minimum(_f0_from_ior(ior_in) * 2 * level, 1.0)
    f0_d = _c(f0_untinted) * spec_tint
    # As Cycles: a base colour above one brightens the diffuse part only; the
    # metal's f0 and the glass's tint take it clamped to one. The metal's
    # Specular Tint is its F82 tint (f82_edge: its edge by the curve's mean).
    clamped = np.minimum(base, 1.0)
    specular = _c(metallic) * clamped + _c(dielectric * (1 - trans)) * f0_d
    diffuse = _c(dielectric * (1 - trans)) * base      # under the specular layer
    # The glass part reflects by its own Fresnel (tinted like the specular
    # layer) and refracts tinted by sqrt(base colour): through a closed
    # object, in and out, the base colour (Cycles' Principled convention).
    transmission = _c(dielectric * trans) * np.sqrt(clamped)
    trans_refl = _c(dielectric * trans) * spec_tint
    below = 1.0
    if np.any(coat > 0):
        coat_ior = np.maximum(inp.float("Coat IOR", 1.5), 1.0)
        f0_coat = _f0_from_ior(coat_ior)
        tint = 1 + _c(coat) * (np.clip(inp.color("Coat Tint", (1, 1, 1)), 0, None) - 1)
        below = tint * _c(1 - coat * f0_coat)
    # The dielectric layer's Fresnel rises from f0 to one along the exact
    # curve of the IOR that f0 stands for (Cycles' remapped real Fresnel).
    layer = _c(dielectric * (1 - trans))
    lobes = Closure.bsdf(1.0, None, layered=diffuse * below, layer_f0=f0_d.mean(axis=-1),
                         specular=specular * below,
                         spec_edge=(_c(metallic) * f82_edge(clamped, np.minimum(spec_tint, 1.0)) + layer) * below,
                         spec_exact=layer * (1 - f0_d) * below,
                         spec_ior=layer_ior(f0_untinted, ior_in),
                         spec_rough=rough, spec_ss=_single_scatter(inp), transmission=transmission * below,
                         trans_refl=trans_refl * below,
                         trans_rough=rough, ior=ior)
    if np.any(coat > 0):
        lobes = lobes + Closure.bsdf(1.0, None, specular=_c(coat * f0_coat) * np.ones(3, np.float32),
                                     spec_edge=_c(coat) * np.ones(3, np.float32),
                                     spec_exact=_c(coat * (1 - f0_coat)) * np.ones(3, np.float32),
                                     spec_ior=coat_ior,
                                     spec_rough=np.clip(inp.float("Coat Roughness", 0.03), 0, 1))
    sheen = np.clip(inp.float("Sheen Weight", 0.0), 0, None)
    if np.any(sheen > 0):
        lobes = lobes + Closure.bsdf(1.0, None, sheen=_c(sheen) * np.clip(inp.color("Sheen Tint", (1, 1, 1)), 0, None),
                                     sheen_rough=np.clip(inp.float("Sheen Roughness", 0.5), 0, 1))
    if normal is not None:
        lobes = _with_normal(lobes, normal)
    out = lobes.scaled(alpha) if np.any(alpha < 1) else lobes
    if np.any(alpha < 1):
        out = out + Closure(transparent=np.ones(3, np.float32) * _c(1 - alpha))
    if np.any(strength != 0):
        out = out + Closure(emission=emission * _c(alpha))
    return {"BSDF": out}


def _with_normal(c, normal):
    """The closure with every BSDF lobe using ``normal``."""
    w = np.float32(0)
    for name in BSDF_LOBES:
        if name in c.fields:
            w = w + np.abs(c.fields[name]).mean(axis=-1)
    c.normal_sum = normal * f32(w)[..., None] if f32(w).ndim else normal * w
    c.normal_w = f32(w)
    return c


def _bsdf(inp, geom, **lobes):
    c = Closure.bsdf(1.0, None, **lobes)
    normal = _normal(inp, geom)
    return _with_normal(c, normal) if normal is not None else c


@node("BSDF_DIFFUSE")
def diffuse_bsdf(inp, geom, n, sh):
    return {"BSDF": _bsdf(inp, geom, diffuse=np.clip(inp.color("Color", (0.8, 0.8, 0.8)), 0, None))}


def _single_scatter(inp):
    """1 where the node's microfacet distribution scatters once, as
    Cycles' GGX, Beckmann and Ashikhmin-Shirley do (all drawn here as
    GGX); None (no single-scattering share) for Multiscatter GGX, whose
    lost energy Cycles puts back."""
    return None if inp.prop("distribution", "MULTI_GGX") == "MULTI_GGX" else np.float32(1)


@node("BSDF_GLOSSY", "BSDF_ANISOTROPIC")
def glossy_bsdf(inp, geom, n, sh):
    color = np.clip(inp.color("Color", (0.8, 0.8, 0.8)), 0, None)
    return {"BSDF": _bsdf(inp, geom, specular=color, spec_edge=color,
                          spec_rough=np.clip(inp.float("Roughness", 0.5), 0, 1), spec_ss=_single_scatter(inp))}


@node("BSDF_METALLIC")
def metallic_bsdf(inp, geom, n, sh):
    """The Metallic BSDF node (Blender 4.0+): a GGX conductor whose normal
    reflectance is the Base Color (F82 Tint) or, for a Physical Conductor,
    that of its complex IOR (n + ik per channel). The lobes here rise by
    Schlick's curve from that reflectance to an edge colour chosen so that
    the curve's cosine-weighted mean is Cycles' Fresnel's (conductor_edge):
    Cycles' F82 tint dips below Schlick's curve at grazing angles, and so
    does the exact conductor Fresnel. (Anisotropy is drawn isotropic.)"""
    if inp.prop("fresnel_type", "F82") == "PHYSICAL_CONDUCTOR":
        eta = np.maximum(inp.vector("IOR", (2.757, 2.513, 2.231)), 0.0)
        k = np.maximum(inp.vector("Extinction", (3.867, 3.404, 3.009)), 0.0)
        f0, edge = conductor_edge(eta, k)
    else:
        f0 = np.clip(inp.color("Base Color", (0.617, 0.577, 0.540)), 0, 1)
        edge = f82_edge(f0, np.clip(inp.color("Edge Tint", (0.695, 0.726, 0.770)), 0, 1))
    return {"BSDF": _bsdf(inp, geom, specular=f32(f0), spec_edge=f32(edge),
                          spec_rough=np.clip(inp.float("Roughness", 0.5), 0, 1), spec_ss=_single_scatter(inp))}


# Schlick's curve f0 + (e - f0)(1 - mu)^5 has the cosine-weighted mean
# (2 mu dmu over [0, 1]) f0 + (e - f0) / 21.
_SCHLICK_MEAN = 1.0 / 21.0
_MU, _MU_W = np.polynomial.legendre.leggauss(32)
_MU, _MU_W = 0.5 * (_MU + 1.0), 0.5 * _MU_W


def f82_edge(f0, tint):
    """The edge colour of Schlick's curve with the mean of Cycles' F82-tint
    Fresnel: Schlick's curve minus b mu (1 - mu)^6, b making the curve at
    mu = 1/7 the tint times Schlick's there; that term's mean is b / 126."""
    mu = 1.0 / 7.0
    at = f0 + (1.0 - f0) * (1.0 - mu) ** 5
    b = at * (1.0 - tint) / (mu * (1.0 - mu) ** 6)
    return 1.0 - b / 6.0


def conductor_fresnel(cos, eta, k):
    """Unpolarised Fresnel reflectance of a conductor of complex IOR eta + ik
    at cosines ``cos`` (broadcasting)."""
    c2 = cos * cos
    s2 = 1.0 - c2
    t0 = eta * eta - k * k - s2
    ab = np.sqrt(t0 * t0 + 4.0 * eta * eta * k * k)
    a = np.sqrt(np.maximum(0.5 * (ab + t0), 0.0))
    t1 = ab + c2
    t2 = 2.0 * a * cos
    rs = (t1 - t2) / np.maximum(t1 + t2, 1e-12)
    t3 = c2 * ab + s2 * s2
    t4 = t2 * s2
    rp = rs * (t3 - t4) / np.maximum(t3 + t4, 1e-12)
    return 0.5 * (rs + rp)


def conductor_edge(eta, k):
    """(f0, edge): a conductor's normal reflectance and the edge colour of
    Schlick's curve with its Fresnel's cosine-weighted mean (eta, k:
    (..., 3))."""
    eta, k = f32(eta)[..., None], f32(k)[..., None]
    f = conductor_fresnel(_MU.astype(np.float32), eta, k)
    mean = (f * (2.0 * _MU * _MU_W).astype(np.float32)).sum(axis=-1)
    f0 = conductor_fresnel(np.float32(1.0), eta, k)[..., 0]
    return f0, np.clip(f0 + (mean - f0) / _SCHLICK_MEAN, 0.0, 1.0)


@node("BSDF_SHEEN")
def sheen_bsdf(inp, geom, n, sh):
    """The Sheen BSDF node (Velvet before Blender 4.0): Microfiber is the
    Principled BSDF's sheen lobe (core/bsdfs/sheen.py) of its colour and roughness,
    on its own (nothing below it to dim); Ashikhmin is Cycles' Ashikhmin
    velvet of sigma = Roughness (core/bsdfs/bsdf.py)."""
    color = np.clip(inp.color("Color", (0.8, 0.8, 0.8)), 0, None)
    rough = np.clip(inp.float("Roughness", 0.5), 0, 1)
    if inp.prop("distribution", "MICROFIBER") == "ASHIKHMIN":
        return {"BSDF": _bsdf(inp, geom, velvet=color, velvet_sigma=rough)}
    return {"BSDF": _bsdf(inp, geom, sheen=color, sheen_rough=rough, sheen_free=np.float32(1))}


@node("BSDF_GLASS")
def glass_bsdf(inp, geom, n, sh):
    color = np.clip(inp.color("Color", (1, 1, 1)), 0, None)
    ior = np.maximum(inp.float("IOR", 1.5), 1.0)
    rough = np.clip(inp.float("Roughness", 0.0), 0, 1)
    return {"BSDF": _bsdf(inp, geom, transmission=color, trans_refl=color, trans_rough=rough, ior=ior)}


@node("BSDF_REFRACTION")
def refraction_bsdf(inp, geom, n, sh):
    return {"BSDF": _bsdf(inp, geom, transmission=np.clip(inp.color("Color", (1, 1, 1)), 0, None),
                          trans_rough=np.clip(inp.float("Roughness", 0.0), 0, 1),
                          ior=np.maximum(inp.float("IOR", 1.45), 1.0))}


@node("BSDF_TRANSPARENT")
def transparent_bsdf(inp, geom, n, sh):
    return {"BSDF": Closure(transparent=np.clip(inp.color("Color", (1, 1, 1)), 0, None))}


@node("BSDF_TRANSLUCENT")
def translucent_bsdf(inp, geom, n, sh):
    return {"BSDF": _bsdf(inp, geom, translucent=np.clip(inp.color("Color", (0.8, 0.8, 0.8)), 0, None))}


@node("SUBSURFACE_SCATTERING")
def subsurface(inp, geom, n, sh):
    return {"BSSRDF": _bsdf(inp, geom, diffuse=np.clip(inp.color("Color", (0.8, 0.8, 0.8)), 0, None))}


@node("EMISSION")
def emission(inp, geom, n, sh):
    return {"Emission": Closure(emission=inp.color("Color", (1, 1, 1)) * _c(inp.float("Strength", 1.0)))}


@node("BACKGROUND")
def background(inp, geom, n, sh):
    return {"Background": Closure(emission=inp.color("Color", (0.05, 0.05, 0.05))
                                  * _c(inp.float("Strength", 1.0)))}


@node("HOLDOUT")
def holdout(inp, geom, n, sh):
    return {"Holdout": Closure(holdout=np.float32(1))}


@node("MIX_SHADER")
def mix_shader(inp, geom, n, sh):
    f = np.clip(inp.float("Fac", 0.5), 0, 1)
    a, b = inp.closure("Shader"), inp.closure("Shader_001")
    return {"Shader": a.scaled(1 - f) + b.scaled(f)}


@node("ADD_SHADER")
def add_shader(inp, geom, n, sh):
    return {"Shader": inp.closure("Shader") + inp.closure("Shader_001")}
