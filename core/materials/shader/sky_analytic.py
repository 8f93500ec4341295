"""The Sky Texture's analytic models: Preetham and Hosek-Wilkie, as Cycles evaluates them.

Both are closed forms of the angle theta of the ray from the zenith and the
angle gamma between the ray and the sun, with parameters fixed per sun
direction and turbidity; neither draws a sun disc. Cycles reads the sun's
direction (the node's ``sun_direction``) as theta = acos(z), phi =
atan2(x, y), a ray's as phi = pi/2 - atan2(y, x), and clamps the ray's theta
just above the horizon, so the ground mirrors the horizon's colour.

- Preetham, Shirley and Smits 1999, "A Practical Analytic Model for
  Daylight": Perez et al.'s five-parameter luminance distribution
  F = (1 + A e^(B / cos theta)) (1 + C e^(D gamma) + E cos^2 gamma) for each of
  Y, x, y, parameters linear in turbidity, scaled to the paper's zenith values
  (Y's times 0.06, as Cycles scales it), then xyY to XYZ.
- Hosek and Wilkie 2012, "An Analytic Model for Full Spectral Sky-Dome
  Radiance": nine parameters per XYZ channel, interpolated from the published
  tables (core/materials/shader/sky_hosek_data.py) by a quintic Bezier over the cube
  root of the sun's elevation, linearly over ground albedo (0, 1) and
  turbidity (1..10); F = (1 + A e^(B / (cos theta + 0.01))) (C + D e^(E gamma)
  + F cos^2 gamma + G chi(H, gamma) + I sqrt(cos theta)) times the channel's
  radiance, times 2 pi / 683 (Cycles' scale of the luminous model).

XYZ goes to linear Rec.709 with negatives clipped, as in Cycles.
"""

from math import comb

import numpy as np

from .nodes_spectrum import XYZ_TO_REC709

_HORIZON = np.pi / 2 - 0.001
_BEZIER = np.array([comb(5, k) for k in range(6)], np.float64)


def _sun_angles(direction):
    d = np.asarray(direction, np.float64).reshape(3)
    return float(np.arccos(np.clip(d[2], -1.0, 1.0))), float(np.arctan2(d[0], d[1]))


def _view_angles(d, sun_theta, sun_phi):
    """(theta clamped above the horizon, gamma) of ray directions d (N, 3)."""
    d = np.asarray(d, np.float64).reshape(-1, 3)
    theta = np.arccos(np.clip(d[:, 2], -1.0, 1.0))
    phi = np.pi / 2 - np.arctan2(d[:, 1], d[:, 0])
    cos_g = np.sin(theta) * np.sin(sun_theta) * np.cos(sun_phi - phi) + np.cos(theta) * np.cos(sun_theta)
    return np.minimum(theta, _HORIZON), np.arccos(np.clip(cos_g, -1.0, 1.0))


def _to_rgb(xyz):
    return np.maximum(xyz @ XYZ_TO_REC709.T, 0.0).astype(np.float32)


def _perez(lam, theta, gamma):
    return (1.0 + lam[0] * np.exp(lam[1] / np.cos(theta))) * \
        (1.0 + lam[2] * np.exp(lam[3] * gamma) + lam[4] * np.cos(gamma) ** 2)


