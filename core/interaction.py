"""Surface hits of a ray batch: position, normals, uv, material, for every hit."""

from dataclasses import dataclass

import numpy as np

from .rows import gather
from .sampling import dot, normalize


@dataclass
class SurfaceHits:
    """Struct-of-arrays surface interaction for a batch of hits (all valid).

    Normals are flipped to face the incoming direction (``wo`` side), as Cycles
    does for reflection-only materials: every surface is two-sided.
    """
    p: np.ndarray           # (N, 3) position
    ng: np.ndarray          # (N, 3) unit geometric normal, facing wo
    ns: np.ndarray          # (N, 3) unit shading normal, same hemisphere as ng
    uv: np.ndarray          # (N, 2)
    wo: np.ndarray          # (N, 3) unit direction back along the incoming ray
    prim: np.ndarray        # (N,) int32 triangle index
    material: np.ndarray    # (N,) int32 material id
    front: np.ndarray       # (N,) bool, True where the ray hit the front face

    def __len__(self):
        return len(self.prim)

    def subset(self, mask_or_index):
        index = np.asarray(mask_or_index)
        if index.dtype == bool:
            index = np.nonzero(index)[0]
        return SurfaceHits(*(gather(getattr(self, f), index) for f in self.__dataclass_fields__))


def surface_hits(scene, origins, directions, hits, mask=None):
    """Build SurfaceHits for the rays that hit (or the subset ``mask`` of them)."""
    idx = np.nonzero(hits.hit if mask is None else mask)[0]
    prim = hits.prim[idx]
    b1 = hits.u[idx][:, None]
    b2 = hits.v[idx][:, None]
    b0 = 1.0 - b1 - b2
    tri = gather(scene.triangles, prim)
    p0, p1, p2 = (gather(scene.vertices, tri[:, k]) for k in range(3))
    d = gather(directions, idx)
    # The hit point from the barycentrics is more precise than o + t d far away.
    p = (b0 * p0 + b1 * p1 + b2 * p2).astype(np.float32)
    fn = scene.face_normals
    ng = gather(fn, prim) if fn is not None else normalize(np.cross(p1 - p0, p2 - p0)).astype(np.float32)
    n = gather(scene.normals, prim)
    ns = normalize(b0 * n[:, 0] + b1 * n[:, 1] + b2 * n[:, 2]).astype(np.float32)
    bad_ns = ~(dot(ns, ns) > 0.5)
    ns = np.where(bad_ns[:, None], ng, ns)
    uvs = gather(scene.uvs, prim)
    uv = (b0 * uvs[:, 0] + b1 * uvs[:, 1] + b2 * uvs[:, 2]).astype(np.float32)
    wo = (-d).astype(np.float32)
    front = dot(ng, wo) >= 0
    sign = np.where(front, 1.0, -1.0).astype(np.float32)[:, None]
    ng = ng * sign
    ns = ns * np.where(dot(ns, ng) >= 0, 1.0, -1.0).astype(np.float32)[:, None]
    return SurfaceHits(p=p, ng=ng, ns=ns, uv=uv, wo=wo, prim=prim.astype(np.int32),
                       material=np.take(scene.material_ids, prim), front=front), idx
