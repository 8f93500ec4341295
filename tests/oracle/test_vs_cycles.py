"""The path tracer against Cycles, the independent oracle shipped in bpy.

The same Cornell box (Diffuse BSDF walls) is lit by an emissive quad, a point
light and an area light and rendered by both engines, each twice with
independent seeds. Mean brightness must agree within 2 %, and the block-wise
differences must be what the noise allows: the sum of squared block differences
over the sum of their estimated variances (from each engine's two independent
renders) stays near 1; a brightness convention off by a few percent, or a
missing light path, pushes it far above.
"""

import numpy as np
import pytest

from support.blender_util import compare_with_cycles, open_example, set_resolution

SIZE = 64
BLOCK = 8
SAMPLES = 128
BOUNCES = 8


def _cornell(light):
    import bpy
    scene = open_example("cornell_box.blend")
    set_resolution(scene, SIZE, SIZE)
    if light != "emitter":
        bpy.data.objects.remove(bpy.data.objects["CeilingLight"])
        if light == "point":
            data = bpy.data.lights.new("Point", "POINT")
            data.energy = 60.0
            data.shadow_soft_size = 0.05
            obj = bpy.data.objects.new("Point", data)
            obj.location = (0.0, 0.0, 1.7)
        else:
            data = bpy.data.lights.new("Area", "AREA")
            data.energy = 60.0
            data.shape = "RECTANGLE"
            data.size, data.size_y = 0.6, 0.4
            obj = bpy.data.objects.new("Area", data)
            obj.location = (0.0, 0.0, 1.98)
        scene.collection.objects.link(obj)
    return scene


@pytest.mark.parametrize("light", ["emitter", "point", "area"])
def test_cornell_box_matches_cycles(addon, light):
    r = compare_with_cycles(_cornell(light), SAMPLES, BOUNCES, BLOCK)
    assert np.isfinite(r["ours"]).all()
    print(f"{light}: mean ours {r['ours_mean']:.4f} cycles {r['cycles_mean']:.4f} "
          f"ratio {r['ratio']:.4f} block chi {r['chi']:.2f}")
    assert abs(r["ratio"] - 1.0) < 0.02
    assert r["chi"] < 2.5


def test_depth_of_field_matches_cycles(addon):
    """Camera depth of field (f/0.1, a triangular aperture, focused on an
    empty in front of the short box): Cycles' thin lens. Compared below the
    emitter's brightness (its blurred outline is mostly noise). Without
    depth of field the block chi is 8.6, with 0.8x the aperture 2.5."""
    import bpy
    scene = _cornell("emitter")
    focus = bpy.data.objects.new("Focus", None)
    focus.location = (0.35, -0.7, 0.3)
    scene.collection.objects.link(focus)
    dof = scene.camera.data.dof
    dof.use_dof = True
    dof.focus_object = focus
    dof.aperture_fstop = 0.1
    dof.aperture_blades = 3
    dof.aperture_rotation = 0.2
    r = compare_with_cycles(scene, SAMPLES, BOUNCES, BLOCK, clamp=1.0)
    print(f"dof: ratio {r['ratio']:.4f} block chi {r['chi']:.2f}")
    assert abs(r["ratio"] - 1.0) < 0.02
    assert r["chi"] < 2.5


def test_stereo_right_eye_matches_cycles(addon):
    """Stereo 3D (interocular 0.3, Off-Axis): the right eye, moved and
    shifted by Blender's stereo rig, against Cycles' right eye (block chi
    1510 with the left eye's shift)."""
    scene = _cornell("emitter")
    scene.render.use_multiview = True
    scene.render.views_format = "STEREO_3D"
    scene.camera.data.stereo.interocular_distance = 0.3
    r = compare_with_cycles(scene, SAMPLES // 2, BOUNCES, BLOCK, clamp=1.0, view="R")
    print(f"stereo right eye: ratio {r['ratio']:.4f} block chi {r['chi']:.2f}")
    assert abs(r["ratio"] - 1.0) < 0.02
    assert r["chi"] < 2.5
