"""Motion blur of final renders: the camera's matrices over the shutter.

Render Properties > Motion Blur: the shutter (in frames) and its position
around the frame (start, centre, end), as Cycles reads them; the camera is
evaluated at the shutter's start, middle and end (Cycles' three motion
steps) by re-evaluating the scene at those subframes (RenderEngine.frame_set,
as Cycles does), and core/camera/motion.py interpolates between them per camera
ray; so are the objects' matrices, whose motion core/object_motion.py
renders in time slices (Path Tracing; the ReSTIR modes blur the camera's
motion only, their reprojection following the frame's camera). Objects
that may deform (modifiers, shape keys, animation) and keep Cycles'
Object > Motion Blur > Deformation on are read again at each step: their
triangles' corners in world space, where they changed (deformation blur).
"""

import math

import numpy as np

from .sync.objects import read_object_mesh
from .sync.reader import may_change

STEPS = 3


def shutter_times(render, frame):
    """The frame times of the shutter's steps, or None without blur."""
    if not render.use_motion_blur:
        return None
    shutter = float(render.motion_blur_shutter)
    if not shutter > 0 or not math.isfinite(shutter):
        return None
    start = {"START": 0.0, "END": -shutter}.get(render.motion_blur_position, -0.5 * shutter)
    return [frame + start + shutter * k / (STEPS - 1) for k in range(STEPS)]


def may_deform(obj):
    """Whether an object's mesh may change over the shutter and Cycles would
    blur it (Object > Motion Blur: Motion Blur and Deformation, both on by
    default): animation on it, its shape keys or its data, or an armature
    that is animated. A static mesh with modifiers is not read again at
    every step of every frame; camera_motion keeps only the meshes whose
    object-space corners did change (the others move rigidly)."""
    o = obj.original if obj.original is not None else obj
    cycles = getattr(o, "cycles", None)
    if cycles is not None and not (getattr(cycles, "use_motion_blur", True)
                                   and getattr(cycles, "use_deform_motion", True)):
        return False
    if may_change(o) or getattr(getattr(o, "data", None), "animation_data", None) is not None:
        return True
    return any(m.type == "ARMATURE" and may_change(getattr(m, "object", None)) for m in o.modifiers)


def object_corners(obj):
    """(T, 2, 3, 3): object-space corner positions and corner normals of an
    evaluated object's triangles, as the scene reads them (sync/objects.py),
    or None."""
    mesh = read_object_mesh(obj)
    if mesh is None or len(mesh.triangles) == 0:
        return None
    return np.stack([mesh.positions[mesh.triangles], mesh.normals], axis=1).astype(np.float32)


def world_corners(steps, matrices):
    """(K, T, 2, 3, 3) world-space corners of object-space ``steps`` (K, T, 2,
    3, 3) placed by their matrices (K, 4, 4)."""
    m = np.asarray(matrices, np.float64)
    c = np.asarray(steps, np.float64)
    p = np.einsum("kij,ktcj->ktci", m[:, :3, :3], c[:, :, 0]) + m[:, None, None, :3, 3]
    normal_m = np.linalg.pinv(m[:, :3, :3]).transpose(0, 2, 1)
    n = np.einsum("kij,ktcj->ktci", normal_m, c[:, :, 1])
    n /= np.maximum(np.linalg.norm(n, axis=3, keepdims=True), 1e-30)
    return np.stack([p, n], axis=2).astype(np.float32)


def camera_motion(engine, depsgraph, warn, objects=True):
    """(camera, objects, deformed): the scene camera's (STEPS, 4, 4) matrices
    over the shutter, or None when it does not move; {object key: (STEPS, 4,
    4)} of every geometry instance (core/object_motion.py keeps those that
    move); {object key: (STEPS, T, 2, 3, 3)} world-space triangle corners
    and corner normals of the objects that deform. (None, {}, {}) when
    motion blur is off or the shutter is zero. Leaves the scene evaluated at
    its frame again."""
    from .export import instance_key                # noqa: PLC0415 (bpy-heavy)
    from .export.mesh import GEOMETRY_TYPES         # noqa: PLC0415
    scene = depsgraph.scene
    times = shutter_times(scene.render, scene.frame_current + scene.frame_subframe)
    if times is None:
        return None, {}, {}
    if not objects:
        warn("Motion blur in the ReSTIR modes: the camera's motion only; objects render sharp "
             "(Path Tracing blurs them)")
    frame, subframe = scene.frame_current, scene.frame_subframe
    matrices, read_objects, objects, deformed = [], objects, {}, {}
    try:
        for t in times:
            whole = math.floor(t)
            engine.frame_set(int(whole), t - whole)
            if depsgraph.scene.camera is not None:
                matrices.append(np.array(depsgraph.scene.camera.evaluated_get(depsgraph).matrix_world, np.float64))
            for inst in (depsgraph.object_instances if read_objects else ()):    # (the scene's objects)
                obj = inst.object
                if obj.type in GEOMETRY_TYPES:
                    key = instance_key(inst, obj)
                    objects.setdefault(key, []).append(np.array(inst.matrix_world, np.float64))
                    if not inst.is_instance and may_deform(obj):
                        deformed.setdefault(key, []).append(object_corners(obj))
    finally:
        engine.frame_set(frame, subframe)
    objects = {k: np.stack(v) for k, v in objects.items() if len(v) == len(times)}
    deformed = {k: world_corners(np.stack(v), objects[k]) for k, v in deformed.items()
                if k in objects and len(v) == len(times)
                and all(c is not None and c.shape == v[0].shape for c in v)
                and not all(np.allclose(c[:, 0], v[0][:, 0], atol=1e-7) for c in v)}
    if len(matrices) != len(times):
        return None, objects, deformed
    m = np.stack(matrices)
    if not np.isfinite(m).all() or np.allclose(m, m[:1], atol=1e-7):
        return None, objects, deformed
    return m.astype(np.float32), objects, deformed
