"""Surface hits of a ray batch: position, normals, material, for every hit."""

from dataclasses import dataclass

import numpy as np

from ..util.rows import gather, scale
from ..util.vectors import dot, normalize


@dataclass
class SurfaceHits:
    """Struct-of-arrays surface interaction for a batch of hits (all valid).

    Normals are flipped to face the incoming direction (``wo`` side), as Cycles
    does for reflection-only materials: every surface is two-sided. Texture
    coordinates and other corner data are interpolated from ``bary`` when a
    material's nodes ask for them (core/materials/shader/geometry.py).
    """
    p: np.ndarray           # (N, 3) position
    ng: np.ndarray          # (N, 3) unit geometric normal, facing wo
    ns: np.ndarray          # (N, 3) unit shading normal, same hemisphere as ng (mirrored through
                            # the face's plane where it pointed across it)
    wo: np.ndarray          # (N, 3) unit direction back along the incoming ray
    prim: np.ndarray        # (N,) int32 triangle index
    material: np.ndarray    # (N,) int32 material id
    front: np.ndarray       # (N,) bool, True where the ray hit the front face
    bary: np.ndarray = None # (N, 2) float32 barycentrics (b1, b2) of the hit in its triangle

    def __len__(self):
        return len(self.prim)

    def subset(self, mask_or_index):
        index = np.asarray(mask_or_index)
        if index.dtype == bool:
            index = np.nonzero(index)[0]
        return SurfaceHits(*(None if getattr(self, f) is None else gather(getattr(self, f), index)
                             for f in self.__dataclass_fields__))


@dataclass
class HitSides:
    """Which triangle each ray hit and from which side: what the emission of
    materials that are uniform over their surface needs (surface_emission
    where materials.emission_per_hit is False), without SurfaceHits' points,
    normals and barycentrics."""
    prim: np.ndarray        # (N,) int32 triangle index
    front: np.ndarray       # (N,) bool, True where the ray hit the front face

    def __len__(self):
        return len(self.prim)


def surface_hits(scene, origins, directions, hits, mask=None):
    """Build SurfaceHits for the rays that hit (or the subset ``mask`` of them)."""
    idx = np.nonzero(hits.hit if mask is None else mask)[0]
    prim = hits.prim[idx]
    b1 = hits.u[idx]
    b2 = hits.v[idx]
    b0 = 1.0 - b1 - b2
    tri = gather(scene.triangles, prim)
    p0, p1, p2 = (gather(scene.vertices, tri[:, k]) for k in range(3))
    # The hit point from the barycentrics is more precise than o + t d far away.
    # (Weighted sums column by column: core/util/rows.py.)
    p = scale(p0, b0)
    p += scale(p1, b1)
    p += scale(p2, b2)
    p = p.astype(np.float32, copy=False)
    fn = scene.face_normals
    ng = gather(fn, prim) if fn is not None else normalize(np.cross(p1 - p0, p2 - p0)).astype(np.float32)
    n = gather(scene.normals, prim)
    ns = scale(n[:, 0], b0)
    ns += scale(n[:, 1], b1)
    ns += scale(n[:, 2], b2)
    ns = normalize(ns).astype(np.float32, copy=False)
    bad_ns = ~(dot(ns, ns) > 0.5)
    if bad_ns.any():
        ns[bad_ns] = ng[bad_ns]
    wo = gather(directions, idx).astype(np.float32, copy=False)     # a fresh copy: negated in place
    np.negative(wo, out=wo)
    front = dot(ng, wo) >= 0
    side = np.where(front, np.float32(1), np.float32(-1))
    ng, ns = scale(ng, side), scale(ns, side)
    # A shading normal across the face's plane (custom normals at right
    # angles to their faces, stored a hair off) is mirrored through the
    # plane, not turned around: it stays nearly where the mesh points it.
    across = dot(ns, ng)
    if (across < 0).any():
        ns = (ns - scale(ng, 2 * np.minimum(across, 0))).astype(np.float32)
    return SurfaceHits(p=p, ng=ng, ns=ns, wo=wo, prim=prim.astype(np.int32),
                       material=np.take(scene.material_ids, prim), front=front,
                       bary=np.stack([b1, b2], axis=1).astype(np.float32, copy=False)), idx
