"""Point clouds and hair curves of the evaluated scene as MeshData: spheres
and tubes of triangles (core/geometry/strands.py), radii as Cycles reads them."""

import numpy as np

from ...core.geometry.strands import spheres, spline_steps, tubes
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
        points = _positions(attrs, n)
        pos, tris, normals, curve = tubes(points, _attribute(attrs, "radius", "POINT", n, CURVE_RADIUS), offsets,
                                          spline_steps=spline_steps(points, offsets))
        slots = _attribute(attrs, "material_index", "CURVE", len(data.curves), 0, np.int32)[curve]
    if len(tris) == 0:
        return None
    e = np.cross(pos[tris[:, 1]] - pos[tris[:, 0]], pos[tris[:, 2]] - pos[tris[:, 0]])
    face = e / np.maximum(np.linalg.norm(e, axis=1, keepdims=True), 1e-30)
    return MeshData(pos, tris, normals, np.zeros((len(tris), 3, 2), np.float32), slots.astype(np.int32),
                    face_normals=face.astype(np.float32))


MAX_HAIR_POINTS = 400000        # co_hair points read per object (about 2 s); more strands are left out


def _hair_systems(obj):
    return [p for p in getattr(obj, "particle_systems", ())
            if p.settings.type == "HAIR" and p.settings.render_type == "PATH"]


def has_particle_hair(obj):
    return bool(_hair_systems(obj))


def _steps(psys, obj):
    """Points per strand of the system's path cache: 2^render steps + 1 in
    a render's depsgraph, 2^viewport steps + 1 in the viewport's."""
    st = psys.settings
    render = 2 ** int(st.render_step)
    if render != 2 ** int(st.display_step) and any(psys.co_hair(obj, particle_no=0, step=render)):
        return render + 1
    return 2 ** int(st.display_step) + 1


def _shape_radius(shape, root, tip, time):
    """Cycles' radius along a particle strand (time: its share of the length)."""
    r = 1.0 - time
    if shape < 0:
        r = r ** (1.0 + shape)
    elif shape > 0:
        r = r ** (1.0 / max(1.0 - shape, 1e-6))
    return r * (root - tip) + tip


def particle_hair(obj, warn=None):
    """MeshData (object space) of the object's hair particle systems drawn as
    strands (Render As Path), as tubes (core/geometry/strands.py), or None. Strands
    are read point by point (ParticleSystem.co_hair, world space), at most
    MAX_HAIR_POINTS per object; radii as Cycles takes them (root and tip
    radius x radius scale / 2, the shape, a closed tip)."""
    systems = _hair_systems(obj)
    if not systems:
        return None
    to_object = np.linalg.inv(np.array(obj.matrix_world, np.float64))
    parts, budget = [], MAX_HAIR_POINTS
    for psys in systems:
        st = psys.settings
        parents, children = len(psys.particles), len(psys.child_particles)
        # With children, the parents render only with Display Parents on (as in Cycles).
        first = parents if children and st.child_type != "NONE" and not st.use_parent_particles else 0
        total = parents + children - first
        if total <= 0:
            continue
        steps = _steps(psys, obj)
        strands = min(total, budget // steps)
        if strands < total and warn is not None:
            warn(f"Object '{obj.name}': particle hair '{psys.name}' renders {strands} of its {total} strands")
        if strands == 0:
            continue
        budget -= strands * steps
        co = np.array([tuple(psys.co_hair(obj, particle_no=i, step=k)) for i in range(first, first + strands)
                       for k in range(steps)], np.float64).reshape(strands, steps, 3)
        co = co @ to_object[:3, :3].T + to_object[:3, 3]
        seg = np.linalg.norm(np.diff(co, axis=1), axis=2)
        length = np.concatenate([np.zeros((strands, 1)), np.cumsum(seg, axis=1)], axis=1)
        time = length / np.maximum(length[:, -1:], 1e-30)
        scale = float(st.radius_scale) * 0.5
        radius = _shape_radius(float(st.shape), float(st.root_radius) * scale, float(st.tip_radius) * scale, time)
        if st.use_close_tip:
            radius[:, -1] = 0.0
        offsets = np.arange(strands + 1) * steps
        pos, tris, normals, _ = tubes(co.reshape(-1, 3), radius.ravel(), offsets,
                                      spline_steps=spline_steps(co.reshape(-1, 3), offsets))
        parts.append((pos, tris, normals, max(int(st.material) - 1, 0)))
    if not parts:
        return None
    return _merge([MeshData(p, t, n, np.zeros((len(t), 3, 2), np.float32), np.full(len(t), s, np.int32))
                   for p, t, n, s in parts if len(t)])


def _merge(meshes):
    """One MeshData of several (corner data padded with zeros)."""
    meshes = [m for m in meshes if m is not None and len(m.triangles)]
    if not meshes:
        return None
    if len(meshes) == 1:
        return meshes[0]
    offset = np.cumsum([0] + [len(m.positions) for m in meshes[:-1]])
    keys = set().union(*(m.corners for m in meshes))
    corners = {}
    for k in keys:
        width = next(m.corners[k].shape[-1] for m in meshes if k in m.corners)
        corners[k] = np.concatenate([m.corners[k] if k in m.corners else
                                     np.zeros((len(m.triangles), 3, width), np.float32) for m in meshes])
    faces = None
    if all(m.face_normals is not None for m in meshes):
        faces = np.concatenate([m.face_normals for m in meshes]).astype(np.float32)
    return MeshData(np.concatenate([m.positions for m in meshes]).astype(np.float32),
                    np.concatenate([m.triangles + o for m, o in zip(meshes, offset)]).astype(np.int32),
                    np.concatenate([m.normals for m in meshes]).astype(np.float32),
                    np.concatenate([m.uvs for m in meshes]).astype(np.float32),
                    np.concatenate([m.slots for m in meshes]).astype(np.int32), corners, faces)


def with_particle_hair(obj, mesh, warn=None):
    """The object's mesh with its particle hair added (the mesh left out when
    the emitter is hidden in renders: Show Emitter off)."""
    hair = particle_hair(obj, warn)
    if hair is None:
        return mesh
    if hair.face_normals is None:
        e = np.cross(hair.positions[hair.triangles[:, 1]] - hair.positions[hair.triangles[:, 0]],
                     hair.positions[hair.triangles[:, 2]] - hair.positions[hair.triangles[:, 0]])
        hair.face_normals = (e / np.maximum(np.linalg.norm(e, axis=1, keepdims=True), 1e-30)).astype(np.float32)
    if mesh is None or not getattr(obj, "show_instancer_for_render", True):
        return hair
    return _merge([mesh, hair])


def pad_corners(corners, mesh):
    """Corner data read from an object's mesh, padded with zero rows for the
    hair triangles with_particle_hair added after the mesh's."""
    n = len(mesh.triangles)
    out = {}
    for k, v in corners.items():
        extra = n - len(v)
        out[k] = v if extra <= 0 else np.concatenate([v, np.zeros((extra,) + v.shape[1:], v.dtype)])
    return out
