"""Emitters: analytic lights and emissive triangles, sampled in proportion to power.

``LightSet.sample`` picks one emitter per shading point and returns a direction,
its distance, the incident radiance and the solid-angle pdf (selection included);
``emitted_along`` adds what BSDF-sampled rays see of the analytic lights and
``pdf_triangle`` gives the NEE pdf of an emissive triangle that a ray hit, so
both strategies combine by multiple importance sampling.

Brightness follows Cycles (docs/cycles-conventions.md):
- point / spot of power P and radius r: radiance P / (4 pi^2 r^2), i.e.
  intensity P / (4 pi); with soft falloff (Blender's default) the emitter is a
  disk of radius r facing the receiver, otherwise a sphere; r = 0 is a point;
- spot mask: smoothstep((cos a - cos(size/2)) / ((1 - cos(size/2)) blend));
- sun of strength E: irradiance E on a surface facing it, spread over its disk;
- area light of power P and area A: one-sided radiance P / (pi A) along -Z;
- emission colour x strength and world colour x strength: radiance.
Lights are not surfaces: they cast no shadow and rays pass through them;
camera rays see them only where ``camera_visible`` is set (off by default).
"""

from dataclasses import dataclass

import numpy as np

from .rows import divide, gather, matmul3, rows_finite, scale, scatter, scatter_add
from .sampling import (Distribution1D, dot, luminance, orthonormal_basis,
                       power_heuristic, square_to_concentric_disk, square_to_uniform_cone,
                       square_to_uniform_triangle, to_world)
from .scene import (LIGHT_AREA, LIGHT_POINT, LIGHT_SPOT, LIGHT_SUN, SHAPE_DISK,
                    SHAPE_ELLIPSE)

INF_DIST = np.float32(1e30)

# Which routine samples an emitter (LightSet._group) and, for point and spot
# lights, which shape they have (LightSet._sphere_kind).
_SPHERE, _SUN, _AREA, _TRI, _NONE = range(5)
_POINT, _DISK, _BALL = range(3)


@dataclass
class LightSample:
    wi: np.ndarray          # (N, 3) unit direction from the shading point to the light
    dist: np.ndarray        # (N,) distance to the sampled point (INF_DIST for the sun)
    radiance: np.ndarray    # (N, 3) incident radiance (or irradiance-like for delta lights)
    pdf: np.ndarray         # (N,) solid-angle pdf including selection; 1 x pmf for delta lights
    delta: np.ndarray       # (N,) bool: no BSDF ray can hit this light (no MIS)


def _one_minus_cos_cone(r2_over_d2):
    """1 - sqrt(1 - x), accurate for small x."""
    x = np.clip(r2_over_d2, 0.0, 1.0)
    return x / (1.0 + np.sqrt(1.0 - x))


def _smoothstep(x):
    x = np.clip(x, 0.0, 1.0)
    return x * x * (3.0 - 2.0 * x)


def _same_index(li):
    """li[0] when every row uses the same light (e.g. a scene with one), else None."""
    if len(li) and li[0] == li[-1] and (li == li[0]).all():
        return int(li[0])
    return None


def _per_row(table, li, one):
    """table[li]: a (1, ...) slice broadcasting over the rows when they all use
    light ``one``, else a row gather (core/rows.py: a[li] is slow on (N, 3) rows)."""
    return table[one:one + 1] if one is not None else gather(table, li)


def _rows_where(mask, rows):
    """np.where(mask[:, None], rows, 0) as float32 (N, 3), as a product with the
    0/1 mask: the same for finite rows and several times faster than np.where."""
    return scale(rows, mask.astype(np.float32)).astype(np.float32, copy=False)


def _empty_sample(n):
    """(wi, dist, radiance, pdf, delta) of n rows that sampled nothing."""
    wi = np.zeros((n, 3), np.float32)
    wi[:, 2] = 1
    return wi, np.zeros(n, np.float32), np.zeros((n, 3), np.float32), np.zeros(n, np.float32), \
        np.zeros(n, bool)


def _by_code(codes, present, routines, li, p, u):
    """Light samples where each row is drawn by routines[codes[row]](li, p, u),
    each routine run on its own rows only (gathered and scattered by core/rows.py)."""
    out = _empty_sample(len(li))
    for code in present:
        fn = routines.get(code)
        rows = np.nonzero(codes == code)[0] if fn else ()
        if len(rows):
            for o, v in zip(out, fn(np.take(li, rows), gather(p, rows), gather(u, rows))):
                scatter(o, rows, v)
    return out


