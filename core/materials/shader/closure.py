"""Closures: what a shader node graph leaves at each hit.

Cycles keeps a list of up to 64 weighted closures per shading point. Here a
closure is a fixed set of lobe weights, summed over every BSDF node the
graph's Mix and Add Shader nodes reach, so a whole batch of hits is a few
arrays:

- ``diffuse``: Lambert albedo (Diffuse BSDF); ``layered``: Lambert albedo
  under a dielectric specular layer of normal reflectance ``layer_f0``
  (Principled's base), which keeps what the layer does not reflect at the
  viewing angle (core/bsdfs/bsdf.py ``at_view``).
- ``specular``: normal-incidence reflectance of the GGX reflection lobe
  (Glossy BSDF, Principled's metallic and dielectric specular), with
  ``spec_rough`` the weight-averaged roughness of the lobes that fed it:
  two glossy lobes of different roughness become one of their mean roughness;
  ``spec_edge`` its reflectance at grazing incidence (white for Fresnel
  lobes, the colour for a Glossy BSDF, which Cycles gives no Fresnel);
  ``spec_exact`` the part of spec_edge - specular that rises along the
  exact dielectric Fresnel curve of the weight-averaged ``spec_ior``
  (Principled's dielectric layer and coat) instead of Schlick's;
  ``spec_ss`` the weight-averaged share of those lobes that scatter once
  (distribution GGX: no multiple-scattering energy put back; Multiscatter
  GGX, the default, gives 0).
- ``transmission`` and ``trans_refl``: weights of the refracted and the
  reflected part of the glass lobe (Glass, Refraction, Principled
  transmission; core/bsdfs/glass.py), with weight-averaged ``ior`` and
  ``trans_rough``.
- ``sheen``: weight x tint of the sheen layer on top (Principled sheen,
  core/bsdfs/sheen.py), with weight-averaged ``sheen_rough``; at the viewing angle
  it takes its albedo from every other lobe of the closure (core/bsdfs/bsdf.py
  ``at_view``), except the share ``sheen_free`` from a Sheen BSDF node,
  which lies on top of nothing.
- ``velvet``: the colour of a Sheen BSDF node of Ashikhmin distribution
  (Cycles' Ashikhmin velvet), with weight-averaged ``velvet_sigma``.
- ``transparent``: the share of light passing straight through (Transparent
  BSDF, Principled Alpha).
- ``translucent``: Lambert transmission (Translucent BSDF).
- ``emission``: emitted radiance (Emission, Principled emission).
- ``holdout``: the share of the pixel cut out (Holdout).
- the shading normal, the weight-averaged normal of the BSDF nodes that
  gave one (normal maps and bump).

Every field is an array that broadcasts to the batch: ``(1, 3)`` or ``(N, 3)``
for colours, ``()`` or ``(N,)`` for scalars, so a graph without per-hit inputs
stays a handful of numbers until ``Closure.lobes`` spreads it over the hits.
"""

import numpy as np

COLOR_FIELDS = ("diffuse", "layered", "specular", "spec_edge", "spec_exact", "transmission", "trans_refl",
                "transparent", "translucent", "emission", "sheen", "velvet")
# Scalars summed with a weight and divided by it at the end: name -> (weight,
# lobe or lobes it averages over; a glass lobe's parts both count, so a black
# refraction keeps its reflection's IOR and roughness).
AVERAGED = {"spec_rough": ("spec_w", "specular"), "spec_ss": ("spec_w", "specular"),
            "spec_ior": ("exact_w", "spec_exact"),
            "trans_rough": ("trans_w", ("transmission", "trans_refl")),
            "ior": ("trans_w", ("transmission", "trans_refl")), "layer_f0": ("layer_w", "layered"),
            "sheen_rough": ("sheen_w", "sheen"), "sheen_free": ("sheen_w", "sheen"),
            "velvet_sigma": ("velvet_w", "velvet")}
BSDF_LOBES = ("diffuse", "layered", "specular", "transmission", "translucent", "sheen", "velvet")


def _f32(x):
    return np.asarray(x, np.float32)


