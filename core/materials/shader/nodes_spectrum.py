"""Blackbody and Wavelength nodes.

Colours come from spectra through the CIE 1931 colour matching functions, in
the multi-lobe fit of Wyman, Sloan and Shirley (2013, "Simple Analytic
Approximations to the CIE XYZ Color Matching Functions"; within about 1 % of
the tables), then XYZ to linear Rec.709. Blackbody: Planck's law at the
temperature, normalised to luminance 1 (the node gives a colour, not an
intensity). Wavelength: the matching functions at one wavelength, scaled by
1 / 2.52 and clipped at zero, as Cycles' node does.
"""

import numpy as np

from .evaluate import node, vec

XYZ_TO_REC709 = np.array([[3.2404542, -1.5371385, -0.4985314],
                          [-0.9692660, 1.8760108, 0.0415560],
                          [0.0556434, -0.2040259, 1.0572252]], np.float64)


def _g(x, mu, s1, s2):
    s = np.where(x < mu, s1, s2)
    t = (x - mu) / s
    return np.exp(-0.5 * t * t)


def cie_xyz(nm):
    """CIE 1931 2-degree matching functions at wavelengths in nm: (..., 3)."""
    x = (1.056 * _g(nm, 599.8, 37.9, 31.0) + 0.362 * _g(nm, 442.0, 16.0, 26.7)
         - 0.065 * _g(nm, 501.1, 20.4, 26.2))
    y = 0.821 * _g(nm, 568.8, 46.9, 40.5) + 0.286 * _g(nm, 530.9, 16.3, 31.1)
    z = 1.217 * _g(nm, 437.0, 11.8, 36.0) + 0.681 * _g(nm, 459.0, 26.0, 13.8)
    return np.stack([x, y, z], axis=-1)


_NM = np.arange(380.0, 781.0, 5.0)
_CMF = cie_xyz(_NM)


def blackbody_rec709(kelvin):
    """Linear Rec.709 colour of a black body, luminance 1."""
    t = np.clip(np.asarray(kelvin, np.float64), 800.0, 1e5)
    lam = _NM * 1e-9
    c2 = 1.4387769e-2
    planck = 1.0 / (lam ** 5 * np.expm1(c2 / (lam * t[..., None])))
    xyz = planck @ _CMF
    rgb = np.clip(xyz @ XYZ_TO_REC709.T, 0, None)
    y = xyz[..., 1:2]
    return (rgb / np.where(y > 0, y, 1)).astype(np.float32)


@node("BLACKBODY")
def blackbody(inp, geom, n, sh):
    return {"Color": vec(blackbody_rec709(inp.float("Temperature", 1500.0)))}


@node("WAVELENGTH")
def wavelength(inp, geom, n, sh):
    xyz = cie_xyz(np.asarray(inp.float("Wavelength", 500.0), np.float64))
    return {"Color": vec(np.clip(xyz @ XYZ_TO_REC709.T / 2.52, 0, None))}
