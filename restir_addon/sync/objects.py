"""Reading Blender data for the viewport session: meshes, instances, the view.

Plain functions from bpy data to arrays and core cameras, holding no state
(viewport/session.py decides what to read and keeps it): a mesh is
read in object space and cleaned as core.make_scene cleans it, ``mesh_key``
lets the instances of one mesh share it, ``placed_instance`` puts an instance in world
space, and ``camera_from_region`` makes a core.Camera of the 3D view.
"""

from dataclasses import dataclass, replace

import numpy as np

from ...core.scene import Camera
from ..export.camera import depth_of_field
from ..export.mesh import (
    MeshData, base_mesh, hair_warning, in_edit_mode, mirrors, place, placed_triangles, read_corner_data, read_mesh,
    triangle_cross, unit_rows)
from ..export.strands import STRAND_TYPES, read_strands, with_particle_hair


@dataclass
class Instance:
    """A placed geometry instance as read from Blender."""
    mesh: MeshData                  # object space, shared by instances of one mesh
    matrix: np.ndarray              # (4, 4) float64
    slot_ids: np.ndarray            # material id of each slot
    color: tuple = (1.0, 1.0, 1.0, 1.0)         # Object > Viewport Display colour (Object Info)
    visibility: tuple = (True, True, True)      # visible to camera, shadow and other rays
    pass_index: int = 0             # Object > Relations > Pass Index (Object Info's Object Index)
    attributes: tuple = ()          # ((need, rgba), ...): Attribute nodes of type Object or Instancer
    holdout: bool = False           # Object or collection Holdout: a hole for the camera


def _clean_mesh(mesh, warn=None, name=""):
    """Drop degenerate and non-finite triangles (as core.make_scene does),
    with a warning naming the object."""
    if mesh is None or len(mesh.triangles) == 0:
        return mesh
    with np.errstate(invalid="ignore", over="ignore"):
        cross = triangle_cross(mesh.positions, mesh.triangles)
        area2 = cross[:, 0] * cross[:, 0] + cross[:, 1] * cross[:, 1] + cross[:, 2] * cross[:, 2]
    finite_v = np.isfinite(mesh.positions).all(axis=1)
    finite = finite_v.take(mesh.triangles).all(axis=1)
    keep = finite & (area2 > 0) & np.isfinite(area2)
    if keep.all():
        mesh.face_normals = unit_rows(cross)
        return mesh
    if warn is not None:
        n_bad, n_flat = int((~finite).sum()), int((finite & ~keep).sum())
        if n_bad:
            warn(f"Object '{name}': Skipped {n_bad} triangle(s) with non-finite vertex coordinates")
        if n_flat:
            warn(f"Object '{name}': Skipped {n_flat} degenerate (zero-area) triangle(s)")
    mesh.positions = np.where(np.isfinite(mesh.positions), mesh.positions, 0.0).astype(np.float32)
    return MeshData(mesh.positions, mesh.triangles[keep], mesh.normals[keep], mesh.uvs[keep],
                    mesh.slots[keep], {k: v[keep] for k, v in mesh.corners.items()},
                    unit_rows(cross[keep]))


def mesh_key(obj):
    return obj.data.as_pointer() if obj.type == "MESH" else ("converted", obj.name)


def read_object_mesh(obj, keys=(), warn=None):
    """MeshData of an evaluated geometry object (None if it has no mesh),
    with the corner data ``keys`` its materials read (export/mesh.py); hair
    it leaves out is a warning."""
    mesh = _read_object_geometry(obj, keys, warn)
    text = hair_warning(obj, mesh)
    if text and warn is not None:
        warn(text)
    return mesh


def _read_object_geometry(obj, keys, warn):
    def read(me):
        try:
            mesh = read_mesh(me)
        except KeyError:            # loose geometry without positions
            return None
        if keys:
            mesh.corners = read_corner_data(me, set(keys), warn or (lambda text: None), obj.name, base_mesh(obj))
        return _clean_mesh(mesh, warn, obj.name)

    if obj.type == "MESH" and not in_edit_mode(obj.data):
        return with_particle_hair(obj, read(obj.data), warn)
    if obj.type in STRAND_TYPES:        # point clouds and hair curves: triangles made here
        return read_strands(obj, warn)
    try:
        me = obj.to_mesh()
    except RuntimeError:
        return None
    if me is None:
        return None
    try:
        mesh = read(me)
    finally:
        obj.to_mesh_clear()
    return with_particle_hair(obj, mesh, warn) if obj.type == "MESH" else mesh


