"""Surfaces rays pass through: transparent materials (Transparent BSDF,
Principled Alpha) and objects hidden from some rays (Blender's ray visibility:
camera, shadow, and diffuse, glossy or transmission for the rays of paths by
the kind of their bounce).

A hit on a material that can be transparent lets the ray through with the
probability of its transparent share t (the mean of the closure's transparent
colour at that hit): the ray continues from just behind the surface, up to
MAX_TRANSPARENT surfaces, as Cycles' transparent bounces do. A ray that
stops there sees the surface's other lobes divided by 1 - t
(core/materials/shading.py), so the expectation is Cycles' mix of the two. Shadow
rays pass the same way, so an alpha-clipped leaf casts a leaf-shaped shadow
and a half-transparent pane lets half the light through on average.

The choice is made with a hash of the triangle, the point on it, the
distance along the ray and the surface count: deterministic (a path re-traced with its seed finds
the same surfaces, as ReSTIR's validation needs) yet uncorrelated between
rays. An object hidden from a kind of ray is passed by every ray of that
kind: camera rays (Camera visibility), shadow rays (Shadow), the rays of
paths by their kind (Diffuse, Glossy, Transmission: integrators/bounces.py)
and ReSTIR's reconnections (Diffuse). ``TransparentAccel`` wraps an
acceleration structure and is used only for scenes that have such materials
or objects; others trace as before.
"""

import numpy as np

from .bounces import KIND_NAMES
from ..geometry.interaction import surface_hits
from ..materials.shading import shading, transparency

MAX_TRANSPARENT = 8
_STEP = np.float32(1e-4)     # relative step past a surface, times the scene extent


def _hash_uniform(prim, t, salt, u=None, v=None):
    """Uniforms in [0, 1) from triangle ids, hit distances, the hits'
    barycentrics (so parallel rays at one distance differ) and a salt."""
    h = prim.astype(np.uint32) * np.uint32(0x9E3779B1)
    h ^= np.ascontiguousarray(t, np.float32).view(np.uint32) * np.uint32(0x85EBCA77)
    for i, x in enumerate((u, v)):
        if x is not None:
            h ^= np.ascontiguousarray(x, np.float32).view(np.uint32) * np.uint32((0x27D4EB2F, 0x165667B1)[i])
            h ^= h >> np.uint32(13)
    h ^= np.uint32((salt * 0xC2B2AE3D) & 0xFFFFFFFF)
    h ^= h >> np.uint32(16)
    h *= np.uint32(0x7FEB352D)
    h ^= h >> np.uint32(15)
    h *= np.uint32(0x846CA68B)
    h ^= h >> np.uint32(16)
    return (h >> np.uint32(8)).astype(np.float32) * np.float32(1.0 / (1 << 24))