class LightSet:
    """All emitters of a scene with a power-proportional selection distribution."""

    def __init__(self, scene, emission_two_sided=True):
        lights = scene.lights
        self.lights = lights
        self.n_analytic = len(lights)
        self.two_sided = emission_two_sided

        # Emissive triangles.
        emission = scene.materials.emission[scene.material_ids] if scene.triangle_count else np.zeros((0, 3), np.float32)
        lum = luminance(emission) if len(emission) else np.zeros(0, np.float32)
        self.tri_index = np.nonzero(lum > 0)[0].astype(np.int32)
        tri = scene.triangles[self.tri_index]
        self.tri_p0 = scene.vertices[tri[:, 0]] if len(tri) else np.zeros((0, 3), np.float32)
        self.tri_e1 = (scene.vertices[tri[:, 1]] - self.tri_p0) if len(tri) else np.zeros((0, 3), np.float32)
        self.tri_e2 = (scene.vertices[tri[:, 2]] - self.tri_p0) if len(tri) else np.zeros((0, 3), np.float32)
        cross = np.cross(self.tri_e1, self.tri_e2) if len(tri) else np.zeros((0, 3), np.float32)
        self.tri_area = (0.5 * np.linalg.norm(cross, axis=1)).astype(np.float32)
        self.tri_normal = (cross / np.maximum(2 * self.tri_area, 1e-30)[:, None]).astype(np.float32)
        self.tri_emission = emission[self.tri_index]
        # Map from any triangle to its slot among emissive ones (-1 if not emissive).
        self.tri_slot = np.full(scene.triangle_count, -1, np.int32)
        self.tri_slot[self.tri_index] = np.arange(len(self.tri_index), dtype=np.int32)

        # Area light areas and radiance.
        ellipse = (lights.shape == SHAPE_DISK) | (lights.shape == SHAPE_ELLIPSE)
        self.area = np.where(ellipse, np.pi / 4, 1.0) * lights.size_u * lights.size_v
        self.area = np.maximum(self.area, 1e-12).astype(np.float32)
        self.ellipse = ellipse
        lo, hi = scene.bounds()
        self.scene_radius = max(0.5 * float(np.linalg.norm(hi - lo)), 1e-3)

        # Selection weights ~ emitted power (the sun: irradiance over the scene's disk).
        p = luminance(lights.power) if len(lights) else np.zeros(0, np.float32)
        w_analytic = np.where(lights.kind == LIGHT_SUN, p * np.pi * self.scene_radius ** 2, p)
        w_tri = lum[self.tri_index] * self.tri_area * np.pi * (2.0 if self.two_sided else 1.0)
        self.distribution = Distribution1D(np.concatenate([w_analytic, w_tri]))
        self._sun_constants()
        self.count = self.distribution.count if self.distribution.total > 0 else 0

        # Sampling routine of each emitter, and those that rows can select
        # (zero-weight emitters never are, except at the clipped ends of the cdf).
        kind = lights.kind
        group = np.select([(kind == LIGHT_POINT) | (kind == LIGHT_SPOT), kind == LIGHT_SUN,
                           kind == LIGHT_AREA], [_SPHERE, _SUN, _AREA], _NONE)
        self._group = np.concatenate([group, np.full(len(self.tri_index), _TRI)]).astype(np.int8)
        live = self.distribution.pmf > 0
        if len(live):
            live[[0, -1]] = True
        self._live_groups = tuple(int(g) for g in np.unique(self._group[live]))
        radius = np.asarray(lights.radius)
        self._sphere_kind = np.where(radius <= 0, _POINT,
                                     np.where(lights.soft_falloff, _DISK, _BALL)).astype(np.int8)
        self._sphere_routines = {_POINT: self._sample_point, _DISK: self._sample_sphere_disk,
                                 _BALL: self._sample_sphere_cone}

    # --- light sampling (next-event estimation) --------------------------------
    #
    # Rows are grouped by the routine that samples them and each routine runs on
    # its own rows only (np.where over all routines would compute every one of
    # them for every row). Per-light constants come from _per_row: a broadcasting
    # (1, ...) slice when every row uses the same light (a scene with one light),
    # else a row gather. Gathers and scatters use core/rows.py (a[idx] and
    # out[idx] = v are several times slower on (N, 3) rows).

    def _select(self, u_select):
        """Index of the emitter each row samples (Distribution1D.sample_discrete
        without the re-stretched u, which sampling does not use)."""
        if self.distribution.count == 1:
            return np.zeros(len(u_select), np.intp)
        idx = np.searchsorted(self.distribution.cdf, u_select, side="right") - 1
        return np.clip(idx, 0, self.distribution.count - 1)

    def sample(self, p, u_select, u):
        """One light sample for each shading point p (N, 3)."""
        n = len(p)
        if self.count == 0 or n == 0:
            return LightSample(*_empty_sample(n))
        idx = self._select(u_select)
        routines = {_SPHERE: self._sample_sphere, _SUN: self._sample_sun,
                    _AREA: self._sample_area, _TRI: self._sample_triangle}
        if len(self._live_groups) == 1:     # one kind of emitter: no regrouping
            fn = routines.get(self._live_groups[0])
            wi, dist, rad, pdf, delta = fn(idx, p, u) if fn else _empty_sample(n)
        else:
            wi, dist, rad, pdf, delta = _by_code(np.take(self._group, idx), self._live_groups,
                                                 routines, idx, p, u)
        if self.distribution.count > 1:
            pdf = pdf * np.take(self.distribution.pmf, idx)
        ok = (pdf > 0) & np.isfinite(pdf) & rows_finite(rad)
        if not ok.all():
            bad = np.nonzero(~ok)[0]
            rad = scatter(np.array(rad, np.float32), bad, 0.0)
            pdf = np.array(pdf, np.float32)
            pdf[bad] = 0.0
        return LightSample(wi, dist, rad.astype(np.float32, copy=False),
                           pdf.astype(np.float32, copy=False), delta)

    def _spot_mask(self, li, dir_from_light):
        lt = self.lights
        one = _same_index(li)
        if one is not None and lt.kind[one] != LIGHT_SPOT:
            return np.ones(len(li), np.float32)
        spot = _per_row(lt.kind, li, one) == LIGHT_SPOT
        cos_a = dot(dir_from_light, _per_row(lt.direction, li, one))
        cos_half = np.cos(0.5 * _per_row(lt.spot_size, li, one))
        smooth = (1.0 - cos_half) * _per_row(lt.spot_blend, li, one)
        hard = (cos_a > cos_half).astype(np.float32)
        soft = _smoothstep((cos_a - cos_half) / np.where(smooth > 0, smooth, 1.0))
        if one is not None:         # one spot light: its own mask only
            return (soft if smooth[0] > 0 else hard).astype(np.float32)
        mask = np.where(smooth > 0, soft, hard)
        return np.where(spot, mask, 1.0).astype(np.float32)

    def _sample_sphere(self, li, p, u):
        """Point and spot lights: a true point (r = 0), a disk of radius r facing
        the receiver (soft falloff) or a sphere sampled by its cone."""
        one = _same_index(li)
        if one is not None:
            return self._sphere_routines[self._sphere_kind[one]](li, p, u)
        return _by_code(np.take(self._sphere_kind, li), (_POINT, _DISK, _BALL),
                        self._sphere_routines, li, p, u)

    def _sphere_common(self, li, p):
        """Per-light constants and the receiver-to-centre geometry."""
        lt = self.lights
        one = _same_index(li)
        c = _per_row(lt.position, li, one)
        r = _per_row(lt.radius, li, one)
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
        power = _per_row(self.lights.power, li, one)
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

    def _sample_point(self, li, p, u):
        """Point/spot lights of radius 0 (delta lights)."""
        one, r, to_c, d2, d, axis, r2, outside = self._sphere_common(li, p)
        rad = self._outside_only(self._sphere_radiance(li, one, axis, r2, d2), outside, len(p))
        return (axis, d.astype(np.float32), rad, np.ones(len(p), np.float32),
                np.ones(len(p), bool))

    def _sample_sphere_disk(self, li, p, u):
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
        return (wi, dq.astype(np.float32), rad, pdf.astype(np.float32),
                np.zeros(len(p), bool))

    def _sample_sphere_cone(self, li, p, u):
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

    def _sample_sun(self, li, p, u):
        n = len(li)
        one = 0 if self.n_analytic == 1 else _same_index(li)
        axis, t, b, one_minus, point, pdf, radiance = (_per_row(a, li, one) for a in self._sun)
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
        one = _same_index(li)
        if one is not None:
            xy = square_to_concentric_disk(u) * 0.5 if self.ellipse[one] else u - 0.5
        else:
            xy = np.where(self.ellipse[li][:, None], square_to_concentric_disk(u) * 0.5, u - 0.5)
        return (_per_row(lt.position, li, one)
                + xy[:, 0:1] * _per_row(lt.size_u, li, one)[:, None] * _per_row(lt.axis_u, li, one)
                + xy[:, 1:2] * _per_row(lt.size_v, li, one)[:, None] * _per_row(lt.axis_v, li, one))

    def _sample_area(self, li, p, u):
        lt = self.lights
        one = _same_index(li)
        area = _per_row(self.area, li, one)
        q = self._area_point(li, u)
        to_q = q - p
        d2 = np.maximum(dot(to_q, to_q), 1e-20)
        d = np.sqrt(d2)
        wi = divide(to_q, d).astype(np.float32, copy=False)
        cos_l = -dot(wi, _per_row(lt.direction, li, one))       # > 0 on the emitting side
        radiance = _per_row(lt.power, li, one) / (np.pi * area)[:, None]
        front = cos_l > 0
        pdf = np.where(front, d2 / np.maximum(cos_l, 1e-12) / area, 0.0)
        rad = _rows_where(front, radiance)
        return wi, d.astype(np.float32), rad, pdf.astype(np.float32), np.zeros(len(li), bool)

    def _sample_triangle(self, li, p, u):
        slot = li - self.n_analytic
        one = _same_index(slot)
        b1, b2 = square_to_uniform_triangle(u)
        q = (_per_row(self.tri_p0, slot, one) + scale(_per_row(self.tri_e1, slot, one), b1)
             + scale(_per_row(self.tri_e2, slot, one), b2))
        to_q = q - p
        d2 = np.maximum(dot(to_q, to_q), 1e-20)
        d = np.sqrt(d2)
        wi = divide(to_q, d).astype(np.float32, copy=False)
        cos_l = -dot(wi, _per_row(self.tri_normal, slot, one))
        visible_side = np.abs(cos_l) > 1e-7 if self.two_sided else cos_l > 1e-7
        pdf = np.where(visible_side, d2 / np.maximum(np.abs(cos_l), 1e-12) / _per_row(self.tri_area, slot, one), 0.0)
        rad = _rows_where(visible_side, _per_row(self.tri_emission, slot, one))
        return wi, d.astype(np.float32), rad, pdf.astype(np.float32), np.zeros(len(li), bool)

    # --- what BSDF-sampled rays see ---------------------------------------------

    def triangle_emission(self, prim, front):
        """Radiance leaving emissive triangles toward the ray that hit them."""
        if not len(self.tri_index):
            return np.zeros((len(prim), 1), np.float32)   # broadcasting zeros, as always
        le = np.zeros((len(prim), 3), np.float32)
        slot = np.take(self.tri_slot, prim)
        lit = slot >= 0
        if not self.two_sided:
            lit &= front
        rows = np.nonzero(lit)[0]      # usually few: fill only those (core/rows.py)
        return scatter(le, rows, gather(self.tri_emission, np.take(slot, rows)))

    def pdf_triangle(self, prim, p_ref, p_hit, wi):
        """NEE solid-angle pdf of having sampled the hit point on an emissive triangle."""
        if not len(self.tri_index):
            return np.zeros(len(prim), np.float32)
        slot = np.take(self.tri_slot, prim)
        ok = slot >= 0
        s = np.maximum(slot, 0)
        pmf = np.take(self.distribution.pmf, self.n_analytic + s)
        to_q = p_hit - p_ref
        d2 = dot(to_q, to_q)
        cos_l = np.abs(dot(wi, gather(self.tri_normal, s)))
        pdf = pmf * d2 / np.maximum(cos_l, 1e-12) / np.take(self.tri_area, s)
        return np.where(ok, pdf, 0.0).astype(np.float32)

    def emitted_along(self, o, d, tmax, pdf_bsdf=None):
        """Radiance of the analytic lights crossed by rays o + t d, 0 < t < tmax,
        weighted against NEE by the power heuristic. pdf_bsdf None means camera
        rays: weight one, and only lights marked camera_visible."""
        n = len(o)
        total = np.zeros((n, 3), np.float32)
        if self.n_analytic == 0 or n == 0:
            return total
        lt = self.lights
        for li in range(self.n_analytic):
            kind = lt.kind[li]
            if pdf_bsdf is None and not lt.camera_visible[li]:
                continue
            pmf = self.distribution.pmf[li]
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
                pdf_light = pmf * t * t / np.maximum(-den, 1e-12) / self.area[li]
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
                    pdf_light = pmf * t * t / (np.maximum(-den, 1e-12) * np.pi * r * r)
                else:
                    proj = dot(oc, d)
                    disc = r * r - (d2 - proj * proj)
                    t = proj - np.sqrt(np.maximum(disc, 0.0))
                    hit = (disc > 0) & (t > 0) & (t < tmax)
                    pdf_light = pmf / (2.0 * np.pi * np.maximum(_one_minus_cos_cone(r * r / d2), 1e-30))
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
            # Only the rows that see the light (core/rows.py: no np.where over rows).
            if pdf_bsdf is None:
                w = np.ones(len(rows), np.float32)
            else:
                pb = pdf_bsdf if np.ndim(pdf_bsdf) == 0 else np.take(pdf_bsdf, rows)
                w = power_heuristic(pb, np.take(pdf_light, rows))
            scatter_add(total, rows, (np.broadcast_to(le, (len(rows), 3)) * w[:, None]).astype(np.float32))
        return total
