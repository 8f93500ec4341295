"""The world as a light: its radiance by direction, importance-sampled as Cycles does.

Directions are Blender world space (z up). The equirectangular mapping is
Cycles' (``direction_to_equirectangular``)::

    u = (atan2(y, x) - pi) / (-2 pi)        +X at u = 0.5, +Y at 0.25, -Y at 0.75, -X at 0 and 1
    v = (theta - pi) / (-pi)                 theta = polar angle from +Z: +Z at v = 1, -Z at v = 0

so an image's bottom row (row 0 of Blender's ``Image.pixels``) is the nadir.
theta is taken as atan2(sqrt(x^2 + y^2), z) rather than acos(z): the same angle,
without acos' loss of precision next to the poles.

Importance map (Cycles' ``background_cdf`` in scene/light.cpp and
``background_map_sample`` / ``background_map_pdf`` in kernel/light/background.h):
``resolution`` x ``resolution / 2`` texels; each texel's weight is the average
of |R|, |G|, |B| of the radiance at its centre (Cycles shades the background at
texel centres) times sin(theta) of its row's centre; per-row conditional CDFs
and a marginal CDF over rows pick a texel, and the sample is uniform inside it
in (u, v). The density is piecewise constant in (u, v), f_uv = weight * W H /
total (mean one), and since d(omega) = 2 pi^2 sin(theta) du dv,

    pdf(omega) = f_uv / (2 pi^2 sin(theta)),

with sin(theta) of the direction itself; it is zero where sin(theta) vanishes
(the poles, a set of measure zero).

A sky with a sun disc (``sun``: its direction and angular radius, from
core/lights/world.py) is sampled as Cycles' sun guiding does: the disc,
half a degree wide, is smaller than a texel and the map would find it only
by chance, a firefly each time. Texels whose centre lies in the disc get the
sky just beside it, and a share ``sun_pmf`` of the samples (the disc's power
against the map's, kept within [0.05, 0.95]) is drawn uniformly in the
disc's cone; the density is the mixture of both, so a BSDF ray that finds
the disc is weighed against it too.

A constant world has no map. Its light sampler is cosine-weighted about the
receiver's normal when one is given (then, for a Lambert surface under an open
sky, light sampling and BSDF sampling have the same density and their MIS
combination is exact for every sample), else uniform over the sphere.

Radiance is sanitised: non-finite values and negative channels become zero.
"""

import hashlib

import numpy as np

from ..util.rows import divide, matmul3
from ..sampling.warps import (
    INV_4PI, cosine_hemisphere_pdf, square_to_cosine_hemisphere, square_to_uniform_sphere)
from ..util.vectors import dot, orthonormal_basis, to_world

CHUNK = 1 << 18             # directions per radiance_fn call while building the map
_MIN_SIN = 1e-7             # sin(theta) below this: a pole, pdf zero
_TWO_PI2 = 2.0 * np.pi * np.pi
_U_TOP = np.nextafter(1.0, 0.0)
_SUN_PMF_MIN, _SUN_PMF_MAX = 0.05, 0.95   # a sun's share of the samples, kept from either end
_SUN_POINTS = 256           # points over the disc that estimate its power


def _unit_directions(d):
    """(N, 3) float32 unit rows; zero, non-finite or malformed rows become +Z."""
    d = np.asarray(d, np.float32).reshape(-1, 3)
    length = np.sqrt(dot(d, d))
    ok = np.isfinite(length) & (length > 0)
    out = divide(d, np.where(ok, length, 1.0).astype(np.float32)).astype(np.float32)
    if not ok.all():
        out[~ok] = (0.0, 0.0, 1.0)
    return out


def _sanitise(rgb, n):
    """(n, 3) float32 radiance: finite and non-negative."""
    rgb = np.asarray(rgb, np.float32).reshape(n, 3)
    return np.maximum(np.nan_to_num(rgb, nan=0.0, posinf=0.0, neginf=0.0), 0.0).astype(np.float32)


def direction_to_uv(d):
    """Cycles' equirectangular (u, v) in [0, 1] of directions d (N, 3) and sin(theta):
    (u (N,), v (N,), sin_theta (N,)), float64."""
    d = np.asarray(d, np.float64).reshape(-1, 3)
    rho = np.sqrt(d[:, 0] ** 2 + d[:, 1] ** 2)
    length = np.sqrt(rho ** 2 + d[:, 2] ** 2)
    theta = np.arctan2(rho, d[:, 2])
    u = (np.arctan2(d[:, 1], d[:, 0]) - np.pi) / (-2.0 * np.pi)
    v = (theta - np.pi) / (-np.pi)
    sin_t = np.where(length > 0, rho / np.where(length > 0, length, 1.0), 0.0)
    return u, v, sin_t


