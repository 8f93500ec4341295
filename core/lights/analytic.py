"""Analytic lights (point, spot, sun, area): sampling toward them and what rays crossing them see.

Brightness follows Cycles (docs/cycles-conventions.md):
- point / spot of power P and radius r: radiance P / (4 pi^2 r^2), i.e.
  intensity P / (4 pi); with soft falloff (Blender's default) the emitter is a
  disk of radius r facing the receiver, otherwise a sphere; r = 0 is a point;
- spot mask: smoothstep((cos a - cos(size/2)) / ((1 - cos(size/2)) blend));
- sun of strength E: irradiance E on a surface facing it, spread over its disk;
- area light of power P and area A: one-sided radiance P / (pi A) along -Z;
- Light Falloff in a light's node tree (scene.Lights ``falloff`` and
  ``falloff_smooth``): radiance times d^k (k = 1 Linear, 2 Constant) and
  d^2 / (s + d^2) for a Smooth s > 0, d the distance from the shading point
  to the point sampled on the light (Cycles' ray length); suns have none.
Lights are not surfaces: they cast no shadow and rays pass through them;
camera rays see them only where ``camera_visible`` is set (off by default).

Every sampling routine takes (li, p, u, n=None) (light indices, receivers,
uniforms, receivers' normals, unused here) and returns (wi, dist, radiance,
pdf, delta) rows with the pdf of the light alone (core/lights/light_set.py multiplies in
the selection probability). Rows are grouped by the routine that samples them
and each routine runs on its own rows only (np.where over all routines would
compute every one of them for every row). Per-light constants come from
per_row: a broadcasting (1, ...) slice when every row uses the same light (a
scene with one light), else a row gather. Gathers and scatters use
core/util/rows.py (a[idx] and out[idx] = v are several times slower on (N, 3) rows).
"""

import numpy as np

from ..util.rows import divide, gather, matmul3, scale, scatter, scatter_add
from ..util.vectors import dot, luminance, orthonormal_basis, to_world
from ..sampling.warps import power_heuristic, square_to_concentric_disk, square_to_uniform_cone
from ..scene import LIGHT_AREA, LIGHT_POINT, LIGHT_SPOT, LIGHT_SUN, SHAPE_DISK, SHAPE_ELLIPSE

INF_DIST = np.float32(1e30)     # distance of lights at infinity (the sun, the world)

# Shapes of point and spot lights (AnalyticLights.sphere_kind).
_POINT, _DISK, _BALL = range(3)


def _one_minus_cos_cone(r2_over_d2):
    """1 - sqrt(1 - x), accurate for small x."""
    x = np.clip(r2_over_d2, 0.0, 1.0)
    return x / (1.0 + np.sqrt(1.0 - x))


def _smoothstep(x):
    x = np.clip(x, 0.0, 1.0)
    return x * x * (3.0 - 2.0 * x)


def same_index(li):
    """li[0] when every row uses the same light (e.g. a scene with one), else None."""
    if len(li) and li[0] == li[-1] and (li == li[0]).all():
        return int(li[0])
    return None


def per_row(table, li, one):
    """table[li]: a (1, ...) slice broadcasting over the rows when they all use
    light ``one``, else a row gather (core/util/rows.py: a[li] is slow on (N, 3) rows)."""
    return table[one:one + 1] if one is not None else gather(table, li)


def rows_where(mask, rows):
    """np.where(mask[:, None], rows, 0) as float32 (N, 3), as a product with the
    0/1 mask: the same for finite rows and several times faster than np.where."""
    return scale(rows, mask.astype(np.float32)).astype(np.float32, copy=False)


def empty_sample(n):
    """(wi, dist, radiance, pdf, delta) of n rows that sampled nothing."""
    wi = np.zeros((n, 3), np.float32)
    wi[:, 2] = 1
    return wi, np.zeros(n, np.float32), np.zeros((n, 3), np.float32), np.zeros(n, np.float32), \
        np.zeros(n, bool)


def by_code(codes, present, routines, li, p, u, n=None):
    """Light samples where each row is drawn by routines[codes[row]](li, p, u, n),
    each routine run on its own rows only (gathered and scattered by core/util/rows.py)."""
    out = empty_sample(len(li))
    for code in present:
        fn = routines.get(code)
        rows = np.nonzero(codes == code)[0] if fn else ()
        if len(rows):
            n_rows = None if n is None else gather(n, rows)
            for o, v in zip(out, fn(np.take(li, rows), gather(p, rows), gather(u, rows), n_rows)):
                scatter(o, rows, v)
    return out


