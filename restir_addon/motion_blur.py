"""Motion blur of final renders: the camera's matrices over the shutter.

Render Properties > Motion Blur: the shutter (in frames) and its position
around the frame (start, centre, end), as Cycles reads them; the camera is
evaluated at the shutter's start, middle and end (Cycles' three motion
steps) by re-evaluating the scene at those subframes (RenderEngine.frame_set,
as Cycles does), and core/motion.py interpolates between them per camera
ray. Path Tracing only; objects' own motion is not blurred (a warning).
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


def camera_motion(engine, depsgraph, warn):
    """(STEPS, 4, 4) matrices of the scene camera over the shutter, or None
    when motion blur is off, the shutter is zero or the camera does not
    move. Leaves the scene evaluated at its frame again."""
    scene = depsgraph.scene
    times = shutter_times(scene.render, scene.frame_current + scene.frame_subframe)
    if times is None:
        return None
    warn("Motion blur: only the camera's motion is rendered, in Path Tracing; moving objects render sharp")
    if scene.camera is None:
        return None
    frame, subframe = scene.frame_current, scene.frame_subframe
    matrices = []
    try:
        for t in times:
            whole = math.floor(t)
            engine.frame_set(int(whole), t - whole)
            matrices.append(np.array(depsgraph.scene.camera.evaluated_get(depsgraph).matrix_world, np.float64))
    finally:
        engine.frame_set(frame, subframe)
    m = np.stack(matrices)
    if not np.isfinite(m).all() or np.allclose(m, m[:1], atol=1e-7):
        return None
    return m.astype(np.float32)
