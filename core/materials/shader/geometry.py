"""What shader nodes read about the points they shade.

``SurfaceGeometry`` serves a batch of surface hits: position, normals,
texture coordinates and attributes interpolated from the triangle corners with
the hit's barycentrics, object data by the triangle's object. Everything is
computed on first use and kept, so a graph that reads no UVs never gathers
them. ``WorldGeometry`` serves directions that escaped to the world: Cycles
gives the background shader the ray direction as its Generated, Object and
Normal coordinates.

Corner data beyond the default UV map lives in ``scene.corner_data`` under
the graph's ``needs`` keys: ``uv:<map>`` (T, 3, 2), ``color:<name>`` (T, 3, 4),
``tangent:<map>`` (T, 3, 4: tangent and bitangent sign), ``generated``
(T, 3, 3). A key the exporter did not write reads as zeros (the exporter
warns about the map it could not find).
"""

import numpy as np

from ...util.rows import gather, scale
from ...util.vectors import dot, normalize
from ...geometry.interaction import SurfaceHits


def _interpolate(corners, prim, bary):
    """Corner values (T, 3, k) at the hits' barycentrics: (N, k)."""
    c = np.take(corners, prim, axis=0)
    b1, b2 = bary[:, 0], bary[:, 1]
    b0 = 1.0 - b1 - b2
    return (c[:, 0] * b0[:, None] + c[:, 1] * b1[:, None] + c[:, 2] * b2[:, None]).astype(np.float32)


def barycentrics(scene, prim, p, with_points=False):
    """(b1, b2) of points p (N, 3) projected into triangles prim (N,), as (N, 2);
    with_points: also the projected points."""
    tri = gather(scene.triangles, prim)
    p0, p1, p2 = (gather(scene.vertices, tri[:, k]) for k in range(3))
    e1, e2 = p1 - p0, p2 - p0
    q = p - p0
    d11, d12, d22 = dot(e1, e1), dot(e1, e2), dot(e2, e2)
    q1, q2 = dot(q, e1), dot(q, e2)
    det = d11 * d22 - d12 * d12
    det = np.where(np.abs(det) > 1e-30, det, 1e-30)
    b1 = (d22 * q1 - d12 * q2) / det
    b2 = (d11 * q2 - d12 * q1) / det
    bary = np.stack([b1, b2], axis=1).astype(np.float32)
    if not with_points:
        return bary
    return bary, (p0 + scale(e1, b1) + scale(e2, b2)).astype(np.float32)


