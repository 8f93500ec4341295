"""Motion blur of final renders: the camera's matrices over the shutter.

Render Properties > Motion Blur: the shutter (in frames) and its position
around the frame (start, centre, end), as Cycles reads them; the camera is
evaluated at the shutter's start, middle and end (Cycles' three motion
steps) by re-evaluating the scene at those subframes (RenderEngine.frame_set,
as Cycles does), and core/camera/motion.py interpolates between them per camera
ray; so are the objects' matrices, whose motion core/object_motion.py
renders in time slices (Path Tracing; the ReSTIR modes blur the camera's
motion only, their reprojection following the frame's camera). Rigid
motion only.
"""

import math

import numpy as np

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


def camera_motion(engine, depsgraph, warn, objects=True):
    """(camera, objects): the scene camera's (STEPS, 4, 4) matrices over the
    shutter, or None when it does not move, and {object key: (STEPS, 4, 4)}
    of every geometry instance (core/object_motion.py keeps those that
    move); (None, {}) when motion blur is off or the shutter is zero. Leaves
    the scene evaluated at its frame again."""
    from .export import instance_key                # noqa: PLC0415 (bpy-heavy)
    from .export.mesh import GEOMETRY_TYPES         # noqa: PLC0415
    scene = depsgraph.scene
    times = shutter_times(scene.render, scene.frame_current + scene.frame_subframe)
    if times is None:
        return None, {}
    warn("Motion blur: objects move rigidly (no deformation blur)" if objects else
         "Motion blur in the ReSTIR modes: the camera's motion only; objects render sharp (Path Tracing blurs them)")
    frame, subframe = scene.frame_current, scene.frame_subframe
    matrices, read_objects, objects = [], objects, {}
    try:
        for t in times:
            whole = math.floor(t)
            engine.frame_set(int(whole), t - whole)
            if depsgraph.scene.camera is not None:
                matrices.append(np.array(depsgraph.scene.camera.evaluated_get(depsgraph).matrix_world, np.float64))
            for inst in (depsgraph.object_instances if read_objects else ()):    # (the scene's objects)
                obj = inst.object
                if obj.type in GEOMETRY_TYPES:
                    objects.setdefault(instance_key(inst, obj), []).append(np.array(inst.matrix_world, np.float64))
    finally:
        engine.frame_set(frame, subframe)
    objects = {k: np.stack(v) for k, v in objects.items() if len(v) == len(times)}
    if len(matrices) != len(times):
        return None, objects
    m = np.stack(matrices)
    if not np.isfinite(m).all() or np.allclose(m, m[:1], atol=1e-7):
        return None, objects
    return m.astype(np.float32), objects
