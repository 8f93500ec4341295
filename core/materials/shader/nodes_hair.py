"""Hair BSDFs, approximated: the Principled Hair BSDF (Chiang and Huang
models) renders as diffuse reflection plus diffuse transmission (Translucent)
of the shares a smooth fibre of its absorption sends back and lets through;
the legacy Hair BSDF as a diffuse surface of its colour. A warning names the
node.

The absorption is Cycles': Direct Coloring's colour mapped to absorption
(Chiang et al. 2016, eq. 9: sigma_a = (ln c / f(beta_N))^2 with f a quintic
in the radial roughness), Melanin Concentration from its eumelanin and
pheomelanin shares plus the tint's, or the Absorption Coefficient itself.
The shares: R, and TRT and the later paths, come back, TT goes through,
averaged over where light falls across the fibre (fibre_split). Hair
scatters around its cone, not as a diffuse surface: this keeps the fibre's
colour and energy, not its highlights (tests/addon/export/test_strands.py states the
tolerance).
"""

import numpy as np

from ...bsdfs.fresnel import fresnel_and_cos_t
from .closure import Closure
from .evaluate import node

EUMELANIN = np.array([0.506, 0.841, 1.653], np.float32)
PHEOMELANIN = np.array([0.343, 0.733, 1.924], np.float32)


def _f(beta):
    return 5.969 - 0.215 * beta + 2.532 * beta ** 2 - 10.73 * beta ** 3 + 5.574 * beta ** 4 + 0.245 * beta ** 5


def color_from_absorption(sigma, beta):
    """Colour whose Chiang absorption at radial roughness beta ((N, 1) or
    scalar) is sigma (N, 3)."""
    return np.exp(-np.sqrt(np.clip(sigma, 0, None)) * _f(beta)).astype(np.float32)


def absorption_from_color(color, beta):
    return (np.log(np.clip(color, 1e-4, 1.0)) / _f(beta)) ** 2


def _column(x):
    return np.atleast_1d(np.asarray(x, np.float32)).reshape(-1, 1)


_H = (np.arange(16) + 0.5) / 16.0       # offsets across the fibre (by symmetry, 0 to 1)


def fibre_split(sigma, eta=1.55):
    """(reflected, transmitted) (N, 3) shares of light falling across a
    smooth fibre of absorption sigma (N, 3) per unit radius, seen at right
    angles (Marschner's and Chiang's paths averaged over the offset h):
    R and the paths after it (TRT, ...) come back, TT goes on."""
    cos_i = np.sqrt(1.0 - _H ** 2)
    cos_t = np.sqrt(1.0 - (_H / eta) ** 2)
    f = fresnel_and_cos_t(cos_i, np.full(len(cos_i), eta))[0][None, :, None]
    t = np.exp(-2.0 * np.asarray(sigma, np.float64)[:, None, :] * cos_t[None, :, None])
    back = f + (1.0 - f) ** 2 * f * t * t / (1.0 - f * t)
    through = (1.0 - f) ** 2 * t
    return back.mean(axis=1).astype(np.float32), through.mean(axis=1).astype(np.float32)


def hair_absorption(inp):
    """(N or 1, 3) absorption per unit radius of a Principled Hair BSDF, as
    Cycles derives it from the node's parametrization."""
    kind = inp.prop("parametrization", "COLOR")
    beta = np.clip(_column(inp.float("Radial Roughness", 0.3)), 0, 1)
    if kind == "COLOR":
        return absorption_from_color(np.clip(inp.color("Color", (0.017513, 0.005763, 0.002059)), 0, 1), beta)
    if kind == "ABSORPTION":
        return np.clip(inp.color("Absorption Coefficient", (0.245531, 0.52, 1.365)), 0, None)
    melanin = np.clip(_column(inp.float("Melanin", 0.8)), 0, 1)
    redness = np.clip(_column(inp.float("Melanin Redness", 1.0)), 0, 1)
    qty = -np.log(np.maximum(1.0 - melanin, 1e-4))
    sigma = qty * (1.0 - redness) * EUMELANIN + qty * redness * PHEOMELANIN
    return sigma + absorption_from_color(np.clip(inp.color("Tint", (1.0, 1.0, 1.0)), 0, 1), beta)


@node("BSDF_HAIR_PRINCIPLED", "BSDF_HAIR")
def hair_bsdf(inp, geom, n, sh):
    sh.warn_once(("hair", n.kind), f"node '{n.name or n.kind}': the hair BSDF renders as diffuse reflection "
                                   "and diffuse transmission of the fibre's shares (no highlights)")
    if n.kind == "BSDF_HAIR":
        color = np.clip(inp.color("Color", (0.8, 0.8, 0.8)), 0, 1)
        return {"BSDF": Closure.bsdf(1.0, None, diffuse=color)}
    sigma = np.atleast_2d(np.asarray(hair_absorption(inp), np.float32))
    eta = float(np.clip(np.mean(inp.float("IOR", 1.55)), 1.0001, 4.0))
    back, through = fibre_split(sigma, eta)
    half = 0.5 * through
    return {"BSDF": Closure.bsdf(1.0, None, diffuse=np.clip(back + half, 0, 1), translucent=np.clip(half, 0, 1))}
