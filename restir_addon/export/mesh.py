"""Evaluated meshes to triangle arrays through bpy's fast attribute path.

Geometry is read once per mesh data block (instances share it) in object space;
``place`` applies each instance's matrix.
"""

from dataclasses import dataclass

import numpy as np

# Curve, surface, text and metaball objects are not listed: the depsgraph hands
# their evaluated geometry over as a separate MESH instance (the one Cycles
# renders), so converting the objects themselves would add every triangle twice.
GEOMETRY_TYPES = {"MESH", "CURVES"}


@dataclass
class MeshData:
    positions: np.ndarray       # (V, 3) object space
    triangles: np.ndarray       # (T, 3) vertex indices
    normals: np.ndarray         # (T, 3, 3) corner normals, object space
    uvs: np.ndarray             # (T, 3, 2)
    slots: np.ndarray           # (T,) material slot index


def _get(collection, attr, dtype, width, count):
    out = np.empty(count * width, dtype)
    if count:
        collection.foreach_get(attr, out)
    return out.reshape(count, width) if width > 1 else out


def read_mesh(me):
    """Triangles of a bpy Mesh (evaluated) as MeshData."""
    nv = len(me.vertices)
    pos = _get(me.attributes["position"].data, "vector", np.float32, 3, nv)
    tris = me.loop_triangles
    nt = len(tris)
    if nt == 0:     # vertices or edges only: a mesh without faces has no corner attributes
        return MeshData(pos, np.zeros((0, 3), np.int32), np.zeros((0, 3, 3), np.float32),
                        np.zeros((0, 3, 2), np.float32), np.zeros(0, np.int32))
    loops = _get(tris, "loops", np.int32, 3, nt)
    corner_vert = _get(me.attributes[".corner_vert"].data, "value", np.int32, 1, len(me.loops))
    tri_vert = corner_vert[loops] if nt else np.zeros((0, 3), np.int32)
    nl = len(me.loops)
    cn = _get(me.corner_normals, "vector", np.float32, 3, nl) if nl else np.zeros((0, 3), np.float32)
    normals = cn[loops] if nt else np.zeros((0, 3, 3), np.float32)
    if me.uv_layers.active is not None and nl:
        uv = _get(me.uv_layers.active.uv, "vector", np.float32, 2, nl)
        uvs = uv[loops]
    else:
        uvs = np.zeros((nt, 3, 2), np.float32)
    tri_poly = _get(me.loop_triangle_polygons, "value", np.int32, 1, nt)
    mat_attr = me.attributes.get("material_index")
    if mat_attr is not None and mat_attr.domain == "FACE" and nt:
        poly_mat = _get(mat_attr.data, "value", np.int32, 1, len(me.polygons))
        slots = poly_mat[tri_poly]
    else:
        slots = np.zeros(nt, np.int32)
    return MeshData(pos, tri_vert.astype(np.int32), normals, uvs, slots.astype(np.int32))


def place(mesh, matrix):
    """World-space positions and normals of a mesh under a 4x4 matrix."""
    m = np.asarray(matrix, np.float64)
    pos = (mesh.positions @ m[:3, :3].T + m[:3, 3]).astype(np.float32)
    try:
        nm = np.linalg.inv(m[:3, :3]).T
    except np.linalg.LinAlgError:
        nm = np.eye(3)
    n = (mesh.normals.reshape(-1, 3) @ nm.T).reshape(-1, 3, 3)
    length = np.linalg.norm(n, axis=2, keepdims=True)
    n = (n / np.where(length > 0, length, 1)).astype(np.float32)
    return pos, n
