"""Evaluated meshes to triangle arrays through bpy's fast attribute path.

Geometry is read once per mesh data block (instances share it) in object space;
``place`` applies each instance's matrix.
"""

from dataclasses import dataclass, field

import numpy as np

# Curve, surface, text and metaball objects are not listed: the depsgraph hands
# their evaluated geometry over as a separate MESH instance (the one Cycles
# renders), so converting the objects themselves would add every triangle twice.
# Point clouds and hair curves are tessellated (export/strands.py).
GEOMETRY_TYPES = {"MESH", "CURVES", "POINTCLOUD"}
# Object types with geometry that this engine does not render: a warning each.
# (Volume objects render as media: export/volume_objects.py.)
UNRENDERED_TYPES = {}


def in_edit_mode(me):
    """A mesh in Edit Mode (being edited, or saved so): its geometry lives in
    the edit data until Blender leaves the mode, and the object's ``data``
    shows what it was before (a file saved in Edit Mode can show no faces at
    all), so it is read through ``to_mesh``, as Cycles reads the evaluated
    mesh."""
    return bool(getattr(me, "is_editmode", False))


def unrendered(obj):
    """The warning for an object whose type has geometry this engine does not render, else None."""
    what = UNRENDERED_TYPES.get(obj.type)
    return None if what is None else f"Object '{obj.name}': {what}"


def hair_warning(obj, mesh):
    """The warning for hair this engine does not render. Hair curves objects
    and particle hair drawn as strands (Render As Path) render as tubes
    (export/strands.py; a system with more strands than it reads warns
    there): None. mesh: the object's MeshData as read (None if it had none)."""
    return None


@dataclass
class MeshData:
    positions: np.ndarray       # (V, 3) object space
    triangles: np.ndarray       # (T, 3) vertex indices
    normals: np.ndarray         # (T, 3, 3) corner normals, object space
    uvs: np.ndarray             # (T, 3, 2)
    slots: np.ndarray           # (T,) material slot index
    corners: dict = field(default_factory=dict)   # read_corner_data's, where a user reads it
    face_normals: np.ndarray = None     # (T, 3) unit geometric normals, object space (when known)


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
    if getattr(me, "normals_domain", "CORNER") == "FACE":
        # Every face flat: Cycles shades each triangle by its own normal (a
        # non-planar quad shows its crease), not by its polygon's.
        ng = unit_rows(triangle_cross(pos, tri_vert))
        normals = np.repeat(ng[:, None, :], 3, axis=1)
    else:
        cn = _get(me.corner_normals, "vector", np.float32, 3, nl) if nl else np.zeros((0, 3), np.float32)
        normals = cn[loops]
    render_uv = _render_uv_layer(me)
    if render_uv is not None and nl:
        uv = _get(render_uv.uv, "vector", np.float32, 2, nl)
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
    return MeshData(pos, tri_vert.astype(np.int32, copy=False), normals, uvs,
                    slots.astype(np.int32, copy=False))


def base_mesh(obj):
    """The mesh an evaluated mesh object was made from (its Generated
    coordinates' source), or None."""
    orig = getattr(obj, "original", None)
    data = getattr(orig, "data", None)
    return data if getattr(orig, "type", None) == "MESH" else None


def _render_uv_layer(me):
    """The UV map Cycles reads by default: the one active for rendering."""
    for layer in me.uv_layers:
        if layer.active_render:
            return layer
    return me.uv_layers.active