class SurfaceGeometry:
    """Lazy per-hit inputs of a batch of surface hits (see module notes)."""

    is_world = False

    def __init__(self, scene, surf, camera_ray=False, shadow_ray=False):
        self.scene = scene
        self.surf = surf
        self.n = len(surf)
        self.camera_ray = camera_ray
        self.shadow_ray = shadow_ray    # a shadow ray deciding whether it passes (Light Path)
        self._cache = {}

    def _cached(self, key, make):
        if key not in self._cache:
            self._cache[key] = make()
        return self._cache[key]

    # -- the hit itself -------------------------------------------------------
    @property
    def position(self):
        return self.surf.p

    @property
    def normal(self):
        """Shading normal (facing the incoming ray, as Cycles' N)."""
        return self.surf.ns

    @property
    def true_normal(self):
        return self.surf.ng

    @property
    def incoming(self):
        """Unit direction back toward the ray's origin (Cycles' I)."""
        return self.surf.wo

    @property
    def backfacing(self):
        return (~self.surf.front).astype(np.float32)

    @property
    def object_id(self):
        return self._cached("oid", lambda: np.take(self.scene.object_ids, self.surf.prim))

    # -- interpolated corner data ---------------------------------------------
    def corner(self, key, width):
        def make():
            data = getattr(self.scene, "corner_data", {}) or {}
            corners = data.get(key)
            if corners is None and key in ("uv:", "uv"):
                corners = self.scene.uvs
            if corners is None:
                return np.zeros((self.n, width), np.float32)
            return _interpolate(corners, self.surf.prim, self.bary)
        return self._cached(("corner", key), make)

    @property
    def bary(self):
        """The hits' barycentrics; found from their positions where the hits
        came without them (samples re-traced from stored points)."""
        if self.surf.bary is not None:
            return self.surf.bary
        return self._cached("bary", lambda: barycentrics(self.scene, self.surf.prim, self.surf.p))

    def uv(self, name=""):
        """Texture coordinates of a UV map ("" = the active render map) as (N, 3), z = 0."""
        def make():
            data = getattr(self.scene, "corner_data", {}) or {}
            key = f"uv:{name}" if f"uv:{name}" in data else "uv:"
            uv = self.corner(key, 2)
            return np.concatenate([uv, np.zeros((self.n, 1), np.float32)], axis=1)
        return self._cached(("uv", name), make)

    def attribute(self, name=""):
        """A colour/float attribute as ((N, 3) colour, (N,) alpha)."""
        rgba = self.corner(f"color:{name}", 4)
        return rgba[:, :3], rgba[:, 3]

    def tangent(self, name=""):
        """Unit tangent and bitangent sign of a UV map's tangent space ((N, 3), (N,))."""
        t = self.corner(f"tangent:{name}", 4)
        return normalize(np.ascontiguousarray(t[:, :3])), np.where(t[:, 3] < 0, -1.0, 1.0).astype(np.float32)

    @property
    def generated(self):
        """Blender's Generated coordinates (object bounds mapped to [0, 1]^3)."""
        data = getattr(self.scene, "corner_data", {}) or {}
        if "generated" in data:
            return self.corner("generated", 3)
        return self.object_coords

    @property
    def object_coords(self):
        def make():
            m = getattr(self.scene, "object_matrices", None)
            if m is None or len(m) == 0:
                return self.position
            inv = self._inverse_matrices()
            mi = np.take(inv, self.object_id, axis=0)
            p = self.position
            return (np.einsum("nij,nj->ni", mi[:, :3, :3], p) + mi[:, :3, 3]).astype(np.float32)
        return self._cached("object", make)

    def _inverse_matrices(self):
        key = "_inverse_object_matrices"
        inv = getattr(self.scene, key, None)
        if inv is None or len(inv) != len(self.scene.object_matrices):
            m = np.asarray(self.scene.object_matrices, np.float64)
            try:
                inv = np.linalg.inv(m).astype(np.float32)
            except np.linalg.LinAlgError:
                inv = np.stack([np.linalg.pinv(x) for x in m]).astype(np.float32)
            setattr(self.scene, key, inv)
        return inv

    def object_vector(self, v):
        """A world direction in the object's space (Normal output of Texture Coordinate)."""
        m = getattr(self.scene, "object_matrices", None)
        if m is None or len(m) == 0:
            return v
        # Normals transform by the inverse transpose of the object matrix:
        # into object space that is the transpose of the object matrix itself.
        mt = np.take(np.asarray(m, np.float32), self.object_id, axis=0)
        return normalize(np.einsum("nji,nj->ni", mt[:, :3, :3], v).astype(np.float32))

    def object_vector_to_world(self, v):
        """An object-space normal direction in world space (Normal Map's Object space)."""
        m = getattr(self.scene, "object_matrices", None)
        if m is None or len(m) == 0:
            return np.broadcast_to(v, (self.n, 3))
        inv = np.take(self._inverse_matrices(), self.object_id, axis=0)
        v = np.broadcast_to(np.asarray(v, np.float32), (self.n, 3))
        return normalize(np.einsum("nji,nj->ni", inv[:, :3, :3], v).astype(np.float32))

    def object_attribute(self, name):
        """(N, 4) value of an Attribute node of type Object or Instancer
        (``name``: "object:NAME" or "instancer:NAME"), per object as the
        add-on read it (restir_addon/export/object_attributes.py); zero where
        none was read."""
        values = (getattr(self.scene, "object_info", {}) or {}).get(name)
        if values is None or len(values) == 0:
            return np.zeros((self.n, 4), np.float32)
        return np.take(np.asarray(values, np.float32), self.object_id, axis=0)

    def object_info(self, name):
        """Object Info: "Location" (N, 3), "Color" (N, 3), "Random", "Alpha" and
        "Object Index" (the object's pass index) (N,)."""
        oid = self.object_id
        if name == "Location":
            m = getattr(self.scene, "object_matrices", None)
            if m is None or len(m) == 0:
                return np.zeros((self.n, 3), np.float32)
            return np.take(np.asarray(m, np.float32)[:, :3, 3], oid, axis=0)
        table = getattr(self.scene, "object_info", {}) or {}
        default = {"Color": (1, 1, 1), "Random": 0.0, "Alpha": 1.0, "Object Index": 0.0}[name]
        values = table.get(name)
        if values is None or len(values) == 0:
            return np.broadcast_to(np.float32(default), (self.n, 3) if name == "Color" else (self.n,))
        return np.take(np.asarray(values, np.float32), oid, axis=0)

    # -- moved copies, for the Bump node ----------------------------------------
    def offset(self, dp):
        """The same hits moved by dp (N, 3) within their triangles' planes:
        position and every interpolated attribute follow."""
        s = self.surf
        bary, p = barycentrics(self.scene, s.prim, s.p + dp, with_points=True)
        moved = SurfaceHits(p=p, ng=s.ng, ns=s.ns, wo=s.wo, prim=s.prim, material=s.material,
                            front=s.front, bary=bary)
        return SurfaceGeometry(self.scene, moved, self.camera_ray)


