"""Point clouds and hair curves of the evaluated scene as MeshData: spheres
and tubes of triangles (core/strands.py), radii as Cycles reads them."""

import numpy as np

from ...core.strands import spheres, tubes
from .mesh import MeshData

STRAND_TYPES = {"POINTCLOUD", "CURVES"}
POINT_RADIUS = 0.01         # Cycles' radius of points without a "radius" attribute
CURVE_RADIUS = 0.005        # and of curve points without one


def _attribute(attributes, name, domain, count, default, dtype=np.float32):
    """(count,) values of a scalar attribute of that domain, else default."""
    a = attributes.get(name)
    if a is None or a.domain != domain or len(a.data) != count or count == 0:
        return np.full(count, default, dtype)
    out = np.empty(count, dtype)
    try:
        a.data.foreach_get("value", out)
    except (TypeError, RuntimeError, AttributeError):
        return np.full(count, default, dtype)
    return out


def _positions(attributes, count):
    out = np.zeros(count * 3, np.float32)
    if count:
        attributes["position"].data.foreach_get("vector", out)
    return out.reshape(count, 3)


def read_strands(obj, warn=None):
    """MeshData (object space) of a point cloud or hair curves object, None
    if it gives no triangles."""
    data = obj.data
    if obj.type == "POINTCLOUD":
        n = len(data.points)
        attrs = data.attributes
        pos, tris, normals, kept = spheres(_positions(attrs, n), _attribute(attrs, "radius", "POINT", n,
                                                                            POINT_RADIUS))
        per_point = _attribute(attrs, "material_index", "POINT", n, 0, np.int32)[kept]
        slots = np.repeat(per_point, len(tris) // max(len(per_point), 1))
    else:
        n, attrs = len(data.points), data.attributes
        offsets = np.zeros(len(data.curves) + 1, np.int32)
        if len(data.curves):
            data.curve_offset_data.foreach_get("value", offsets)
        pos, tris, normals, curve = tubes(_positions(attrs, n), _attribute(attrs, "radius", "POINT", n,
                                                                           CURVE_RADIUS), offsets)
        slots = _attribute(attrs, "material_index", "CURVE", len(data.curves), 0, np.int32)[curve]
    if len(tris) == 0:
        return None
    e = np.cross(pos[tris[:, 1]] - pos[tris[:, 0]], pos[tris[:, 2]] - pos[tris[:, 0]])
    face = e / np.maximum(np.linalg.norm(e, axis=1, keepdims=True), 1e-30)
    return MeshData(pos, tris, normals, np.zeros((len(tris), 3, 2), np.float32), slots.astype(np.int32),
                    face_normals=face.astype(np.float32))
