"""The material table's Principled subset as BSDF parameters: each row of
``scene.materials`` (base colour, metallic, roughness, IOR, Specular IOR
Level) becomes a Lambert base under a dielectric specular layer, mixed with
a metal, as Cycles' Principled BSDF with those inputs (bsdf.py evaluates
the lobes)."""

import numpy as np

from ..util.rows import scale
from .bsdf import lobe_params
from .fresnel import ior_from_f0


def bsdf_params(materials, material_ids):
    """Per-hit BSDF parameters from the material table.

    Computed once per material, then gathered per hit (core/util/rows.py): the same
    arithmetic, on a handful of rows instead of every hit."""
    return material_lobes(materials).subset(np.asarray(material_ids))


def principled_lobes(base, metallic, roughness, ior, level):
    """(diffuse, f0, roughness, layer_f0) of the Principled subset, for any
    broadcastable inputs: the metallic share reflects base colour, the
    dielectric share a Fresnel f0 of its IOR (scaled by 2 x Specular IOR
    Level) layered over a Lambert base; ``at_view`` takes from that base what
    the layer reflects at the viewing angle. The layer's Fresnel rises from
    f0 to one along the exact curve of the IOR of that f0 (``layer_ior``)."""
    metallic, base = np.clip(metallic, 0, 1)[..., None], np.maximum(base, 0)   # (Cycles: metals' f0 at most 1)
    f0_dielectric = np.minimum(((ior - 1) / (ior + 1)) ** 2 * 2.0 * np.maximum(level, 0), 1.0)[..., None]
    f0 = (1 - metallic) * f0_dielectric + metallic * np.minimum(base, 1)
    diffuse = (1 - metallic) * base
    return diffuse, f0, np.clip(roughness, 0, 1), f0_dielectric[..., 0]


def layer_ior(f0, ior):
    """The IOR whose exact Fresnel curve the Principled BSDF's dielectric
    layer of normal reflectance f0 follows: that of f0 (Specular IOR Level
    moves it, as in Cycles), below one where the IOR input is."""
    return ior_from_f0(f0, np.asarray(ior) < 1)


def material_lobes(materials):
    """BSDFParams with one row per material of the table."""
    diffuse, f0, rough, layer_f0 = principled_lobes(materials.base_color, materials.metallic,
                                                    materials.roughness, materials.ior, materials.specular)
    dielectric = 1 - np.clip(materials.metallic, 0, 1)
    p = lobe_params(diffuse, f0, rough, np.ones_like(f0),
                    exact=(scale(np.ones_like(f0), dielectric * (1 - layer_f0)), layer_ior(layer_f0, materials.ior)))
    p.layered = p.diffuse.copy()
    p.layer_f0 = np.array(np.broadcast_to(layer_f0, p.alpha.shape), np.float32)
    return p