def read_corner_data(me, keys, warn, name="", base=None):
    """Corner data the materials' nodes read (core/materials/shader/geometry.py keys):
    ``uv:<map>`` (T, 3, 2), ``color:<attribute>`` (T, 3, 4), ``tangent:<map>``
    (T, 3, 4: tangent and bitangent sign), ``generated`` (T, 3, 3; ``base``:
    the object's mesh before evaluation, see _generated). A map or attribute
    the mesh lacks reads as zeros, with a warning."""
    tris = me.loop_triangles
    nt, nl = len(tris), len(me.loops)
    out = {}
    if nt == 0 or not keys:
        return out
    loops = _get(tris, "loops", np.int32, 3, nt)
    for key in sorted(keys):
        kind, _, arg = key.partition(":")
        if kind == "uv":
            layer = me.uv_layers.get(arg) if arg else _render_uv_layer(me)
            if layer is None:
                if arg:
                    warn(f"Mesh '{name}' has no UV map '{arg}'; it reads as zero")
                out[key] = np.zeros((nt, 3, 2), np.float32)
                continue
            out[key] = _get(layer.uv, "vector", np.float32, 2, nl)[loops]
        elif kind == "color":
            out[key] = _color_attribute(me, arg, loops, warn, name)
        elif kind == "tangent":
            out[key] = _tangents(me, arg, loops, warn, name)
        elif key == "generated":
            out[key] = _generated(me, loops, base)
    return out


def _color_attribute(me, attr_name, loops, warn, name):
    nt = len(loops)
    attrs = me.color_attributes
    attr = attrs.get(attr_name) if attr_name else None
    if attr is None and not attr_name:
        idx = attrs.render_color_index
        attr = attrs[idx] if 0 <= idx < len(attrs) else None
    if attr is None:
        generic = me.attributes.get(attr_name) if attr_name else None
        if generic is None or generic.domain not in ("POINT", "CORNER") or generic.data_type not in (
                "FLOAT", "FLOAT_VECTOR", "FLOAT_COLOR", "BYTE_COLOR", "FLOAT2"):
            if attr_name:
                warn(f"Mesh '{name}' has no attribute '{attr_name}' on points or corners; it reads as zero")
            return np.zeros((nt, 3, 4), np.float32)
        attr = generic
    count = len(attr.data)
    kind = attr.data_type
    if kind in ("FLOAT_COLOR", "BYTE_COLOR"):
        values = _get(attr.data, "color", np.float32, 4, count)       # scene linear for both
    elif kind == "FLOAT":
        v = _get(attr.data, "value", np.float32, 1, count)
        values = np.stack([v, v, v, np.ones_like(v)], axis=1)
    else:
        width = 2 if kind == "FLOAT2" else 3
        v = _get(attr.data, "vector", np.float32, width, count)
        values = np.concatenate([v, np.zeros((count, 3 - width), np.float32),
                                 np.ones((count, 1), np.float32)], axis=1)
    if attr.domain == "POINT":
        corner_vert = _get(me.attributes[".corner_vert"].data, "value", np.int32, 1, len(me.loops))
        return values[corner_vert[loops]]
    return values[loops]


def _tangents(me, uv_name, loops, warn, name):
    nt = len(loops)
    try:
        me.calc_tangents(uvmap=uv_name) if uv_name else me.calc_tangents()
    except RuntimeError as exc:
        warn(f"Mesh '{name}': no tangents for normal maps ({exc}); normal maps there are flat")
        return np.zeros((nt, 3, 4), np.float32)
    nl = len(me.loops)
    t = _get(me.loops, "tangent", np.float32, 3, nl)
    sign = _get(me.loops, "bitangent_sign", np.float32, 1, nl)
    me.free_tangents()
    return np.concatenate([t, sign[:, None]], axis=1)[loops]


def _generated(me, loops, base=None):
    """Blender's Generated coordinates: positions in the mesh's texture space,
    [0, 1]^3. As Blender's original coordinates they are the mesh's before
    its deformation (an armature's pose, shape keys, deforming modifiers):
    ``base``'s (the object's own mesh) positions and texture space where it
    has as many vertices as the evaluated one, else the evaluated mesh's."""
    nv = len(me.vertices)
    source = base if base is not None and len(getattr(base, "vertices", ())) == nv else me
    pos = None
    if source is not me:
        try:        # (an original mesh may not hold its positions as an attribute)
            pos = _get(source.vertices, "co", np.float32, 3, nv)
        except (AttributeError, RuntimeError, TypeError):
            source = me
    if pos is None:
        pos = _get(me.attributes["position"].data, "vector", np.float32, 3, nv)
    loc = np.asarray(source.texspace_location, np.float32)
    size = np.asarray(source.texspace_size, np.float32)
    size = np.where(np.abs(size) > 1e-12, size, 1.0)
    orco = (pos - loc) / size * 0.5 + 0.5
    corner_vert = _get(me.attributes[".corner_vert"].data, "value", np.int32, 1, len(me.loops))
    return orco[corner_vert[loops]].astype(np.float32)