class WorldGeometry:
    """Inputs of the background shader for escaped directions d (N, 3)."""

    is_world = True
    camera_ray = False

    def __init__(self, directions, camera_ray=False):
        self.d = np.asarray(directions, np.float32)
        self.n = len(self.d)
        self.camera_ray = camera_ray

    position = property(lambda self: self.d)
    normal = property(lambda self: -self.d)
    true_normal = normal
    incoming = normal
    generated = property(lambda self: self.d)
    object_coords = generated
    backfacing = property(lambda self: np.zeros(self.n, np.float32))

    def uv(self, name=""):
        return np.zeros((self.n, 3), np.float32)

    def attribute(self, name=""):
        return np.zeros((self.n, 3), np.float32), np.zeros(self.n, np.float32)

    def tangent(self, name=""):
        return np.zeros((self.n, 3), np.float32), np.ones(self.n, np.float32)

    def object_vector(self, v):
        return v

    def object_vector_to_world(self, v):
        return np.broadcast_to(np.asarray(v, np.float32), (self.n, 3))

    def object_info(self, name):
        return np.zeros((self.n, 3) if name in ("Location", "Color") else (self.n,), np.float32)

    def object_attribute(self, name):
        return np.zeros((self.n, 4), np.float32)

    def offset(self, dp):
        return WorldGeometry(self.d + dp, self.camera_ray)


class VolumeGeometry(SurfaceGeometry):
    """Inputs of a volume shader at points p (N, 3) inside one object (Cycles'
    volume shading): the position, object space and Generated coordinates
    (the object's bounds, ``box`` (lo, hi) in object space, mapped to
    [0, 1]^3, as a mesh's automatic texture space); no normal, UV or
    attribute (zero), as no surface is there."""

    def __init__(self, scene, points, object_id, box):
        self.scene = scene
        self.surf = None
        self.n = len(points)
        self.camera_ray = False
        self.shadow_ray = False
        self._cache = {}
        self._p = np.asarray(points, np.float32)
        self._oid = np.full(self.n, int(object_id), np.int64)
        self._box = (np.asarray(box[0], np.float32), np.asarray(box[1], np.float32))

    position = property(lambda self: self._p)
    normal = property(lambda self: np.zeros((self.n, 3), np.float32))
    true_normal = normal
    incoming = normal
    backfacing = property(lambda self: np.zeros(self.n, np.float32))
    object_id = property(lambda self: self._oid)

    def corner(self, key, width):
        return np.zeros((self.n, width), np.float32)

    def uv(self, name=""):
        return np.zeros((self.n, 3), np.float32)

    @property
    def generated(self):
        lo, hi = self._box
        size = np.where(hi - lo > 0, hi - lo, 1.0)
        return ((self.object_coords - lo) / size).astype(np.float32)

    def offset(self, dp):
        return VolumeGeometry(self.scene, self._p + dp, self._oid[0] if self.n else 0, self._box)
