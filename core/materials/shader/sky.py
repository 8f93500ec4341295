"""Blender's Sky Texture: the node's settings to radiance, as Cycles renders it.

Preetham and Hosek-Wilkie are closed forms (core/materials/shader/sky_analytic.py).

Single and Multiple Scattering (core/materials/shader/sky_scattering.py builds their
tables) are read as Cycles' kernel reads them (svm sky): the ray's azimuth
from the sun picks the column, its elevation the row through the table's
square-root spacing, bilinearly with clamped edges; XYZ goes to linear
Rec.709 with negatives clipped. The sun's disc (``sun_disc``) is drawn
where the ray is within half its angular diameter of the sun and above the
Earth's edge: radiance blended between the disc's bottom and top by
elevation, times a limb darkening 1 - 0.6 (1 - sqrt(1 - (angle / half)^2)),
times ``sun_intensity``. Single Scattering's ground fades to black within
0.4 of the horizon (in z); Multiple Scattering has a lit ground.

Sun elevation and rotation are normalised as Cycles' simplify_settings does
(an elevation past the zenith turns the sun around), so animated suns agree.
Tables are cached per parameter set.
"""

from functools import lru_cache

import numpy as np

from . import sky_scattering as scattering
from .nodes_spectrum import XYZ_TO_REC709

SCATTERING = ("SINGLE_SCATTERING", "MULTIPLE_SCATTERING")
MIN_SUN_SIZE = 0.0005       # Cycles' clamp of the sun's angular diameter
LIMB = 0.6


def normalised_sun(elevation, rotation):
    """(elevation in [-pi/2, pi/2], Cycles' kernel rotation) as simplify_settings makes them."""
    two_pi = 2 * np.pi
    e = np.fmod(float(elevation), two_pi)
    r = float(rotation)
    if abs(e) >= np.pi:
        e -= np.copysign(2.0, e) * np.pi
    if e >= np.pi / 2 or e <= -np.pi / 2:
        e = np.copysign(np.pi, e) - e
        r += np.pi
    r = np.fmod(r, two_pi)
    if r < 0:
        r += two_pi
    return e, two_pi - r


class ScatteringSky:
    """One Single or Multiple Scattering sky: its table, its sun, and radiance(d)."""

    def __init__(self, multiple, sun_disc, sun_size, sun_intensity, sun_elevation, sun_rotation,
                 altitude, air, aerosol, ozone):
        self.multiple = bool(multiple)
        self.elevation, self.rotation = normalised_sun(sun_elevation, sun_rotation)
        self.diameter = max(float(sun_size), MIN_SUN_SIZE)
        self.sun_disc = bool(sun_disc)
        self.intensity = float(sun_intensity)
        self.earth_angle = -float(scattering.earth_intersection_angle(altitude))
        self.table = _table(self.multiple, self.elevation, altitude, air, aerosol, ozone)
        if self.multiple:
            sun = scattering.multiple_scattering_sun(self.elevation, self.diameter, altitude, air, aerosol, ozone)
        else:
            sun = scattering.single_scattering_sun(self.elevation, self.diameter, altitude, air, aerosol)
        self.sun_xyz = sun                  # (2, 3) bottom and top of the disc
        e, r = self.elevation, self.rotation
        # Cycles' spherical_to_direction(elevation - pi/2, rotation - pi/2).
        self.sun_direction = np.array([-np.cos(e) * np.cos(r - np.pi / 2), -np.cos(e) * np.sin(r - np.pi / 2),
                                       np.sin(e)])

    @property
    def has_sun(self):
        """Whether a disc is drawn (and is bright): the environment samples it apart."""
        visible = self.elevation + self.diameter / 2 > self.earth_angle
        if not self.multiple:
            visible = visible and self.elevation + self.diameter / 2 > 0
        return self.sun_disc and self.intensity > 0 and visible and bool((self.sun_xyz > 0).any())

    def _lookup(self, u, v):
        """Bilinear table lookup, clamped at the edges (Cycles' linear, extend)."""
        t = self.table
        h, w = t.shape[:2]
        x = u * np.float32(w) - np.float32(0.5)
        y = v * np.float32(h) - np.float32(0.5)
        x0, y0 = np.floor(x), np.floor(y)
        fx, fy = (x - x0)[:, None], (y - y0)[:, None]
        x0, y0 = x0.astype(np.int64), y0.astype(np.int64)
        x1, y1 = np.clip(x0 + 1, 0, w - 1), np.clip(y0 + 1, 0, h - 1)
        x0, y0 = np.clip(x0, 0, w - 1), np.clip(y0, 0, h - 1)
        flat = t.reshape(-1, 3)
        a, b = np.take(flat, y0 * w + x0, axis=0), np.take(flat, y0 * w + x1, axis=0)
        c, d = np.take(flat, y1 * w + x0, axis=0), np.take(flat, y1 * w + x1, axis=0)
        top = a + fx * (b - a)
        return top + fy * (c + fx * (d - c) - top)

    def radiance(self, d):
        """(N, 3) float32 linear Rec.709 radiance toward directions d (N, 3)."""
        d = np.asarray(d, np.float32).reshape(-1, 3)
        length = np.sqrt(np.einsum("ij,ij->i", d, d))
        z = np.clip(d[:, 2] / np.where(length > 0, length, 1), -1.0, 1.0)
        elev = np.arcsin(z)
        phi = np.arctan2(d[:, 1], d[:, 0])
        u = np.mod((-phi - np.float32(np.pi / 2) + np.float32(self.rotation)) / np.float32(2 * np.pi), 1.0)
        v = np.sqrt(np.abs(elev) / np.float32(np.pi / 2)) * np.sign(elev) * 0.5 + 0.5
        below = np.zeros(len(d), bool) if self.multiple else z < 0
        if below.any():
            v = np.where(below, np.float32(0.508), v)
        rgb = _to_rgb(self._lookup(u, v))
        if below.any():
            fade = np.where(z < -0.4, 0.0, np.maximum(1.0 + 2.5 * z, 0.0) ** 3).astype(np.float32)
            rgb = np.where(below[:, None], rgb * fade[:, None], rgb)
        if self.sun_disc:
            half = self.diameter / 2
            # Candidates by a loose cosine test, then the precise angle (float64).
            near = np.nonzero(d @ self.sun_direction.astype(np.float32) > np.cos(2 * half) * length)[0]
            if len(near):
                angle = _angle(d[near].astype(np.float64), self.sun_direction)
                e = np.arcsin(np.clip(z[near].astype(np.float64), -1, 1))
                disc = (angle < half) & (e > self.earth_angle) & ~below[near]
                i, angle, e = near[disc], angle[disc], e[disc]
                y = ((e - self.elevation) / self.diameter + 0.5)[:, None]
                xyz = self.sun_xyz[0] + y * (self.sun_xyz[1] - self.sun_xyz[0])
                limb = 1.0 - LIMB * (1.0 - np.sqrt(np.maximum(1.0 - (angle / half) ** 2, 0.0)))
                rgb[i] += _to_rgb(xyz) * (limb * self.intensity).astype(np.float32)[:, None]
        return rgb


