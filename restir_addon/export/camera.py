"""The scene camera to core.Camera, and the render resolution."""

import numpy as np

from ...core.scene import Camera


def render_size(scene):
    r = scene.render
    scale = r.resolution_percentage / 100.0
    return max(1, int(r.resolution_x * scale)), max(1, int(r.resolution_y * scale))


def export_camera(depsgraph, warn):
    """core.Camera of the scene's active camera, or None when there is none."""
    scene = depsgraph.scene
    cam_obj = scene.camera
    if cam_obj is None:
        return None
    cam_obj = cam_obj.evaluated_get(depsgraph)
    if cam_obj.type != "CAMERA":
        warn(f"Active camera '{cam_obj.name}' is not a camera object; using its transform with default lens")
        return Camera(to_world=np.array(cam_obj.matrix_world, np.float32))
    data = cam_obj.data
    projection = data.type
    if projection not in ("PERSP", "ORTHO"):
        warn(f"Camera type '{projection}' is not supported; rendering as perspective")
        projection = "PERSP"
    if scene.render.pixel_aspect_x != scene.render.pixel_aspect_y:
        warn("Non-square pixel aspect is not supported; rendering with square pixels")
    return Camera(
        to_world=np.array(cam_obj.matrix_world, np.float32),
        projection=projection,
        lens=float(data.lens),
        sensor_width=float(data.sensor_width),
        sensor_height=float(data.sensor_height),
        sensor_fit=data.sensor_fit,
        ortho_scale=float(data.ortho_scale),
        shift_x=float(data.shift_x),
        shift_y=float(data.shift_y),
        clip_start=float(data.clip_start),
        clip_end=float(data.clip_end),
    )