class Closure:
    """Weighted lobes of one shader output over a batch (see module notes)."""

    __slots__ = ("fields", "normal_sum", "normal_w")

    def __init__(self, **fields):
        self.fields = {k: _f32(v) for k, v in fields.items() if v is not None}
        self.normal_sum = None      # sum of weight x custom normal, (N, 3)
        self.normal_w = None        # sum of the weights behind it

    @staticmethod
    def bsdf(weight=1.0, normal=None, **lobes):
        """One BSDF node's lobes. lobes: colour fields, and ``spec_rough`` /
        ``trans_rough`` / ``ior`` as plain values (averaged by the lobe's weight)."""
        c = Closure()
        w = _f32(weight)
        for k, v in lobes.items():
            if v is None:
                continue
            v = _f32(v)
            if k in COLOR_FIELDS:
                c.fields[k] = v * (w[..., None] if w.ndim else w)
        for k, (wk, source) in AVERAGED.items():
            if k in lobes and lobes[k] is not None:
                lobe_w = _lobe_weight(c, source)
                c.fields[k] = _f32(lobes[k]) * lobe_w
                c.fields[wk] = lobe_w
        if normal is not None:
            total = _total_weight(c)
            c.normal_sum = _f32(normal) * total[..., None]
            c.normal_w = total
        return c

    def scaled(self, k):
        """This closure times a factor (scalar or per hit)."""
        k = _f32(k)
        out = Closure()
        for name, v in self.fields.items():
            out.fields[name] = v * (k[..., None] if (k.ndim and name in COLOR_FIELDS) else k)
        if self.normal_sum is not None:
            out.normal_sum = self.normal_sum * (k[..., None] if k.ndim else k)
            out.normal_w = self.normal_w * k
        return out

    def __add__(self, other):
        out = Closure()
        for name in set(self.fields) | set(other.fields):
            a, b = self.fields.get(name), other.fields.get(name)
            out.fields[name] = a if b is None else (b if a is None else a + b)
        for attr in ("normal_sum", "normal_w"):
            a, b = getattr(self, attr), getattr(other, attr)
            setattr(out, attr, a if b is None else (b if a is None else a + b))
        return out

    def get(self, name, n):
        """Field ``name`` spread over n hits ((n, 3) or (n,)), zeros if absent."""
        v = self.fields.get(name)
        shape = (n, 3) if name in COLOR_FIELDS else (n,)
        if v is None:
            return np.zeros(shape, np.float32)
        return np.ascontiguousarray(np.broadcast_to(v, shape), np.float32)

    def averaged(self, name, n, default):
        """A weight-averaged scalar (roughness, IOR), ``default`` where no lobe had weight."""
        w = self.get(AVERAGED[name][0], n)
        s = self.get(name, n)
        return np.where(w > 0, s / np.where(w > 0, w, 1), np.float32(default)).astype(np.float32)

    def normal(self, n, fallback):
        """The weight-averaged custom normal, or ``fallback`` where none was given."""
        if self.normal_sum is None:
            return fallback
        total = np.broadcast_to(_total_weight(self), (n,))
        custom = np.broadcast_to(self.normal_sum, (n, 3))
        rest = np.maximum(total - np.broadcast_to(self.normal_w, (n,)), 0)
        v = custom + fallback * rest[:, None]
        length = np.sqrt((v * v).sum(axis=1))
        ok = length > 1e-8
        return np.where(ok[:, None], v / np.where(ok, length, 1)[:, None], fallback).astype(np.float32)


def _lobe_weight(c, source):
    """The weight of the lobe or lobes ``source`` (a field name or a tuple of them)."""
    names = (source,) if isinstance(source, str) else source
    return sum(_weight_of(c.fields.get(name)) for name in names)


def _weight_of(color):
    """A lobe's scalar weight: the mean of its colour weight (as Cycles' sample weight)."""
    if color is None:
        return np.float32(0)
    return np.abs(color).mean(axis=-1)


def _total_weight(c):
    total = np.float32(0)
    for name in BSDF_LOBES:
        if name in c.fields:
            total = total + _weight_of(c.fields[name])
    return _f32(total)