class TransparentAccel:
    """An acceleration structure whose queries pass transparent surfaces
    stochastically (see the module notes); everything else is the wrapped one's."""

    def __init__(self, inner, scene, transparent_triangles, pass_probability, hidden=None):
        self.inner = inner
        self.scene = scene
        self.flag = transparent_triangles          # (T,) bool
        self.pass_probability = pass_probability   # fn(scene, surf) -> (N,)
        # (T,) bool per kind of ray: triangles of objects hidden from it.
        none = np.zeros(len(transparent_triangles), bool)
        self.hidden = {kind: none for kind in ("camera", "shadow") + KIND_NAMES}
        self.hidden.update(hidden or {})
        self.step = _STEP * np.float32(scene.extent())
        # Rays of paths pick diffuse, glossy or transmission visibility by
        # their kind (integrators/bounces.py) where the objects differ in them.
        per_kind = [self.hidden[k] for k in KIND_NAMES]
        self.per_kind_visibility = any((h != per_kind[0]).any() for h in per_kind[1:])
        self._hidden_by_kind = np.stack(per_kind) if self.per_kind_visibility else None
        self._hidden_by_any = self._hidden_by_kind.any(axis=0) if self.per_kind_visibility else None

    def __getattr__(self, name):
        return getattr(self.inner, name)

    def intersect_closest(self, origins, directions, tmax=None, camera=False, kinds=None):
        """Closest hits of camera rays, or of path rays of the given kinds
        (diffuse where None)."""
        if camera:
            return self._closest(origins, directions, tmax, self.hidden["camera"])
        if kinds is None or self._hidden_by_kind is None:
            return self._closest(origins, directions, tmax, self.hidden["diffuse"])
        return self._closest(origins, directions, tmax, self._hidden_by_any,
                             lambda rows, prim: self._hidden_by_kind[kinds[rows], prim])

    def _closest(self, origins, directions, tmax, hidden, hidden_at=None, shadow=False):
        """hidden: (T,) triangles some of the rays pass; hidden_at(rows, prim):
        which of those rays pass their hit triangles (all of them if None);
        shadow: shadow rays (materials see Light Path > Is Shadow Ray)."""
        o = np.ascontiguousarray(origins, np.float32).reshape(-1, 3)
        d = np.ascontiguousarray(directions, np.float32).reshape(-1, 3)
        hits = self.inner.intersect_closest(o, d, tmax)
        stop_flag = self.flag | hidden
        if not len(o):
            return hits
        limit = None if tmax is None else np.array(np.broadcast_to(np.asarray(tmax, np.float32), (len(o),)))
        travelled = np.zeros(len(o), np.float32)
        rows = np.arange(len(o))        # rays still moving: the rest stopped for good
        for k in range(MAX_TRANSPARENT):
            rows = rows[hits.hit[rows] & np.take(stop_flag, np.maximum(hits.prim[rows], 0))]
            if len(rows) == 0:
                break
            go = np.take(hidden, hits.prim[rows]) if hidden_at is None else hidden_at(rows, hits.prim[rows])
            if not go.all():
                maybe = np.nonzero(~go)[0]
                go[maybe] = self._passes(o, d, hits, rows[maybe], k, shadow)
            rows = rows[go]
            if len(rows) == 0:
                break
            travelled[rows] = hits.t[rows] + self.step       # hits.t: from the first origin
            start = o[rows] + d[rows] * travelled[rows][:, None]
            rest = None if limit is None else np.maximum(limit[rows] - travelled[rows], 1e-30)
            again = self.inner.intersect_closest(start, d[rows], rest)
            hits.prim[rows] = again.prim
            hits.u[rows], hits.v[rows] = again.u, again.v
            hits.t[rows] = np.where(again.prim >= 0, again.t + travelled[rows], np.inf)
        return hits

    def _passes(self, o, d, hits, rows, k, shadow=False):
        """Which of the hit rows go through their surface."""
        sub = type(hits)(hits.t[rows], hits.prim[rows], hits.u[rows], hits.v[rows])
        surf, _ = surface_hits(self.scene, o[rows], d[rows], sub)
        p = self.pass_probability(self.scene, surf, shadow)
        u = _hash_uniform(hits.prim[rows], hits.t[rows], k + 1, hits.u[rows], hits.v[rows])
        return u < p

    def occluded(self, origins, directions, tmax):
        blocked = self.inner.occluded(origins, directions, tmax)
        rows = np.nonzero(blocked)[0]
        if len(rows) == 0:
            return blocked
        o = np.ascontiguousarray(origins, np.float32).reshape(-1, 3)[rows]
        d = np.ascontiguousarray(directions, np.float32).reshape(-1, 3)[rows]
        limit = np.array(np.broadcast_to(np.asarray(tmax, np.float32), (len(blocked),)))[rows]
        hits = self._closest(o, d, limit, self.hidden["shadow"], shadow=True)
        blocked[rows] = hits.hit & (hits.t < limit)
        return blocked


def wrap(accel, scene):
    """accel, wrapped in a TransparentAccel when the scene has materials that
    can be transparent or objects hidden from some rays
    (``scene.ray_visibility``: (O, 5) bool, camera / shadow / diffuse / glossy /
    transmission rays; (O, 3) gives diffuse for all three)."""
    if scene.triangle_count == 0:
        return accel
    sh = shading(scene)
    flag = np.zeros(scene.triangle_count, bool)
    if sh.transparent_ids:
        flag = np.isin(scene.material_ids, np.fromiter(sh.transparent_ids, np.int32))
    hidden = {}
    vis = getattr(scene, "ray_visibility", None)
    if vis is not None and len(vis) and not np.asarray(vis).all():
        vis = np.asarray(vis, bool)
        if vis.shape[1] == 3:               # (camera, shadow, diffuse for all other rays)
            vis = vis[:, [0, 1, 2, 2, 2]]
        per_tri = np.take(vis, scene.object_ids, axis=0)
        hidden = {kind: ~per_tri[:, i] for i, kind in enumerate(("camera", "shadow") + KIND_NAMES)}
    if not flag.any() and not any(h.any() for h in hidden.values()):
        return accel
    return TransparentAccel(accel, scene, flag, transparency, hidden)