def uv_to_direction(u, v):
    """Unit directions (N, 3) float32 of equirectangular coordinates (inverse of direction_to_uv)."""
    phi = np.pi * (1.0 - 2.0 * np.asarray(u, np.float64))
    theta = np.pi * (1.0 - np.asarray(v, np.float64))
    s = np.sin(theta)
    return np.stack([s * np.cos(phi), s * np.sin(phi), np.cos(theta)], axis=1).astype(np.float32)


def _rotation(rotation):
    """A 3x3 matrix from None, an angle about +Z (radians) or a 3x3 matrix."""
    if rotation is None:
        return None
    r = np.asarray(rotation, np.float64)
    if r.ndim == 0:
        c, s = np.cos(float(r)), np.sin(float(r))
        return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    return r.reshape(3, 3)


def equirect_lookup(pixels_hw3, d):
    """Bilinear lookup of an equirectangular image at directions d (N, 3), as a
    Cycles Environment Texture with Linear interpolation: pixel centres at
    half-integers (the -0.5 offset), periodic in u, clamped in v."""
    img = pixels_hw3
    h, w = img.shape[:2]
    u, v, _ = direction_to_uv(d)
    x = u * w - 0.5
    y = v * h - 0.5
    x0 = np.floor(x)
    y0 = np.floor(y)
    fx = (x - x0).astype(np.float32)[:, None]
    fy = (y - y0).astype(np.float32)[:, None]
    x0 = x0.astype(np.int64) % w
    x1 = (x0 + 1) % w
    y1 = np.clip(y0.astype(np.int64) + 1, 0, h - 1)
    y0 = np.clip(y0.astype(np.int64), 0, h - 1)
    flat = img.reshape(h * w, 3)

    def at(yy, xx):
        return np.take(flat, yy * w + xx, axis=0)

    top = at(y0, x0) * (1 - fx) + at(y0, x1) * fx
    bottom = at(y1, x0) * (1 - fx) + at(y1, x1) * fx
    return (top * (1 - fy) + bottom * fy).astype(np.float32)