def triangle_cross(positions, triangles):
    """(T, 3) float32 cross products of each triangle's edges (twice its area
    along its normal), gathered one coordinate at a time: several times
    faster than positions[triangles] and np.cross on (T, 3) rows."""
    cols = [np.ascontiguousarray(positions[:, k]) for k in range(3)]
    i0, i1, i2 = (np.ascontiguousarray(triangles[:, k]) for k in range(3))
    e1 = [c.take(i1) - c.take(i0) for c in cols]
    e2 = [c.take(i2) - c.take(i0) for c in cols]
    out = np.empty((len(triangles), 3), np.float32)
    out[:, 0] = e1[1] * e2[2] - e1[2] * e2[1]
    out[:, 1] = e1[2] * e2[0] - e1[0] * e2[2]
    out[:, 2] = e1[0] * e2[1] - e1[1] * e2[0]
    return out


def unit_rows(v):
    """Rows of v divided by their length (rows of zero length stay zero)."""
    length = np.sqrt(v[:, 0] * v[:, 0] + v[:, 1] * v[:, 1] + v[:, 2] * v[:, 2])
    return (v / np.maximum(length, 1e-30)[:, None]).astype(np.float32, copy=False)


SWAP = [0, 2, 1]     # a triangle's corners with the second and third swapped


def mirrors(matrix):
    """Whether a 4x4 matrix turns space inside out (negative determinant, a
    negative scale on one or three axes): a placed triangle's corners then
    wind the other way round, and its winding normal points into the
    object. Placed triangles of such instances take their corners in the
    order 0, 2, 1 (as Cycles does), so winding, face normal and the corner
    normals all point out again."""
    linear = np.asarray(matrix, np.float64)[:3, :3]
    return bool(np.linalg.det(linear) < 0)


def placed_triangles(mesh, matrix, flip=None):
    """(triangles, uvs) of a mesh as placed under a matrix: corners 0, 2, 1
    where it mirrors (flip: mirrors(matrix), if the caller has it)."""
    if mirrors(matrix) if flip is None else flip:
        return mesh.triangles[:, SWAP], mesh.uvs[:, SWAP]
    return mesh.triangles, mesh.uvs


def place(mesh, matrix, flip=None):
    """World-space positions and corner normals of a mesh under a 4x4 matrix
    (corners in placed_triangles' order; flip: mirrors(matrix), if known). A
    matrix without rotation or scale (the common case of big static meshes)
    only translates; normals are transformed in float32, renormalised only
    where the matrix is not a rotation times a uniform scale."""
    m = np.asarray(matrix, np.float64)
    linear = m[:3, :3]
    if np.array_equal(linear, np.eye(3)):
        return (mesh.positions + m[:3, 3].astype(np.float32)).astype(np.float32), mesh.normals
    pos = (mesh.positions @ linear.T.astype(np.float32) + m[:3, 3].astype(np.float32)).astype(np.float32)
    try:
        nm = np.linalg.inv(linear).T
    except np.linalg.LinAlgError:
        nm = np.eye(3)
    n = mesh.normals.reshape(-1, 3) @ nm.T.astype(np.float32)
    gram = nm @ nm.T
    if np.allclose(gram, gram[0, 0] * np.eye(3), rtol=1e-6, atol=0.0) and gram[0, 0] > 0:
        n *= np.float32(1.0 / np.sqrt(gram[0, 0]))       # rotation and uniform scale
    else:
        length = np.sqrt(np.einsum("ij,ij->i", n, n))[:, None]
        n /= np.where(length > 0, length, 1)
    n = n.reshape(-1, 3, 3).astype(np.float32, copy=False)
    return pos, (n[:, SWAP] if (mirrors(m) if flip is None else flip) else n)