def _face_normals(pos, tris):
    """Unit geometric normals, computed as core.make_scene does."""
    if len(tris) == 0:
        return np.zeros((0, 3), np.float32)
    p = pos[tris]
    ng = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    return (ng / np.maximum(np.linalg.norm(ng, axis=1, keepdims=True), 1e-30)).astype(np.float32)


def placed_instance(inst):
    """World-space (positions, corner normals, face normals, triangles, uvs)
    of an instance, corners in export.mesh.placed_triangles' order (0, 2, 1
    where its matrix mirrors); face normals from the object-space ones where
    the mesh has them (the normal matrix keeps them exact up to rounding)."""
    mesh = inst.mesh
    flip = mirrors(inst.matrix)
    pos, nrm = place(mesh, inst.matrix, flip)
    tris, uvs = placed_triangles(mesh, inst.matrix, flip)
    if not np.isfinite(nrm).all():
        nrm = np.where(np.isfinite(nrm), nrm, 0.0).astype(np.float32)
    if mesh.face_normals is None or len(mesh.face_normals) != len(mesh.triangles):
        return pos, nrm, _face_normals(pos, tris), tris, uvs
    linear = np.asarray(inst.matrix, np.float64)[:3, :3]
    if np.array_equal(linear, np.eye(3)):
        return pos, nrm, mesh.face_normals, tris, uvs
    det = np.linalg.det(linear)
    if not np.isfinite(det) or abs(det) < 1e-30:
        return pos, nrm, _face_normals(pos, tris), tris, uvs
    # cross(Ma, Mb) = det(M) M^-T cross(a, b): a mirror (det < 0) turns the
    # winding normal into the object, and the swapped corners turn it back.
    nm = np.linalg.inv(linear).T.astype(np.float32)
    return pos, nrm, unit_rows(mesh.face_normals @ nm.T), tris, uvs


def camera_from_view(view_matrix, window_matrix):
    """core.Camera of a viewport from its view (world to view) and window
    (projection) matrices, whatever the image size: the sensor is fitted to
    the width, and the image keeps the projection's aspect."""
    V = np.asarray(view_matrix, np.float64)
    P = np.asarray(window_matrix, np.float64)
    to_world = np.linalg.inv(V).astype(np.float32)
    if abs(P[3, 3]) < 0.5:      # perspective: last row (0, 0, -1, 0)
        near, far = P[2, 3] / (P[2, 2] - 1.0), P[2, 3] / (P[2, 2] + 1.0)
        return Camera(to_world=to_world, projection="PERSP", lens=float(P[0, 0]), sensor_width=2.0,
                      sensor_height=2.0, sensor_fit="HORIZONTAL", shift_x=float(P[0, 2] / 2),
                      shift_y=float(P[1, 2] * P[0, 0] / (2 * P[1, 1])), clip_start=float(near),
                      clip_end=float(far))
    near, far = (P[2, 3] + 1.0) / P[2, 2], (P[2, 3] - 1.0) / P[2, 2]
    return Camera(to_world=to_world, projection="ORTHO", ortho_scale=float(2.0 / P[0, 0]),
                  sensor_fit="HORIZONTAL", shift_x=float(-P[0, 3] / 2),
                  shift_y=float(-P[1, 3] * P[0, 0] / (2 * P[1, 1])), clip_start=float(near),
                  clip_end=float(far))


def camera_from_region(region_data, scene=None):
    """core.Camera of a 3D viewport's RegionView3D. Looking through the
    scene's camera (scene given), with its depth of field, as Cycles' viewport."""
    camera = camera_from_view(region_data.view_matrix, region_data.window_matrix)
    cam_obj = None if scene is None else scene.camera
    if (cam_obj is not None and cam_obj.type == "CAMERA"
            and getattr(region_data, "view_perspective", None) == "CAMERA"):
        camera = replace(camera, **depth_of_field(cam_obj, cam_obj.data))
    return camera


def same_camera(a, b):
    if a is None or b is None:
        return a is b
    return all(np.array_equal(np.asarray(getattr(a, f)), np.asarray(getattr(b, f)))
               for f in a.__dataclass_fields__)
