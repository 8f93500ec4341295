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

from .sampling import (Distribution1D, dot, luminance, orthonormal_basis, power_heuristic,
                       square_to_concentric_disk, square_to_uniform_cone,
                       square_to_uniform_triangle, to_world)
from .scene import (LIGHT_AREA, LIGHT_POINT, LIGHT_SPOT, LIGHT_SUN, SHAPE_DISK,
                    SHAPE_ELLIPSE)

INF_DIST = np.float32(1e30)


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

    # --- light sampling (next-event estimation) --------------------------------

    def sample(self, p, u_select, u):
        """One light sample for each shading point p (N, 3)."""
        n = len(p)
        wi = np.zeros((n, 3), np.float32)
        wi[:, 2] = 1
        dist = np.zeros(n, np.float32)
        rad = np.zeros((n, 3), np.float32)
        pdf = np.zeros(n, np.float32)
        delta = np.zeros(n, bool)
        if self.count == 0 or n == 0:
            return LightSample(wi, dist, rad, pdf, delta)
        idx, _ = self.distribution.sample_discrete(u_select)
        pmf = self.distribution.pmf[idx]
        is_tri = idx >= self.n_analytic
        lt = self.lights
        kind = np.where(is_tri, -1, lt.kind[np.minimum(idx, max(self.n_analytic - 1, 0))] if self.n_analytic else -1)

        for sel, fn in (((kind == LIGHT_POINT) | (kind == LIGHT_SPOT), self._sample_sphere),
                        (kind == LIGHT_SUN, self._sample_sun),
                        (kind == LIGHT_AREA, self._sample_area),
                        (is_tri, self._sample_triangle)):
            rows = np.nonzero(sel)[0]
            if len(rows):
                w, d, r, pd, dl = fn(idx[rows], p[rows], u[rows])
                wi[rows], dist[rows], rad[rows], pdf[rows], delta[rows] = w, d, r, pd, dl
        pdf = pdf * pmf
        ok = (pdf > 0) & np.isfinite(pdf) & np.isfinite(rad).all(axis=1)
        rad = np.where(ok[:, None], rad, 0.0).astype(np.float32)
        return LightSample(wi, dist, rad, np.where(ok, pdf, 0.0).astype(np.float32), delta)

    def _spot_mask(self, li, dir_from_light):
        lt = self.lights
        spot = lt.kind[li] == LIGHT_SPOT
        cos_a = dot(dir_from_light, lt.direction[li])
        cos_half = np.cos(0.5 * lt.spot_size[li])
        smooth = (1.0 - cos_half) * lt.spot_blend[li]
        hard = (cos_a > cos_half).astype(np.float32)
        soft = _smoothstep((cos_a - cos_half) / np.where(smooth > 0, smooth, 1.0))
        mask = np.where(smooth > 0, soft, hard)
        return np.where(spot, mask, 1.0).astype(np.float32)

    def _sample_sphere(self, li, p, u):
        """Point and spot lights: a true point (r = 0), a disk of radius r facing
        the receiver (soft falloff) or a sphere sampled by its cone."""
        lt = self.lights
        c = lt.position[li]
        r = lt.radius[li]
        to_c = c - p
        d2 = np.maximum(dot(to_c, to_c), 1e-20)
        d = np.sqrt(d2)
        axis = (to_c / d[:, None]).astype(np.float32)
        r2 = r * r
        outside = d2 > r2 * 1.0001
        point = r <= 0
        soft = lt.soft_falloff[li] & ~point
        t, b = orthonormal_basis(axis)
        # Sphere: uniform in the cone it subtends.
        one_minus = _one_minus_cos_cone(r2 / d2)
        local = square_to_uniform_cone(u, np.where(point, 1.0, 1.0 - one_minus))
        wi_sphere = to_world(local, t, b, axis)
        proj = dot(to_c, wi_sphere)
        dist_sphere = proj - np.sqrt(np.maximum(r2 - (d2 - proj * proj), 0.0))
        pdf_sphere = 1.0 / (2.0 * np.pi * np.maximum(one_minus, 1e-30))
        # Disk facing the receiver: uniform by area.
        xy = square_to_concentric_disk(u) * r[:, None]
        to_q = to_c + xy[:, 0:1] * t + xy[:, 1:2] * b
        dq2 = np.maximum(dot(to_q, to_q), 1e-20)
        dq = np.sqrt(dq2)
        wi_disk = to_q / dq[:, None]
        cos_q = np.maximum(dot(wi_disk, axis), 1e-12)
        pdf_disk = dq2 / (cos_q * np.pi * np.maximum(r2, 1e-30))

        wi = np.where(point[:, None], axis, np.where(soft[:, None], wi_disk, wi_sphere)).astype(np.float32)
        dist = np.where(point, d, np.where(soft, dq, dist_sphere)).astype(np.float32)
        pdf = np.where(point, 1.0, np.where(soft, pdf_disk, pdf_sphere))
        power = lt.power[li] * self._spot_mask(li, -wi)[:, None]
        intensity = power / (4.0 * np.pi)
        radiance = intensity / np.maximum(np.pi * r2, 1e-30)[:, None]
        rad = np.where(point[:, None], intensity / d2[:, None], radiance)
        rad = np.where(outside[:, None], rad, 0.0)
        return wi, dist, rad.astype(np.float32), pdf.astype(np.float32), point

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
        axis, t, b, one_minus, point, pdf, radiance = (a[li] for a in self._sun)
        # Uniform in the cone: 1 - cos(theta) = u0 (1 - cos_max), kept in float64.
        om = u[:, 0].astype(np.float64) * one_minus
        cos_t = 1.0 - om
        sin_t = np.sqrt(np.maximum(om * (2.0 - om), 0.0))
        phi = 2.0 * np.pi * u[:, 1]
        local = np.stack([sin_t * np.cos(phi), sin_t * np.sin(phi), cos_t], axis=1).astype(np.float32)
        wi = np.where(point[:, None], axis, to_world(local, t, b, axis)).astype(np.float32)
        dist = np.full(len(li), INF_DIST, np.float32)
        return wi, dist, radiance, pdf, np.ones(len(li), bool)

    def _area_point(self, li, u):
        lt = self.lights
        disk = square_to_concentric_disk(u) * 0.5
        rect = u - 0.5
        xy = np.where(self.ellipse[li][:, None], disk, rect)
        return (lt.position[li] + xy[:, 0:1] * lt.size_u[li][:, None] * lt.axis_u[li]
                + xy[:, 1:2] * lt.size_v[li][:, None] * lt.axis_v[li])

    def _sample_area(self, li, p, u):
        lt = self.lights
        q = self._area_point(li, u)
        to_q = q - p
        d2 = np.maximum(dot(to_q, to_q), 1e-20)
        d = np.sqrt(d2)
        wi = (to_q / d[:, None]).astype(np.float32)
        cos_l = -dot(wi, lt.direction[li])       # > 0 on the emitting side
        radiance = lt.power[li] / (np.pi * self.area[li])[:, None]
        front = cos_l > 0
        pdf = np.where(front, d2 / np.maximum(cos_l, 1e-12) / self.area[li], 0.0)
        rad = np.where(front[:, None], radiance, 0.0)
        return wi, d.astype(np.float32), rad.astype(np.float32), pdf.astype(np.float32), np.zeros(len(li), bool)

    def _sample_triangle(self, li, p, u):
        slot = li - self.n_analytic
        b1, b2 = square_to_uniform_triangle(u)
        q = self.tri_p0[slot] + b1[:, None] * self.tri_e1[slot] + b2[:, None] * self.tri_e2[slot]
        to_q = q - p
        d2 = np.maximum(dot(to_q, to_q), 1e-20)
        d = np.sqrt(d2)
        wi = (to_q / d[:, None]).astype(np.float32)
        cos_l = -dot(wi, self.tri_normal[slot])
        visible_side = np.abs(cos_l) > 1e-7 if self.two_sided else cos_l > 1e-7
        pdf = np.where(visible_side, d2 / np.maximum(np.abs(cos_l), 1e-12) / self.tri_area[slot], 0.0)
        rad = np.where(visible_side[:, None], self.tri_emission[slot], 0.0)
        return wi, d.astype(np.float32), rad.astype(np.float32), pdf.astype(np.float32), np.zeros(len(li), bool)

    # --- what BSDF-sampled rays see ---------------------------------------------

    def triangle_emission(self, prim, front):
        """Radiance leaving emissive triangles toward the ray that hit them."""
        slot = self.tri_slot[prim]
        le = np.where((slot >= 0)[:, None], self.tri_emission[np.maximum(slot, 0)] if len(self.tri_index) else 0.0, 0.0)
        if not self.two_sided:
            le = np.where(front[:, None], le, 0.0)
        return le.astype(np.float32)

    def pdf_triangle(self, prim, p_ref, p_hit, wi):
        """NEE solid-angle pdf of having sampled the hit point on an emissive triangle."""
        slot = self.tri_slot[prim]
        ok = slot >= 0
        s = np.maximum(slot, 0)
        if not len(self.tri_index):
            return np.zeros(len(prim), np.float32)
        pmf = self.distribution.pmf[self.n_analytic + s]
        to_q = p_hit - p_ref
        d2 = dot(to_q, to_q)
        cos_l = np.abs(dot(wi, self.tri_normal[s]))
        pdf = pmf * d2 / np.maximum(cos_l, 1e-12) / self.tri_area[s]
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
                den = d @ nrm
                t = ((lt.position[li] - o) @ nrm) / np.where(den != 0, den, 1)
                hit = (den < 0) & (t > 0) & (t < tmax)
                if not hit.any():
                    continue
                q = o + d * t[:, None] - lt.position[li]
                x = (q @ lt.axis_u[li]) / lt.size_u[li]
                y = (q @ lt.axis_v[li]) / lt.size_v[li]
                inside = (x * x + y * y <= 0.25) if self.ellipse[li] else ((np.abs(x) <= 0.5) & (np.abs(y) <= 0.5))
                hit &= inside
                le = lt.power[li] / (np.pi * self.area[li])
                pdf_light = pmf * t * t / np.maximum(-den, 1e-12) / self.area[li]
            elif kind in (LIGHT_POINT, LIGHT_SPOT) and lt.radius[li] > 0:
                c = lt.position[li]
                r = lt.radius[li]
                oc = c - o
                d2 = np.maximum(np.einsum("ij,ij->i", oc, oc), 1e-20)
                if lt.soft_falloff[li]:
                    # Disk through c facing the ray origin.
                    nrm = -oc / np.sqrt(d2)[:, None]
                    den = np.einsum("ij,ij->i", d, nrm)
                    # (c - o) . nrm = -|c - o| and den < 0, so t > 0 in front of the ray.
                    t = np.einsum("ij,ij->i", oc, nrm) / np.where(den < 0, den, -1.0)
                    q = o + d * t[:, None] - c
                    hit = (den < 0) & (t > 0) & (t < tmax) & (np.einsum("ij,ij->i", q, q) <= r * r)
                    pdf_light = pmf * t * t / (np.maximum(-den, 1e-12) * np.pi * r * r)
                else:
                    proj = np.einsum("ij,ij->i", oc, d)
                    disc = r * r - (d2 - proj * proj)
                    t = proj - np.sqrt(np.maximum(disc, 0.0))
                    hit = (disc > 0) & (t > 0) & (t < tmax)
                    pdf_light = pmf / (2.0 * np.pi * np.maximum(_one_minus_cos_cone(r * r / d2), 1e-30))
                hit &= d2 > r * r
                if not hit.any():
                    continue
                power = lt.power[li][None, :] * self._spot_mask(np.full(n, li), -d)[:, None]
                le = power / (4.0 * np.pi * np.pi * r * r)
            else:
                continue  # point lights of zero radius and the sun: NEE only
            w = np.ones(n, np.float32) if pdf_bsdf is None else power_heuristic(pdf_bsdf, pdf_light)
            total += np.where(hit[:, None], np.broadcast_to(le, (n, 3)) * w[:, None], 0.0).astype(np.float32)
        return total
