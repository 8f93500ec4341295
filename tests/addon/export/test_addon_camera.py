"""Export of the scene camera to core.Camera: projection, sensor fit,
shift and clipping against Blender's own camera frame, depth of field as
Cycles reads it, the render size, and a scene without a camera.

Every test starts from an empty factory file (export_util.fresh).
"""

import math

import numpy as np
import pytest

from support.export_util import QUAD, add_mesh, export, fresh


def _camera(name, **props):
    import bpy
    data = bpy.data.cameras.new(name)
    for key, value in props.items():
        setattr(data, key, value)
    ob = bpy.data.objects.new(name, data)
    bpy.context.scene.collection.objects.link(ob)
    bpy.context.scene.camera = ob
    return ob


CAMERAS = {
    "persp_vertical": dict(type="PERSP", lens=35.0, sensor_width=32.0, sensor_height=18.0,
                           sensor_fit="VERTICAL", shift_x=0.1, shift_y=-0.05,
                           clip_start=0.5, clip_end=50.0),
    "persp_auto_portrait": dict(type="PERSP", lens=50.0, sensor_fit="AUTO", shift_x=-0.2),
    "ortho_horizontal": dict(type="ORTHO", ortho_scale=4.0, sensor_fit="HORIZONTAL",
                             shift_y=0.15, clip_start=0.01, clip_end=20.0),
}


@pytest.mark.parametrize("case", list(CAMERAS))
def test_camera_matches_blender_projection(addon, case, rng):
    import bpy
    from bpy_extras.object_utils import world_to_camera_view
    from mathutils import Vector
    project = addon.core.camera.projection.project
    scene = fresh()
    props = CAMERAS[case]
    width, height = (24, 40) if "portrait" in case else (40, 24)
    scene.render.resolution_x, scene.render.resolution_y = width, height
    cam = _camera(case, **props)
    cam.location, cam.rotation_euler = (1.0, -6.0, 2.0), (math.radians(80), 0.0, math.radians(10))
    bpy.context.view_layer.update()
    s = export(addon, width, height)
    c = s.camera

    assert c.projection == props["type"]
    np.testing.assert_allclose(c.to_world, np.array(cam.matrix_world), atol=1e-6)
    for key, value in props.items():
        if key != "type":
            got = getattr(c, key)
            assert got == value if isinstance(value, str) else math.isclose(got, value, rel_tol=1e-6), key

    # The exported camera projects world points where Blender's camera frame puts them.
    points = rng.uniform(-2, 2, (20, 3)) + [1.0, 0.0, 2.0]
    film, _ = project(c, width, height, points)
    for p, f in zip(points, film):
        ndc = world_to_camera_view(scene, cam, Vector(p))
        np.testing.assert_allclose(f, (ndc.x * width, ndc.y * height), atol=1e-3)


def test_camera_depth_of_field(addon):
    """Depth of field as Cycles reads it: aperture radius lens / (2 f-stop)
    (mm to scene units), 1 / (2 f-stop) for orthographic cameras, the focus
    object's distance along the view axis, no blades a disk; off: a
    pinhole. Its panels are shown for the engine."""
    import bpy
    scene = fresh()
    cam = _camera("dof", lens=40.0)
    cam.location, cam.rotation_euler = (1.0, -6.0, 2.0), (math.radians(80), 0.0, math.radians(10))
    assert export(addon, 16, 16).camera.aperture_size == 0.0          # use_dof off
    dof = cam.data.dof
    dof.use_dof, dof.aperture_fstop, dof.focus_distance = True, 2.0, 3.5
    dof.aperture_blades, dof.aperture_rotation, dof.aperture_ratio = 0, 0.4, 1.5
    bpy.context.view_layer.update()
    c = export(addon, 16, 16).camera
    assert math.isclose(c.aperture_size, 40.0e-3 / 4.0, rel_tol=1e-6) and math.isclose(c.focus_distance, 3.5)
    assert c.aperture_blades == 0 and math.isclose(c.aperture_ratio, 1.5) and math.isclose(c.aperture_rotation, 0.4, rel_tol=1e-6)
    target = bpy.data.objects.new("target", None)
    target.location = (3.0, 2.0, 1.0)
    scene.collection.objects.link(target)
    dof.focus_object, dof.aperture_blades = target, 6
    bpy.context.view_layer.update()
    c = export(addon, 16, 16).camera
    view = np.array(cam.matrix_world)[:3, 2]
    expected = abs(float(np.dot(view / np.linalg.norm(view), np.array(cam.matrix_world)[:3, 3] - target.location)))
    assert math.isclose(c.focus_distance, expected, rel_tol=1e-5) and c.aperture_blades == 6
    # The viewport looking through the camera has its depth of field; other views do not.
    from types import SimpleNamespace
    from_region = addon.restir_addon.sync.objects.camera_from_region
    view = np.linalg.inv(np.array(cam.matrix_world))
    window = np.array([[2.0, 0, 0, 0], [0, 2.0, 0, 0], [0, 0, -1.002, -0.2002], [0, 0, -1.0, 0]])
    through = from_region(SimpleNamespace(view_matrix=view, window_matrix=window, view_perspective="CAMERA"), scene)
    free = from_region(SimpleNamespace(view_matrix=view, window_matrix=window, view_perspective="PERSP"), scene)
    assert math.isclose(through.focus_distance, expected, rel_tol=1e-5) and through.aperture_size > 0
    assert free.aperture_size == 0.0
    cam.data.type = "ORTHO"
    bpy.context.view_layer.update()
    assert math.isclose(export(addon, 16, 16).camera.aperture_size, 0.25, rel_tol=1e-6)
    assert "RESTIR_GI" in bpy.types.DATA_PT_camera_dof.COMPAT_ENGINES
    assert "RESTIR_GI" in bpy.types.DATA_PT_camera_dof_aperture.COMPAT_ENGINES


def test_resolution_percentage(addon):
    import bpy
    scene = fresh()
    scene.render.resolution_x, scene.render.resolution_y = 200, 120
    scene.render.resolution_percentage = 25
    _camera("cam")
    s, has_camera = addon.restir_addon.export.export_scene(bpy.context.evaluated_depsgraph_get())
    assert has_camera
    assert (s.width, s.height) == (50, 30)


def test_no_camera(addon):
    import bpy
    fresh()
    add_mesh("obj", *QUAD)
    s, has_camera = addon.restir_addon.export.export_scene(bpy.context.evaluated_depsgraph_get(), 8, 8)
    assert not has_camera
    assert s.triangle_count == 2


@pytest.mark.parametrize("case", ["clipping", "scale"])
def test_a_blind_camera_says_why(addon, case):
    """Clip Start beyond Clip End, or a camera scaled to zero, sees nothing:
    the export names the camera and the reason; an ordinary camera says
    nothing."""
    import bpy
    fresh()
    add_mesh("obj", *QUAD)
    cam = _camera("Eye", clip_start=1.0, clip_end=100.0)
    cam.location = (0, 0, 5)
    assert not [w for w in export(addon, 8, 8).warnings if "Eye" in w]
    if case == "clipping":
        cam.data.clip_start, cam.data.clip_end = 50.0, 10.0
    else:
        cam.scale = (0.0, 0.0, 0.0)
    bpy.context.view_layer.update()
    said = [w for w in export(addon, 8, 8).warnings if "Eye" in w]
    assert len(said) == 1 and ("Clip Start" in said[0] if case == "clipping" else "scale of zero" in said[0]), said
