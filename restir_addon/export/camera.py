"""The scene camera to core.Camera, and the render resolution."""

import numpy as np

from ...core.camera.projection import crop
from ...core.camera.panorama import TYPES as PANORAMA_TYPES
from ...core.scene import Camera


def render_size(scene):
    r = scene.render
    scale = r.resolution_percentage / 100.0
    return max(1, int(r.resolution_x * scale)), max(1, int(r.resolution_y * scale))


def render_region(scene):
    """(x0, y0, width, height): the pixels a final render computes, y0 from
    the bottom. With Output > Render Region (use_border) the region, its
    bounds truncated to pixels as Blender does (Blender's render result is
    that size, cropped or not); else the whole image."""
    w, h = render_size(scene)
    r = scene.render
    if not r.use_border:
        return 0, 0, w, h
    x0, x1 = int(r.border_min_x * w), int(r.border_max_x * w)
    y0, y1 = int(r.border_min_y * h), int(r.border_max_y * h)
    x0, y0 = min(max(x0, 0), w - 1), min(max(y0, 0), h - 1)
    return x0, y0, max(1, min(x1, w) - x0), max(1, min(y1, h) - y0)


def export_camera(depsgraph, warn, region=False):
    """core.Camera of the scene's active camera, or None when there is none.
    region: the camera of the render region alone (render_region), for final
    renders."""
    camera = _export_camera(depsgraph, warn)
    scene = depsgraph.scene
    if camera is None or not region or not scene.render.use_border:
        return camera
    x0, y0, w, h = render_region(scene)
    return crop(camera, *render_size(scene), x0, y0, w, h)


def _export_camera(depsgraph, warn):
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
    pano = {}
    if projection == "PANO":
        pano = panorama_settings(data, warn)
    elif projection not in ("PERSP", "ORTHO"):
        warn(f"Camera type '{projection}' is not supported; rendering as perspective")
        projection = "PERSP"
    if scene.render.pixel_aspect_x != scene.render.pixel_aspect_y:
        warn("Non-square pixel aspect is not supported; rendering with square pixels")
    _warn_blind(cam_obj, data, warn)
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
        **pano, **depth_of_field(cam_obj, data),
    )


def _warn_blind(cam_obj, data, warn):
    """Say why a camera sees nothing, where its settings make it so (the
    image stays black, as in Cycles)."""
    if data.type != "PANO" and data.clip_start >= data.clip_end:
        warn(f"Camera '{cam_obj.name}': Clip Start ({data.clip_start:g} m) is not before Clip End "
             f"({data.clip_end:g} m), so nothing is visible")
    axes = np.array(cam_obj.matrix_world, np.float64)[:3, :3]
    if not np.isfinite(axes).all() or abs(np.linalg.det(axes)) < 1e-18:
        warn(f"Camera '{cam_obj.name}' has a scale of zero (or a flat transform), so nothing is visible; "
             f"set its scale to 1")


def panorama_settings(data, warn):
    """core.Camera fields of a panoramic camera (core/camera/panorama.py); a type
    this engine does not know renders as equirectangular, with a warning."""
    kind = getattr(data, "panorama_type", "FISHEYE_EQUISOLID")
    if kind not in PANORAMA_TYPES:
        warn(f"Panorama type '{kind}' is not supported; rendering as equirectangular")
        kind = "EQUIRECTANGULAR"
    get = lambda name, default: float(getattr(data, name, default))    # noqa: E731
    return dict(panorama_type=kind, latitude_min=get("latitude_min", -np.pi / 2),
                latitude_max=get("latitude_max", np.pi / 2), longitude_min=get("longitude_min", -np.pi),
                longitude_max=get("longitude_max", np.pi), fisheye_fov=get("fisheye_fov", np.pi),
                fisheye_lens=get("fisheye_lens", 10.5),
                **{f"fisheye_polynomial_k{i}": get(f"fisheye_polynomial_k{i}", 0.0) for i in range(5)},
                **{f"central_cylindrical_range_{k}": get(f"central_cylindrical_range_{k}", d)
                   for k, d in (("u_min", -np.pi), ("u_max", np.pi), ("v_min", -1.0), ("v_max", 1.0))},
                central_cylindrical_radius=get("central_cylindrical_radius", 1.0))


def depth_of_field(cam_obj, data):
    """The camera's thin-lens settings as core.Camera fields, as Cycles reads
    them: aperture radius lens / (2 f-stop) (lens in mm, so 1e-3 scene
    units per mm; 1 / (2 f-stop) for an orthographic camera), and the focus
    distance along the view axis to the focus object when there is one."""
    dof = data.dof
    if not dof.use_dof:
        return {}
    fstop = max(float(dof.aperture_fstop), 1e-5)
    size = 1.0 / (2.0 * fstop) if data.type == "ORTHO" else float(data.lens) * 1e-3 / (2.0 * fstop)
    focus = float(dof.focus_distance)
    target = dof.focus_object
    if target is not None:
        m = np.array(cam_obj.matrix_world, np.float64)
        view = m[:3, 2] / max(np.linalg.norm(m[:3, 2]), 1e-12)
        focus = abs(float(np.dot(view, m[:3, 3] - np.array(target.matrix_world.translation, np.float64))))
    blades = int(dof.aperture_blades)
    return dict(aperture_size=size, focus_distance=max(focus, 1e-5), aperture_blades=blades if blades >= 3 else 0,
                aperture_rotation=float(dof.aperture_rotation), aperture_ratio=float(dof.aperture_ratio))
