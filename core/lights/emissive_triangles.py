"""Emissive triangles as lights: the mesh faces whose materials emit.

``EmissiveTriangles`` holds their corners, areas, normals and emission
(the centre's; a graph that varies over the surface is read at each light
sample's own point, as Cycles evaluates the emitter's shader there), samples
points on them as next-event estimation sees them, and gives the pdf of a
point a BSDF-sampled ray hit and the radiance it leaves toward that ray.
Selection among them and the other emitters is core/lights/light_set.py's.

A triangle a point sees under a large solid angle (a face a few centimetres
away) is sampled uniformly over that solid angle (core/lights/spherical_triangle.py),
else uniformly over its area; both give solid-angle pdfs without selection.
"""

import numpy as np

from .analytic import per_row, rows_where, same_index
from ..materials.shading import emission_at_points, emissive_triangles, shading
from ..util.rows import divide, gather, scale, scatter
from ..util.vectors import dot, luminance
from ..sampling.warps import square_to_uniform_triangle
from . import spherical_triangle


class EmissiveTriangles:
    """The emissive triangles of ``scene`` (two_sided: they emit from both faces)."""

    def __init__(self, scene, two_sided=True):
        self.two_sided = two_sided
        candidates, emission = emissive_triangles(scene)
        # Object ids whose triangles may emit (LightSet.follow keeps the set
        # while only other objects move).
        self.emitting_objects = np.unique(scene.object_ids[candidates]) if len(candidates) \
            else np.zeros(0, np.int32)
        lum = luminance(emission) if len(emission) else np.zeros(0, np.float32)
        self.index = candidates[lum > 0].astype(np.int32)
        tri = scene.triangles[self.index]
        none = np.zeros((0, 3), np.float32)
        self.p0 = scene.vertices[tri[:, 0]] if len(tri) else none
        self.e1 = (scene.vertices[tri[:, 1]] - self.p0) if len(tri) else none
        self.e2 = (scene.vertices[tri[:, 2]] - self.p0) if len(tri) else none
        cross = np.cross(self.e1, self.e2) if len(tri) else none
        self.area = (0.5 * np.linalg.norm(cross, axis=1)).astype(np.float32)
        self.normal = (cross / np.maximum(2 * self.area, 1e-30)[:, None]).astype(np.float32)
        self.emission = emission[lum > 0]
        # Selection weight ~ emitted power: radiance x area x pi (x 2 if two-sided).
        self.power = lum[lum > 0] * self.area * np.pi * (2.0 if two_sided else 1.0)
        # Triangles whose graph varies over the surface (None: none does).
        varying = shading(scene).emitting
        self._scene = scene
        self.textured = np.isin(scene.material_ids[self.index], varying) if varying and len(tri) else None
        if self.textured is not None and not self.textured.any():
            self.textured = None
        # Map from any triangle to its slot among emissive ones (-1 if not emissive).
        self.slot = np.full(scene.triangle_count, -1, np.int32)
        self.slot[self.index] = np.arange(len(self.index), dtype=np.int32)

    def follow(self, scene):
        """The next frame of the scene, in which no emitting object changed."""
        self._scene = scene

    def __len__(self):
        return len(self.index)

    def boxes(self):
        """(T, 2, 3) bounds of each triangle."""
        corners = (self.p0, self.p0 + self.e1, self.p0 + self.e2)
        return np.stack([np.minimum(np.minimum(*corners[:2]), corners[2]),
                         np.maximum(np.maximum(*corners[:2]), corners[2])], 1)

    def sample(self, slot, p, u):
        """A point on triangles ``slot`` (N,) seen from points p (N, 3), for
        uniforms u (N, 2): (wi, dist, radiance, solid-angle pdf, delta)."""
        one = same_index(slot)
        b1, b2 = square_to_uniform_triangle(u)
        p0, e1, e2 = (per_row(t, slot, one) for t in (self.p0, self.e1, self.e2))
        # Triangles that a point sees under a large solid angle: uniform in it.
        omega, near = spherical_triangle.large_solid_angles(p, p0, e1, e2)
        if len(near):
            corners = [np.broadcast_to(v, p.shape) if len(v) == 1 and len(p) > 1 else v
                       for v in (p0, p0 + e1, p0 + e2)]
            _w, s1, s2 = spherical_triangle.sample(gather(p, near), *(gather(v, near) for v in corners),
                                                   gather(u, near))
            b1, b2 = b1.copy(), b2.copy()
            b1[near], b2[near] = s1, s2
        q = p0 + scale(e1, b1) + scale(e2, b2)
        to_q = q - p
        d2 = np.maximum(dot(to_q, to_q), 1e-20)
        d = np.sqrt(d2)
        wi = divide(to_q, d).astype(np.float32, copy=False)
        cos_l = -dot(wi, per_row(self.normal, slot, one))
        visible_side = np.abs(cos_l) > 1e-7 if self.two_sided else cos_l > 1e-7
        pdf = d2 / np.maximum(np.abs(cos_l), 1e-12) / per_row(self.area, slot, one)
        if len(near):
            pdf = pdf.astype(np.float64)
            pdf[near] = 1.0 / omega[near]
        pdf = np.where(visible_side, pdf, 0.0)
        rad = rows_where(visible_side, per_row(self.emission, slot, one))
        if self.textured is not None:
            rows = np.nonzero(np.take(self.textured, slot) & visible_side)[0]
            if len(rows):
                s = np.take(slot, rows)
                bary = np.stack([np.take(b1, rows), np.take(b2, rows)], axis=1)
                e = emission_at_points(self._scene, np.take(self.index, s), gather(q, rows),
                                       gather(self.normal, s), -gather(wi, rows), bary)
                rad = scatter(np.array(rad, np.float32), rows, e)
        return wi, d.astype(np.float32), rad, pdf.astype(np.float32), np.zeros(len(slot), bool)

    def emitted(self, prim, front):
        """Radiance leaving triangles prim (any, N) toward the rays that hit
        them on their front (N,) or back faces."""
        if not len(self.index):
            return np.zeros((len(prim), 1), np.float32)   # broadcasting zeros, as always
        le = np.zeros((len(prim), 3), np.float32)
        slot = np.take(self.slot, prim)
        lit = slot >= 0
        if not self.two_sided:
            lit &= front
        rows = np.nonzero(lit)[0]      # usually few: fill only those (core/util/rows.py)
        return scatter(le, rows, gather(self.emission, np.take(slot, rows)))

    def pdf(self, slot, p_ref, p_hit, wi):
        """Solid-angle pdf, selection aside, of sample() having given the
        point p_hit on triangles slot (N,) from p_ref along wi."""
        to_q = p_hit - p_ref
        d2 = dot(to_q, to_q)
        cos_l = np.abs(dot(wi, gather(self.normal, slot)))
        pdf = d2 / np.maximum(cos_l, 1e-12) / np.take(self.area, slot)
        omega, near = spherical_triangle.large_solid_angles(
            p_ref, gather(self.p0, slot), gather(self.e1, slot), gather(self.e2, slot))
        if len(near):       # sampled by solid angle from there (sample)
            pdf = pdf.astype(np.float64)
            pdf[near] = 1.0 / omega[near]
        return pdf