class PreethamSky:
    has_sun = False

    def __init__(self, sun_direction, turbidity):
        self.theta, self.phi = _sun_angles(sun_direction)
        t, s = float(turbidity), self.theta
        s2, s3 = s * s, s * s * s
        chi = (4.0 / 9.0 - t / 120.0) * (np.pi - 2.0 * s)
        zenith = np.array([
            ((4.0453 * t - 4.9710) * np.tan(chi) - 0.2155 * t + 2.4192) * 0.06,
            (0.00166 * s3 - 0.00375 * s2 + 0.00209 * s) * t * t
            + (-0.02903 * s3 + 0.06377 * s2 - 0.03202 * s + 0.00394) * t
            + (0.11693 * s3 - 0.21196 * s2 + 0.06052 * s + 0.25886),
            (0.00275 * s3 - 0.00610 * s2 + 0.00317 * s) * t * t
            + (-0.04214 * s3 + 0.08970 * s2 - 0.04153 * s + 0.00516) * t
            + (0.15346 * s3 - 0.26756 * s2 + 0.06670 * s + 0.26688)])
        # Perez parameters of Y, x and y: rows A..E, linear in turbidity.
        slope = np.array([[0.1787, -0.3554, -0.0227, 0.1206, -0.0670],
                          [-0.0193, -0.0665, -0.0004, -0.0641, -0.0033],
                          [-0.0167, -0.0950, -0.0079, -0.0441, -0.0109]])
        offset = np.array([[-1.4630, 0.4275, 5.3251, -2.5771, 0.3703],
                           [-0.2592, 0.0008, 0.2125, -0.8989, 0.0452],
                           [-0.2608, 0.0092, 0.2102, -1.6537, 0.0529]])
        self.perez = slope * t + offset
        self.zenith = zenith / np.array([_perez(lam, 0.0, s) for lam in self.perez])

    def radiance(self, d):
        theta, gamma = _view_angles(d, self.theta, self.phi)
        big_y, x, y = (self.zenith[i] * _perez(self.perez[i], theta, gamma) for i in range(3))
        safe_y = np.where(y != 0, y, 1.0)
        big_x = np.where(y != 0, x / safe_y * big_y, 0.0)
        big_z = np.where((y != 0) & (big_y != 0), (1.0 - x - y) / safe_y * big_y, 0.0)
        return _to_rgb(np.stack([big_x, big_y, big_z], axis=1))


def _cook(table, turbidity, albedo, elevation):
    """Blend a Hosek-Wilkie table (albedo, turbidity, 6 control points, ...)
    at turbidity and albedo, over the cube root of the elevation."""
    e = (elevation / (np.pi / 2)) ** (1.0 / 3.0)
    k = np.arange(6)
    weights = _BEZIER * (1.0 - e) ** (5 - k) * e ** k
    t = int(turbidity)
    rem = turbidity - t

    def at(a, ti):
        return np.tensordot(weights, table[a, ti], axes=(0, 0))

    out = (1.0 - rem) * ((1.0 - albedo) * at(0, t - 1) + albedo * at(1, t - 1))
    if t < 10:
        out = out + rem * ((1.0 - albedo) * at(0, t) + albedo * at(1, t))
    return out


class HosekWilkieSky:
    has_sun = False

    def __init__(self, sun_direction, turbidity, ground_albedo):
        from .sky_hosek_data import CONFIGS, RADIANCES   # noqa: PLC0415 (a large table)
        theta, self.phi = _sun_angles(sun_direction)
        self.theta = float(np.clip(theta, 0.0, np.pi / 2))
        # Cycles clamps turbidity to [0, 10]; the tables start at 1.
        t = float(np.clip(turbidity, 1.0, 10.0))
        a = float(ground_albedo)
        elevation = np.pi / 2 - self.theta
        self.config = np.stack([_cook(CONFIGS[c], t, a, elevation) for c in range(3)])       # (3, 9)
        self.scale = np.array([_cook(RADIANCES[c], t, a, elevation) for c in range(3)])    # (3,)

    def radiance(self, d):
        theta, gamma = _view_angles(d, self.theta, self.phi)
        c = self.config[:, :, None]                         # (3, 9, 1) against (N,)
        cos_t, cos_g = np.cos(theta), np.cos(gamma)
        mie = (1.0 + cos_g * cos_g) / (1.0 + c[:, 8] ** 2 - 2.0 * c[:, 8] * cos_g) ** 1.5
        f = (1.0 + c[:, 0] * np.exp(c[:, 1] / (cos_t + 0.01))) * \
            (c[:, 2] + c[:, 3] * np.exp(c[:, 4] * gamma) + c[:, 5] * cos_g * cos_g + c[:, 6] * mie
             + c[:, 7] * np.sqrt(cos_t))
        xyz = (f * self.scale[:, None]).T
        return _to_rgb(xyz) * np.float32(2.0 * np.pi / 683.0)