class Environment:
    """The world as a light: radiance(direction), importance sampling as Cycles does it.

    radiance_fn(d (N, 3) float32 unit directions) -> (N, 3) radiance; it may be
    expensive (a node graph), so it is called on whole arrays: once per batch
    of directions, and over every texel centre (in chunks of CHUNK) to build
    the map. constant: (3,) radiance of a constant world (no map then).
    camera_radiance: what camera rays see instead, where that differs (a
    world graph reading Light Path; core/lights/world.py), else None.
    """

    camera_radiance = None

    def __init__(self, radiance_fn, resolution=1024, constant=None, sun=None):
        self._fn = radiance_fn
        self.sun = None if sun is None or constant is not None else (
            np.asarray(sun[0], np.float64) / np.linalg.norm(sun[0]), float(sun[1]))
        self.sun_pmf = 0.0
        self._has_map = False
        self.constant = None if constant is None else _sanitise(constant, 1)[0]
        self.width = max(2, int(resolution))
        self.height = max(1, self.width // 2)
        self.version = 0            # a builder may bump it; digest() includes it
        if self.constant is not None:
            self.mean_radiance = self.constant.copy()
            self.is_black = not bool((self.constant > 0).any())
            self._digest = hashlib.sha1(b"constant" + self.constant.tobytes()).digest()
            return
        self._build()

    # --- construction ---------------------------------------------------------------

    @staticmethod
    def constant_color(rgb):
        """A constant world of radiance rgb (3,)."""
        return Environment(None, constant=rgb)

    @staticmethod
    def from_equirect(pixels_hw3, strength=1.0, rotation=None):
        """An equirectangular image (H, W, 3 or 4; row 0 at the bottom, as
        Blender's Image.pixels) times ``strength``, looked up bilinearly.
        rotation: an angle about +Z or a 3x3 matrix applied to directions
        before the lookup (a Mapping node in front of the texture). The map has
        the image's width, as Cycles' automatic resolution."""
        img = np.asarray(pixels_hw3, np.float32)
        if img.ndim != 3 or img.shape[2] < 3:
            raise ValueError("from_equirect expects an (H, W, 3) or (H, W, 4) image")
        img = np.ascontiguousarray(np.nan_to_num(img[:, :, :3], nan=0.0, posinf=0.0, neginf=0.0))
        img *= np.float32(strength)
        rot = _rotation(rotation)

        def radiance(d):
            if rot is not None:
                d = matmul3(d, rot.T.astype(np.float32))
            return equirect_lookup(img, d)

        return Environment(radiance, resolution=img.shape[1])

    def _build(self):
        """Evaluate the radiance at every texel centre; weights, CDFs, mean, digest."""
        w, h = self.width, self.height
        v_c = (np.arange(h) + 0.5) / h
        u_c = (np.arange(w) + 0.5) / w
        step = max(1, CHUNK // w)           # rows of texels per radiance_fn call
        rgb = np.concatenate([self.radiance(uv_to_direction(np.tile(u_c, len(v_c[r:r + step])),
                                                            np.repeat(v_c[r:r + step], w)))
                              for r in range(0, h, step)]).reshape(h, w, 3)
        sun_power = self._without_sun(rgb, u_c, v_c) if self.sun is not None else None
        sin_row = np.sin(np.pi * v_c)                                   # (H,)
        weight = rgb.astype(np.float64).mean(axis=2) * sin_row[:, None]  # |RGB| = RGB: sanitised
        row_sum = weight.sum(axis=1)
        total = float(row_sum.sum())
        self.is_black = not total > 0
        # Spherical mean of the radiance: sum L sin(theta) * (2 pi^2 / (W H)) / (4 pi).
        mean = np.einsum("hwc,h->c", rgb.astype(np.float64), sin_row) * np.pi / (2.0 * w * h)
        h_ = hashlib.sha1(b"map %d %d" % (w, h))
        h_.update(rgb.tobytes())
        if sun_power is not None:
            # The disc's share of the samples: its power against the map's.
            mean += sun_power / (4.0 * np.pi)
            sky_power = total * _TWO_PI2 / (w * h)
            sun_lum = float(sun_power.mean())
            if sun_lum > 0:
                self.sun_pmf = float(np.clip(sun_lum / (sun_lum + sky_power), _SUN_PMF_MIN, _SUN_PMF_MAX)) \
                    if total > 0 else 1.0
                self.is_black = False
            h_.update(np.float64([*self.sun[0], self.sun[1], *sun_power]).tobytes())
        self.mean_radiance = mean.astype(np.float32)
        self._digest = h_.digest()
        self._has_map = total > 0
        if total <= 0:
            self.sun_pmf = 1.0 if self.sun_pmf > 0 else 0.0
            return
        cond = np.zeros((h, w + 1))
        np.cumsum(weight, axis=1, out=cond[:, 1:])
        empty = row_sum <= 0
        cond /= np.where(empty, 1.0, row_sum)[:, None]
        cond[empty, 1:] = np.arange(1, w + 1) / w       # never chosen; a valid ramp
        cond[:, -1] = 1.0
        # Rows side by side in one increasing array (row i shifted by 2 i), so
        # one searchsorted finds every sample's column in its own row.
        cond += 2.0 * np.arange(h)[:, None]
        self._cond_flat = cond.ravel()
        marg = np.zeros(h + 1)
        np.cumsum(row_sum / total, out=marg[1:])
        marg[-1] = 1.0
        self._marg = marg
        self._f_uv = (weight * (w * h / total)).astype(np.float32).ravel()

    def _without_sun(self, rgb, u_c, v_c):
        """Take the sun's disc out of the map (in place): texels whose centre
        falls in it get the sky just beside it, as Cycles' map leaves the sun
        out when a sky samples it apart. Returns the disc's power (3,): its
        mean radiance over a spread of points times its solid angle."""
        s, half = self.sun
        w, h = self.width, self.height
        _, v_sun, _ = direction_to_uv(s[None, :])
        reach = 2.0 * half / np.pi * h + 2
        rows = np.arange(max(0, int(v_sun[0] * h - reach)), min(h, int(v_sun[0] * h + reach) + 1))
        d = uv_to_direction(np.tile(u_c, len(rows)), np.repeat(v_c[rows], w)).astype(np.float64)
        inside = np.nonzero(d @ s > np.cos(half))[0]
        if len(inside):
            perp = d[inside] - np.outer(d[inside] @ s, s)
            perp /= np.maximum(np.linalg.norm(perp, axis=1), 1e-12)[:, None]
            beside = s * np.cos(1.5 * half) + perp * np.sin(1.5 * half)
            rgb[rows[inside // w], inside % w] = self.radiance(beside)
        k = np.arange(_SUN_POINTS) + 0.5
        cos_t = 1.0 - k / _SUN_POINTS * (1.0 - np.cos(half))
        phi = k * np.pi * (3.0 - np.sqrt(5.0))
        points = self._cone_directions(cos_t, phi)
        return self.radiance(points).astype(np.float64).mean(axis=0) * 2.0 * np.pi * (1.0 - np.cos(half))

    def _cone_directions(self, cos_t, phi):
        """Unit directions about the sun at polar cosines cos_t and angles phi (float64)."""
        s = self.sun[0]
        t = np.cross(s, [1.0, 0.0, 0.0] if abs(s[0]) < 0.9 else [0.0, 1.0, 0.0])
        t /= np.linalg.norm(t)
        b = np.cross(s, t)
        sin_t = np.sqrt(np.maximum(1.0 - cos_t * cos_t, 0.0))
        return ((sin_t * np.cos(phi))[:, None] * t + (sin_t * np.sin(phi))[:, None] * b
                + cos_t[:, None] * s)

    def _sun_pdf(self, d):
        """(N,) density of the sun's cone sampling at directions d; inside is
        angle < half measured as the sky measures it (2 atan2(|d - s|, |d + s|)
        of the unit d), so a sample at the disc's rim is the sun's in both."""
        s, half = self.sun
        d = np.asarray(d, np.float64)
        d = d / np.maximum(np.linalg.norm(d, axis=1), 1e-30)[:, None]
        angle = 2.0 * np.arctan2(np.linalg.norm(d - s, axis=1), np.linalg.norm(d + s, axis=1))
        return np.where(angle < half, 1.0 / (2.0 * np.pi * (1.0 - np.cos(half))), 0.0)

    # --- queries ----------------------------------------------------------------------

    def digest(self):
        """Bytes that change whenever the world's radiance does (at the texel
        centres) or the builder bumps ``version``: for Scene.lighting_key."""
        return self._digest + b"v%d" % self.version

    def radiance(self, d):
        """(N, 3) float32 radiance arriving from directions d (N, 3)."""
        d = _unit_directions(d)
        n = len(d)
        if self.constant is not None:
            return np.array(np.broadcast_to(self.constant, (n, 3)), np.float32)
        if n == 0:
            return np.zeros((0, 3), np.float32)
        return _sanitise(self._fn(d), n)

    def pdf(self, d, n=None):
        """(N,) solid-angle density of ``sample`` at directions d (n: the
        receivers' unit normals, used by constant worlds only)."""
        d = _unit_directions(d)
        if self.constant is not None:
            if self.is_black:
                return np.zeros(len(d), np.float32)
            if n is None:
                return np.full(len(d), INV_4PI, np.float32)
            return cosine_hemisphere_pdf(dot(d, np.asarray(n, np.float32)))
        if self.is_black or len(d) == 0:
            return np.zeros(len(d), np.float32)
        u, v, sin_t = direction_to_uv(d)
        col = np.clip((u * self.width).astype(np.int64), 0, self.width - 1)
        row = np.clip((v * self.height).astype(np.int64), 0, self.height - 1)
        return self._mixed_pdf(d, row, col, sin_t)

    def _mixed_pdf(self, d, row, col, sin_t):
        """The map's density, mixed with the sun's cone where a sun is sampled apart."""
        if self.sun_pmf <= 0:
            return self._map_pdf(row, col, sin_t)
        pdf = self.sun_pmf * self._sun_pdf(d)
        if self.sun_pmf < 1 and self._has_map:
            pdf += (1.0 - self.sun_pmf) * self._map_pdf(row, col, sin_t)
        return pdf.astype(np.float32)

    def _map_pdf(self, row, col, sin_t):
        f = np.take(self._f_uv, row * self.width + col)
        pole = sin_t < _MIN_SIN
        pdf = f / (_TWO_PI2 * np.where(pole, 1.0, sin_t))
        return np.where(pole | ~np.isfinite(pdf), 0.0, pdf).astype(np.float32)

    def _sample_map(self, u):
        """Directions (N, 3) float32 drawn from the map by uniforms u (N, 2) in [0, 1)."""
        w, h = self.width, self.height
        # Row from the marginal CDF, then the column from that row's CDF.
        row = np.clip(np.searchsorted(self._marg, u[:, 0], side="right") - 1, 0, h - 1)
        lo, hi = self._marg[row], self._marg[row + 1]
        dv = np.where(hi > lo, (u[:, 0] - lo) / np.where(hi > lo, hi - lo, 1.0), 0.5)
        shift = 2.0 * row
        pos = np.searchsorted(self._cond_flat, u[:, 1] + shift, side="right") - 1
        col = np.clip(pos - row * (w + 1), 0, w - 1)
        at = row * (w + 1) + col
        c_lo = np.take(self._cond_flat, at) - shift
        c_hi = np.take(self._cond_flat, at + 1) - shift
        du = np.where(c_hi > c_lo, (u[:, 1] - c_lo) / np.where(c_hi > c_lo, c_hi - c_lo, 1.0), 0.5)
        du = np.clip(du, 0.0, _U_TOP)
        dv = np.clip(dv, 0.0, _U_TOP)
        wi = uv_to_direction((col + du) / w, (row + dv) / h)
        return wi, row, col

    def sample(self, u, n=None):
        """Directions drawn from uniforms u (N, 2) in [0, 1):
        (wi (N, 3) float32, pdf (N,) solid angle, radiance (N, 3)).
        n: receivers' unit normals (N, 3), used by constant worlds only.
        Rows with pdf 0 (a black world, a pole) carry no light."""
        u = np.clip(np.nan_to_num(np.asarray(u, np.float64).reshape(-1, 2), nan=0.0), 0.0, _U_TOP)
        count = len(u)
        if self.is_black or count == 0:
            wi = np.zeros((count, 3), np.float32)
            wi[:, 2] = 1.0
            return wi, np.zeros(count, np.float32), np.zeros((count, 3), np.float32)
        if self.constant is not None:
            u32 = u.astype(np.float32)
            if n is None:
                wi = square_to_uniform_sphere(u32)
                pdf = np.full(count, INV_4PI, np.float32)
            else:
                n = np.asarray(n, np.float32)
                t, b = orthonormal_basis(n)
                wi = to_world(square_to_cosine_hemisphere(u32), t, b, n).astype(np.float32)
                pdf = cosine_hemisphere_pdf(dot(wi, n))
            return wi, pdf, self.radiance(wi)
        if self.sun_pmf <= 0:
            wi, row, col = self._sample_map(u)
            _, _, sin_t = direction_to_uv(wi)
            return wi, self._map_pdf(row, col, sin_t), self.radiance(wi)
        else:
            # Sun or map by u[:, 0], the choice's remainder reused as a uniform.
            sun = u[:, 0] < self.sun_pmf
            wi = np.empty((count, 3), np.float32)
            row = np.zeros(count, np.int64)
            col = np.zeros(count, np.int64)
            if sun.any():
                us = u[sun]
                half = self.sun[1]
                cos_t = 1.0 - (us[:, 0] / self.sun_pmf) * (1.0 - np.cos(half))
                wi[sun] = self._cone_directions(cos_t, 2.0 * np.pi * us[:, 1])
            if (~sun).any():
                um = u[~sun]
                um[:, 0] = np.clip((um[:, 0] - self.sun_pmf) / (1.0 - self.sun_pmf), 0.0, _U_TOP)
                wi[~sun], row[~sun], col[~sun] = self._sample_map(um)
        u_, v_, sin_t = direction_to_uv(wi)
        # Cone samples find their texel; map samples keep the texel they drew.
        row = np.where(sun, np.clip((v_ * self.height).astype(np.int64), 0, self.height - 1), row)
        col = np.where(sun, np.clip((u_ * self.width).astype(np.int64), 0, self.width - 1), col)
        pdf = self._mixed_pdf(wi, row, col, sin_t)
        return wi, pdf, self.radiance(wi)


def scene_environment(scene):
    """The world of a scene as an Environment, or None when it is black:
    scene.environment if set, else a constant world of scene.world_color."""
    env = getattr(scene, "environment", None)
    if env is None:
        color = np.asarray(getattr(scene, "world_color", np.zeros(3)), np.float32)
        if not (np.isfinite(color) & (color > 0)).any():
            return None
        env = Environment.constant_color(color)
    return None if env.is_black else env