_M = XYZ_TO_REC709.astype(np.float32)


def _to_rgb(xyz):
    xyz = np.asarray(xyz, np.float32)
    x, y, z = xyz[:, 0], xyz[:, 1], xyz[:, 2]
    return np.maximum(np.stack([_M[r, 0] * x + _M[r, 1] * y + _M[r, 2] * z for r in range(3)], axis=1), 0.0)


def _angle(d, s):
    """Angles between rows of d (not necessarily unit) and unit s, precise near zero."""
    length = np.sqrt((d * d).sum(axis=1))
    u = d / np.where(length > 0, length, 1.0)[:, None]
    return 2 * np.arctan2(np.sqrt(((u - s) ** 2).sum(axis=1)), np.sqrt(((u + s) ** 2).sum(axis=1)))


@lru_cache(maxsize=8)
def _table(multiple, elevation, altitude, air, aerosol, ozone):
    """The sky's table (float32), shared by skies that differ only in their
    sun's rotation, size or intensity."""
    build = scattering.multiple_scattering_table if multiple else scattering.single_scattering_table
    return build(elevation, altitude, air, aerosol, ozone).astype(np.float32)


@lru_cache(maxsize=16)
def _scattering_sky(params):
    return ScatteringSky(*params)


def scattering_params(props):
    """The hashable parameter set of a node's settings (props: Node.props)."""
    return (props.get("sky_type", "MULTIPLE_SCATTERING") == "MULTIPLE_SCATTERING",
            bool(props.get("sun_disc", True)), float(props.get("sun_size", 0.009512044)),
            float(props.get("sun_intensity", 1.0)), float(props.get("sun_elevation", np.radians(15.0))),
            float(props.get("sun_rotation", 0.0)), float(props.get("altitude", 100.0)),
            float(props.get("air_density", 1.0)), float(props.get("aerosol_density", 1.0)),
            float(props.get("ozone_density", 1.0)))


@lru_cache(maxsize=16)
def _analytic_sky(sky_type, sun_direction, turbidity, ground_albedo):
    from .sky_analytic import HosekWilkieSky, PreethamSky   # noqa: PLC0415
    if sky_type == "PREETHAM":
        return PreethamSky(sun_direction, turbidity)
    return HosekWilkieSky(sun_direction, turbidity, ground_albedo)


def sky_model(props):
    """The sky a Sky Texture node of settings props renders, or None where
    the type is not modelled (the caller falls back)."""
    sky_type = props.get("sky_type", "MULTIPLE_SCATTERING")
    if sky_type in SCATTERING:
        return _scattering_sky(scattering_params(props))
    if sky_type in ("PREETHAM", "HOSEK_WILKIE"):
        return _analytic_sky(sky_type, tuple(float(x) for x in props.get("sun_direction", (0.0, 0.0, 1.0))),
                             float(props.get("turbidity", 2.2)), float(props.get("ground_albedo", 0.3)))
    return None
