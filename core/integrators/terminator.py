"""The shadow terminator of smooth-shaded meshes, as Cycles handles it.

A triangle shaded with interpolated normals stands for a curved surface it
only approximates: near the terminator the shading normal still faces a
light that lies below the triangle's own plane, and a shadow ray from the
flat triangle meets the triangle itself or its neighbours, a staircase of
dark facets where the curved surface would be lit. Cycles (Object >
Shading > Shadow Terminator > Geometry Offset, 0.1 by default) starts such
shadow rays from a point lifted towards the smooth surface the normals
describe: Hanika's parabolic approximation ("Hacking the Shadow
Terminator", Ray Tracing Gems II), bounded by the vertices' tangent planes;
the lift fades in as the light grazes the surface, and a light below the
triangle's plane is tested from there against the triangle itself, which
the ray may now pass beside.

``amounts`` gives each light sample's share of the lift, ``smooth_lift``
the lift at hit points; core/integrators/base.direct_light uses both, with
the scene's ``shadow_terminator`` (Cycles' default for every object; an
object's own Geometry Offset is not read).
"""

import numpy as np

from ..util.rows import gather, scale
from ..util.vectors import dot

def amounts(ns, ng, wi, cutoff):
    """(N,) float32 share in [0, 1] of the lift for lights in directions wi
    (N, 3) from points with shading normals ns and geometric normals ng:
    none where the light is well above the triangle's plane, all of it from
    where it grazes or lies below the plane (cutoff: the Geometry Offset)."""
    nl = dot(ns, wi)
    ngl = np.where(nl < 0, -1.0, 1.0).astype(np.float32) * dot(ng, wi)     # (transmission: the far side)
    nl = np.abs(nl)
    near = np.clip(2.0 - (ngl + nl) / cutoff, 0.0, 1.0)
    far = np.clip(1.0 - ngl / cutoff, 0.0, 1.0)
    return np.where(nl < cutoff, near, far).astype(np.float32)


def smooth_lift(scene, prim, bary, ng):
    """(N, 3) float32: from hit points on triangles ``prim`` at barycentrics
    ``bary`` (N, 2), the offset to the smooth surface the corner normals
    describe (zero on flat-shaded triangles), on the side of ``ng`` (N, 3),
    the geometric normals facing the incoming rays."""
    tri = gather(scene.triangles, prim)
    v = [gather(scene.vertices, tri[:, k]) for k in range(3)]
    corner = gather(scene.normals, prim)
    n = [corner[:, k] for k in range(3)]
    b1, b2 = bary[:, 0], bary[:, 1]
    b0 = 1.0 - b1 - b2
    p = scale(v[0], b0) + scale(v[1], b1) + scale(v[2], b2)
    normal = scale(n[0], b0) + scale(n[1], b1) + scale(n[2], b2)
    # The parabola through the corners whose slopes the corner normals give.
    e02 = dot(n[2] - n[0], v[0] - v[2])
    e12 = dot(n[2] - n[1], v[1] - v[2])
    e01 = dot(n[1] - n[0], v[1] - v[0])
    h = e02 * b0 * (b0 - 1.0) + (e02 + e12 + e01) * b0 * b1 + e12 * b1 * (b1 - 1.0)
    # ... within the envelope of the corners' tangent planes, on the side
    # the normals face (seen from behind, the surface bulges the other way).
    outward = dot(normal, ng) > 0
    sign = np.where(outward, np.float32(1), np.float32(-1))
    bound = None
    for k in range(3):
        i, j = [m for m in range(3) if m != k]
        reach = np.maximum(np.maximum(sign * dot(v[i] - v[k], n[k]), sign * dot(v[j] - v[k], n[k])), 0.0)
        above = np.maximum(sign * dot(v[k] - p, n[k]) + reach, 0.0)
        bound = above if bound is None else np.minimum(bound, above)
    h = np.where(outward, np.maximum(bound, 0.5 * h), np.minimum(-bound, 0.5 * h))
    return scale(normal, h).astype(np.float32)
