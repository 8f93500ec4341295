"""The camera of a final render's view: one view of Blender's stereo rig,
or the scene camera with its motion over the shutter (motion_blur.py)."""

from dataclasses import replace

import numpy as np

from ..core.camera.projection import crop
from .export.camera import export_camera, render_region, render_size
from .motion_blur import camera_motion


def view_names(scene):
    """The views to render: [None] without stereoscopy; left and right for
    Stereo 3D; the enabled views for Multi-View."""
    r = scene.render
    if not r.use_multiview:
        return [None]
    if r.views_format == "STEREO_3D":
        return ["left", "right"]
    return [v.name for v in r.views if v.use] or [None]


def view_camera(engine, depsgraph, view, warn):
    """core.Camera of one view of the scene camera (Blender's stereo rig:
    the view's matrix and shift from the engine), or None for the camera
    itself (view None)."""
    if view is None:
        return None
    scene = depsgraph.scene
    cam_obj = scene.camera
    base = export_camera(depsgraph, warn)
    if base is None or cam_obj is None or cam_obj.type != "CAMERA":
        return base
    engine.active_view_set(view)
    matrix = np.array(engine.camera_model_matrix(cam_obj, use_spherical_stereo=False), np.float32).reshape(4, 4)
    camera = replace(base, to_world=matrix,
                     shift_x=float(engine.camera_shift_x(cam_obj, use_spherical_stereo=False)))
    if scene.render.use_border:
        camera = crop(camera, *render_size(scene), *render_region(scene))
    return camera


def moving_camera(engine, depsgraph, warn, objects=True):
    """(camera, objects): the scene camera with its motion over the shutter
    (motion_blur.py), or None (the frame's camera), and the objects'
    matrices over the shutter by object key ({} without motion blur, or
    without ``objects``: the ReSTIR modes blur the camera's motion only),
    and the deforming objects' triangle corners by object key."""
    motion, objects, deformed = camera_motion(engine, depsgraph, warn, objects)
    if motion is None:
        return None, objects, deformed
    camera = export_camera(depsgraph, warn, region=True)
    return (None if camera is None else replace(camera, motion=motion)), objects, deformed