class AnalyticLights:
    """The analytic lights of a scene (scene.Lights rows) and their per-light constants."""

    def __init__(self, lights):
        self.lights = lights
        ellipse = (lights.shape == SHAPE_DISK) | (lights.shape == SHAPE_ELLIPSE)
        self.area = np.where(ellipse, np.pi / 4, 1.0) * lights.size_u * lights.size_v
        self.area = np.maximum(self.area, 1e-12).astype(np.float32)
        self.ellipse = ellipse
        radius = np.asarray(lights.radius)
        self.sphere_kind = np.where(radius <= 0, _POINT,
                                    np.where(lights.soft_falloff, _DISK, _BALL)).astype(np.int8)
        self._sphere_routines = {_POINT: self._sample_point, _DISK: self._sample_sphere_disk,
                                 _BALL: self._sample_sphere_cone}
        self._sun_constants()
        self._falloff_constants()

    def _falloff_constants(self):
        """Per-light Light Falloff (exponent, smooth) and whether it changes
        anything (not for suns: Cycles leaves distant lights' falloff out)."""
        lt = self.lights
        n = len(lt)
        k = np.zeros(n, np.float32) if getattr(lt, "falloff", None) is None else \
            np.asarray(lt.falloff, np.float32)
        smooth = np.zeros(n, np.float32) if getattr(lt, "falloff_smooth", None) is None else \
            np.asarray(lt.falloff_smooth, np.float32)
        active = ((k != 0) | (smooth > 0)) & (np.asarray(lt.kind) != LIGHT_SUN)
        self._falloff = (k, smooth, active) if active.any() else None

    def _with_falloff(self, rad, li, one, dist):
        """rad (N, 3) times each row's Light Falloff factor at the distance
        dist (N,) to its light sample (module notes)."""
        if self._falloff is None or (one is not None and not self._falloff[2][one]):
            return rad
        k, smooth, active = (per_row(a, li, one) for a in self._falloff)
        d = np.maximum(np.asarray(dist, np.float64), 0.0)
        d2 = d * d
        g = np.power(d, k) * np.where(smooth > 0, d2 / np.maximum(smooth + d2, 1e-30), 1.0)
        g = np.where(active, g, 1.0)
        return scale(np.broadcast_to(rad, (len(d), 3)), g.astype(np.float32)).astype(np.float32, copy=False)

    def __len__(self):
        return len(self.lights)

    def selection_weights(self, scene_radius):
        """Weights ~ emitted power: luminance of the power, and for suns their
        irradiance over the scene's disk of radius scene_radius."""
        lights = self.lights
        p = luminance(lights.power) if len(lights) else np.zeros(0, np.float32)
        return np.where(lights.kind == LIGHT_SUN, p * np.pi * scene_radius ** 2, p)

    def crossable(self):
        """False when no ray can cross a light, so that emitted_along gives
        zero everywhere: only suns and points of zero radius."""
        lt = self.lights
        if len(lt) == 0:
            return False
        kind = np.asarray(lt.kind)
        sized = ((kind == LIGHT_POINT) | (kind == LIGHT_SPOT)) & (np.asarray(lt.radius) > 0)
        return bool(((kind == LIGHT_AREA) | sized).any())

    def _spot_mask(self, li, dir_from_light):
        lt = self.lights
        one = same_index(li)
        if one is not None and lt.kind[one] != LIGHT_SPOT:
            return np.ones(len(li), np.float32)
        spot = per_row(lt.kind, li, one) == LIGHT_SPOT
        cos_a = dot(dir_from_light, per_row(lt.direction, li, one))
        cos_half = np.cos(0.5 * per_row(lt.spot_size, li, one))
        smooth = (1.0 - cos_half) * per_row(lt.spot_blend, li, one)
        hard = (cos_a > cos_half).astype(np.float32)
        soft = _smoothstep((cos_a - cos_half) / np.where(smooth > 0, smooth, 1.0))
        if one is not None:         # one spot light: its own mask only
            return (soft if smooth[0] > 0 else hard).astype(np.float32)
        mask = np.where(smooth > 0, soft, hard)
        return np.where(spot, mask, 1.0).astype(np.float32)

    def sample_sphere(self, li, p, u, n=None):
        """Point and spot lights: a true point (r = 0), a disk of radius r facing
        the receiver (soft falloff) or a sphere sampled by its cone."""
        one = same_index(li)
        if one is not None:
            return self._sphere_routines[self.sphere_kind[one]](li, p, u)
        return by_code(np.take(self.sphere_kind, li), (_POINT, _DISK, _BALL),
                        self._sphere_routines, li, p, u)

    def _sphere_common(self, li, p):
        """Per-light constants and the receiver-to-centre geometry."""
        lt = self.lights
        one = same_index(li)
        c = per_row(lt.position, li, one)
        r = per_row(lt.radius, li, one)
        to_c = c - p
        d2 = np.maximum(dot(to_c, to_c), 1e-20)
        d = np.sqrt(d2)
        axis = divide(to_c, d).astype(np.float32, copy=False)
        r2 = r * r
        outside = d2 > r2 * 1.0001
        return one, r, to_c, d2, d, axis, r2, outside

    def _sphere_radiance(self, li, one, wi, r2, d2=None):
        """Radiance (intensity / d2 for a point) of point/spot lights toward -wi,
        spot mask included."""
        power = per_row(self.lights.power, li, one)
        if one is None or self.lights.kind[one] == LIGHT_SPOT:
            power = power * self._spot_mask(li, -wi)[:, None]
        intensity = power / (4.0 * np.pi)
        if d2 is not None:
            return intensity / d2[:, None]
        return intensity / np.maximum(np.pi * r2, 1e-30)[:, None]

    @staticmethod
    def _outside_only(rad, outside, n):
        """Radiance as fresh (n, 3) float32 rows, zero for receivers inside the light."""
        rad = np.array(np.broadcast_to(rad, (n, 3)), np.float32)
        if not outside.all():
            scatter(rad, np.nonzero(~outside)[0], 0.0)
        return rad

    def _sample_point(self, li, p, u, n=None):
        """Point/spot lights of radius 0 (delta lights)."""
        one, r, to_c, d2, d, axis, r2, outside = self._sphere_common(li, p)
        rad = self._outside_only(self._sphere_radiance(li, one, axis, r2, d2), outside, len(p))
        rad = self._with_falloff(rad, li, one, d)
        return (axis, d.astype(np.float32), rad, np.ones(len(p), np.float32),
                np.ones(len(p), bool))

    def _sample_sphere_disk(self, li, p, u, n=None):
        """Soft falloff: a disk of radius r through the centre facing the receiver,
        uniform by area."""
        one, r, to_c, d2, d, axis, r2, outside = self._sphere_common(li, p)
        t, b = orthonormal_basis(axis)
        xy = square_to_concentric_disk(u) * r[:, None]
        to_q = to_c + scale(t, xy[:, 0])
        to_q += scale(b, xy[:, 1])
        dq2 = np.maximum(dot(to_q, to_q), 1e-20)
        dq = np.sqrt(dq2)
        wi = divide(to_q, dq).astype(np.float32, copy=False)
        cos_q = np.maximum(dot(wi, axis), 1e-12)
        pdf = dq2 / (cos_q * np.pi * np.maximum(r2, 1e-30))
        rad = self._outside_only(self._sphere_radiance(li, one, wi, r2), outside, len(p))
        rad = self._with_falloff(rad, li, one, dq)
        return (wi, dq.astype(np.float32), rad, pdf.astype(np.float32),
                np.zeros(len(p), bool))

    def _sample_sphere_cone(self, li, p, u, n=None):
        """A sphere of radius r, uniform in the cone it subtends."""
        one, r, to_c, d2, d, axis, r2, outside = self._sphere_common(li, p)
        t, b = orthonormal_basis(axis)
        one_minus = _one_minus_cos_cone(r2 / d2)
        local = square_to_uniform_cone(u, 1.0 - one_minus)
        wi = to_world(local, t, b, axis).astype(np.float32, copy=False)
        proj = dot(to_c, wi)
        dist = proj - np.sqrt(np.maximum(r2 - (d2 - proj * proj), 0.0))
        pdf = 1.0 / (2.0 * np.pi * np.maximum(one_minus, 1e-30))
        rad = self._outside_only(self._sphere_radiance(li, one, wi, r2), outside, len(p))
        rad = self._with_falloff(rad, li, one, dist)
        return (wi, dist.astype(np.float32), rad, pdf.astype(np.float32),
                np.zeros(len(p), bool))

    def _sun_constants(self):
        """Per-light sun quantities, computed once: axis toward the sun, its frame,
        1 - cos(half angle) (without cancellation: the default 0.526 degree sun
        has 1 - cos ~ 1e-5), pdf and radiance of the disk."""
        lt = self.lights
        axis = (-lt.direction).astype(np.float32)
        t, b = orthonormal_basis(axis) if len(axis) else (axis, axis)
        half = 0.5 * np.asarray(lt.angle, np.float64)
        one_minus = 2.0 * np.sin(0.5 * half) ** 2
        point = half <= 0
        pdf = np.where(point, 1.0, 1.0 / np.maximum(2.0 * np.pi * one_minus, 1e-30))
        radiance = np.where(point[:, None], lt.power,
                            lt.power / np.maximum(np.pi * np.sin(half) ** 2, 1e-30)[:, None])
        self._sun = (axis, t, b, one_minus, point, pdf.astype(np.float32), radiance.astype(np.float32))

    def sample_sun(self, li, p, u, n=None):
        n = len(li)
        one = 0 if len(self.lights) == 1 else same_index(li)
        axis, t, b, one_minus, point, pdf, radiance = (per_row(a, li, one) for a in self._sun)
        dist = np.full(n, INF_DIST, np.float32)
        if one is not None:             # one sun: its constants broadcast over the rows
            radiance = np.array(np.broadcast_to(radiance, (n, 3)))
            pdf = np.full(n, pdf[0], np.float32)
            if point[0]:
                return np.array(np.broadcast_to(axis, (n, 3))), dist, radiance, pdf, np.ones(n, bool)
        # Uniform in the cone: 1 - cos(theta) = u0 (1 - cos_max), kept in float64.
        om = u[:, 0].astype(np.float64) * one_minus
        cos_t = 1.0 - om
        sin_t = np.sqrt(np.maximum(om * (2.0 - om), 0.0))
        phi = 2.0 * np.pi * u[:, 1]
        x = (sin_t * np.cos(phi)).astype(np.float32)
        y = (sin_t * np.sin(phi)).astype(np.float32)
        z = cos_t.astype(np.float32)
        if one is not None:             # to_world with a constant frame, column by column
            wi = np.stack([x * t[0, k] + y * b[0, k] + z * axis[0, k] for k in range(3)], axis=1)
            return wi, dist, radiance, pdf, np.ones(n, bool)
        local = np.stack([x, y, z], axis=1)
        wi = np.where(point[:, None], axis, to_world(local, t, b, axis)).astype(np.float32)
        return wi, dist, radiance, pdf, np.ones(n, bool)

    def _area_point(self, li, u):
        lt = self.lights
        one = same_index(li)
        if one is not None:
            xy = square_to_concentric_disk(u) * 0.5 if self.ellipse[one] else u - 0.5
        else:
            xy = np.where(self.ellipse[li][:, None], square_to_concentric_disk(u) * 0.5, u - 0.5)
        return (per_row(lt.position, li, one)
                + xy[:, 0:1] * per_row(lt.size_u, li, one)[:, None] * per_row(lt.axis_u, li, one)
                + xy[:, 1:2] * per_row(lt.size_v, li, one)[:, None] * per_row(lt.axis_v, li, one))

    def sample_area(self, li, p, u, n=None):
        lt = self.lights
        one = same_index(li)
        area = per_row(self.area, li, one)
        q = self._area_point(li, u)
        to_q = q - p
        d2 = np.maximum(dot(to_q, to_q), 1e-20)
        d = np.sqrt(d2)
        wi = divide(to_q, d).astype(np.float32, copy=False)
        cos_l = -dot(wi, per_row(lt.direction, li, one))       # > 0 on the emitting side
        radiance = per_row(lt.power, li, one) / (np.pi * area)[:, None]
        front = cos_l > 0
        pdf = np.where(front, d2 / np.maximum(cos_l, 1e-12) / area, 0.0)
        rad = self._with_falloff(rows_where(front, radiance), li, one, d)
        return wi, d.astype(np.float32), rad, pdf.astype(np.float32), np.zeros(len(li), bool)

    # --- what rays crossing the lights see ---------------------------------------------

    def emitted_along(self, o, d, tmax, pmf, pdf_bsdf=None, hidden=None):
        """Radiance of the analytic lights crossed by rays o + t d, 0 < t < tmax,
        weighted against NEE by the power heuristic (pmf: each light's selection
        probability, or pmf(light, rows) giving it at those rays). pdf_bsdf
        None means camera rays: weight one, and only lights marked
        camera_visible. hidden: (L, N) or (L, 1) bool, the rays each light is
        hidden from."""
        n = len(o)
        total = np.zeros((n, 3), np.float32)
        if len(self.lights) == 0 or n == 0:
            return total
        lt = self.lights
        for li in range(len(self.lights)):
            kind = lt.kind[li]
            if pdf_bsdf is None and not lt.camera_visible[li]:
                continue
            if hidden is not None and hidden[li].all():
                continue
            # Selection probability: the geometry's factor below, times the
            # emitter's probability at the rows that see it (a callable
            # pmf(li, rows) is evaluated there only).
            pmf_li = 1.0 if callable(pmf) else pmf[li]
            if kind == LIGHT_AREA:
                nrm = lt.direction[li]
                den = matmul3(d, nrm)
                t = matmul3(lt.position[li] - o, nrm) / np.where(den != 0, den, 1)
                hit = (den < 0) & (t > 0) & (t < tmax)
                if not hit.any():
                    continue
                q = o + scale(d, t) - lt.position[li]
                x = matmul3(q, lt.axis_u[li]) / lt.size_u[li]
                y = matmul3(q, lt.axis_v[li]) / lt.size_v[li]
                inside = (x * x + y * y <= 0.25) if self.ellipse[li] else ((np.abs(x) <= 0.5) & (np.abs(y) <= 0.5))
                hit &= inside
                rows = np.nonzero(hit)[0]
                le = lt.power[li] / (np.pi * self.area[li])
                pdf_light = pmf_li * t * t / np.maximum(-den, 1e-12) / self.area[li]
            elif kind in (LIGHT_POINT, LIGHT_SPOT) and lt.radius[li] > 0:
                c = lt.position[li]
                r = lt.radius[li]
                oc = c - o
                d2 = np.maximum(dot(oc, oc), 1e-20)
                if lt.soft_falloff[li]:
                    # Disk through c facing the ray origin.
                    nrm = divide(-oc, np.sqrt(d2))
                    den = dot(d, nrm)
                    # (c - o) . nrm = -|c - o| and den < 0, so t > 0 in front of the ray.
                    t = dot(oc, nrm) / np.where(den < 0, den, -1.0)
                    q = o + scale(d, t) - c
                    hit = (den < 0) & (t > 0) & (t < tmax) & (dot(q, q) <= r * r)
                    pdf_light = pmf_li * t * t / (np.maximum(-den, 1e-12) * np.pi * r * r)
                else:
                    proj = dot(oc, d)
                    disc = r * r - (d2 - proj * proj)
                    t = proj - np.sqrt(np.maximum(disc, 0.0))
                    hit = (disc > 0) & (t > 0) & (t < tmax)
                    pdf_light = pmf_li / (2.0 * np.pi * np.maximum(_one_minus_cos_cone(r * r / d2), 1e-30))
                hit &= d2 > r * r
                rows = np.nonzero(hit)[0]
                if not len(rows):
                    continue
                power = lt.power[li][None, :]
                if kind == LIGHT_SPOT:
                    power = power * self._spot_mask(np.full(len(rows), li), -gather(d, rows))[:, None]
                le = power / (4.0 * np.pi * np.pi * r * r)
            else:
                continue  # point lights of zero radius and the sun: NEE only
            if self._falloff is not None and self._falloff[2][li]:
                le = self._with_falloff(le, np.full(len(rows), li), li, np.take(t, rows))
            # Only the rows that see the light (core/util/rows.py: no np.where over rows).
            if pdf_bsdf is None:
                w = np.ones(len(rows), np.float32)
            else:
                pb = pdf_bsdf if np.ndim(pdf_bsdf) == 0 else np.take(pdf_bsdf, rows)
                pl = np.take(pdf_light, rows)
                if callable(pmf):
                    pl = pl * pmf(li, rows)
                w = power_heuristic(pb, pl)
            if hidden is not None and hidden[li].any():
                w = w * ~np.take(np.broadcast_to(hidden[li], (n,)), rows)
            scatter_add(total, rows, (np.broadcast_to(le, (len(rows), 3)) * w[:, None]).astype(np.float32))
        return total
